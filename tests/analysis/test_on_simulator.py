"""The analysis on data from the DAQ simulator, run through the real `Rig` code path.

The simulated brace's torque is known: the spring model of Eq 13-18 at the simulator's default preload and
zero offset, plus brake friction on each branch. The §5.7 low-angle "bump" is switched off so that the
spring is the brace's only friction-free torque. The simulated robot adds gravity, Dahl friction and viscous
friction, lags and slows near its torque limit: the brace-on and brace-off trials sweep different angles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from protocol_runner.analysis.filters import lowpass
from protocol_runner.analysis.pipeline import ConfigurationResult, Recording, TrialPair, process_configuration
from protocol_runner.analysis.processing_settings import ProcessingSettings
from protocol_runner.analysis.scaling import rig_runner, scale_brace_off_input
from protocol_runner.analysis.transition import command_on_input_base, transition_index
from protocol_runner.hardware.joint import JointConfig, TrialRecording
from protocol_runner.hardware.simulator.daq import SimulatedRig

from ..knee_device import KNEE_MAX_PRELOAD_MM as DEFAULT_MAX_PRELOAD_MM
from ..knee_device import KNEE_PARAMS, knee_brace, lever_spring
from ..knee_rig import knee_joint_config

PARAMS = KNEE_PARAMS
FRICTION_NM = 3.75
BRACE = knee_brace((0.0, 130.0), FRICTION_NM, 13.0, 3, cuff_shift=False)  # no bump: the spring is all
DEG = np.pi / 180.0


def _joint() -> JointConfig:
    return knee_joint_config(max_rate_deg_s=1000.0, max_accel_deg_s2=100_000.0)


def _command() -> np.ndarray:
    """Appendix A Eq 24-25: robot ROM 20-110 deg at full speed (50 deg/s), five periods, 100 Hz."""
    amp, mean = 45.0, 65.0
    period = 2 * np.pi * amp / 50.0
    t = np.arange(round(5 * period * 100.0)) / 100.0
    return mean + amp * np.sin(2 * np.pi * t / period)


def _run(command: np.ndarray, brace: list | None, step_id: str) -> TrialRecording:
    sim = SimulatedRig([_joint()], seed=7, params=PARAMS)
    sim.set_device(brace)
    sim.begin_step(step_id)
    return sim.make_rig().run_trajectory([command], where=step_id)[0]


def _recording(r: TrialRecording) -> Recording:
    return Recording(r.input_time_s, r.angle_deg, r.torque_nm, r.command_deg, r.command_time_s)


@dataclass(frozen=True)
class Simulated:
    on: TrialRecording
    off: TrialRecording


@pytest.fixture(scope="module")
def simulated() -> Simulated:
    return Simulated(on=_run(_command(), BRACE, "on"), off=_run(_command(), None, "off"))


def _process(sim: Simulated, subtraction: str, off: TrialRecording | None = None) -> ConfigurationResult:
    pair = TrialPair(_recording(sim.on), _recording(off if off is not None else sim.off))
    return process_configuration(
        [pair],
        ProcessingSettings(subtraction=subtraction),  # type: ignore[arg-type]
        device=[lever_spring(13.0, 3)],
    )


def test_the_braced_joint_sweeps_a_smaller_range(simulated: Simulated) -> None:
    on_span = np.ptp(simulated.on.angle_deg[3000:])
    off_span = np.ptp(simulated.off.angle_deg[3000:])
    assert off_span - on_span > 5.0  # the spring and gravity stall the braced joint before 110 deg


def test_equal_angle_processing_recovers_the_simulated_spring(simulated: Simulated) -> None:
    by_angle = _process(simulated, "equal_angle").elements
    by_time = _process(simulated, "equal_time").elements
    assert by_angle is not None and by_time is not None
    assert by_angle.value("springs", "max_preload_mm") == pytest.approx(DEFAULT_MAX_PRELOAD_MM, abs=1.0)
    assert by_angle.value("springs", "zero_offset_deg") == pytest.approx(0.0, abs=0.5)
    assert by_angle.rmse_nm < 0.3
    # equal time mixes the robot's gravity torque at other angles into the brace loop (thesis §5.6)
    assert by_time.rmse_nm > 3 * by_angle.rmse_nm
    assert abs(by_time.value("springs", "zero_offset_deg")) > 1.5


def test_energy_per_cycle_is_the_brake_loss(simulated: Simulated) -> None:
    result = _process(simulated, "equal_angle")
    trial = result.trials[0]
    assert result.energy_loss_j.size >= 3
    # brake + hinge friction F on each branch: about 2 F (range) pi/180 per cycle; the robot's viscous
    # friction differs between the two trials (they move at different speeds at the same angle) and
    # the brake's Stribeck rise near reversals: allow 15 %
    friction = FRICTION_NM + 0.75  # brake + hinge
    expected = 2 * friction * np.ptp(trial.angle_deg) * DEG
    np.testing.assert_allclose(result.energy_loss_j, expected, rtol=0.15)
    by_time = _process(simulated, "equal_time")
    assert by_time.energy.mean_j > 2 * result.energy.mean_j


def test_scaling_matches_the_brace_off_range_on_the_simulator(simulated: Simulated) -> None:
    on = simulated.on
    command_in = command_on_input_base(on.command_time_s, on.command_deg, on.input_time_s)
    start = transition_index(command_in, on.angle_deg)
    steady = lowpass(on.angle_deg[start:])
    target = (float(steady.min()), float(steady.max()))
    runs: list[TrialRecording] = []

    def run_off(command: np.ndarray) -> TrialRecording:
        runs.append(_run(command, None, f"off/scaling/{len(runs)}"))
        return runs[-1]

    result = scale_brace_off_input(
        _command(), target, rig_runner(run_off), tolerance_deg=0.5, input_limits_deg=(0.0, 130.0)
    )
    assert result.converged
    assert result.history[0].range_error_deg > 3.0
    assert len(result.history) <= 3
    # with matched ranges the subtraction is at least as good as before
    best = runs[min(range(len(runs)), key=lambda i: result.history[i].range_error_deg)]
    scaled = _process(simulated, "equal_angle", off=best).elements
    assert scaled is not None and scaled.rmse_nm < 0.3


def test_energy_loss_grows_with_brake_friction(simulated: Simulated) -> None:
    # thesis §5.7.2: "the energy loss increases with increasing friction of the brace"
    energies = []
    for level_nm in (0.0, 6.25):
        brace = knee_brace((0.0, 130.0), level_nm, 13.0, 3, cuff_shift=False)
        on = _run(_command(), brace, f"on/friction/{level_nm}")
        pair = TrialPair(_recording(on), _recording(simulated.off))
        energies.append(process_configuration([pair]).energy.mean_j)
    assert energies[0] > 0.0
    assert energies[1] > 2 * energies[0]
