"""`run-protocol --report ARCHIVE --reprocess`: redo processing and fits from an archive's raw data.

No rig and no session directory are needed: the raw trials, the protocol text and the plan are in the
archive. The processing and fit settings come from the archived protocol, or from a given protocol file
(only its `processing` and `fits` sections are used; the acquisition stays what it was). The result is a
new archive next to the old one; the old one is never modified. Raw data are copied unchanged.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import h5py

from ..analysis.service import analyse_configuration
from ..errors import InvalidInput
from ..protocol.loaded import LoadedProtocol
from ..protocol.loader import find_protocol, load_protocol, parse_protocol_text
from ..protocol.processing import bouc_wen_settings, element_fit_enabled, processing_settings
from .attrs import CONFIGURATIONS as CONFIGURATIONS_ATTR
from .attrs import DEVICE_JSON, FILENAME
from .attrs import JOINTS as JOINTS_ATTR
from .checksums import is_marked, seal_attributes, seal_missing
from .h5util import attr_str, put_attrs, text_of
from .model_results import PREDICTIONS, compare_owner
from .outputs import create_binary, refuse_special, temporary_beside, terminated_as_interrupt
from .paths import FITS, TRIALS, configuration_name
from .reprocess_joints import complete_pairs, reprocess_joints
from .results import bouc_wen_fill, comparison_values, processed_fill
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


def reprocess_archive(archive: Path, *, protocol_file: str | None = None, output: Path | None = None) -> Path:
    """Write the reprocessed copy of `archive` (to `output`, default `new_archive_path`) and return its path.

    The copy is made under a temporary name beside it, with the umask's permissions like any file the
    program writes, and renamed when complete; it is removed whatever stops the work (an error, Ctrl-C,
    SIGTERM), so no partial archive is ever left behind. An `output` that is not a regular file (a link, a
    device, a FIFO) is refused (archive/outputs.py)."""
    validate_archive(archive)  # every dataset and attribute within bounds and intact, or a message naming it
    out = output or new_archive_path(archive)
    refuse_special(out, "--reprocess output")
    partial = temporary_beside(out)
    with terminated_as_interrupt():
        try:
            _write_reprocessed(archive, partial, protocol_file)
            os.replace(partial, out)
        finally:
            partial.unlink(missing_ok=True)
    return out


def _write_reprocessed(archive: Path, partial: Path, protocol_file: str | None) -> None:
    with create_binary(partial) as fh, archive.open("rb") as src:
        shutil.copyfileobj(src, fh)
    with h5py.File(partial, "r+") as f:
        archived = _archived_protocol(f, archive)
        settings_source = archived
        if protocol_file is not None:
            settings_source = load_protocol(find_protocol(protocol_file), check_files=False)
        _reprocess(f, settings_source)
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


def archived_device(cfg: h5py.Group) -> list[tuple[str, str, dict[str, object]]]:
    """The configuration's device as the session resolved it (its `device_json` attribute, docs/archive.md):
    (name, type, parameters) per element; empty for an archive written before devices were declared (its
    element fit is then not applicable). A `device_json` that is not the documented list is named."""
    if DEVICE_JSON not in cfg.attrs:
        return []
    where = f"{cfg.file.filename}: {cfg.name}@{DEVICE_JSON}"
    try:
        doc = json.loads(attr_str(cfg, DEVICE_JSON, "[]"))
    except json.JSONDecodeError as exc:
        raise InvalidInput(f"{where}: not valid JSON ({exc.msg})") from None
    if not isinstance(doc, list) or not all(isinstance(e, dict) and "name" in e and "type" in e for e in doc):
        raise InvalidInput(f"{where}: must be a JSON list of elements, each with a name and a type")
    return [(str(e.pop("name")), str(e.pop("type")), e) for e in doc]


def _reprocess(f: h5py.File, loaded: LoadedProtocol) -> None:
    """Redo what the session's process, fit and compare steps did, from the raw trials in `f`, with the
    same function (`analysis.service.analyse_configuration`), so that unchanged settings reproduce the
    session's values exactly."""
    settings = processing_settings(loaded)
    fit = bouc_wen_settings(loaded) if loaded.protocol.fits.bouc_wen.enabled else None
    elements = element_fit_enabled(loaded)
    for name, cfg in f["configurations"].items():
        if TRIALS not in cfg:
            continue
        if JOINTS_ATTR in cfg.attrs:  # several joints driven together: processed joint by joint
            reprocess_joints(f, name, archived_device(cfg), settings, fit, elements=elements)
            continue
        pairs = complete_pairs(cfg, name)
        for stale in ("energy_loss_j", "energy_cycle_trial", FITS):
            if stale in cfg:
                del cfg[stale]
        if not pairs:
            continue
        analysis = analyse_configuration(
            pairs, settings, fit, device=archived_device(cfg) if elements else None
        )
        processed_fill(name, analysis, settings)(f)
        if analysis.bouc_wen is not None:
            bouc_wen_fill(name, analysis.bouc_wen)(f)
            if elements:  # the model comparison, as the fit step makes it
                compare_owner(cfg, archived_device(cfg), analysis.bouc_wen)
    if PREDICTIONS in f:  # made from the old fits: `report.predictions.record_predictions` makes them anew
        del f[PREDICTIONS]
    for comp in f.get("comparisons", {}).values():
        names = [configuration_name(int(k)) for k in comp.attrs[CONFIGURATIONS_ATTR]]
        groups = [f["configurations"][n] for n in names if n in f["configurations"]]
        if len(groups) == len(names):
            put_attrs(comp, "comparison", comparison_values(groups))
        else:  # never leave numbers from the old processing beside the new
            for key in ("energy_mean_j", "energy_std_j", "energy_cycles", "max_angle_deg"):
                if key in comp.attrs:
                    del comp.attrs[key]
