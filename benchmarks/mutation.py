"""Mutation score of the science modules (analysis/ and models/), per module, in bounded time.

Tool: cosmic-ray (``pip install -e ".[dev,mutation]"``).  It edits one source file at a time and runs a test command in
a fresh process, so it also mutates the numba ``@njit`` kernels (``models/bouc_wen/kernels.py``) and
module-level constants (the Eq 24/25 matrices), which a trampoline-based tool (mutmut 3) leaves out.

What it does:

1. Copies ``src/``, ``tests/``, ``protocols/``, ``reports/``, ``docs/`` and ``pyproject.toml`` of the working tree into a scratch directory (one
   copy per job): the mutants are written to the copy, never to the checkout.
2. For each module it lists cosmic-ray's mutants, drops those that are not plausible bugs (see
   ``_not_plausible``), draws a seeded sample of at most ``--sample`` of them (the same sample on every
   run while the source is unchanged, so scores before and after new tests compare) and leaves out of
   the sample the mutants judged equivalent in ``benchmarks/mutation_equivalents.txt``.
3. Runs the module's own test files (``TESTS`` below) once unmutated, to check they pass and to time
   them, then once per sampled mutant with ``pytest -x`` and a timeout of ``3 x baseline + 15 s`` (a
   timeout counts as killed: the mutant hangs the analysis).
4. Prints ``killed / tested`` per module and writes every surviving mutant (file, line, operator, diff) to
   ``<out>/survivors.txt``.

Run: ``python benchmarks/mutation.py [--sample 40] [--jobs 2] [--modules energy,spring] [--out DIR]``.
The defaults finish in well under 30 minutes on a 2-core machine.  Not part of ``.ci/run``.
"""

from __future__ import annotations

import argparse
import ast
import json
import multiprocessing
import os
import random
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
EQUIVALENTS = Path(__file__).resolve().parent / "mutation_equivalents.txt"

# The science packages: their modules are found on disk, so a new module is scored as soon as
# it exists (devices/ and expectations/ too, once they do).
SCIENCE = ("analysis", "models", "devices", "expectations")


def _science_modules() -> dict[str, str]:
    """module (relative to src/protocol_runner) -> glob of its test files (relative to the repository root).

    A module's tests are ``tests/*/test_<name>*.py``; a module inside a sub-package
    (models/bouc_wen/fitting.py) shares ``tests/*/test_<sub-package>*.py`` (the sub-package is one model;
    its evidence tests, tests/analysis/test_bouc_wen_evidence.py, count too).
    """
    out: dict[str, str] = {}
    base = ROOT / "src" / "protocol_runner"
    for package in SCIENCE:
        for path in sorted((base / package).rglob("*.py")):
            if path.name == "__init__.py":
                continue
            rel = path.relative_to(base)
            name = rel.parts[1] if len(rel.parts) > 2 else path.stem
            out[rel.as_posix()] = (
                f"tests/*/test_{name}*.py"  # any folder: fit evidence tests sit in analysis/
            )
    return out


# Science outside those packages: the metric library and the expectation evaluator of the report,
# scored with their in-memory tests (seconds; the archive-based tests/report/test_report_expectations.py
# takes minutes per mutant on a loaded machine). A module's tests may be several globs, space-separated.
REPORT_SCIENCE = {
    "report/headline.py": "tests/report/test_metrics.py tests/report/test_metrics_joints.py",
    "report/evaluate.py": "tests/report/test_evaluate.py",
}

# Modules of the Bouc-Wen sub-package with fact tests of their own, scored with those (seconds per mutant)
# rather than every tests/*/test_bouc_wen*.py (about a minute per mutant on a loaded two-core machine, which
# alone would take the default run past 30 minutes); each set alone scores its module at 90 % or more
# (re-check with --modules when the module or its tests change).
MODEL_SCIENCE = {
    "models/bouc_wen/backbone.py": "tests/models/test_bouc_wen_backbone_facts.py",
    "models/bouc_wen/copies.py": "tests/models/test_bouc_wen_copies_facts.py",
    "models/bouc_wen/kernels.py": "tests/models/test_bouc_wen_integrator_facts.py tests/models/test_bouc_wen_kernels.py",
    "models/bouc_wen/schemes.py": "tests/models/test_bouc_wen_integrator_facts.py",
    "models/bouc_wen/identifiability.py": "tests/models/test_bouc_wen_identifiability*.py",
    "models/bouc_wen/fitting.py": "tests/models/test_bouc_wen_fitting*.py tests/models/test_bouc_wen_facts.py "
    "tests/models/test_bouc_wen_crossval_facts.py tests/models/test_bouc_wen_starts*.py "
    "tests/models/test_bouc_wen_threads*.py tests/models/test_bouc_wen_options*.py",
    "models/bouc_wen/params.py": "tests/models/test_bouc_wen_params*.py",
    "models/bouc_wen/problem.py": "tests/models/test_bouc_wen_problem*.py tests/models/test_bouc_wen_facts.py "
    "tests/models/test_bouc_wen_simulation.py",  # the latter: the 4x-finer check, refined_rmse
    "models/bouc_wen/simulation.py": "tests/models/test_bouc_wen_simulation*.py tests/models/test_bouc_wen_refined.py",
    "models/bouc_wen/records.py": "tests/models/test_bouc_wen_records*.py",
    # the element registry and its types: the registry's contract and documentation tests (seconds)
    "models/element_types.py": "tests/models/test_elements_*.py",
    "models/elements.py": "tests/models/test_elements_*.py",
    "models/element_torques.py": "tests/models/test_element_torques*.py",
}

# Science modules whose name glob picks the wrong tests: analysis/bouc_wen_fit.py would get the models'
# tests/models/test_bouc_wen_fitting.py (which never imports it) and not its evidence tests;
# analysis/reference.py would get a dry run of a whole session (tests/session/test_reference_dataset.py).
NARROWED = {
    "analysis/bouc_wen_fit.py": "tests/analysis/test_bouc_wen_fit_*.py tests/analysis/test_bouc_wen_evidence.py",
    "analysis/reference.py": "tests/analysis/test_reference*.py",
    # fact files only: test_element_fit.py's simulated-rig run through the processing and
    # test_elastic_backbone.py's cross-validated fit take 10-15 s each, a pass per surviving mutant
    "analysis/element_fit.py": "tests/analysis/test_element_fit_facts.py tests/analysis/test_element_fit_lever*.py",
    "analysis/elastic_backbone.py": "tests/analysis/test_elastic_backbone_facts.py",
    # the element model's fit and the model comparison are stated with the element model
    "analysis/model_fit.py": "tests/models/test_element_model_*.py",
    "analysis/model_comparison.py": "tests/models/test_element_model_*.py",
    # the settings' limits and descriptions are stated where the pipeline takes them
    "analysis/processing_settings.py": "tests/analysis/test_pipeline_settings.py tests/protocol/test_processing_settings.py",
}

TESTS = _science_modules() | MODEL_SCIENCE | REPORT_SCIENCE | NARROWED

ARITHMETIC = {"Add", "Sub", "Mul", "Div", "FloorDiv"}
LOGICAL = {"BitAnd", "BitOr"}
_BINOP = re.compile(r"core/ReplaceBinaryOperator_(\w+?)_(\w+)$")


def _not_plausible(operator: str) -> bool:
    """Mutations left out as not plausible bugs: bit shifts, xor, ``%`` and ``**`` in place of arithmetic
    (a float array raises at once), arithmetic in place of a mask ``&``/``|``, ``~`` for ``-``, and removed
    decorators (``@dataclass`` fails at once; ``@njit`` only makes the kernel slower)."""
    if operator == "core/RemoveDecorator" or operator.endswith("_Invert"):
        return True
    m = _BINOP.match(operator)
    if m is None:
        return False
    src, dst = m.groups()
    return not ({src, dst} <= ARITHMETIC or {src, dst} <= LOGICAL)


def _annotation_spans(path: Path) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """(line, col) positions inside annotations: with ``from __future__ import annotations`` a mutated
    annotation is never evaluated, so those mutants are equivalent by construction."""
    spans: list[tuple[tuple[int, int], tuple[int, int]]] = []
    for node in ast.walk(ast.parse(path.read_text())):
        annotations = []
        if isinstance(node, ast.arg | ast.AnnAssign) and node.annotation is not None:
            annotations.append(node.annotation)
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.returns is not None:
            annotations.append(node.returns)
        for a in annotations:
            spans.append(((a.lineno, a.col_offset), (a.end_lineno or a.lineno, a.end_col_offset or 0)))
    return spans


def _bare_star(source: list[str], pos: tuple[int, int]) -> bool:
    """cosmic-ray takes the keyword-only marker ``*`` of a signature for a multiplication."""
    rest = source[pos[0] - 1][pos[1] :]
    return rest.startswith("*") and rest[1:].lstrip()[:1] in (",", ")", "")


def _equivalents(module: str) -> set[tuple[str, str, str]]:
    """(source line, mutated line, enclosing function or ""), stripped, of the mutants of `module` judged
    equivalent in benchmarks/mutation_equivalents.txt: blocks of ``module:``, ``in:`` (optional: the
    function, when the same line occurs in several), ``source:``, ``mutant:`` and ``why:`` lines, separated by
    blank lines; ``mutant: *`` stands for every mutant of that source line."""
    out: set[tuple[str, str, str]] = set()
    if not EQUIVALENTS.exists():
        return out
    for block in re.split(r"\n\s*\n", EQUIVALENTS.read_text()):
        fields = {}
        for line in block.splitlines():
            key, sep, value = line.partition(":")
            if sep and key.strip() in ("module", "in", "source", "mutant", "why"):
                fields[key.strip()] = value.strip()
        if fields.get("module") == module and "source" in fields and "mutant" in fields:
            out.add((fields["source"], fields["mutant"], fields.get("in", "")))
    return out


def _is_equivalent(equivalent: set[tuple[str, str, str]], line: str, mutated: str | None, where: str) -> bool:
    return any(
        src == line and (mut == "*" or mut == mutated) and (not fn or fn == where)
        for src, mut, fn in equivalent
    )


def _copy_tree(dest: Path) -> None:
    dest.mkdir(parents=True)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", ".hypothesis")
    for name in ("src", "tests", "protocols", "reports", "docs"):  # tests read protocols, templates, docs
        shutil.copytree(ROOT / name, dest / name, ignore=ignore)
    shutil.copy2(ROOT / "pyproject.toml", dest / "pyproject.toml")


def _mutants(module: str, sample: int, seed: int) -> tuple[int, int, int, list]:
    """(generated, eligible, judged equivalent, sampled work items) for one module, in the copy (cwd)."""
    from cosmic_ray.commands.init import _all_work_items
    from cosmic_ray.mutating import mutate_code
    from cosmic_ray.plugins import get_operator

    rel = Path("src/protocol_runner") / module
    spans = _annotation_spans(rel)
    code = rel.read_text()
    source = code.splitlines()
    equivalent = _equivalents(module)
    equivalent_lines = {line for line, _, _ in equivalent}
    items = list(_all_work_items([rel], {}))
    eligible = []
    n_equivalent = 0
    for it in items:
        (m,) = it.mutations
        line = source[m.start_pos[0] - 1].strip()
        in_annotation = any(a <= tuple(m.start_pos) < b for a, b in spans)
        if (
            _not_plausible(m.operator_name)
            or in_annotation
            or line.startswith("@")  # decorator arguments (frozen=, cache=) compute no number
            or _bare_star(source, m.start_pos)
        ):
            continue
        eligible.append(it)
    eligible.sort(key=lambda it: (it.mutations[0].operator_name, it.mutations[0].occurrence))
    # sample first, then leave the equivalent ones out: marking a mutant equivalent keeps the sample
    sampled = (
        eligible if sample <= 0 or len(eligible) <= sample else random.Random(seed).sample(eligible, sample)
    )
    chosen = []
    for it in sorted(sampled, key=lambda it: tuple(it.mutations[0].start_pos)):
        (m,) = it.mutations
        line = source[m.start_pos[0] - 1].strip()
        if line in equivalent_lines:
            mutated = mutate_code(code, get_operator(m.operator_name)(), m.occurrence)
            mutated_line = None if mutated is None else mutated.splitlines()[m.start_pos[0] - 1].strip()
            if _is_equivalent(equivalent, line, mutated_line, m.definition_name or ""):
                n_equivalent += 1
                continue
        chosen.append(it)
    return len(items), len(eligible), n_equivalent, chosen


def _test_command(module: str) -> str | None:
    # the small fact-stating files first: with -x a killed mutant then costs only them
    found = {str(p) for pattern in TESTS[module].split() for p in Path().glob(pattern)}
    tests = " ".join(sorted(found, key=lambda p: (not p.endswith("_facts.py"), p)))
    return f"{sys.executable} -m pytest -x -q -p no:cacheprovider {tests}" if tests else None


def _run_module(module: str, sample: int, seed: int, log: Path) -> dict:
    """Runs in the copy (cwd).  Returns the module's counts and survivors; one line per mutant to `log`."""
    from cosmic_ray.mutating import mutate_and_test
    from cosmic_ray.work_item import TestOutcome

    n_all, n_eligible, n_equivalent, chosen = _mutants(module, sample, seed)
    cmd = _test_command(module)
    t0 = time.monotonic()
    if cmd is None:
        return {
            "module": module,
            "all": n_all,
            "tested": 0,
            "killed": 0,
            "error": f"no tests ({TESTS[module]})",
        }
    base = subprocess.run(cmd.split(), capture_output=True, text=True)
    base_s = time.monotonic() - t0
    res: dict = {
        "module": module,
        "all": n_all,
        "eligible": n_eligible,
        "equivalent": n_equivalent,
        "tested": 0,
        "killed": 0,
    }
    if base.returncode != 0:
        res["error"] = "tests fail unmutated:\n" + base.stdout[-2000:]
        return res
    timeout = 3 * base_s + 15
    survivors = []
    for it in chosen:
        (m,) = it.mutations
        t1 = time.monotonic()
        r = mutate_and_test(it.mutations, cmd, timeout)
        with log.open("a") as f:
            f.write(
                f"{module}:{m.start_pos[0]} {m.operator_name} {r.test_outcome} {time.monotonic() - t1:.1f} s\n"
            )
        if r.test_outcome is None:  # no mutation possible here
            continue
        res["tested"] += 1
        if r.test_outcome == TestOutcome.SURVIVED:
            print(f"  survived {module}:{m.start_pos[0]} {m.operator_name}", flush=True)
            survivors.append(
                {
                    "line": m.start_pos[0],
                    "operator": m.operator_name,
                    "occurrence": m.occurrence,
                    "function": m.definition_name or "",
                    "diff": r.diff,
                }
            )
        else:
            res["killed"] += 1
    res["survivors"] = survivors
    res["baseline_s"] = round(base_s, 1)
    res["seconds"] = round(time.monotonic() - t0, 1)
    return res


def _worker(copy: Path, tasks, sample: int, seed: int, log: Path, queue) -> None:
    """Score modules taken from `tasks` (a queue of module names; None: no more) one after another."""
    os.chdir(copy)
    os.environ["PYTHONPATH"] = str(copy / "src")
    os.environ["PYTHONDONTWRITEBYTECODE"] = "1"
    # numba kernels compiled with bounds checks: an index mutant that would write past an array raises
    # instead of corrupting memory silently (and perhaps passing)
    os.environ["NUMBA_BOUNDSCHECK"] = "1"
    for module in iter(tasks.get, None):
        res = _run_module(module, sample, seed, log)
        _print_row(res)
        queue.put(res)


def _print_row(res: dict) -> None:
    if "error" in res:
        print(f"{res['module']:32s} ERROR {res['error']}", flush=True)
        return
    score = 100.0 * res["killed"] / res["tested"] if res["tested"] else float("nan")
    print(
        f"{res['module']:32s} {res['killed']:4d}/{res['tested']:<4d} {score:6.1f} %"
        f"   (sample of {res['eligible']} eligible less {res['equivalent']} equivalent;"
        f" {res['all']} generated; {res['seconds']:.0f} s, unmutated tests {res.get('baseline_s', 0):.1f} s)",
        flush=True,
    )


def _rescore(path: Path) -> int:
    """Re-count a results.json with the current equivalents list: survivors now judged equivalent leave
    both the survivors and the tested count (the sample itself does not change)."""
    results = json.loads(path.read_text())
    for res in sorted(results, key=lambda r: r["module"]):
        if "error" in res:
            _print_row(res)
            continue
        equivalent = _equivalents(res["module"])
        kept = []
        for s in res.get("survivors", []):
            lines = (s.get("diff") or "").splitlines()
            old = [x[1:].strip() for x in lines if x.startswith("-") and not x.startswith("---")]
            new = [x[1:].strip() for x in lines if x.startswith("+") and not x.startswith("+++")]
            if old and new and _is_equivalent(equivalent, old[0], new[0], s.get("function", "")):
                res["tested"] -= 1
                res["equivalent"] = res.get("equivalent", 0) + 1
            else:
                kept.append(s)
        res["survivors"] = kept
        _print_row(res)
        for s in kept:
            print(f"  survived {res['module']}:{s['line']} {s['operator']}")
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sample", type=int, default=40, help="mutants per module (0: all); default 40")
    p.add_argument("--seed", type=int, default=19)
    p.add_argument("--jobs", type=int, default=2, help="modules run in parallel, one copy each")
    p.add_argument("--modules", default="", help="comma-separated substrings of module paths to run")
    p.add_argument("--out", type=Path, default=None, help="directory for survivors.txt and results.json")
    p.add_argument(
        "--rescore", type=Path, default=None, help="re-count a results.json with the current equivalents"
    )
    args = p.parse_args(argv)
    if args.rescore is not None:
        return _rescore(args.rescore)

    modules = [m for m in TESTS if not args.modules or any(s in m for s in args.modules.split(","))]
    if not modules:
        p.error(f"no module matches {args.modules!r}")
    out = args.out or Path(tempfile.mkdtemp(prefix="mutation-out-"))
    out.mkdir(parents=True, exist_ok=True)
    (out / "mutants.log").unlink(missing_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix="mutation-copy-"))
    jobs = max(1, min(args.jobs, len(modules)))
    # each job takes the next module when it finishes one (modules differ tenfold in time); the slowest
    # first: the compiled kernels (numba recompiles the mutated file for every mutant), then the Bouc-Wen
    # modules, whose fit tests take longest
    order = sorted(modules, key=lambda m: ("kernels" not in m, "bouc_wen" not in m, m))
    tasks: multiprocessing.Queue = multiprocessing.Queue()
    for module in order:
        tasks.put(module)
    for _ in range(jobs):
        tasks.put(None)
    t0 = time.monotonic()
    print(
        f"cosmic-ray mutation score, sample <= {args.sample or 'all'} per module, seed {args.seed}, {jobs} jobs"
    )
    queue: multiprocessing.Queue = multiprocessing.Queue()
    procs = []
    try:
        for i in range(jobs):
            copy = scratch / f"copy{i}"
            _copy_tree(copy)
            proc = multiprocessing.Process(
                target=_worker, args=(copy, tasks, args.sample, args.seed, out / "mutants.log", queue)
            )
            proc.start()
            procs.append(proc)
        results = [queue.get() for _ in modules]
        for proc in procs:
            proc.join()
    finally:
        for proc in procs:
            if proc.is_alive():
                proc.terminate()
        shutil.rmtree(scratch, ignore_errors=True)

    results.sort(key=lambda r: r["module"])
    print("\nper module (killed / tested, score):")
    for res in results:
        _print_row(res)
    tested = sum(r["tested"] for r in results)
    killed = sum(r["killed"] for r in results)
    low = [r["module"] for r in results if "error" in r or not r["tested"] or r["killed"] < 0.9 * r["tested"]]
    print(f"total {killed}/{tested} = {100.0 * killed / max(tested, 1):.1f} %; {time.monotonic() - t0:.0f} s")
    print(f"below 90 %: {', '.join(low) if low else 'none'}")
    with (out / "survivors.txt").open("w") as f:
        for res in results:
            for s in res.get("survivors", []):
                f.write(f"== {res['module']}:{s['line']} {s['operator']} #{s['occurrence']}\n{s['diff']}\n")
    (out / "results.json").write_text(json.dumps(results, indent=1))
    print(f"survivors: {out / 'survivors.txt'}; every mutant: {out / 'mutants.log'}")
    return 0 if not low else 1


if __name__ == "__main__":
    sys.exit(main())
