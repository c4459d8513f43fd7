"""A file stands alone (#37 item 2): with `MENAGERIE_ROOT` pointing at an empty folder, replay
and convert build the env on the compiled model the file stores, say so, and replay it
exactly."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT, menagerie
from test_demos_hdf5 import PICK

from mjkdl.demos import DemoFile, collect


@pytest.fixture(scope="module")
def picks(tmp_path_factory: pytest.TempPathFactory) -> Path:
    menagerie("franka_emika_panda")
    out = tmp_path_factory.mktemp("alone") / "picks.hdf5"
    collect(PICK, "expert", out, episodes=2, seed=0, progress=False)
    return out


def without_assets(*args: str, folder: Path) -> subprocess.CompletedProcess:
    """`python -m mjkdl.demos ...` with `MENAGERIE_ROOT` an empty folder."""
    empty = folder / "empty"
    empty.mkdir(exist_ok=True)
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MENAGERIE_ROOT": str(empty)}
    return subprocess.run(
        [sys.executable, "-m", "mjkdl.demos", *args],
        capture_output=True, text=True, env=env, timeout=600,
    )  # fmt: skip


def test_replay_runs_on_the_stored_model(picks: Path, tmp_path: Path) -> None:
    with DemoFile(picks) as f:
        lengths = [d.num_samples for d in f]
        fingerprint = f.stored_model(0)[1]
    r = without_assets("replay", str(picks), folder=tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines() == [
        f"demo_{i}: {n} steps, max state error 0" for i, n in enumerate(lengths)
    ]
    assert "StoredModelWarning: MuJoCo Menagerie model 'franka_emika_panda' is not available" in (
        r.stderr
    )
    assert f"runs on the model {picks} stores instead (models/{fingerprint[:12]}..." in r.stderr
    assert "ReplayWarning" not in r.stderr  # the same model: nothing to report


@pytest.mark.parametrize("mode", ["actions", "states"])
def test_convert_runs_on_the_stored_model(picks: Path, tmp_path: Path, mode: str) -> None:
    out = tmp_path / f"{mode}.hdf5"
    kwargs = '{"camera_names": ["wrist"], "camera_size": [24, 32]}'
    r = without_assets("convert", str(picks), str(out), "--env-kwargs", kwargs, "--mode", mode,
                       folder=tmp_path)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert f"{out}: 2 demos, observations by {mode}" in r.stdout
    assert r.stderr.count("StoredModelWarning") == 1
    with DemoFile(picks) as a, DemoFile(out) as b:
        assert b.stored_model(1)[1:] == a.stored_model(1)[1:]  # the model is carried over
        assert b.demo(1).obs["wrist_rgb"].shape == (a.demo(1).num_samples, 24, 32, 3)


def test_assets_missing_and_no_stored_model_is_the_assets_error(tmp_path: Path) -> None:
    r = without_assets("collect", PICK, "--expert", "--episodes", "1", "--out",
                       str(tmp_path / "x.hdf5"), folder=tmp_path)  # fmt: skip
    assert r.returncode != 0
    assert "MuJoCo Menagerie model 'franka_emika_panda' is not available" in r.stderr


def test_evaluate_takes_a_file_and_runs_on_its_model(picks: Path, tmp_path: Path) -> None:
    r = without_assets("evaluate", str(picks), "--expert", "--episodes", "2", "--seed", "0",
                       folder=tmp_path)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines()[-1].startswith("success: 100.0 % (95 % CI 34.2-100.0 %, 2/2)")
    assert r.stderr.count("StoredModelWarning") == 1


def test_collect_refuses_a_file_for_an_env_id(picks: Path, tmp_path: Path) -> None:
    r = without_assets("collect", str(picks), "--expert", "--episodes", "1", "--out",
                       str(tmp_path / "y.hdf5"), folder=tmp_path)  # fmt: skip
    assert r.returncode == 2
    assert f"collect records into a Gymnasium id's env, got the demonstration file {picks}" in (
        r.stderr
    )
