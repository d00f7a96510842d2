"""The Bouc-Wen fits of a whole campaign, alone: CPU time of fitting every configuration of an archive as the
session's fit steps do, and whether a second checkout gives the same numbers.

    python benchmarks/bench_fits.py [--archive A.h5] [--protocol knee_phase1.yaml] [--repeats 5]
                                    [--baseline DIR [--rtol R]]

The fits are the largest share of a dry run's CPU (docs/simulator.md), and a full dry run's wall time moves
with the shared machine by several per cent between sittings; this measures them without the rest, in one
process and one thread. Each repeat is a fresh subprocess (from this checkout, or `--baseline`'s, with its
src/ first on the path) that reads every configuration's stored processed loops from the archive (default:
a seeded dry run of the protocol made first, `--seed 7`), fits them with the protocol's `fits.bouc_wen`
settings (`analysis.service.fit_stored_loops`, as the fit step: the fit, its intervals, the leave-one-trial-
out errors and the model torques; the "elements" backbone, which needs the device, is not supported here),
after one small warm-up fit, and prints the process CPU of the fits. With `--baseline` the two checkouts
alternate run by run, and the script also checks that both give every configuration the same RMSE, R^2,
parameters and cross-validated errors, bit for bit (a speed-up of the fits must not change what they find),
or with RMSE, R^2 and held-out errors within `--rtol` (relative) for a change whose tolerance is documented
(docs/analysis.md); it prints the largest relative differences of those and of the parameters either way.
Prints the medians and the ratio.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parents[1]

# Runs in the measured checkout: fits every configuration and prints one JSON line (CPU and the numbers).
CHILD = r"""
import json, sys, time
import h5py
from protocol_runner.protocol.loader import find_protocol, load_protocol
from protocol_runner.protocol.processing import bouc_wen_settings
from protocol_runner.analysis.service import fit_stored_loops

archive, protocol = sys.argv[1], sys.argv[2]
settings = bouc_wen_settings(load_protocol(find_protocol(protocol)))
if settings.backbone == "elements":
    sys.exit("the 'elements' backbone needs the device: not supported by this benchmark")
loops = {}
with h5py.File(archive, "r") as f:
    for name in sorted(f["configurations"]):
        trials = f[f"configurations/{name}/trials"]
        group = [trials[t]["processed"] for t in sorted(trials, key=int) if "processed" in trials[t]]
        if group:
            loops[name] = [(p["angle_deg"][()], p["brace_torque_nm"][()]) for p in group]
first = next(iter(loops.values()))
fit_stored_loops(first[:2], settings)  # warm-up: numba's cache loaded, scipy's first calls made
numbers = {}
c0 = time.process_time()
for name, segments in loops.items():
    result = fit_stored_loops(segments, settings)
    fit = result.fit
    numbers[name] = {
        "findings": [fit.rmse_nm, fit.r2, *result.cv_rmse_nm],
        "parameters": fit.params.as_array().tolist(),
    }
cpu = time.process_time() - c0
print(json.dumps({"cpu_s": cpu, "configurations": len(loops), "numbers": numbers}))
"""


def _fits(checkout: Path, archive: Path, protocol: str) -> dict[str, Any]:
    env = dict(os.environ, PYTHONPATH=str(checkout / "src"), OPENBLAS_NUM_THREADS="1")
    out = subprocess.run(
        [sys.executable, "-c", CHILD, str(archive), protocol],
        cwd=checkout,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    run: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    return run


def _seeded_archive(protocol: str, tmp: Path) -> Path:
    session = tmp / "session"
    print(f"making a seeded dry run of {protocol} (--seed 7) ...", flush=True)
    cmd = [sys.executable, "-m", "protocol_runner.cli", protocol, "--dry-run", "--seed", "7"]
    made = subprocess.run(
        [*cmd, "--session", str(session)],
        cwd=HERE,
        env=dict(os.environ, PYTHONPATH=str(HERE / "src")),
        capture_output=True,
        text=True,
    )
    if made.returncode != 0:
        sys.exit(f"the dry run failed (exit {made.returncode}):\n{made.stderr[-2000:]}")
    return session / "archive.h5"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--archive", type=Path, default=None, help="archive whose configurations are fitted")
    ap.add_argument("--protocol", default="knee_phase1.yaml", help="protocol whose fit settings are used")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--baseline", type=Path, default=None, help="another checkout to time in the same run")
    ap.add_argument(
        "--rtol", type=float, default=0.0, help="largest relative difference allowed from the baseline"
    )
    args = ap.parse_args()
    checkouts = [("this", HERE)] + ([("baseline", args.baseline.resolve())] if args.baseline else [])
    with tempfile.TemporaryDirectory() as tmp:
        archive = args.archive.resolve() if args.archive else _seeded_archive(args.protocol, Path(tmp))
        cpu: dict[str, list[float]] = {name: [] for name, _ in checkouts}
        numbers: dict[str, dict[str, dict[str, list[float]]]] = {}
        for k in range(args.repeats):
            order = checkouts if k % 2 == 0 else checkouts[::-1]
            for name, checkout in order:
                run = _fits(checkout, archive, args.protocol)
                cpu[name].append(float(run["cpu_s"]))
                numbers.setdefault(name, run["numbers"])
                print(
                    f"run {k + 1} ({name}): {run['cpu_s']:.2f} s CPU, {run['configurations']} configurations"
                )
    result: dict[str, object] = {
        name: {"cpu_s_median": round(statistics.median(v), 3)} for name, v in cpu.items()
    }
    if args.baseline is not None:
        result["less_cpu_than_baseline"] = round(
            statistics.median(cpu["baseline"]) / statistics.median(cpu["this"]), 3
        )
        result["same_numbers_bit_for_bit"] = numbers["this"] == numbers["baseline"]
        # the fits' findings (RMSE, R^2, held-out errors) against --rtol; the parameters only reported (those
        # the data leave open move far more than the errors when the optimum moves a little)
        worst = {c: _largest_relative_difference(numbers, c, "findings") for c in numbers["this"]}
        result["largest_relative_difference_rmse_r2_cv"] = max(worst.values(), default=0.0)
        result["largest_relative_difference_parameters"] = max(
            (_largest_relative_difference(numbers, c, "parameters") for c in numbers["this"]), default=0.0
        )
    print(json.dumps(result, indent=2))
    if args.baseline is not None and not result["same_numbers_bit_for_bit"]:
        differ = [c for c, d in worst.items() if d > args.rtol]
        if differ:
            allowed = "bit for bit" if args.rtol == 0.0 else f"within {args.rtol:g}"
            sys.exit(
                f"FAIL the two checkouts do not fit the same numbers ({allowed}) for {', '.join(differ)}"
            )


def _largest_relative_difference(numbers: dict[str, Any], configuration: str, kind: str) -> float:
    """The largest |a - b| / |b| between this checkout's and the baseline's `kind` numbers ("findings" or
    "parameters") of one configuration (inf when they do not pair up; equal numbers, NaN with NaN
    included, differ by 0)."""
    this = numbers["this"][configuration][kind]
    baseline = numbers["baseline"].get(configuration, {}).get(kind)
    if baseline is None or len(this) != len(baseline):
        return math.inf
    worst = 0.0
    for a, b in zip(this, baseline, strict=True):
        if a == b or (math.isnan(a) and math.isnan(b)):
            continue
        worst = max(worst, abs(a - b) / abs(b) if b != 0.0 else math.inf)
    return worst


if __name__ == "__main__":
    main()
