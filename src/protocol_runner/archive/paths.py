"""The archive layout's names: every group path of `archive.h5` (and of the unit files, which hold the
same paths), and the datasets of each kind of group with their units (docs/archive.md, which
tests/archive/test_paths.py checks against this module). `put_dataset` writes a dataset with its unit.
"""

from __future__ import annotations

import h5py
import numpy.typing as npt

from .h5util import put

CONFIGURATIONS = "configurations"
TRIALS = "trials"
PROCESSED = "processed"
FITS = "fits"
COMPARISONS = "comparisons"
CALIBRATION = "calibration"
REFERENCE = "reference"
CHECKLISTS = "session/checklists"
JOINTS = "joints"

#: Datasets of each kind of group, with their units ("1" for counts and plain numbers).
DATASETS: dict[str, dict[str, str]] = {
    "recording": {
        "time_s": "s",
        "angle_deg": "deg",
        "torque_nm": "N*m",
        "angle_codes": "counts",
        "torque_codes": "counts",
        "command_time_s": "s",
        "command_deg": "deg",
        "command_volts": "V",
        "command_codes": "counts",
        "tick_lateness_s": "s",
    },
    "processed": {"time_s": "s", "angle_deg": "deg", "brace_torque_nm": "N*m"},
    "configuration": {"energy_loss_j": "J", "energy_cycle_trial": "1"},
    "bouc_wen": {"angle_deg": "deg", "torque_nm": "N*m", "model_torque_nm": "N*m", "segment_lengths": "1"},
    "spring": {"angle_deg": "deg", "torque_nm": "N*m", "model_torque_nm": "N*m"},
    "elements": {"angle_deg": "deg", "torque_nm": "N*m", "model_torque_nm": "N*m"},
    "reference": {"angle_deg": "deg", "torque_nm": "N*m"},
}


def configuration_name(key: int) -> str:
    """The group name of a configuration: `config_NN`, NN the matrix key zero-padded to two digits."""
    return f"config_{key:02d}"


def configuration_path(key: int) -> str:
    return f"{CONFIGURATIONS}/{configuration_name(key)}"


def recording_path(key: int, trial: int | str, brace: str) -> str:
    """`brace` is "on" or "off"."""
    return f"{configuration_path(key)}/{TRIALS}/{trial}/brace_{brace}"


def comparison_path(name: str) -> str:
    return f"{COMPARISONS}/{name}"


def calibration_path(set_name: str, when: str) -> str:
    return f"{CALIBRATION}/{set_name}/{when}"


def joint_path(group: str, joint: str) -> str:
    """One joint's group inside a multi-joint group (docs/archive.md "Several joints"): its recording in a
    trial's `recording_path`, its results in a configuration, its check in a `calibration_path`."""
    return f"{group}/{JOINTS}/{joint}"


def joint_groups(group: h5py.Group, archive_joints: str) -> list[tuple[str, h5py.Group]]:
    """Each joint's part of a trial, configuration, comparison or calibration group, in channel order:
    `(joint, group)` per child of its `joints/` group. A group without one (an older single-joint archive)
    is the part of the joint the root attribute `joint` (`archive_joints`) names."""
    if JOINTS in group:
        children = group[JOINTS]
        order = [str(name) for name in group.attrs.get(JOINTS, ())] or list(children)
        return [(name, children[name]) for name in order if name in children]
    return [(archive_joints.split(",")[0].strip(), group)]


def put_dataset(
    group: h5py.Group, kind: str, name: str, data: npt.ArrayLike, *, dtype: npt.DTypeLike | None = None
) -> h5py.Dataset:
    """Write dataset `name` of a group of `kind` (a key of DATASETS) with the layout's unit."""
    return put(group, name, data, DATASETS[kind][name], dtype=dtype)
