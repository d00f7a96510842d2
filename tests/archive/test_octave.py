"""GNU Octave reads every archive: its built-in `load` reads every dataset, and docs/matlab.md's recipe runs.

The type check runs everywhere; the Octave runs need `octave-cli` (Debian's `octave` package) and skip,
saying so, without it."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner.archive.export import export_mat
from protocol_runner.archive.h5util import put_text, text_of

REPO = Path(__file__).resolve().parents[2]
OCTAVE = shutil.which("octave-cli") or shutil.which("octave")
needs_octave = pytest.mark.skipif(OCTAVE is None, reason="GNU Octave (octave-cli) is not installed")


def test_every_dataset_is_numeric_or_a_fixed_length_ascii_string(reference_archive: Path) -> None:
    """Octave's `load` reads neither variable-length nor UTF-8-labelled strings nor empty string arrays,
    and stops reading the file at the first such dataset."""
    seen: list[str] = []
    with h5py.File(reference_archive, "r") as f:

        def visit(name: str, obj: h5py.HLObject) -> None:
            if not isinstance(obj, h5py.Dataset):
                return
            kind = obj.dtype.kind
            if kind == "S":
                assert h5py.check_string_dtype(obj.dtype).encoding == "ascii", name
                assert obj.size > 0, f"{name}: empty string array"
                seen.append(name)
            else:
                assert kind in "iuf", f"{name}: {obj.dtype}"

        f.visititems(visit)
    assert {"protocol", "plan", "session/events"} <= set(seen)


def test_text_keeps_its_utf8_characters_and_an_empty_list_stays_readable(tmp_path: Path) -> None:
    with h5py.File(tmp_path / "t.h5", "w") as f:
        put_text(f, "text", "flexion 0-130 \u00b0 (\u00a72.3)\n")
        put_text(f, "lines", ["a", "\u00fcber"])
        put_text(f, "none", [])
    with h5py.File(tmp_path / "t.h5", "r") as f:
        assert text_of(f["text"]) == "flexion 0-130 \u00b0 (\u00a72.3)\n"
        assert [b.decode() for b in f["lines"][()]] == ["a", "\u00fcber"]
        assert f["none"].shape == (1,) and f["none"][0] == b""


def _octave(script: str, cwd: Path) -> str:
    assert OCTAVE is not None
    path = cwd / "recipe.m"
    path.write_text(script)
    options = ["--norc", "--no-history"] + ([] if OCTAVE.endswith("-cli") else ["--no-gui"])
    done = subprocess.run([OCTAVE, *options, str(path)], cwd=cwd, capture_output=True, text=True, timeout=300)
    if done.returncode != 0 and "graphics_toolkit" in done.stderr:
        pytest.skip(f"Octave has no graphics toolkit to draw the loop: {done.stderr.strip()[-200:]}")
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


@pytest.fixture(scope="module")
def session_dir(reference_archive: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder as docs/matlab.md leaves it: archive.h5 and its export in mat/."""
    folder = tmp_path_factory.mktemp("octave")
    shutil.copyfile(reference_archive, folder / "archive.h5")
    export_mat(folder / "archive.h5", folder / "mat")
    return folder


def _field(name: str) -> str:
    """The field name Octave's `load` gives an HDF5 group or dataset name."""
    clean = re.sub(r"[^A-Za-z0-9_]", "_", name)
    return clean if clean[:1].isalpha() else f"_{clean}" if not clean.startswith("_") else clean


@needs_octave
def test_octave_load_reads_every_dataset_of_the_archive(session_dir: Path) -> None:
    walk = """1;
function walk(s, path)
  for k = fieldnames(s)'
    v = s.(k{1});
    if isstruct(v)
      walk(v, [path '/' k{1}]);
    else
      printf('%s %d %.17g %.17g\\n', [path '/' k{1}], numel(v), sum(double(v(:))), sum(abs(double(v(:)))));
    end
  end
end
walk(load('archive.h5'), '');
"""
    got = {}
    for line in _octave(walk, session_dir).splitlines():
        path, n, total, magnitude = line.rsplit(" ", 3)
        got[path] = (int(n), float(total), float(magnitude))
    expected = {}
    with h5py.File(session_dir / "archive.h5", "r") as f:

        def visit(name: str, obj: h5py.HLObject) -> None:
            if isinstance(obj, h5py.Dataset):
                path = "/" + "/".join(_field(p) for p in name.split("/"))
                value = obj[()]
                if obj.dtype.kind == "S":  # a char matrix: one row per string, padded with blanks
                    rows = np.atleast_1d(value)
                    width = max(len(r) for r in rows)
                    raw = b"".join(r.ljust(width, b" ") for r in rows)
                    expected[path] = (len(raw), float(sum(raw)), float(sum(raw)))
                else:
                    data = np.asarray(value, dtype=np.float64)
                    expected[path] = (obj.size, float(np.sum(data)), float(np.sum(np.abs(data))))

        f.visititems(visit)
    assert sorted(got) == sorted(expected)
    for path, (n, total, magnitude) in expected.items():
        assert got[path][0] == n, path  # every value read: same count, same sum (to rounding)
        assert got[path][1] == pytest.approx(total, abs=1e-12 * magnitude), path
        assert got[path][2] == pytest.approx(magnitude, rel=1e-12), path


@needs_octave
def test_the_documented_octave_recipe_gives_the_archive_numbers(session_dir: Path) -> None:
    """docs/matlab.md's tested blocks, run as written (figures drawn off screen, the loop saved as PNG)."""
    doc = (REPO / "docs" / "matlab.md").read_text()
    blocks = re.findall(r"<!-- octave-test[^\n]*-->\n```matlab\n(.*?)```", doc, flags=re.S)
    assert len(blocks) == 2
    script = "set(0, 'defaultfigurevisible', 'off');\n" + "\n".join(blocks) + "print('-dpng', 'loop.png');\n"
    out = _octave(script, session_dir)
    with h5py.File(session_dir / "archive.h5", "r") as f:
        cfg = f["configurations/config_12/joints/knee_flexion"]
        energy = cfg["energy_loss_j"]
        n_processed = cfg["trials/1/processed/angle_deg"].shape[0]
        mean_j, std_j = energy.attrs["mean_j"], energy.attrs["std_j"]
        assert f"energy loss {mean_j:.3f} +- {std_j:.3f} J per cycle, {energy.shape[0]} cycles" in out, out
        assert (
            f"archive: {energy.shape[0]} cycles, mean {np.mean(energy[:]):.3f} J; "
            f"trial 1: {n_processed} processed samples" in out
        ), out
    assert "protocol text intact: 1" in out, out
    png = (session_dir / "loop.png").read_bytes()
    assert png.startswith(b"\x89PNG") and len(png) > 5000
