"""Evaluation: per-episode results in seed order, the Wilson interval, videos, workers."""

from __future__ import annotations

import re
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pytest
from conftest import menagerie
from test_demos_hdf5 import PICK, REACH, cli

from mjkdl.demos import evaluate, wilson_interval


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


def test_wilson_interval_matches_the_published_values() -> None:
    # Newcombe (1998), Statistics in Medicine 17:857, table I: 81/263 -> 0.2553-0.3662
    assert wilson_interval(81, 263) == pytest.approx((0.2553, 0.3662), abs=5e-5)
    assert wilson_interval(50, 100) == pytest.approx((0.4038, 0.5962), abs=5e-5)
    assert wilson_interval(0, 10) == pytest.approx((0.0, 0.2775), abs=5e-5)
    assert wilson_interval(10, 10) == pytest.approx((0.7225, 1.0), abs=5e-5)
    with pytest.raises(ValueError, match="at least one episode, got 0"):
        wilson_interval(0, 0)


def test_evaluate_in_python_with_videos(tmp_path: Path) -> None:
    ev = evaluate(PICK, "demo_envs:approach", episodes=3, seed=5,
                  env_kwargs={"max_episode_steps": 6}, video_dir=tmp_path / "v", videos=2,
                  video_size=(96, 64), progress=False)  # fmt: skip
    assert [e.seed for e in ev.episodes] == [5, 6, 7]
    assert all(e.length == 6 and not e.success for e in ev.episodes)
    assert ev.success_rate == 0.0 and ev.interval == pytest.approx((0.0, 0.5615), abs=5e-5)
    assert ev.videos == [tmp_path / "v" / "episode_5.mp4", tmp_path / "v" / "episode_6.mp4"]
    frames = imageio_ffmpeg.read_frames(str(ev.videos[0]))
    assert next(frames)["size"] == (96, 64) and sum(1 for _ in frames) == 7
    assert sorted(p.name for p in (tmp_path / "v").iterdir()) == ["episode_5.mp4", "episode_6.mp4"]
    assert ev.summary().startswith("success: 0.0 % (95 % CI 0.0-56.1 %, 0/3); mean return ")


def test_the_command_line_prints_each_episode_and_the_rate() -> None:
    r = cli("evaluate", REACH, "--random", "--episodes", "4", "--seed", "2", "--workers", "2",
            "--env-kwargs", '{"max_episode_steps": 5}')  # fmt: skip
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert [ln.split(":")[0] for ln in lines[:4]] == ["seed 2", "seed 3", "seed 4", "seed 5"]
    assert all(
        re.fullmatch(r"seed \d: success=False return=\d+\.\d{3} length=5", ln) for ln in lines[:4]
    )
    rate = r"success: 0\.0 % \(95 % CI 0\.0-49\.0 %, 0/4\); mean return \d+\.\d{3}, "
    assert re.fullmatch(rate + r"mean length 5\.0 steps", lines[4])
    single = evaluate(
        REACH, "random", episodes=4, seed=2, env_kwargs={"max_episode_steps": 5}, progress=False
    )
    returns = [float(ln.split("return=")[1].split()[0]) for ln in lines[:4]]
    assert returns == pytest.approx([e.total_reward for e in single.episodes], abs=5e-4)


def test_success_is_the_envs_is_success() -> None:
    from mjkdl.demos.episodes import success_of

    assert success_of({"is_success": True, "diverged": False}) is True
    assert success_of({"is_success": np.bool_(False)}) is False
    assert success_of({"diverged": False}) is False  # no key: never a success


def test_the_expert_succeeds_and_says_so() -> None:
    r = cli("evaluate", PICK, "--expert", "--episodes", "5", "--seed", "0")
    assert r.returncode == 0, r.stderr
    assert all("success=True" in ln for ln in r.stdout.splitlines()[:5])
    assert r.stdout.splitlines()[5].startswith("success: 100.0 % (95 % CI 56.6-100.0 %, 5/5)")


def test_any_gymnasium_env_evaluates_without_videos(tmp_path: Path) -> None:
    ev = evaluate("CartPole-v1", "random", episodes=3, seed=0, progress=False)
    assert [e.seed for e in ev.episodes] == [0, 1, 2] and all(e.length > 5 for e in ev.episodes)
    assert ev.success_rate == 0.0  # CartPole has no is_success: its termination is a fall
    with pytest.raises(ValueError, match="CartPoleEnv is not an mjkdl task env"):
        evaluate("CartPole-v1", "random", episodes=1, video_dir=tmp_path, progress=False)
    with pytest.raises(ValueError, match=r"returned 7, which the action space Discrete\(2\) lacks"):
        evaluate("CartPole-v1", lambda env: lambda obs: 7, episodes=1, progress=False)
