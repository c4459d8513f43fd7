"""Replay: 20 recorded demos replayed in a fresh process reproduce every state exactly; state
replay renders the recorded camera frames again; another model or version is reported."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import h5py
import imageio_ffmpeg
import pytest
from conftest import menagerie
from demo_envs import CAMERA
from test_demos_hdf5 import PICK, cli

from mjkdl.demos import DemoFile, ReplayWarning, collect, file_env, replay, replay_all


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


@pytest.fixture(scope="module")
def twenty(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """20 demos of the scripted expert grasping and lifting the cube (contacts and all),
    recorded by the command line with two workers."""
    menagerie("franka_emika_panda")
    out = tmp_path_factory.mktemp("replay") / "twenty.hdf5"
    r = cli("collect", PICK, "--expert", "--episodes", "20", "--seed", "100", "--workers", "2",
            "--keep-failures", "--out", str(out))  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert f"{out}: kept 20 of 20 episodes" in r.stdout
    return out


def test_twenty_demos_replay_exactly_in_a_fresh_process(twenty: Path) -> None:
    with DemoFile(twenty) as f:
        assert [d.seed for d in f] == list(range(100, 120))
        lengths = [d.num_samples for d in f]
        successes = sum(d.success for d in f)
    assert successes >= 19  # the expert lifts the cube: grasps, contacts, a free body
    r = cli("replay", str(twenty))
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines == [f"demo_{i}: {n} steps, max state error 0" for i, n in enumerate(lengths)]
    assert "ReplayWarning" not in r.stderr


def test_replay_in_python_and_a_video(twenty: Path, tmp_path: Path) -> None:
    video = tmp_path / "replay.mp4"
    result = replay(twenty, 3, video=video, video_size=(160, 120))
    assert result.max_state_error == 0.0 and result.first_mismatch == -1
    assert result.success and result.recorded_success
    reader = imageio_ffmpeg.read_frames(str(video))
    meta = next(reader)
    assert meta["size"] == (160, 120)
    assert sum(1 for _ in reader) == result.steps + 1  # the start and every step


def test_replaying_all_demos_builds_one_env(twenty: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    replay_module = sys.modules["mjkdl.demos.replay"]
    built = []

    def counting(file: DemoFile) -> object:
        built.append(file.env_name)
        return file_env(file)

    monkeypatch.setattr(replay_module, "file_env", counting)
    results = list(replay_all(twenty, [0, 5, "demo_7"]))
    assert [r.demo for r in results] == ["demo_0", "demo_5", "demo_7"]
    assert all(r.max_state_error == 0.0 for r in results)
    assert built == [PICK]


def test_a_changed_action_is_found_at_its_step(twenty: Path, tmp_path: Path) -> None:
    copy = tmp_path / "edited.hdf5"
    copy.write_bytes(twenty.read_bytes())
    with h5py.File(copy, "r+") as f:
        f["data/demo_2/actions"][10, 0] += 0.01
    result = replay(copy, 2)
    assert result.first_mismatch == 11 and result.max_state_error > 0
    r = cli("replay", str(copy), "--demo", "2")
    assert r.returncode == 1 and "first at step 11" in r.stdout


def test_another_model_or_version_is_reported_before_replay(twenty: Path, tmp_path: Path) -> None:
    copy = tmp_path / "other.hdf5"
    copy.write_bytes(twenty.read_bytes())
    with h5py.File(copy, "r+") as f:
        f["data/demo_0"].attrs["model_hash"] = "0" * 64
        args = json.loads(f["data"].attrs["env_args"])
        args["mujoco_version"] = "3.1.0"
        f["data"].attrs["env_args"] = json.dumps(args)
    with pytest.warns(ReplayWarning) as caught:
        replay(copy, 0)
    messages = [str(w.message) for w in caught]
    assert any("was recorded with MuJoCo 3.1.0, this is" in m for m in messages), messages
    assert any("demo_0 was recorded with another model than" in m for m in messages), messages
    r = cli("replay", str(copy), "--demo", "0")
    assert "was recorded with another model" in r.stderr


def test_state_replay_renders_the_recorded_frames(tmp_path: Path) -> None:
    out = tmp_path / "cam.hdf5"
    collect(PICK, "demo_envs:approach", out, episodes=1, keep_failures=True,
            env_kwargs={**CAMERA, "max_episode_steps": 8}, progress=False)  # fmt: skip
    result = replay(out, 0, mode="states", video=tmp_path / "states.mp4", video_size=(96, 64))
    assert result.steps == 8
    assert 0 <= result.max_pixel_error <= 2  # poses as mj_forward gives them, not bit for bit
    assert (tmp_path / "states.mp4").stat().st_size > 0
    assert replay(out, 0).max_state_error == 0.0


def test_bad_replay_requests(twenty: Path, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="--mode must be one of actions, states, got 'joints'"):
        replay(twenty, 0, mode="joints")
    with pytest.raises(KeyError, match="no demo named 'demo_20'"):
        replay(twenty, 20)
    r = cli("replay", str(twenty), "--video", str(tmp_path / "x.mp4"))
    assert r.returncode == 2 and "--video films one demo: add --demo i" in r.stderr
    r = cli("replay", str(tmp_path / "missing.hdf5"))
    assert r.returncode == 2 and "missing.hdf5: no such demonstration file" in r.stderr
