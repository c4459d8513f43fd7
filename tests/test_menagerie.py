"""`mjk.menagerie.model_path`: known names, unknown names, models missing under MENAGERIE_ROOT."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import menagerie

import mjkdl as mjk


@pytest.mark.parametrize(
    ("name", "file"), [("kinova_gen3", "gen3.xml"), ("robotiq_2f85", "2f85.xml")]
)
def test_known_names_resolve_to_existing_files(name, file):
    path = Path(menagerie(name))
    assert path.is_file()
    assert path.name == file
    assert path.parent.name == name
    assert mjk.menagerie.model_path(name) == str(path)


def test_model_path_honours_menagerie_root():
    gen3 = Path(menagerie("kinova_gen3"))
    root = gen3.parent.parent
    assert (
        Path(mjk.menagerie.model_path("kinova_gen3")).resolve()
        == (root / "kinova_gen3" / "gen3.xml").resolve()
    )


def test_names_lists_known_robots():
    names = mjk.menagerie.names()
    assert "kinova_gen3" in names
    assert "robotiq_2f85" in names


def test_unknown_name_lists_close_matches():
    with pytest.raises(KeyError, match=r"'kinova_gen'.*close matches: .*kinova_gen3") as err:
        mjk.menagerie.model_path("kinova_gen")
    assert isinstance(err.value, mjk.MjkdlError)
    assert str(err.value).startswith("no MuJoCo Menagerie robot")


def test_model_missing_under_menagerie_root(tmp_path, monkeypatch):
    monkeypatch.setenv("MENAGERIE_ROOT", str(tmp_path))
    with pytest.raises(FileNotFoundError, match="MENAGERIE_ROOT") as err:
        mjk.menagerie.model_path("kinova_gen3")
    message = str(err.value)
    assert "kinova_gen3" in message
    assert str(tmp_path) in message
