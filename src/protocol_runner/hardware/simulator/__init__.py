"""The DAQ simulator: boards that satisfy `hardware.interfaces` wired to a physical model of the RSST joint
and the knee brace (DESIGN.md "The DAQ simulator"; docs/simulator.md)."""

from protocol_runner.hardware.simulator.daq import SimulatedAnalogInput, SimulatedRig, step_seed
from protocol_runner.hardware.simulator.output import SimulatedAnalogOutput, SimulatedClock
from protocol_runner.hardware.simulator.params import DEFAULT_PARAMS, BraceSetup, SimulatorParams

__all__ = [
    "DEFAULT_PARAMS",
    "BraceSetup",
    "SimulatedAnalogInput",
    "SimulatedAnalogOutput",
    "SimulatedClock",
    "SimulatedRig",
    "SimulatorParams",
    "step_seed",
]
