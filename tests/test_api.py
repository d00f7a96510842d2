"""The Python interface (docs/api.md): the documented example runs as written, and importing the package
stays cheap."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _example() -> str:
    text = (REPO / "docs" / "api.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) == 1
    return blocks[0]


def test_the_documented_example_runs_as_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    exec(compile(_example(), "docs/api.md", "exec"), {})
    out = capsys.readouterr().out.splitlines()
    session = tmp_path / "sessions" / "elbow-config-1"
    assert out[1] == "complete sessions/elbow-config-1/archive.h5"
    assert re.fullmatch(
        r"configuration 1 \(.+\): [1-9]\d* cycles, mean energy lost \d+\.\d{3} J per cycle", out[2]
    )
    assert out[3] == (
        "again.html ['cycles.csv', 'trials.csv', 'configurations.csv', 'models.csv', 'elements.csv', "
        "'predictions.csv']"
    )
    for name in ("archive.h5", "report.html", "again.html", "tables/cycles.csv"):
        assert (session / name).is_file(), name


def test_importing_the_package_loads_neither_numpy_nor_numba() -> None:
    code = "import sys, protocol_runner; print(sorted(m for m in ('numpy', 'numba', 'h5py') if m in sys.modules))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


def test_a_protocol_mistake_raises_invalid_input_with_file_and_line(tmp_path: Path) -> None:
    import protocol_runner
    from protocol_runner.errors import InvalidInput

    bad = tmp_path / "bad.yaml"
    bad.write_text(
        (REPO / "protocols" / "elbow_example.yaml").read_text(encoding="utf-8") + "\nbogus_key: 1\n"
    )
    with pytest.raises(InvalidInput, match=r"bad\.yaml:\d+: .*bogus_key"):
        protocol_runner.load_protocol(bad)
