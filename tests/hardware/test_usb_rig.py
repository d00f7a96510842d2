"""The real rig loop (`Rig.run_trajectory`) through the real USB drivers and pyusb to the fake boards, in
simulated time: what the archive records is what went over the wire and came back."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pytest

from protocol_runner.hardware.board_group import BoardGroup
from protocol_runner.hardware.conversions import angle_to_volts
from protocol_runner.hardware.joint import JointConfig
from protocol_runner.hardware.rig import Rig
from protocol_runner.hardware.safety import SafetyLimits
from protocol_runner.hardware.usb1608fs import open_all_1608fs
from protocol_runner.hardware.usb3105 import Usb3105
from protocol_runner.hardware.usb_common import DeviceGone
from tests.fakeusb.backend import FakeBackend
from tests.fakeusb.device import Faults
from tests.fakeusb.usb1608fs import ManualClock, Usb1608FsModel, make_usb1608fs
from tests.fakeusb.usb3105 import Usb3105Model, make_usb3105
from tests.rsst_reference import RSST_JOINTS

KNEE = RSST_JOINTS[9]


class SimClock:
    """Simulated time shared by the rig and the fake boards: sleeping jumps."""

    def __init__(self, manual: ManualClock) -> None:
        self.manual = manual

    def now_s(self) -> float:
        return self.manual()

    def sleep_until(self, t_s: float) -> None:
        self.manual.t_s = max(self.manual.t_s, t_s)


def joint(output_channel: int = 8, angle: int = 8, torque: int = 20) -> JointConfig:
    return JointConfig(
        name="knee",
        range_deg=KNEE.range_deg,
        torque_range_nm=KNEE.torque_range_nm,
        output_channel=output_channel,
        angle_input_channel=angle,
        torque_input_channel=torque,
        limits=SafetyLimits((0.0, 130.0), 200.0, 2000.0, 20.0, 10.0),
    )


def sensors(t: npt.ArrayLike, ch: int) -> npt.NDArray[np.float64]:
    """Board 1 ch 0 (global 8): angle volts of 50 deg; board 2 ch 4 (global 20): a 0.2 Hz torque sine."""
    t = np.asarray(t, dtype=np.float64)
    return (
        np.full_like(t, float(angle_to_volts(50.0, KNEE.range_deg)))
        if ch == 0
        else 2.0 * np.sin(0.4 * np.pi * t)
    )


def build() -> tuple[Rig, Usb3105Model, list[Usb1608FsModel], ManualClock]:
    manual = ManualClock(t_s=100.0)
    ao_model = make_usb3105()
    ao_model.set_calibration(8, 1.0008, -3.0)
    ai_models = [make_usb1608fs(serial=f"0000000{k}", signal=sensors, clock=manual) for k in range(3)]
    backend = FakeBackend(ao_model, *ai_models)
    clock = SimClock(manual)
    ao = Usb3105.open(backend=backend)
    ai = BoardGroup(open_all_1608fs(backend=backend, clock=clock))
    return Rig([joint()], ao, ai, clock), ao_model, ai_models, manual


def test_codes_recorded_are_the_codes_on_the_wire() -> None:
    rig, ao_model, _, _ = build()
    command = 40.0 + 20.0 * np.sin(2 * np.pi * np.arange(500) / 100.0 / 5.0)
    rec = rig.run_trajectory([command], where="test")[0]
    aouts = ao_model.reports_with_command(0x14)
    wire = np.array([r[2] | (r[3] << 8) for r in aouts if r[1] == 8])
    np.testing.assert_array_equal(rec.command_codes, wire)
    assert ao_model.reports_with_command(0x1C) == [bytes([0x1C, 8, 1])]
    # the calibrated DAC puts Eq 1's volts on the pin, within one LSB
    assert ao_model.pin_volts(8) == pytest.approx(rec.command_volts[-1], abs=20.0 / 65536)


def test_telemetry_comes_back_from_the_right_global_channels() -> None:
    rig, _, _, _ = build()
    rec = rig.run_trajectory([np.full(300, 40.0)], where="test")[0]
    assert rec.n_samples == pytest.approx(3000, abs=20)  # 1 kHz over the 3 s trial (+ one tick)
    np.testing.assert_allclose(rec.angle_deg, 50.0, atol=0.01)  # Eq 2 of the angle channel
    t_abs = rec.input_time_s + rec.t0_s
    np.testing.assert_allclose(rec.torque_volts, 2.0 * np.sin(0.4 * np.pi * t_abs), atol=2 * 20.0 / 65536)
    np.testing.assert_allclose(np.diff(rec.input_time_s), 1e-3)


def test_board_unplugged_mid_trial_raises_device_gone() -> None:
    rig, ao_model, _, _ = build()
    ao_model.faults = Faults(vanish_after_transfers=ao_model.transfer_count + 150)
    with pytest.raises(DeviceGone):
        rig.run_trajectory([np.full(500, 40.0)], where="test")
    assert rig.last_command_deg[0] == 40.0  # the rig knows what was last written, for parking
