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
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.report.report_archive_builder import ArchiveSpec, ConfigSpec, write_archive  # noqa: E402

from protocol_runner.report.figures import default_workers, figure_ids  # noqa: E402
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


def _time(fn: object, repeats: int) -> list[float]:
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()  # type: ignore[operator]
        out.append(time.perf_counter() - t0)
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
        workers = default_workers(n_figures)
        multi = _time(lambda: generate_report(archive, report, workers=workers), args.repeats)
        print(
            f"generate_report, 1 process : median {statistics.median(single):.2f} s "
            f"(min {min(single):.2f}, max {max(single):.2f})"
        )
        print(
            f"generate_report, {workers} processes: median {statistics.median(multi):.2f} s "
            f"(min {min(multi):.2f}, max {max(multi):.2f})  <- default; target < 10 s"
        )
        print(f"report: {report.stat().st_size / 1e6:.2f} MB, {n_figures} inline figures")


if __name__ == "__main__":
    main()
