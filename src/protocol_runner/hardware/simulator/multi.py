"""The DAQ simulator for several joints: one clock, one USB-3105 stand-in and one scan shared by one
simulated robot joint per driven joint (`daq._RigModel`, each with its own rig `simulator:` parameters,
calibration tables and device).

The joints are simulated INDEPENDENTLY: each plant sees only its own command and its own device; no
coupling through the leg's kinematic chain (thesis §1.3) is modelled. Each joint draws its noise from its
own generator, seeded from (session seed, joint name, step id), so the data are reproducible and the
joints' noises are not copies of each other. Every output write reaches every joint's model; each acts
only on its own channel, at the write's time, exactly as a single-joint dry run.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence

import numpy as np

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.interfaces import ScanBlock
from protocol_runner.hardware.joint import JointConfig
from protocol_runner.hardware.multi_rig import MultiRig
from protocol_runner.hardware.simulator.daq import _RigModel
from protocol_runner.hardware.simulator.output import SimulatedAnalogOutput, SimulatedClock, check_channel
from protocol_runner.hardware.simulator.params import SimulatorParams
from protocol_runner.hardware.simulator.scan import AI_CHANNELS, AI_MAX_RATE_HZ


def joint_seed(seed: int, joint: str) -> int:
    """The seed of one joint's model: sha256 of the session seed and the joint's name (64 bits)."""
    return int.from_bytes(hashlib.sha256(f"{int(seed)}\x1fjoint\x1f{joint}".encode()).digest()[:8], "little")


class _MultiInput:
    """A scan over the channels of several joint models: each model fills its own angle and torque
    columns (its other channels are none of its business)."""

    def __init__(self, models: Sequence[_RigModel], clock: SimulatedClock) -> None:
        self._models = tuple(models)
        self._clock = clock
        self._plan: list[tuple[_RigModel, list[int], list[int]]] = []
        self._n = 0
        self._rate = 0.0
        self._t0 = 0.0
        self._rows = 0
        self._running = False

    @property
    def resolution_bits(self) -> int:
        return 12

    def start_scan(self, channels: Sequence[int], rate_hz: float) -> None:
        chans = [check_channel(c, AI_CHANNELS, "DT9814 (simulated)") for c in channels]
        if not chans or not (math.isfinite(rate_hz) and 0 < rate_hz * len(chans) <= AI_MAX_RATE_HZ):
            raise InvalidInput(f"DT9814 (simulated): cannot scan {len(chans)} channels at {rate_hz!r} Hz")
        plan = []
        for m in self._models:
            own = [
                (i, c)
                for i, c in enumerate(chans)
                if c in (m.joint.angle_input_channel, m.joint.torque_input_channel)
            ]
            if own:
                plan.append((m, [c for _, c in own], [i for i, _ in own]))
        covered = sorted(i for _, _, cols in plan for i in cols)
        if covered != list(range(len(chans))):
            raise InvalidInput(
                "DT9814 (simulated, several joints): every scanned channel must be a driven joint's"
            )
        self._plan, self._n = plan, len(chans)
        self._rate, self._t0, self._rows, self._running = float(rate_hz), self._clock.now_s(), 0, True

    def _read(self) -> ScanBlock:
        if not self._running:
            return ScanBlock.empty(self._n)
        now = self._clock.now_s()
        due = math.floor((now - self._t0) * self._rate + 1e-9) + 1
        if due <= self._rows:
            return ScanBlock.empty(self._n)
        parts = [
            m.acquire(self._t0, self._rate, self._rows, due - self._rows, chans, now)
            for m, chans, _ in self._plan
        ]
        rows = {p[1].shape[0] for p in parts}
        if len(rows) != 1:
            raise InvalidInput("simulated joints on different integration grids (give them one plant_step_s)")
        n = rows.pop()
        codes = np.zeros((n, self._n), dtype=np.int32)
        volts = np.zeros((n, self._n), dtype=np.float64)
        for (_, _, cols), (_, c, v) in zip(self._plan, parts, strict=True):
            codes[:, cols] = c
            volts[:, cols] = v
        self._rows += n
        return ScanBlock(t_s=parts[0][0], codes=codes, volts=volts)

    def read_available(self) -> ScanBlock:
        return self._read()

    def stop_scan(self) -> ScanBlock:
        block = self._read()
        self._running = False
        return block

    def close(self) -> None:
        self._running = False


class MultiSimulatedRig:
    """Several simulated joints behind one simulated USB-3105 and one scan; `make_rig()` gives the
    `MultiRig` the steps use. `set_device(joint, elements)` fits one joint's device."""

    def __init__(
        self,
        joints: Sequence[JointConfig],
        params: Sequence[SimulatorParams],
        *,
        seed: int = 0,
        realtime: bool = False,
    ) -> None:
        if len({p.plant_step_s for p in params}) != 1:
            raise InvalidInput("the simulated joints of one rig need the same plant_step_s")
        self.joints = tuple(joints)
        self.clock = SimulatedClock(realtime=realtime)
        self.ao = SimulatedAnalogOutput(self.clock)
        self.models = tuple(
            _RigModel(j, p, joint_seed(seed, j.name), self.clock, self.ao)
            for j, p in zip(joints, params, strict=True)
        )
        self.ai = _MultiInput(self.models, self.clock)
        self.begin_step("")

    def begin_step(self, step_id: str) -> None:
        """Every joint: noise reseeded from (seed, joint, step id), at rest at its park angle."""
        self.ao.clear_records()
        for m in self.models:
            m.begin_step(step_id)

    def set_device(self, joint: str, elements: Sequence[object] | None) -> None:
        self.models[[j.name for j in self.joints].index(joint)].plant.set_device(elements)

    def make_rig(self) -> MultiRig:
        return MultiRig(self.joints, self.ao, self.ai, self.clock)
