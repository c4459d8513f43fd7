"""`mjk.menagerie.model_path`: known names, unknown names, models missing under MENAGERIE_ROOT;
the examples' one-line message when a model is missing."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT, menagerie

import mjkdl as mjk


@pytest.mark.parametrize(
    ("name", "file"), [("kinova_gen3", "gen3.xml"), ("robotiq_2f85", "2f85.xml")]
)
def test_known_names_resolve_under_menagerie_root(name, file):
    menagerie(name)  # skips when the model is not on this machine
    root = os.environ.get("MENAGERIE_ROOT")
    if not root:
        pytest.skip("MENAGERIE_ROOT is not set: the models come from the package's cache")
    path = Path(mjk.menagerie.model_path(name))
    assert path.is_file()
    assert path.resolve() == (Path(root) / name / file).resolve()


def test_model_path_follows_menagerie_root(tmp_path, monkeypatch):
    real = Path(menagerie("kinova_gen3")).parent
    (tmp_path / "kinova_gen3").symlink_to(real, target_is_directory=True)
    monkeypatch.setenv("MENAGERIE_ROOT", str(tmp_path))
    path = mjk.menagerie.model_path("kinova_gen3")
    assert Path(path).parent.parent == tmp_path
    assert Path(path).name == "gen3.xml"
    with mjk.Scene.build(
        mjk.SceneSpec(
            timestep=0.002, add_floor=False, add_skybox=False, robots=[mjk.RobotSpec(path=path)]
        )
    ) as scene:
        assert scene.model.njnt == 7


def test_names_lists_known_robots():
    names = mjk.menagerie.names()
    assert "kinova_gen3" in names
    assert "robotiq_2f85" in names


def test_unknown_name_lists_close_matches():
    with pytest.raises(KeyError, match=r"'kinova_gen'.*close matches: .*kinova_gen3") as err:
        mjk.menagerie.model_path("kinova_gen")
    assert isinstance(err.value, mjk.MjkdlError)
    assert str(err.value).startswith("no MuJoCo Menagerie robot")


@pytest.mark.parametrize("name", [None, 3, ["kinova_gen3"]])
def test_a_name_that_is_not_text_is_refused(name):
    with pytest.raises(mjk.SpecTypeError) as err:
        mjk.menagerie.model_path(name)
    assert str(err.value) == f"menagerie.model_path(name) must be a string, got {name!r}"


def test_model_missing_under_menagerie_root(tmp_path, monkeypatch):
    monkeypatch.setenv("MENAGERIE_ROOT", str(tmp_path))
    with pytest.raises(FileNotFoundError, match="MENAGERIE_ROOT") as err:
        mjk.menagerie.model_path("kinova_gen3")
    message = str(err.value)
    assert "kinova_gen3" in message
    assert str(tmp_path) in message


def test_example_without_menagerie_exits_with_one_line(tmp_path):
    env = dict(os.environ, MENAGERIE_ROOT=str(tmp_path), MUJOCO_GL="egl")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    done = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "gravity_comp.py"), "--headless"],
        env=env,
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 1
    assert done.stdout == ""
    lines = done.stderr.splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith("gravity_comp.py: MuJoCo Menagerie model 'kinova_gen3'")
    assert f"MENAGERIE_ROOT={tmp_path} has no folder 'kinova_gen3'" in lines[0]


def test_a_menagerie_root_that_does_not_exist_says_so(tmp_path, monkeypatch):
    missing = tmp_path / "nowhere"
    monkeypatch.setenv("MENAGERIE_ROOT", str(missing))
    with pytest.raises(mjk.ModelFileError) as err:
        mjk.menagerie.model_path("robotiq_2f85")
    assert str(err.value) == (
        f"MuJoCo Menagerie model 'robotiq_2f85' is not available: MENAGERIE_ROOT={missing} "
        "does not exist: point it at a Menagerie clone (git clone "
        "https://github.com/google-deepmind/mujoco_menagerie), or unset it so the "
        "mujoco-menagerie package downloads models into its cache"
    )
    assert mjk.menagerie.available() == {}
    (tmp_path / "file").write_text("")
    monkeypatch.setenv("MENAGERIE_ROOT", str(tmp_path / "file"))
    with pytest.raises(mjk.ModelFileError, match=r"MENAGERIE_ROOT=\S+file is not a folder"):
        mjk.menagerie.model_path("robotiq_2f85")


def _cli(**settings: Path) -> subprocess.CompletedProcess:
    """`python -m mjkdl.menagerie` with these environment variables, MENAGERIE_ROOT unset
    unless given."""
    env = {k: v for k, v in os.environ.items() if k != "MENAGERIE_ROOT"}
    env.update({k: str(v) for k, v in settings.items()})
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return subprocess.run(
        [sys.executable, "-m", "mjkdl.menagerie"],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_the_command_line_lists_what_it_finds_and_where(tmp_path):
    real = Path(menagerie("kinova_gen3")).parent
    (tmp_path / "kinova_gen3").symlink_to(real, target_is_directory=True)
    (tmp_path / "not_a_model").mkdir()
    done = _cli(MENAGERIE_ROOT=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    lines = done.stdout.splitlines()
    known = len(mjk.menagerie.names())
    assert lines == [
        f"MuJoCo Menagerie models from MENAGERIE_ROOT={tmp_path}",
        f"  kinova_gen3  {tmp_path / 'kinova_gen3'}",
        f"1 models here, {known - 1} more known to Menagerie (not in this folder)",
    ]


def test_the_command_line_fails_on_a_missing_root(tmp_path):
    done = _cli(MENAGERIE_ROOT=tmp_path / "nowhere")
    assert done.returncode == 1
    assert done.stdout == ""
    assert done.stderr.startswith(f"MENAGERIE_ROOT={tmp_path / 'nowhere'} does not exist: ")


def test_the_command_line_without_a_root_names_the_cache(tmp_path):
    env_cache = tmp_path / "cache"
    done = _cli(MENAGERIE_CACHE_DIR=env_cache)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[0] == (
        "MENAGERIE_ROOT is not set: models come from the mujoco-menagerie package's cache at "
        f"{env_cache}, downloaded on first use"
    )
    assert done.stdout.splitlines()[-1].startswith("0 models here, ")


def test_the_test_summary_counts_menagerie_skips(tmp_path):
    env = dict(os.environ, MENAGERIE_ROOT=str(tmp_path), MUJOCO_GL="egl")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            str(ROOT / "tests" / "test_menagerie.py"),
            "-k",
            "known_names_resolve",
        ],
        env=env,
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout
    assert (
        "2 tests skipped for want of Menagerie models (kinova_gen3, robotiq_2f85): "
        f"not under MENAGERIE_ROOT={tmp_path}. README.md says how to get them; "
        "`python -m mjkdl.menagerie` lists what is found where."
    ) in done.stdout
