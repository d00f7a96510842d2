"""The report at the end of a session (session/reporting.py) has the analysis workers draw the figures and
compute the model predictions; the report looks exactly as one the session makes itself,
and when the workers are gone it makes everything itself."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Callable
from concurrent.futures import Future
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from protocol_runner.report.figure_plan import figure_ids
from protocol_runner.report.load import load_report_data
from protocol_runner.session import reporting
from tests.report.report_archive_builder import small_spec, write_archive

Called = list[tuple[str, tuple[Any, ...]]]


def _images(html: str) -> list[tuple[str, str]]:
    return re.findall(r'id="(fig-[^"]+)"><img src="(data:image/png;base64,[^"]+)"', html)


def _text(html: str, folder: Path) -> str:
    """The report's text but for where it is and when it was made."""
    html = re.sub(r'id="generated-utc">[^<]*<', "", html)
    return html.replace(str(folder), "FOLDER")


def _report(folder: Path, call: reporting.Call | None) -> str:
    folder.mkdir()
    archive = write_archive(folder / "archive.h5", small_spec())
    return reporting.render_report(folder, archive, call).read_text(encoding="utf-8")


def _inline(called: Called) -> reporting.Call:
    """A worker that runs the job at once, here, recording what it was given."""

    def call(fn: Callable[..., Any], *args: Any) -> Future[Any]:
        called.append((fn.__name__, args))
        future: Future[Any] = Future()
        future.set_result(fn(*args))
        return future

    return call


def test_the_workers_draw_every_figure_and_the_report_is_the_same(tmp_path: Path) -> None:
    own = _report(tmp_path / "own", None)
    called: Called = []
    drawn = _report(tmp_path / "workers", _inline(called))

    assert _images(drawn) == _images(own)  # the same figures, byte for byte, in the same places
    archive = tmp_path / "workers" / "archive.h5"
    every = figure_ids(load_report_data(archive, verify=False))
    assert len(_images(own)) == len(every) > 8
    handed = [task for name, args in called if name == "_draw" for task in args[1]]
    assert sorted(handed) == sorted(every)  # each figure drawn once, all of them by the workers
    assert [args[0] for name, args in called if name == "_predictions"] == [archive]
    assert _text(drawn, tmp_path / "workers") == _text(own, tmp_path / "own")


def test_with_the_workers_gone_the_report_draws_itself(tmp_path: Path) -> None:
    own = _report(tmp_path / "own", None)
    called: Called = []

    def gone(fn: Callable[..., Any], *args: Any) -> Future[Any] | None:
        called.append((fn.__name__, args))
        return None  # AnalysisPool.call without running workers

    def broken(fn: Callable[..., Any], *args: Any) -> Future[Any]:
        future: Future[Any] = Future()
        future.set_exception(BrokenProcessPool("a worker died"))
        return future

    assert _images(_report(tmp_path / "gone", gone)) == _images(own)
    assert {name for name, _ in called} == {"_predictions", "_draw"}
    assert _images(_report(tmp_path / "broken", broken)) == _images(own)


def test_the_figures_are_handed_out_before_the_page_is_rendered(tmp_path: Path, monkeypatch: Any) -> None:
    """The workers get every figure to draw before this process renders the page (which holds its
    interpreter meanwhile), and the report takes them from those jobs: none is handed out twice."""
    from protocol_runner.report import render

    events: list[str] = []
    real_render = render._render

    def page(*args: Any, **kwargs: Any) -> str:
        events.append("page")
        return real_render(*args, **kwargs)

    monkeypatch.setattr(render, "_render", page)
    called: Called = []
    inline = _inline(called)

    def call(fn: Callable[..., Any], *args: Any) -> Future[Any]:
        events.append(fn.__name__)
        return inline(fn, *args)

    html = _report(tmp_path / "w", call)
    assert events[:1] == ["_predictions"] and "_draw" in events and "page" in events
    last_draw = max(i for i, event in enumerate(events) if event == "_draw")
    assert last_draw < events.index("page")
    handed = [task for name, args in called if name == "_draw" for task in args[1]]
    assert sorted(handed) == sorted(figure_ids(load_report_data(tmp_path / "w" / "archive.h5", verify=False)))
    assert len(_images(html)) == len(handed)


PINNED = """
import sys
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

from protocol_runner.session import reporting
from tests.report.report_archive_builder import small_spec, write_archive

folder = Path(sys.argv[1])
archive = write_archive(folder / "archive.h5", small_spec())
with ProcessPoolExecutor(1, mp_context=get_context("spawn")) as workers:
    report = reporting.render_report(folder, archive, workers.submit)
assert report.is_file() and "data:image/png" in report.read_text(encoding="utf-8")
print(sorted({m.split(".")[0] for m in sys.modules}))
"""


def test_the_session_that_has_its_report_drawn_by_the_workers_never_loads_matplotlib(tmp_path: Path) -> None:
    """The session process at its end only reads, assembles and writes; the drawing library (a quarter of a
    second to import) stays in the workers."""
    repo = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(repo / "src"), str(repo)])}
    done = subprocess.run(
        [sys.executable, "-c", PINNED, str(tmp_path)], env=env, capture_output=True, text=True, check=True
    )
    loaded = done.stdout.strip().splitlines()[-1]
    assert "'jinja2'" in loaded and "'h5py'" in loaded  # it did read and render
    assert "'matplotlib'" not in loaded and "'PIL'" not in loaded


def test_the_verdicts_are_written_after_the_figures_are_handed_out_and_the_predictions_have_read_the_archive(
    tmp_path: Path, monkeypatch: Any
) -> None:
    """The verdicts (written into the archive) no longer hold up the figures' hand-out; they wait for the
    workers' predictions, which read the archive, to end (here a worker that takes 0.1 s)."""
    import threading

    from protocol_runner.report import evaluate as verdicts
    from protocol_runner.report import render

    events: list[str] = []
    real_verdicts, real_render = verdicts.record_verdicts, render._render

    def recorded(*args: Any) -> None:
        events.append("verdicts")
        real_verdicts(*args)

    def page(*args: Any, **kwargs: Any) -> str:
        events.append("page")
        return real_render(*args, **kwargs)

    monkeypatch.setattr(verdicts, "record_verdicts", recorded)
    monkeypatch.setattr(render, "_render", page)

    def call(fn: Callable[..., Any], *args: Any) -> Future[Any]:
        future: Future[Any] = Future()
        if fn.__name__ == "_predictions":

            def later() -> None:
                result = fn(*args)
                events.append("predictions done")
                future.set_result(result)

            threading.Timer(0.1, later).start()
        else:
            events.append(fn.__name__)
            future.set_result(fn(*args))
        return future

    html = _report(tmp_path / "w", call)
    assert (
        events.index("_draw")
        < events.index("predictions done")
        < events.index("verdicts")
        < events.index("page")
    )
    assert len(_images(html)) == len(
        figure_ids(load_report_data(tmp_path / "w" / "archive.h5", verify=False))
    )
