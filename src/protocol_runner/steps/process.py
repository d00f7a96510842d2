"""Processing step: one configuration's archived trials -> the device's own torque, energy, element fit.

Reads the trial units (never the rig), then `analysis.pipeline.process_configuration`: transition
removal (§3.3.1), zero-phase filtering (§3.2), equal-angle subtraction of the brace-off torque (§3.3,
§5.6), cycles and energy per cycle (Eq 10-12), and the fit of the device's elastic elements (§6.1).
"""

from __future__ import annotations

from ..analysis.pipeline import TrialPair, process_configuration
from ..archive.paths import configuration_name, recording_path
from ..archive.results import processed_fill, read_recording
from ..models.interim_knee_device import lever_spring
from ..protocol.plan import ProcessStep
from .context import StepContext, StepOutcome


def run(step: ProcessStep, ctx: StepContext) -> StepOutcome:
    name = configuration_name(step.configuration)
    pairs = []
    for n, (on_id, off_id) in enumerate(step.trials, start=1):
        with ctx.unit(on_id) as f_on, ctx.unit(off_id) as f_off:
            pairs.append(
                TrialPair(
                    read_recording(f_on[recording_path(step.configuration, n, "on")]),
                    read_recording(f_off[recording_path(step.configuration, n, "off")]),
                    trial=n,
                )
            )
    cfg_step = next(
        s
        for s in ctx.plan.steps
        if getattr(s, "configuration", None) == step.configuration and s.kind == "trial"
    )
    settings = cfg_step.settings  # type: ignore[attr-defined]
    fits = ctx.loaded.protocol.fits
    enabled = getattr(fits, "elements", getattr(fits, "spring", None))
    device = getattr(settings, "device", None)
    if device is None:  # INTERIM until the protocol declares its device (helper PROTO)
        device = lever_spring(settings.stiffness_n_per_mm, settings.preload_position)
    result = process_configuration(
        pairs, ctx.processing, device=device if enabled and enabled.enabled else None
    )
    summary = (
        f"{result.energy.n} cycles, energy {result.energy.mean_j:.2f} +- {result.energy.std_j:.2f} J"
        if result.energy.n
        else "no complete cycle"
    )
    return StepOutcome(processed_fill(name, result, ctx.processing), summary)
