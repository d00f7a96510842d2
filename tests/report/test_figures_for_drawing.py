"""`figure_plan.for_drawing`: the data handed to another process for some figures draws exactly the same
figures, and leaves out the raw recordings no asked figure reads (the report's last figures
reach the session's workers sooner)."""

from __future__ import annotations

import pickle
from pathlib import Path

from protocol_runner.report.figure_plan import configuration_jobs, figure_ids, for_drawing
from protocol_runner.report.figures import draw_figures
from protocol_runner.report.load import load_report_data


def test_figures_drawn_from_the_slimmed_data_are_the_same_bytes(small_archive: Path) -> None:
    data = load_report_data(small_archive, verify=False)
    ids = figure_ids(data)
    first = data.configurations[0]
    own = [job_id for job_id, _, _ in configuration_jobs([first])]
    others = [i for i in ids if not i.startswith("fig-config-")]
    assert own and others  # a configuration's figures and cross-configuration ones are both exercised
    for chunk in (own + others, others, ids[::3]):
        slim = for_drawing(data, chunk)
        assert draw_figures(slim, chunk) == draw_figures(data, chunk)


def test_recordings_are_kept_only_for_the_configurations_whose_own_figures_are_asked(
    small_archive: Path,
) -> None:
    data = load_report_data(small_archive, verify=False)
    first, *rest = data.configurations
    assert rest and any(t.brace_on is not None for c in data.configurations for t in c.trials)
    own = [job_id for job_id, _, _ in configuration_jobs([first])]
    slim = for_drawing(data, own)
    assert slim.configurations[0] == first  # the same object: nothing dropped
    for cfg in slim.configurations[1:]:
        assert all(t.brace_on is None and t.brace_off is None for t in cfg.trials)
        assert all(t.processed is not None for t in cfg.trials if t.recorded)  # loops kept
    assert len(pickle.dumps(slim)) < len(pickle.dumps(data))
