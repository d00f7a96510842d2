"""Record the declared expectations and their verdicts in an archive (`/expectations`, docs/archive.md).

Called once the archive is consolidated (and again after `--reprocess`): the verdicts are decided on the
archive's own data by the report's evaluator and stored for tools; the report itself always re-decides
them from the archived protocol text and data, so a stored verdict never disagrees with a regenerated
report of the same archive. Each expectation is a group `/expectations/<id>` whose attributes give the
declaration and the outcome, and whose `evidence` dataset (sealed with its checksum) holds one row per
configuration: key, trials, mean, 95 % interval low and high, in the metric's unit.
"""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np

from protocol_runner.archive.checksums import seal
from protocol_runner.archive.h5util import set_attrs


def record_verdicts(archive: Path) -> int:
    """Evaluate `archive`'s declared expectations and (re)write `/expectations`; return how many."""
    from protocol_runner.report.findings import evaluate_expectations
    from protocol_runner.report.load import load_report_data

    result = evaluate_expectations(load_report_data(Path(archive), workers=1))
    with h5py.File(archive, "a") as h5:
        if "expectations" in h5:
            del h5["expectations"]
        root = h5.create_group("expectations")
        root.attrs["problems"] = json.dumps(list(result.problems))
        for v in result.verdicts:
            grp = root.create_group(v.spec.id)
            set_attrs(
                grp,
                {
                    "text": v.spec.text,
                    "section": v.spec.section,
                    "metric": v.spec.metric,
                    "unit": v.unit,
                    "relation": v.spec.relation,
                    "configurations": json.dumps(v.spec.configurations),
                    "declaration": v.spec.model_dump_json(exclude_none=True),
                    "verdict": v.verdict,
                    "reason": v.reason,
                    "simulator_tuned": int(v.spec.simulator_tuned),  # 0/1: numbers export as doubles
                    "dry_run": int(result.dry_run),
                },
            )
            rows = np.asarray([[e.key, e.n, e.mean, e.low, e.high] for e in v.evidence], dtype=float)
            ds = grp.create_dataset("evidence", data=rows.reshape(-1, 5))
            ds.attrs["columns"] = "key, trials, mean, ci95_low, ci95_high"
            ds.attrs["metric_unit"] = v.unit  # not `units`: one name keeps one unit per archive
            seal(ds, rows.reshape(-1, 5))
    return len(result.verdicts)
