"""The processing filter is recorded and shown in Hz with its order and type."""

from __future__ import annotations

import h5py

from protocol_runner.analysis.processing_settings import ProcessingSettings
from protocol_runner.report.load import _filter_text


def test_cutoff_in_hz_is_the_normalised_cutoff_times_nyquist() -> None:
    settings = ProcessingSettings()  # the thesis's 10th-order Butterworth at 0.1 of Nyquist
    described = settings.filter_description(1000.0)
    assert described["cutoff_hz"] == 50.0
    assert described["kind"] == "butterworth" and described["order"] == 10
    assert "cutoff_hz" not in settings.filter_description()


def test_the_report_names_type_order_and_cutoff_in_hz(tmp_path) -> None:  # type: ignore[no-untyped-def]
    with h5py.File(tmp_path / "a.h5", "w") as f:
        g = f.create_group("processed")
        assert _filter_text(g.attrs) == ""  # an archive written before the cut-off was stored in Hz
        g.attrs["filter_type"] = "butterworth"
        g.attrs["filter_order"] = 10
        g.attrs["filter_cutoff_hz"] = 50.0
        assert _filter_text(g.attrs) == "Butterworth low-pass, order 10, cut-off 50.0 Hz, zero-phase"
