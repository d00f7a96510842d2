"""The DAQ simulator: boards that satisfy `hardware.interfaces` wired to a physical model of an RSST joint
and the device under test, composed from its elements (docs/simulator.md)."""
