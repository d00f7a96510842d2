"""A crafted archive declaring a 10^12-element dataset gets a clear exit 2 naming it, after bounded work
(archive/layout.py): shapes are checked against the layout before anything is read, by --verify, the
report, --reprocess and --export-mat."""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner.archive.layout import HARD_CAP, MARGIN_S, MAX_INPUT_RATE_HZ, element_cap
from protocol_runner.cli import main
from protocol_runner.protocol.schema import InputSpec

TARGET = "configurations/config_12/trials/1/brace_on/joints/knee_flexion/angle_deg"  # read by the report and by --reprocess


def craft(path: Path, name: str, **create: object) -> None:
    """Replace dataset `name` by one declaring a huge shape: chunked, nothing stored (HDF5 fills it in)."""
    with h5py.File(path, "r+") as f:
        units = f[name].attrs["units"]
        del f[name]
        ds = f.create_dataset(name, **create)  # type: ignore[arg-type]
        ds.attrs["units"] = units


@pytest.mark.parametrize(
    "create",
    [
        {"shape": (10**12,), "dtype": "f8", "chunks": (1024,), "fillvalue": 1.0},
        {"shape": (10**6, 10**6), "dtype": "f4", "chunks": (64, 64)},
        {"shape": (2000,), "dtype": "f8", "chunks": (2000,), "maxshape": (None,)},  # in bounds, no checksum
    ],
    ids=["1e12 elements", "1e12 elements 2-D", "small (checksum missing)"],
)
def test_a_dataset_declaring_a_huge_shape_gets_exit_2_before_any_read(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str], create: dict[str, object]
) -> None:
    archive = tmp_path / "archive.h5"
    shutil.copyfile(reference_archive, archive)
    craft(archive, TARGET, **create)
    for args in (
        ("--verify", str(archive)),
        ("--report", str(archive), "--output", str(tmp_path / "r.html")),
        ("--report", str(archive), "--reprocess"),
        ("--report", str(archive), "--export-mat", str(tmp_path / "mat")),
    ):
        t0 = time.monotonic()
        code = main(list(args))
        err = capsys.readouterr().err
        assert code == 2, (args, err)
        assert f"dataset /{TARGET}" in err and "Traceback" not in err
        assert time.monotonic() - t0 < 30
        if create["shape"] != (2000,):
            assert "elements, more than the" in err
        else:
            assert "has no checksum" in err


def test_the_bound_follows_the_plan_and_is_capped(tmp_path: Path) -> None:
    path = tmp_path / "a.h5"

    def cap_with(steps: list[dict[str, object]]) -> int:
        with h5py.File(path, "w") as f:
            f.create_dataset("plan", data=json.dumps({"steps": steps}), dtype=h5py.string_dtype())
            return element_cap(f)

    # the longest step's planned duration plus the margin, at the highest input rate a protocol may declare
    long_trial = {"kind": "trial", "trajectory": {"profile": "sinusoid", "duration_s": 130.0}}
    short = {"kind": "calibration_check", "trajectory": {"duration_s": 5.6}}
    assert cap_with([short, long_trial]) == int((130.0 + MARGIN_S) * MAX_INPUT_RATE_HZ)
    assert cap_with([]) == int(MARGIN_S * MAX_INPUT_RATE_HZ)
    # a plan claiming absurd durations cannot lift the bound past one hour at that rate
    assert cap_with([{"trajectory": {"duration_s": 1e12}}]) == HARD_CAP
    assert cap_with([{"trajectory": {"duration_s": float("nan")}}]) == int(MARGIN_S * MAX_INPUT_RATE_HZ)
    with h5py.File(path, "w") as f:  # no plan at all
        assert element_cap(f) == int(MARGIN_S * MAX_INPUT_RATE_HZ)


def test_the_rate_bound_is_the_schemas_highest_input_rate() -> None:
    limits = [m.le for m in InputSpec.model_fields["rate_hz"].metadata if hasattr(m, "le")]
    assert limits == [MAX_INPUT_RATE_HZ]


def test_every_recorded_dataset_is_well_within_the_bound(reference_archive: Path) -> None:
    with h5py.File(reference_archive, "r") as f:
        cap = element_cap(f)
        sizes: list[int] = []
        f.visititems(lambda _, o: sizes.append(o.size) if isinstance(o, h5py.Dataset) else None)
    assert max(sizes) * 10 < cap
    assert np.asarray(sizes).sum() < HARD_CAP
