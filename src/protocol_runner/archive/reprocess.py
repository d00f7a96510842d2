"""`run-protocol --report ARCHIVE --reprocess`: redo processing and fits from an archive's raw data.

No rig and no session directory are needed: the raw trials, the protocol text and the plan are in the
archive. The processing and fit settings come from the archived protocol, or from a given protocol file
(only its `processing` and `fits` sections are used; the acquisition stays what it was). The result is a
new archive next to the old one; the old one is never modified. Raw data are copied unchanged.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from pathlib import Path

import h5py
import numpy as np

from ..analysis.pipeline import TrialPair, process_configuration
from ..errors import InvalidInput
from ..protocol.loader import LoadedProtocol, find_protocol, load_protocol, parse_protocol_text
from ..steps.context import processing_settings
from ..steps.fit import bouc_wen_fill, centred_loop, fit_bouc_wen
from ..steps.process import processed_fill, read_recording
from .h5util import attr_str, set_attrs, text_of


def _archived_protocol(f: h5py.File, archive: Path) -> LoadedProtocol:
    if "protocol" not in f:
        raise InvalidInput(f"{archive}: has no /protocol; cannot reprocess without the protocol that was run")
    text = text_of(f["protocol"])
    name = attr_str(f["protocol"], "filename", "protocol.yaml")
    return parse_protocol_text(
        text, path=archive.parent / name, display_name=f"{archive}:/protocol", check_files=False
    )


def new_archive_path(archive: Path) -> Path:
    candidate = archive.with_name(archive.stem + ".reprocessed.h5")
    n = 2
    while candidate.exists():
        candidate = archive.with_name(f"{archive.stem}.reprocessed-{n}.h5")
        n += 1
    return candidate


def reprocess_archive(archive: Path, *, protocol_file: str | None = None, output: Path | None = None) -> Path:
    from ..report.load import validate_archive  # clear messages for foreign or damaged files

    validate_archive(archive)
    out = output or new_archive_path(archive)
    with tempfile.NamedTemporaryFile(dir=out.parent, suffix=".partial", delete=False) as tmp:
        partial = Path(tmp.name)
    try:
        shutil.copyfile(archive, partial)
        with h5py.File(partial, "r+") as f:
            archived = _archived_protocol(f, archive)
            settings_source = archived
            if protocol_file is not None:
                settings_source = load_protocol(find_protocol(protocol_file), check_files=False)
            _reprocess(f, settings_source)
            set_attrs(
                f,
                {
                    "reprocessed_from": str(archive.name),
                    "reprocessing_protocol_sha256": settings_source.sha256,
                    "reprocessing_settings": json.dumps(settings_source.protocol.processing.model_dump()),
                },
            )
        partial.replace(out)
    finally:
        partial.unlink(missing_ok=True)
    return out


def _reprocess(f: h5py.File, loaded: LoadedProtocol) -> None:
    settings = processing_settings(loaded)
    fits = loaded.protocol.fits
    energies: dict[int, np.ndarray] = {}
    max_angle: dict[int, float] = {}
    for name, cfg in f["configurations"].items():
        trials = cfg.get("trials")
        if trials is None:
            continue
        pairs = []
        for n in sorted(trials, key=int):
            g = trials[n]
            if "brace_on" in g and "brace_off" in g:
                pairs.append(
                    TrialPair(read_recording(g["brace_on"]), read_recording(g["brace_off"]), trial=int(n))
                )
            if "processed" in g:
                del g["processed"]
        for stale in ("energy_loss_j", "energy_cycle_trial", "fits"):
            if stale in cfg:
                del cfg[stale]
        if not pairs:
            continue
        stiffness = float(cfg.attrs.get("stiffness_n_per_mm", 0.0))
        preload = int(cfg.attrs.get("preload_position", 3))
        result = process_configuration(
            pairs,
            settings,
            stiffness_n_per_mm=stiffness if fits.spring.enabled else None,
            preload_position=preload if fits.spring.enabled else None,
        )
        processed_fill(name, result, settings)(f)
        key = int(cfg.attrs["key"])
        energies[key] = result.energy_loss_j
        max_angle[key] = max(float(np.max(t.angle_deg)) for t in result.trials)
        if fits.bouc_wen.enabled:
            segments = [centred_loop(t.angle_deg, t.brace_torque_nm) for t in result.trials]
            bw, cv = fit_bouc_wen(segments, fits.bouc_wen)
            bouc_wen_fill(name, bw, segments, cv)(f)
    if "comparisons" in f:
        for comp in f["comparisons"].values():
            keys = [int(k) for k in comp.attrs["configurations"]]
            if not all(k in energies for k in keys):
                continue
            means = [float(np.mean(energies[k])) if energies[k].size else float("nan") for k in keys]
            stds = [
                float(np.std(energies[k], ddof=1)) if energies[k].size > 1 else float("nan") for k in keys
            ]
            set_attrs(
                comp,
                {
                    "energy_mean_j": means,
                    "energy_std_j": stds,
                    "energy_cycles": [int(energies[k].size) for k in keys],
                    "max_angle_deg": [max_angle[k] for k in keys],
                },
            )
