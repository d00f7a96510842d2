"""The fits of a whole campaign, alone: CPU time of fitting every configuration (and joint) of an archive as
the session's fit steps do - the Bouc-Wen fit and the model comparison (element model, reduced Dahl
model, with their leave-one-trial-out refits) - per configuration against a budget of 1 s, and whether a
second checkout gives the same Bouc-Wen numbers.

    python benchmarks/bench_fits.py [--archive A.h5] [--protocol knee_phase1.yaml] [--repeats 5]
                                    [--baseline DIR [--rtol R]] [--budget-s 1.0]

The fits are the largest share of a dry run's CPU (docs/simulator.md), and a full dry run's wall time moves
with the shared machine by several per cent between sittings; this measures them without the rest, in one
process and one thread. Each repeat is a fresh subprocess (from this checkout, or `--baseline`'s, with its
src/ first on the path) that reads every configuration's stored processed loops and trials from the
archive (default: a seeded dry run of the protocol made first, `--seed 7`; for a several-joint archive,
every joint that carries a device), fits them with the protocol's `fits.bouc_wen` settings
(`analysis.service.fit_stored_loops`, as the fit step: the fit, its intervals, the leave-one-trial-out
errors and the model torques, with the stored device for the "elements" backbone) and, where the
configuration declares a device and the checkout has it, the model comparison
(`analysis.model_comparison.compare_models`), after one small warm-up of both, and prints each
configuration's process CPU of the two and in total. The per-configuration table shows the median over
the repeats, PASS where the total is within `--budget-s`, FAIL otherwise; the script exits non-zero when
any configuration fails.

With `--baseline` the two checkouts alternate run by run, and the script also checks that both give every
configuration the same Bouc-Wen RMSE, R^2, parameters and cross-validated errors, bit for bit (a speed-up
of the fits must not change what they find), or with RMSE, R^2 and held-out errors within `--rtol`
(relative) for a change whose tolerance is documented (docs/analysis.md); it prints the largest relative
differences of those and of the parameters either way. Prints the medians and the ratio.
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
try:
    from protocol_runner.analysis.model_comparison import compare_models
    from protocol_runner.archive.model_results import read_processed_trials, stored_device
except ImportError:  # a checkout without the model comparison: the Bouc-Wen fits alone
    compare_models = None

archive, protocol = sys.argv[1], sys.argv[2]
settings = bouc_wen_settings(load_protocol(find_protocol(protocol)))
units = {}
with h5py.File(archive, "r") as f:
    for name in sorted(f["configurations"]):
        cfg = f[f"configurations/{name}"]
        joints = [(f"{name}/{j}", cfg[f"joints/{j}"], j) for j in cfg["joints"]] if "joints" in cfg else []
        for label, group, joint in joints or [(name, cfg, "")]:
            if "trials" not in group:
                continue
            trials = group["trials"]
            processed = [trials[t]["processed"] for t in sorted(trials, key=int) if "processed" in trials[t]]
            if not processed:
                continue
            device = stored_device(cfg, joint) if compare_models is not None else ()
            if joints and not device:
                continue  # a joint without a device is not fitted
            units[label] = (
                [(p["angle_deg"][()], p["brace_torque_nm"][()]) for p in processed],
                read_processed_trials(trials) if compare_models is not None else [],
                device,
            )
if settings.backbone == "elements" and compare_models is None:
    sys.exit("the 'elements' backbone needs the stored device: not supported by this checkout")
backbone_device = lambda device: [(e.name, e.type, e.params) for e in device] or None
loops, trials, device = next(iter(units.values()))
warm = fit_stored_loops(loops[:2], settings, backbone_device(device))  # numba's cache, scipy's first calls
if device:
    compare_models(trials[:2], device, warm)
numbers, times = {}, {}
for name, (loops, trials, device) in units.items():
    c0 = time.process_time()
    result = fit_stored_loops(loops, settings, backbone_device(device))
    c1 = time.process_time()
    if device:
        compare_models(trials, device, result)
    c2 = time.process_time()
    times[name] = [c1 - c0, c2 - c1]
    fit = result.fit
    numbers[name] = {
        "findings": [fit.rmse_nm, fit.r2, *result.cv_rmse_nm],
        "parameters": fit.params.as_array().tolist(),
    }
cpu = sum(a + b for a, b in times.values())
print(json.dumps({"cpu_s": cpu, "configurations": len(units), "numbers": numbers, "times": times}))
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
    ap.add_argument("--budget-s", type=float, default=1.0, help="CPU budget of one configuration's fits")
    args = ap.parse_args()
    checkouts = [("this", HERE)] + ([("baseline", args.baseline.resolve())] if args.baseline else [])
    with tempfile.TemporaryDirectory() as tmp:
        archive = args.archive.resolve() if args.archive else _seeded_archive(args.protocol, Path(tmp))
        cpu: dict[str, list[float]] = {name: [] for name, _ in checkouts}
        numbers: dict[str, dict[str, dict[str, list[float]]]] = {}
        times: dict[str, dict[str, list[list[float]]]] = {name: {} for name, _ in checkouts}
        for k in range(args.repeats):
            order = checkouts if k % 2 == 0 else checkouts[::-1]
            for name, checkout in order:
                run = _fits(checkout, archive, args.protocol)
                cpu[name].append(float(run["cpu_s"]))
                numbers.setdefault(name, run["numbers"])
                for unit, split in run["times"].items():
                    times[name].setdefault(unit, []).append(split)
                print(
                    f"run {k + 1} ({name}): {run['cpu_s']:.2f} s CPU, {run['configurations']} configurations"
                )
    failed = _budget_table(times["this"], args.budget_s)
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
    if failed:
        sys.exit(f"FAIL {len(failed)} configuration(s) over {args.budget_s:g} s: {', '.join(failed)}")
    if args.baseline is not None and not result["same_numbers_bit_for_bit"]:
        differ = [c for c, d in worst.items() if d > args.rtol]
        if differ:
            allowed = "bit for bit" if args.rtol == 0.0 else f"within {args.rtol:g}"
            sys.exit(
                f"FAIL the two checkouts do not fit the same numbers ({allowed}) for {', '.join(differ)}"
            )


def _budget_table(times: dict[str, list[list[float]]], budget_s: float) -> list[str]:
    """Print each configuration's median CPU of the Bouc-Wen fit, the model comparison and both, PASS or
    FAIL against `budget_s`; return the failing ones."""
    failed = []
    print(f"{'configuration':<28} {'bouc_wen_s':>10} {'models_s':>9} {'total_s':>8}")
    for unit, runs in times.items():
        bouc_wen = statistics.median(r[0] for r in runs)
        models = statistics.median(r[1] for r in runs)
        total = statistics.median(r[0] + r[1] for r in runs)
        verdict = "PASS" if total <= budget_s else "FAIL"
        if verdict == "FAIL":
            failed.append(unit)
        print(f"{unit:<28} {bouc_wen:>10.3f} {models:>9.3f} {total:>8.3f} {verdict}")
    worst = max((statistics.median(r[0] + r[1] for r in runs) for runs in times.values()), default=0.0)
    print(f"slowest configuration {worst:.3f} s CPU (budget {budget_s:g} s): {'FAIL' if failed else 'PASS'}")
    return failed


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
