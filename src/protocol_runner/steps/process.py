"""Processing step: one configuration's archived trials -> the brace's own torque, energy, spring fit.

Reads the trial units (never the rig), then `analysis.pipeline.process_configuration`: transition
removal (§3.3.1), zero-phase filtering (§3.2), equal-angle subtraction of the brace-off torque (§3.3,
§5.6), cycles and energy per cycle (Eq 10-12), and the physical spring model fit (§6.1).
"""

from __future__ import annotations

import h5py
import numpy as np

from ..analysis.pipeline import (
    ConfigurationResult,
    ProcessingSettings,
    Recording,
    TrialPair,
    process_configuration,
)
from ..archive.h5util import SIGNAL, put, set_attrs
from ..protocol.plan import ProcessStep, configuration_name
from .context import Fill, StepContext, StepOutcome

# The processed loops are stored at 200 Hz: they are low-passed far below 100 Hz (thesis filter: 10 % of
# the 500 Hz Nyquist frequency, order 10), so nothing is lost, and the campaign's archive stays < 100 MB.
# Energies and fits are computed before this decimation, at the full input rate.
PROCESSED_RATE_HZ = 200.0


def read_recording(g: h5py.Group) -> Recording:
    return Recording(
        time_s=g["time_s"][:],
        angle_deg=g["angle_deg"][:],
        torque_nm=g["torque_nm"][:],
        command_deg=g["command_deg"][:],
        command_time_s=g["command_time_s"][:],
    )


def run(step: ProcessStep, ctx: StepContext) -> StepOutcome:
    name = configuration_name(step.configuration)
    pairs = []
    for n, (on_id, off_id) in enumerate(step.trials, start=1):
        with ctx.unit(on_id) as f_on, ctx.unit(off_id) as f_off:
            base = f"configurations/{name}/trials/{n}"
            pairs.append(
                TrialPair(
                    read_recording(f_on[f"{base}/brace_on"]),
                    read_recording(f_off[f"{base}/brace_off"]),
                    trial=n,
                )
            )
    cfg_step = next(
        s
        for s in ctx.plan.steps
        if getattr(s, "configuration", None) == step.configuration and s.kind == "trial"
    )
    settings = cfg_step.settings  # type: ignore[attr-defined]
    spring_enabled = ctx.loaded.protocol.fits.spring.enabled
    result = process_configuration(
        pairs,
        ctx.processing,
        stiffness_n_per_mm=settings.stiffness_n_per_mm if spring_enabled else None,
        preload_position=settings.preload_position if spring_enabled else None,
    )
    summary = (
        f"{result.energy.n} cycles, energy {result.energy.mean_j:.2f} +- {result.energy.std_j:.2f} J"
        if result.energy.n
        else "no complete cycle"
    )
    return StepOutcome(processed_fill(name, result, ctx.processing), summary)


def processed_fill(name: str, result: ConfigurationResult, settings: ProcessingSettings) -> Fill:
    import json

    def fill(f: h5py.File) -> None:
        cfg = f.require_group(f"configurations/{name}")
        for t in result.trials:
            g = cfg.require_group(f"trials/{t.trial}").create_group("processed")
            dt = float(np.median(np.diff(t.time_s))) if t.time_s.size > 1 else 1.0
            stride = max(1, round(1.0 / (dt * PROCESSED_RATE_HZ)))
            put(g, "time_s", t.time_s[::stride], "s")
            put(g, "angle_deg", t.angle_deg[::stride], "deg", dtype=SIGNAL)
            put(g, "brace_torque_nm", t.brace_torque_nm[::stride], "N*m", dtype=SIGNAL)
            set_attrs(
                g,
                {
                    "sample_rate_hz": 1.0 / (dt * stride),
                    "decimation": stride,
                    "energy_cycles_j": [float(e) for e in t.energy_j],
                },
            )
            set_attrs(
                g,
                {
                    "transition_index0_on": int(t.transition_index_on),
                    "transition_index0_off": int(t.transition_index_off),
                    "subtraction": settings.subtraction,
                    "filter": json.dumps(settings.filter_description(1.0 / dt)),
                    # the zero-phase low-pass filter ran at the input rate 1/dt, before the decimation
                    "filter_type": settings.filter_kind,
                    "filter_order": int(settings.filter_order),
                    "filter_cutoff_hz": float(settings.filter_cutoff / (2.0 * dt)),
                    "coverage": float(t.coverage),
                },
            )
        put(cfg, "energy_loss_j", result.energy_loss_j, "J")
        put(cfg, "energy_cycle_trial", result.energy_cycle_trial, "1")
        cfg["energy_loss_j"].attrs["mean_j"] = result.energy.mean_j
        cfg["energy_loss_j"].attrs["std_j"] = result.energy.std_j
        sp = result.spring
        if sp is not None:
            g = cfg.require_group("fits").create_group("spring")
            set_attrs(
                g,
                {
                    "applicable": bool(sp.applicable),
                    "reason": sp.reason,
                    "max_preload_mm": float(sp.max_preload_mm),
                    "zero_offset_deg": float(sp.zero_offset_deg),
                    "rmse_nm": float(sp.rmse_nm),
                    "rmse_all_samples_nm": float(sp.rmse_all_samples_nm),
                    "stiffness_n_per_mm": float(sp.stiffness_n_per_mm),
                    "preload_position": int(sp.preload_position),
                    "target": sp.target,
                },
            )
            put(g, "angle_deg", sp.curve_angle_deg, "deg", dtype=SIGNAL)
            put(g, "torque_nm", sp.curve_torque_nm, "N*m", dtype=SIGNAL)
            put(g, "model_torque_nm", sp.model_torque_nm, "N*m")

    return fill
