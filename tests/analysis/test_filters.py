"""Zero-phase Butterworth / Chebyshev low-pass filtering (thesis §3.2, §4.4)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from protocol_runner.analysis.filters import design_lowpass, filter_zero_phase, lowpass, padding_length
from protocol_runner.analysis.validation import AnalysisError

KINDS = ["butterworth", "chebyshev"]


def _lag_of_peak(x: np.ndarray, y: np.ndarray) -> int:
    xc = signal.correlate(y - y.mean(), x - x.mean(), mode="full")
    return int(np.argmax(xc)) - (x.shape[0] - 1)


@pytest.mark.parametrize("kind", KINDS)
def test_filtered_low_frequency_sinusoid_has_no_lag(kind: str) -> None:
    fs = 1000.0
    t = np.arange(0.0, 8.0, 1.0 / fs)
    clean = 50.0 + 40.0 * np.sin(2 * np.pi * 0.5 * t)
    rng = np.random.default_rng(1)
    noisy = clean + rng.normal(0.0, 2.0, t.shape)
    out = lowpass(noisy, kind=kind, order=10, cutoff=0.1)  # type: ignore[arg-type]
    assert _lag_of_peak(clean, out) == 0
    # and a causal filter of the same design does lag: the check can fail
    causal = signal.sosfilt(design_lowpass(kind, 10, 0.1), noisy)  # type: ignore[arg-type]
    assert _lag_of_peak(clean, causal) > 0
    # white noise keeps about sqrt(cut-off) of its amplitude (10 % of the band): std 2 -> about 0.65
    assert np.sqrt(np.mean((out - clean)[500:-500] ** 2)) < 0.4 * 2.0


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("order", [1, 4, 10])
def test_unit_dc_gain(kind: str, order: int) -> None:
    constant = np.full(2000, -37.5)
    np.testing.assert_allclose(lowpass(constant, kind=kind, order=order, cutoff=0.1), constant, rtol=1e-9)  # type: ignore[arg-type]


def test_cutoff_is_a_fraction_of_nyquist() -> None:
    # A Butterworth is -3 dB at its cut-off; forward-backward squares it: amplitude 0.5 at f = 0.1 * fs / 2.
    fs = 1000.0
    t = np.arange(0.0, 4.0, 1.0 / fs)
    f_cut = 0.1 * fs / 2
    out = lowpass(np.sin(2 * np.pi * f_cut * t), kind="butterworth", order=10, cutoff=0.1)
    amplitude = np.max(np.abs(out[1000:-1000]))
    assert amplitude == pytest.approx(0.5, abs=0.01)
    passband = lowpass(np.sin(2 * np.pi * 0.2 * f_cut * t), kind="butterworth", order=10, cutoff=0.1)
    assert np.max(np.abs(passband[1000:-1000])) == pytest.approx(1.0, abs=1e-3)
    stopband = lowpass(np.sin(2 * np.pi * 4 * f_cut * t), kind="butterworth", order=10, cutoff=0.1)
    assert np.max(np.abs(stopband[1000:-1000])) < 1e-6


def test_chebyshev_ripple_parameter_changes_the_design() -> None:
    a = design_lowpass("chebyshev", 6, 0.1, ripple_db=0.1)
    b = design_lowpass("chebyshev", 6, 0.1, ripple_db=3.0)
    assert not np.allclose(a, b)
    # Chebyshev is steeper than Butterworth of the same order just above the cut-off
    w = np.array([0.15 * np.pi])
    _, h_cheb = signal.sosfreqz(b, worN=w)
    _, h_butt = signal.sosfreqz(design_lowpass("butterworth", 6, 0.1), worN=w)
    assert abs(h_cheb[0]) < abs(h_butt[0])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"cutoff": 0.0}, "strictly between 0 and 1"),
        ({"cutoff": 1.0}, "strictly between 0 and 1"),
        ({"cutoff": 10.0}, "strictly between 0 and 1"),
        ({"order": 0}, "order"),
        ({"order": 2.5}, "order"),
        ({"kind": "bessel"}, "unknown filter kind"),
        ({"kind": "chebyshev", "ripple_db": 0.0}, "ripple"),
    ],
)
def test_settings_that_do_not_make_a_filter_are_rejected(kwargs: dict, message: str) -> None:
    with pytest.raises(AnalysisError, match=message):
        design_lowpass(**kwargs)


def test_data_shorter_than_the_padding_is_rejected_clearly() -> None:
    sos = design_lowpass("butterworth", 10, 0.1)
    pad = padding_length(sos)
    assert pad == 3 * (2 * 5 + 1)
    filter_zero_phase(np.ones(pad + 1), sos)  # just long enough
    with pytest.raises(AnalysisError, match="too few for this filter"):
        filter_zero_phase(np.ones(pad), sos, name="torque_nm")


def test_a_design_is_made_once_and_handed_out_as_a_new_array_with_the_same_bits() -> None:
    """The designs are cached: a repeated design is bit for bit scipy's own (Butterworth sections rescaled
    to unit DC gain), and each call gets its own writable array, so a caller that changes it changes no
    later design."""
    first = design_lowpass("butterworth", 4, 0.07)
    direct = np.array(signal.butter(4, 0.07, btype="lowpass", output="sos"), dtype=np.float64)
    direct[0, :3] /= float(np.prod(direct[:, :3].sum(axis=1) / direct[:, 3:].sum(axis=1)))
    assert np.array_equal(first, direct)
    first[:] = 0.0
    again = design_lowpass("butterworth", 4, 0.07)
    assert np.array_equal(again, direct) and again.flags.writeable and again is not first
