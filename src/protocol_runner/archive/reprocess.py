"""`run-protocol --report ARCHIVE --reprocess`: redo processing and fits from an archive's raw data.

The processing and fit settings come from the archived protocol, or from a given protocol file (only its
`processing` and `fits` sections are used). The result is a new archive next to the old one, the raw data
copied unchanged; the old one is never modified.
"""

from __future__ import annotations

import json
import os
import shutil
from collections import deque
from collections.abc import Sequence
from concurrent.futures import Executor, Future
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
import numpy.typing as npt

from ..analysis.model_comparison import ModelComparison, compare_stored
from ..analysis.pipeline import TrialPair
from ..analysis.processing_settings import ProcessingSettings
from ..analysis.service import JointsAnalysis, analyse_joints
from ..errors import InvalidInput
from ..protocol.loaded import LoadedProtocol
from ..protocol.loader import find_protocol, load_protocol, parse_protocol_text
from ..protocol.processing import bouc_wen_settings, element_fit_enabled, processing_settings
from .attrs import CONFIGURATIONS as CONFIGURATIONS_ATTR
from .attrs import FILENAME, JOINT, STATUS
from .attrs import JOINTS as JOINTS_ATTR
from .checksums import is_marked, seal_attributes, seal_missing
from .h5util import attr_str, attr_strs, put, put_attrs, text_of
from .model_results import PREDICTIONS, archived_device, joint_device, write_comparison
from .outputs import create_binary, refuse_special, temporary_beside, terminated_as_interrupt
from .paths import (
    COMPARISONS,
    CONFIGURATIONS,
    FITS,
    JOINTS,
    PROCESSED,
    TRIALS,
    configuration_name,
    joint_groups,
    joint_path,
)
from .results import bouc_wen_fill, comparison_values, processed_fill, read_recording
from .verify import validate_archive


def _archived_protocol(f: h5py.File, archive: Path) -> LoadedProtocol:
    if "protocol" not in f:
        raise InvalidInput(f"{archive}: has no /protocol; cannot reprocess without the protocol that was run")
    text = text_of(f["protocol"])
    name = attr_str(f["protocol"], FILENAME, "protocol.yaml")
    # the rig file as run (archives from before /rig existed: the rig the protocol names, as found now)
    rig_text = text_of(f["rig"]) if "rig" in f else None
    return parse_protocol_text(
        text,
        path=archive.parent / name,
        display_name=f"{archive}:/protocol",
        check_files=False,
        rig_text=rig_text,
    )


def new_archive_path(archive: Path) -> Path:
    """The first of `<stem>.reprocessed.h5`, `<stem>.reprocessed-2.h5`, ... that names nothing (not even a
    dangling symbolic link)."""
    candidate = archive.with_name(archive.stem + ".reprocessed.h5")
    n = 2
    while os.path.lexists(candidate):
        candidate = archive.with_name(f"{archive.stem}.reprocessed-{n}.h5")
        n += 1
    return candidate


def reprocess_archive(
    archive: Path,
    *,
    protocol_file: str | None = None,
    output: Path | None = None,
    pool: Executor | None = None,
) -> Path:
    """Write the reprocessed copy of `archive` (to `output`, default `new_archive_path`) and return its path.

    The copy is written under a temporary name and renamed when complete; it is removed whatever stops the
    work (an error, Ctrl-C, SIGTERM). An `output` that is not a regular file is refused (archive/outputs.py).
    With `pool`, the configurations are analysed on its workers, `ANALYSES_AHEAD` ahead of the one whose
    results are written (in order, the same values)."""
    validate_archive(archive)  # every dataset and attribute within bounds and intact, or a message naming it
    out = output or new_archive_path(archive)
    refuse_special(out, "--reprocess output")
    partial = temporary_beside(out)
    with terminated_as_interrupt():
        try:
            _write_reprocessed(archive, partial, protocol_file, pool)
            os.replace(partial, out)
        finally:
            partial.unlink(missing_ok=True)
    return out


def _write_reprocessed(
    archive: Path, partial: Path, protocol_file: str | None, pool: Executor | None
) -> None:
    with create_binary(partial) as fh, archive.open("rb") as src:
        shutil.copyfileobj(src, fh)
    with h5py.File(partial, "r+") as f:
        archived = _archived_protocol(f, archive)
        settings_source = archived
        if protocol_file is not None:
            settings_source = load_protocol(find_protocol(protocol_file), check_files=False)
        _reprocess(f, settings_source, pool)
        if is_marked(f):
            seal_missing(f)  # the new results carry checksums like everything else
        put_attrs(
            f,
            "root",
            {
                "reprocessed_from": str(archive.name),
                "reprocessing_protocol_sha256": settings_source.sha256,
                "reprocessing_settings": json.dumps(settings_source.protocol.processing.model_dump()),
            },
        )
        seal_attributes(f)  # the new results' attributes, and those copied from the checked archive


def _reprocess(f: h5py.File, loaded: LoadedProtocol, pool: Executor | None) -> None:
    """Redo what the session's process, fit and compare steps did, from the raw trials in `f`, with the
    same function (`analysis.service.analyse_joints`), so that unchanged settings reproduce the session's
    values exactly. The results are written keyed by joint whatever layout the raw trials have
    (`paths.joint_groups`)."""
    settings = processing_settings(loaded)
    elements = element_fit_enabled(loaded)
    archive_joints = attr_str(f, JOINT, "")
    running: deque[tuple[h5py.Group, str, _Job, Future[Analysed] | None]] = deque()
    for name, cfg in f[CONFIGURATIONS].items():
        job = _prepare(cfg, name, archive_joints, elements=elements) if TRIALS in cfg else None
        if job is None:
            continue
        running.append((cfg, name, job, pool.submit(_analyse, job, loaded) if pool else None))
        while len(running) > ANALYSES_AHEAD or (running and pool is None):
            _store(*running.popleft(), loaded, settings)
    while running:
        _store(*running.popleft(), loaded, settings)
    if PREDICTIONS in f:  # made from the old fits: `report.predictions.record_predictions` makes them anew
        del f[PREDICTIONS]
    for comp in f.get(COMPARISONS, {}).values():
        _recompare(f, comp, archive_joints)


def complete_pairs(cfg: h5py.Group, name: str, joint: str, archive_joints: str) -> list[TrialPair]:
    """The raw trial pairs of `joint` in configuration group `cfg`, without the trials a board failure cut
    short. A trial whose raw data lack a dataset is named."""
    pairs = []
    trials = cfg[TRIALS]
    for n in sorted(trials, key=int):
        g = trials[n]
        braces = ("brace_on", "brace_off")
        if not all(b in g and attr_str(g[b], STATUS, "complete") == "complete" for b in braces):
            continue
        try:
            on, off = (read_recording(dict(joint_groups(g[b], archive_joints))[joint]) for b in braces)
            pairs.append(TrialPair(on, off, trial=int(n)))
        except KeyError as exc:
            raise InvalidInput(
                f"{name}/{TRIALS}/{n} ({joint}): the raw data lack {exc}; cannot reprocess"
            ) from None
    return pairs


ANALYSES_AHEAD = 2
"""Configurations handed to the worker processes ahead of the one being written (each holds one
configuration's recordings in memory, about 10 MB a trial)."""


@dataclass(frozen=True)
class _Job:
    """What one configuration's analysis needs, read from the archive: each joint's complete trial pairs
    (channel order), each joint's device (None: no element fit) and the joints the Bouc-Wen fit covers."""

    joints: list[str]
    recordings: list[tuple[str, list[TrialPair]]]
    devices: dict[str, Sequence[object] | None]
    fitted: list[str]


def _prepare(cfg: h5py.Group, name: str, archive_joints: str, *, elements: bool) -> _Job | None:
    """Remove a configuration's old results and read what its analysis needs (None when a joint has no
    complete trial pair: the configuration is left without results)."""
    joints = attr_strs(cfg, JOINTS_ATTR) or [j.strip() for j in archive_joints.split(",")]
    for stale in (
        "energy_loss_j",
        "energy_cycle_trial",
        FITS,
        JOINTS,
        "total_energy_loss_j",
        "total_energy_cycle_trial",
    ):
        if stale in cfg:
            del cfg[stale]
    for trial in cfg[TRIALS].values():
        if PROCESSED in trial:  # the processing of an archive written before results were keyed by joint
            del trial[PROCESSED]
    device = archived_device(cfg)
    recordings = [(joint, complete_pairs(cfg, name, joint, archive_joints)) for joint in joints]
    if not all(pairs for _, pairs in recordings):
        return None
    carrying = sorted({str(p[JOINT]) for _, _, p in device if p.get(JOINT)})
    fitted = [j for j in joints if j in carrying] or joints
    devices: dict[str, Sequence[object] | None] = {
        j: joint_device(device, j) if elements and j in fitted else None for j in joints
    }
    return _Job(joints, recordings, devices, fitted)


Analysed = tuple[JointsAnalysis, dict[str, ModelComparison]]
"""A configuration's analysis and the model comparison of each joint with a device and a Bouc-Wen fit."""


def _analyse(job: _Job, loaded: LoadedProtocol) -> Analysed:
    """One configuration's processing and Bouc-Wen fits with the settings of `loaded`, and each joint's
    model comparison as the fit step makes it (`compare_stored` of the processed trials as stored), run in
    a worker (the settings are made there: a backbone's model factory is a closure, which cannot be sent)."""
    settings = processing_settings(loaded)
    fit = bouc_wen_settings(loaded) if loaded.protocol.fits.bouc_wen.enabled else None
    analysis = analyse_joints(job.recordings, settings, fit, devices=job.devices, fitted_joints=job.fitted)
    comparisons = {}
    for joint, one in zip(analysis.joints, analysis.analyses, strict=True):
        device = job.devices[joint]
        if one.bouc_wen is not None and device is not None:
            stored = [
                (_float64(s.time_s), _float64(s.angle_deg), _float64(s.brace_torque_nm)) for s in one.stored
            ]
            comparisons[joint] = compare_stored(stored, device, one.bouc_wen)
    return analysis, comparisons


def _float64(values: npt.ArrayLike) -> npt.NDArray[np.float64]:
    return np.asarray(values, dtype=np.float64)


def _store(
    cfg: h5py.Group,
    name: str,
    job: _Job,
    running: Future[Analysed] | None,
    loaded: LoadedProtocol,
    settings: ProcessingSettings,
) -> None:
    """Write one configuration's new results (its analysis from the worker, or made here without one):
    each joint's processing and Bouc-Wen fit, its model comparison, the total."""
    analysis, comparisons = running.result() if running is not None else _analyse(job, loaded)
    for joint, one in zip(analysis.joints, analysis.analyses, strict=True):
        processed_fill(joint_path(name, joint), one, settings)(cfg.file)
        if one.bouc_wen is not None:
            bouc_wen_fill(joint_path(name, joint), one.bouc_wen)(cfg.file)
        if joint in comparisons:
            write_comparison(cfg[f"{JOINTS}/{joint}"], comparisons[joint])
    put(cfg, "total_energy_loss_j", analysis.total_energy_loss_j, "J")
    put(cfg, "total_energy_cycle_trial", analysis.total_energy_cycle_trial, "1")
    cfg.attrs[JOINTS_ATTR] = np.array(job.joints, dtype=h5py.string_dtype())


_VALUES = ("energy_mean_j", "energy_std_j", "energy_cycles", "max_angle_deg")


def _recompare(f: h5py.File, comp: h5py.Group, archive_joints: str) -> None:
    """A comparison made again from the new results, as `steps/compare.py` makes it (never numbers from the
    old processing beside the new)."""
    names = [configuration_name(int(k)) for k in comp.attrs[CONFIGURATIONS_ATTR]]
    groups = [f[CONFIGURATIONS][n] for n in names if n in f[CONFIGURATIONS]]
    joints = [j.strip() for j in archive_joints.split(",")]
    identity: dict[str, object] = {
        k: attr_str(comp, k) for k in ("parameter", "section", "title") if k in comp.attrs
    }
    identity[CONFIGURATIONS_ATTR] = [int(k) for k in comp.attrs[CONFIGURATIONS_ATTR]]
    for key in _VALUES:
        if key in comp.attrs:
            del comp.attrs[key]
    if JOINTS in comp:
        del comp[JOINTS]
    comp.attrs[JOINTS_ATTR] = np.array(joints, dtype=h5py.string_dtype())
    complete = len(groups) == len(names) and all(JOINTS in g for g in groups)
    for joint in joints:
        g = comp.create_group(f"{JOINTS}/{joint}")
        values = comparison_values([g_cfg[JOINTS][joint] for g_cfg in groups]) if complete else {}
        put_attrs(g, "comparison", {**identity, **values})
    if complete and len(joints) > 1:
        put_attrs(comp, "comparison", comparison_values(groups))
