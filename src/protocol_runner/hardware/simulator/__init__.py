"""The DAQ simulator: boards that satisfy `hardware.interfaces` wired to a physical model of an RSST joint
and the device under test, composed from its elements (docs/simulator.md)."""

from protocol_runner.hardware.simulator.daq import SimulatedAnalogInput, SimulatedRig, step_seed
from protocol_runner.hardware.simulator.output import SimulatedAnalogOutput, SimulatedClock
from protocol_runner.hardware.simulator.params import DEFAULT_PARAMS, SimulatorParams

__all__ = [
    "DEFAULT_PARAMS",
    "SimulatedAnalogInput",
    "SimulatedAnalogOutput",
    "SimulatedClock",
    "SimulatedRig",
    "SimulatorParams",
    "step_seed",
]
