"""Benchmark: regenerate the HTML report of a full-size campaign archive (target: under 10 s).

Builds a synthetic archive laid out as docs/archive.md says (28 configurations of Appendix A, 68 brace-on
trials of 65 s at 1 kHz, brace-off trials, calibration checks, fits) in a temporary directory, then times
`generate_report` over several repeats, single-process and with the default worker count, and prints the
medians, the archive size and the report size.

    python benchmarks/bench_report.py [--repeats N] [--keep DIR] [--archive ARCHIVE.h5]

`--archive` times an existing archive instead (e.g. the one of a full `--dry-run` of knee_phase1).
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.report.report_archive_builder import ArchiveSpec, ConfigSpec, write_archive  # noqa: E402

from protocol_runner.report.figure_plan import default_workers, figure_ids  # noqa: E402
from protocol_runner.report.load import load_report_data  # noqa: E402
from protocol_runner.report.render import generate_report  # noqa: E402


def campaign_spec() -> ArchiveSpec:
    """Appendix A: three trials per configuration except 15-17 (no springs) and 24-28 (EMU): 68 in all."""
    configs = []
    for key in range(1, 29):
        n_trials = 1 if key in (15, 16, 17) or key >= 24 else 3
        configs.append(
            ConfigSpec(
                key=key, energy_j=2.0 + 0.2 * key, n_trials=n_trials, slope_nm_per_deg=0.1 + 0.01 * key
            )
        )
    return ArchiveSpec(
        configs=configs, duration_s=65.0, reference=True, interrupted=True, compress_floats=True
    )


def _cpu_s() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)  # finished worker processes
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


_CPU: list[float] = []


def _time(fn: object, repeats: int) -> list[float]:
    """Wall-clock seconds per repeat; the CPU seconds (this process + workers) go to _CPU."""
    out = []
    _CPU.clear()
    for _ in range(repeats):
        c0 = _cpu_s()
        t0 = time.perf_counter()
        fn()  # type: ignore[operator]
        out.append(time.perf_counter() - t0)
        _CPU.append(_cpu_s() - c0)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--keep", type=Path, default=None, help="write the archive and report here")
    parser.add_argument("--archive", type=Path, default=None, help="time this archive instead")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        if args.archive is not None:
            archive = args.archive
            print(f"archive: {archive} ({archive.stat().st_size / 1e6:.1f} MB)")
        else:
            archive = folder / "archive.h5"
            t0 = time.perf_counter()
            spec = campaign_spec()
            write_archive(archive, spec)
            n_trials = sum(c.n_trials for c in spec.configs)
            print(
                f"archive: {len(spec.configs)} configurations, {n_trials} brace-on trials of "
                f"{spec.duration_s:.0f} s at {spec.rate_hz:.0f} Hz, {archive.stat().st_size / 1e6:.1f} MB "
                f"(built in {time.perf_counter() - t0:.1f} s)"
            )
        load = _time(lambda: load_report_data(archive), args.repeats)
        data = load_report_data(archive)
        n_figures = len(figure_ids(data))
        print(f"load_report_data: median {statistics.median(load):.2f} s  ({n_figures} figures to draw)")
        report = folder / "report.html"
        single = _time(lambda: generate_report(archive, report, workers=1), args.repeats)
        single_cpu = statistics.median(_CPU)
        workers = default_workers(n_figures)
        multi = _time(lambda: generate_report(archive, report, workers=workers), args.repeats)
        multi_cpu = statistics.median(_CPU)
        print(
            f"generate_report, 1 process : median {statistics.median(single):.2f} s "
            f"(min {min(single):.2f}, max {max(single):.2f}; CPU {single_cpu:.2f} s)"
        )
        print(
            f"generate_report, {workers} processes: median {statistics.median(multi):.2f} s "
            f"(min {min(multi):.2f}, max {max(multi):.2f}; CPU {multi_cpu:.2f} s)  <- default; target < 10 s"
        )
        print(f"report: {report.stat().st_size / 1e6:.2f} MB, {n_figures} inline figures")
        print(
            f"load average now: {', '.join(f'{x:.2f}' for x in os.getloadavg())} (other jobs slow the wall times)"
        )


if __name__ == "__main__":
    main()
