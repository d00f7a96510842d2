"""Record the declared expectations and their verdicts in an archive (`/expectations`, docs/archive.md).

Called once the archive is consolidated (and again after `--reprocess`): decided on the archive's own data
by the report's evaluator, which the report itself re-runs, so a stored verdict never disagrees with a
regenerated report. An expectation decided per joint keeps each joint's outcome in `joints/<joint>`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np

from protocol_runner.archive.h5util import put_attrs, put_text
from protocol_runner.archive.paths import JOINTS

if TYPE_CHECKING:
    from protocol_runner.report.evaluate import Verdict
    from protocol_runner.report.model import ReportData


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def record_verdicts(archive: Path, data: ReportData | None = None) -> int:
    """Evaluate `archive`'s declared expectations and (re)write `/expectations`; return how many.
    `data` is the archive as `load_report_data` reads it, when the caller has already read it."""
    from protocol_runner.report.evaluate import evaluate_expectations
    from protocol_runner.report.load import load_report_data

    result = evaluate_expectations(data if data is not None else load_report_data(Path(archive), workers=1))
    with h5py.File(archive, "a") as h5:
        if "expectations" in h5:
            del h5["expectations"]
        root = h5.create_group("expectations")
        put_attrs(root, "expectations", {"problems": json.dumps(list(result.problems))})
        for v in result.verdicts:
            keyed = (v.spec.joint is not None or v.spec.joints is not None) and bool(v.joint)
            if v.spec.id not in root:
                grp = root.create_group(v.spec.id)
                joints = [w.joint for w in result.verdicts if w.spec.id == v.spec.id]
                put_attrs(grp, "expectation", _declaration(v, result.dry_run, joints if keyed else None))
            grp = root[v.spec.id]
            if keyed:
                grp = grp.require_group(JOINTS).create_group(v.joint)
                put_attrs(grp, "expectation", {"joint": v.joint})
            _outcome(grp, v)
    return len(result.verdicts)


def _declaration(v: Verdict, dry_run: bool, joints: list[str] | None) -> dict[str, object]:
    """The attributes of an expectation's group that its declaration gives (and `joints` when it is
    decided per joint)."""
    return {
        "text": v.spec.text,
        "section": v.spec.section,
        "metric": v.spec.metric,
        "unit": v.unit,
        "relation": v.spec.relation,
        "configurations": json.dumps(v.spec.configurations),
        "declaration": v.spec.model_dump_json(exclude_none=True),
        "simulator_tuned": int(v.spec.depends_on_tuning),  # 0/1: numbers export as doubles
        "depends_on_simulator": json.dumps(v.spec.depends_on_simulator),
        "dry_run": int(dry_run),
        **({JOINTS: np.array(joints, dtype=h5py.string_dtype())} if joints is not None else {}),
    }


def _outcome(grp: h5py.Group, v: Verdict) -> None:
    """The verdict, its numbers and its evidence, in `grp` (the expectation's group or its joint's)."""
    put_attrs(
        grp,
        "expectation",
        {
            "verdict": v.verdict,
            "reason": v.reason,
            **{k: p for k, p in (("p_value", v.p_value), ("p_adjusted", v.p_adjusted)) if math.isfinite(p)},
            "family": v.family,
        },
    )
    rows = [
        {
            "key": e.key,
            "trials": e.n,
            "mean": _finite(e.mean),
            "ci95_low": _finite(e.low),
            "ci95_high": _finite(e.high),
            "unit": v.unit,
        }
        for e in v.evidence
    ]
    put_text(grp, "evidence", json.dumps(rows))
