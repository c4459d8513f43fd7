"""`mjk.assets`: the files shipped inside the package, found from any working directory."""

from __future__ import annotations

import fnmatch
from pathlib import Path

import mujoco
import pytest
from conftest import ROOT

import mjkdl as mjk


def test_table_path_is_absolute_and_compiles(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    path = Path(mjk.assets.path("table"))
    assert path.is_absolute()
    assert path == ROOT / "mjkdl" / "assets" / "table.xml"
    model = mujoco.MjModel.from_xml_path(str(path))
    assert model.site("table_top").id >= 0
    assert mjk.assets.names() == ["table"]


@pytest.mark.parametrize("name", ["tabel", "table.xml", "../assets/table", "", 3])
def test_unknown_asset_lists_the_available_ones(name) -> None:
    with pytest.raises(mjk.UnknownNameError) as info:
        mjk.assets.path(name)
    assert isinstance(info.value, KeyError)
    assert str(info.value) == f"no mjkdl asset named {name!r}; available: table"


def test_every_asset_is_package_data() -> None:
    tomllib = pytest.importorskip("tomllib")  # Python >= 3.11
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert "mjkdl.assets" in config["packages"]
    patterns = config["package-data"]["mjkdl.assets"]
    files = [p.name for p in (ROOT / "mjkdl" / "assets").iterdir() if p.suffix != ".py"]
    files = [f for f in files if f != "__pycache__"]
    assert files
    assert all(any(fnmatch.fnmatch(f, pattern) for pattern in patterns) for f in files)
