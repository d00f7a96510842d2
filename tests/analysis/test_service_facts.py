"""Facts of analysis/service.py that the archive's numbers rest on: the analysis's Bouc-Wen defaults are the
protocol's documented ones (docs/protocol.md, `fits.bouc_wen`), a processed trial is decimated to the
rate nearest `PROCESSED_RATE_HZ` without ever dropping below its own rate, and the backbone asked for is the
one fitted (§6.2: torque = g(angle) + z)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from protocol_runner.analysis.centring import CentredLoop, complete_cycles_span
from protocol_runner.analysis.pipeline import ProcessedTrial
from protocol_runner.analysis.service import (
    PROCESSED_RATE_HZ,
    BoucWenSettings,
    fit_stored_loops,
    stored_trial,
)
from protocol_runner.models.bouc_wen.backbone import Backbone, FixedBackbone
from protocol_runner.protocol.schema import BoucWenFitSpec

from .synthetic_loops import SPRING, spring_and_loop_trials


def test_the_analysis_defaults_are_the_protocol_s() -> None:
    """A caller of the analysis without settings fits what a protocol without `fits.bouc_wen` fields
    fits (8 starts, cross-validated, a degree-9 polynomial backbone)."""
    analysis, protocol = BoucWenSettings(), BoucWenFitSpec()
    for f in dataclasses.fields(BoucWenSettings):
        assert getattr(analysis, f.name) == getattr(protocol, f.name), f.name


@pytest.mark.parametrize("backbone", ["polynomial", "elements", "none"])
def test_only_the_polynomial_backbone_has_a_polynomial_degree(backbone: str) -> None:
    analysis = BoucWenSettings(backbone=backbone, backbone_degree=4)  # type: ignore[arg-type]
    assert analysis.polynomial_degree == (4 if backbone == "polynomial" else None)
    assert (
        analysis.polynomial_degree == BoucWenFitSpec(backbone=backbone, backbone_degree=4).polynomial_degree
    )


def _processed(time_s: np.ndarray) -> ProcessedTrial:
    """A processed trial sampled at `time_s` (angle and torque: a 1 Hz sine and its double)."""
    angle = 30.0 * np.sin(2.0 * np.pi * time_s)
    empty = np.zeros(0)
    return ProcessedTrial(
        trial=3,
        time_s=time_s,
        angle_deg=angle,
        brace_torque_nm=2.0 * angle,
        robot_torque_nm=np.zeros_like(angle),
        transition_index_on=0,
        transition_index_off=0,
        coverage=1.0,
        energy_j=empty,
        centred=CentredLoop(angle, 2.0 * angle, 0.0, 0.0),
    )


@pytest.mark.parametrize(("rate_hz", "decimation"), [(100.0, 1), (200.0, 1), (400.0, 2), (2000.0, 10)])
def test_a_trial_is_decimated_to_the_rate_nearest_the_stored_rate_never_below_its_own(
    rate_hz: float, decimation: int
) -> None:
    """A trial recorded at or below PROCESSED_RATE_HZ is stored sample for sample; a faster one keeps every
    k-th sample, k = its rate / PROCESSED_RATE_HZ."""
    t = np.arange(400) / rate_hz
    s = stored_trial(_processed(t))
    assert s.decimation == decimation and s.trial == 3
    assert s.input_rate_hz == pytest.approx(rate_hz)
    assert s.sample_rate_hz == pytest.approx(rate_hz / decimation)
    assert s.sample_rate_hz <= max(rate_hz, PROCESSED_RATE_HZ) + 1e-9
    np.testing.assert_array_equal(s.time_s, t[::decimation])
    np.testing.assert_array_equal(
        s.angle_deg, (30.0 * np.sin(2.0 * np.pi * t[::decimation])).astype(np.float32)
    )


def test_a_two_sample_trial_has_its_one_step_as_interval() -> None:
    s = stored_trial(_processed(np.array([0.0, 0.001])))
    assert s.input_rate_hz == pytest.approx(1000.0)
    assert s.decimation == 5 and s.time_s.size == 1


@pytest.mark.parametrize("n", [0, 1])
def test_a_trial_without_a_sample_interval_is_stored_as_it_is(n: int) -> None:
    """0 or 1 samples: nothing to decimate (and no interval to take a median of)."""
    t = np.arange(n) / 1000.0
    s = stored_trial(_processed(t))
    assert s.decimation == 1
    np.testing.assert_array_equal(s.time_s, t)
    assert s.angle_deg.size == n and s.brace_torque_nm.size == n


def test_the_elements_backbone_is_the_device_s_spring() -> None:
    """backbone "elements": g is the device's spring (0.3 N*m/deg about the centred angle), whatever degree
    the polynomial would have had."""
    result = fit_stored_loops(
        spring_and_loop_trials(), BoucWenSettings(starts=1, cross_validate=False, backbone="elements"), SPRING
    )
    g = result.fit.backbone
    assert isinstance(g, FixedBackbone) and g.kind == "elements"
    x = np.linspace(-40.0, 40.0, 9)
    np.testing.assert_allclose(g(x), 0.3 * x, rtol=0.01, atol=1e-9)


def test_the_polynomial_backbone_is_a_polynomial_of_the_asked_degree_whatever_the_device() -> None:
    settings = BoucWenSettings(starts=1, cross_validate=False, backbone="polynomial", backbone_degree=3)
    for device in (None, SPRING):
        g = fit_stored_loops(spring_and_loop_trials(), settings, device).fit.backbone
        assert isinstance(g, Backbone) and g.degree == 3


def test_the_thesis_form_has_no_backbone_and_the_fit_is_of_the_centredspring_and_loop_trials() -> None:
    result = fit_stored_loops(
        spring_and_loop_trials(), BoucWenSettings(starts=1, cross_validate=False, backbone="none"), SPRING
    )
    assert result.fit.backbone is None and result.cv_rmse_nm == []
    for a, t in result.segments:  # centred on their means over their complete cycles
        cycles = complete_cycles_span(a)
        assert abs(float(np.mean(a[cycles]))) < 1e-9 and abs(float(np.mean(t[cycles]))) < 1e-9
