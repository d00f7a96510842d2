"""The report's warm-up (session/reporting.py): started once while the session waits for its last analyses,
it leaves the report's template compiled and a figure of each layout drawn (matplotlib and its fonts
loaded), so the report at the end only reads and assembles."""

from __future__ import annotations

from protocol_runner.session import reporting


def test_warm_up_runs_once_and_prepares_the_report() -> None:
    reporting.start_warm_up()
    reporting.start_warm_up()  # the runner calls it before every compare step: one thread in all
    assert len(reporting._WARMING) == 1
    reporting._WARMING[0].join(timeout=120)
    assert not reporting._WARMING[0].is_alive()

    from protocol_runner.report import figures, render

    assert render.TEMPLATE in {name for _, name in render._environment().cache}  # compiled
    assert figures.warm_up.cache_info().currsize == 1  # the figures' warm-up has run
