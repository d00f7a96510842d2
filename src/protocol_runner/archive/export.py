"""`run-protocol --report ARCHIVE --export-mat DIR`: each configuration's processed data as a .mat file.

One file per configuration, `config_NN.mat` (MATLAB 5 format, scipy.io.savemat), holding:

    configuration   struct of the configuration's settings (key, brace ROM, friction, stiffness, ...)
    trial_n         struct per trial n: time_s, angle_deg, brace_torque_nm (processed)
    energy_loss_j   energy lost per complete cycle (J), energy_cycle_trial: each cycle's trial
    bouc_wen        struct: A, n, beta, rmse_nm, r2 (when fitted)
    spring          struct: max_preload_mm, zero_offset_deg, rmse_nm (when fitted)
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np
from scipy.io import savemat

from ..errors import InvalidInput


def _attrs(obj: h5py.HLObject) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in obj.attrs.items():
        if isinstance(value, bytes):
            value = value.decode("utf-8")
        out[key.replace("-", "_")] = value
    return out


def export_mat(archive: Path, out_dir: Path) -> list[Path]:
    from ..report.load import validate_archive  # clear messages for foreign or damaged files

    validate_archive(archive)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InvalidInput(f"--export-mat: cannot create {out_dir}: {exc.strerror}") from None
    written: list[Path] = []
    with h5py.File(archive, "r") as f:
        for name, cfg in f.get("configurations", {}).items():
            content: dict[str, Any] = {"configuration": _attrs(cfg)}
            trials = cfg.get("trials", {})
            for n in sorted(trials, key=int):
                g = trials[n].get("processed")
                if g is None:
                    continue
                content[f"trial_{n}"] = {
                    k: np.asarray(g[k][:], dtype=np.float64)
                    for k in ("time_s", "angle_deg", "brace_torque_nm")
                }
            for ds in ("energy_loss_j", "energy_cycle_trial"):
                if ds in cfg:
                    content[ds] = np.asarray(cfg[ds][:])
            fits = cfg.get("fits", {})
            for fit in ("bouc_wen", "spring"):
                if fit in fits:
                    content[fit] = _attrs(fits[fit])
            path = out_dir / f"{name}.mat"
            savemat(path, content, do_compression=True, oned_as="column")
            written.append(path)
    if not written:
        raise InvalidInput(f"{archive}: no configurations to export")
    return written
