"""The report's "Joints" section for a multi-joint archive: per configuration, each joint's
brace torque against angle (its processed loops), a joint-angle phase plot of the first two driven joints
(e.g. hip against knee over the motion, brace on), and the energy lost per cycle per joint and for the
whole set of joints (the sum over joints, `total_energy_loss_j`); one bar chart of energy per joint and
per configuration. A single-joint archive has no `joints` attribute and gets no such section.

Read from the archive after `load_report_data` has checked every dataset (checksums and bounds).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np

from .h5read import decimate_for_plot, float_ds
from .model import energy_mean_std_j

if TYPE_CHECKING:  # drawn only for a multi-joint archive: a single-joint report loads no matplotlib here
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


@dataclass(frozen=True)
class JointEnergy:
    """The energy lost per cycle by one joint (or by all joints together, "total"): mean, sample SD, cycles."""

    joint: str
    mean_j: float
    std_j: float
    cycles: int

    @classmethod
    def of(cls, joint: str, energy_loss_j: np.ndarray) -> JointEnergy:
        """The statistics of `energy_loss_j` (J per cycle), as the report's configurations compute them."""
        return cls(joint, *energy_mean_std_j(energy_loss_j), int(energy_loss_j.size))


@dataclass(frozen=True)
class JointEnergies:
    """A configuration's energy lost per cycle: per joint (`energies`, in the configuration's joint order)
    and for all joints together (`total`, from `total_energy_loss_j`)."""

    energies: tuple[JointEnergy, ...]
    total: JointEnergy

    def energy(self, name: str) -> JointEnergy:
        """The energy of joint `name`, or of all joints together for "total"."""
        return self.total if name == "total" else next(e for e in self.energies if e.joint == name)


@dataclass(frozen=True)
class JointConfiguration(JointEnergies):
    """One configuration of the section: its energies, its key and motion, and its two figures."""

    key: int
    title: str
    loops_uri: str
    phase_uri: str


@dataclass(frozen=True)
class JointsSection:
    """The section: the joints driven together, each configuration, and the energy bar chart."""

    joints: tuple[str, ...]
    configurations: tuple[JointConfiguration, ...]
    energy_uri: str


def _strs(value: object) -> tuple[str, ...]:
    return tuple(v.decode() if isinstance(v, bytes) else str(v) for v in np.atleast_1d(np.asarray(value)))


def _figure(n_panels: int) -> tuple[Figure, list[Axes]]:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from .drawing import DPI

    fig = Figure(figsize=(3.0 * n_panels + 0.4, 3.0), dpi=DPI)
    FigureCanvasAgg(fig)
    axes = [
        fig.add_axes((0.08 / n_panels + k / n_panels, 0.16, 0.78 / n_panels, 0.72)) for k in range(n_panels)
    ]
    return fig, axes


def _loops(cfg: h5py.Group, joints: tuple[str, ...]) -> str:
    from .drawing import ANGLE_LABEL, COLORS, TORQUE_LABEL, style, to_data_uri

    fig, axes = _figure(len(joints))
    for ax, joint in zip(axes, joints, strict=True):
        trials = cfg.get(f"joints/{joint}/trials")
        for i, name in enumerate(sorted(trials or (), key=lambda s: int(s))):
            g = trials[name].get("processed") if trials is not None else None
            if g is None:
                continue
            a = decimate_for_plot(float_ds(g, "angle_deg"))
            t = decimate_for_plot(float_ds(g, "brace_torque_nm"))
            ax.plot(a, t, lw=0.6, color=COLORS[i % len(COLORS)], label=f"trial {name}")
        style(ax, ANGLE_LABEL, TORQUE_LABEL, joint)
    return to_data_uri(fig)


def _phase(cfg: h5py.Group, joints: tuple[str, ...]) -> str:
    from .drawing import COLORS, style, to_data_uri

    fig, axes = _figure(1)
    ax = axes[0]
    x_joint, y_joint = joints[0], joints[1] if len(joints) > 1 else joints[0]
    on = cfg.get("trials/1/brace_on/joints")
    if on is not None and x_joint in on and y_joint in on:
        x = decimate_for_plot(float_ds(on[x_joint], "angle_deg"))
        y = decimate_for_plot(float_ds(on[y_joint], "angle_deg"))
        ax.plot(x, y, lw=0.6, color=COLORS[0], label="measured")
        cx = decimate_for_plot(float_ds(on[x_joint], "command_deg"))
        cy = decimate_for_plot(float_ds(on[y_joint], "command_deg"))
        ax.plot(cx, cy, lw=0.6, ls="--", color=COLORS[1], label="commanded")
        ax.legend(fontsize=7)
    style(ax, f"{x_joint} angle (deg)", f"{y_joint} angle (deg)", "trial 1, brace on")
    return to_data_uri(fig)


def _energy_bars(configs: list[JointConfiguration], joints: tuple[str, ...]) -> str:
    from .drawing import COLORS, ENERGY_LABEL, style, to_data_uri

    fig, axes = _figure(1)
    ax = axes[0]
    names = [*joints, "total"]
    width = 0.8 / len(names)
    for j, name in enumerate(names):
        means = [c.energy(name).mean_j for c in configs]
        xs = np.arange(len(configs)) + (j - (len(names) - 1) / 2) * width
        ax.bar(xs, np.nan_to_num(means), width=width, color=COLORS[j % len(COLORS)], label=name)
    ax.set_xticks(np.arange(len(configs)), [str(c.key) for c in configs])
    ax.legend(fontsize=7)
    style(ax, "Configuration", ENERGY_LABEL, "energy per cycle, per joint and in total")
    return to_data_uri(fig)


def joints_section(archive: Path) -> JointsSection | None:
    """The section's data and figures, or None for a single-joint archive."""
    with h5py.File(archive, "r") as f:
        configs = f.get("configurations")
        if configs is None:
            return None
        out: list[JointConfiguration] = []
        all_joints: tuple[str, ...] = ()
        for name in sorted(configs):
            cfg = configs[name]
            if "joints" not in cfg.attrs or "joints" not in cfg:
                continue
            joints = _strs(cfg.attrs["joints"])
            all_joints = all_joints or joints
            energies = tuple(JointEnergy.of(j, float_ds(cfg[f"joints/{j}"], "energy_loss_j")) for j in joints)
            title = str(cfg.attrs.get("trajectory_name", ""))
            out.append(
                JointConfiguration(
                    key=int(cfg.attrs.get("key", 0)),
                    title=title,
                    energies=energies,
                    total=JointEnergy.of("total", float_ds(cfg, "total_energy_loss_j")),
                    loops_uri=_loops(cfg, joints),
                    phase_uri=_phase(cfg, joints),
                )
            )
        if not out:
            return None
        return JointsSection(all_joints, tuple(out), _energy_bars(out, all_joints))
