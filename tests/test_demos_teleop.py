"""Teleoperation: the session's action mapping and commands, then the command line under Xvfb
driven by xdotool key presses (a held key moves the TCP; Enter saves a demo)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, menagerie
from test_demos_hdf5 import REACH, cli
from test_viewer import display, tool  # noqa: F401  (the module's Xvfb display fixture)

from mjkdl.demos import DemoFile, EpisodeWriter, make_env
from mjkdl.demos.devices import Command, Reading
from mjkdl.demos.teleop import Teleop


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


class Scripted:
    """A device that plays back readings."""

    name = "scripted"

    def __init__(self, readings: list[Reading]) -> None:
        self.readings = readings

    def read(self) -> Reading:
        return self.readings.pop(0)


def still(*commands: Command) -> Reading:
    return Reading(np.zeros(6), list(commands))


def test_session_maps_twists_and_handles_commands(tmp_path: Path) -> None:
    env = make_env(REACH, {"max_episode_steps": 50})
    up = Reading(np.array([0, 0, 1, 0, 0, 0.5]), [])
    readings = [up, up, still(Command.GRIPPER), still(Command.SAVE), up, still(Command.DISCARD),
                up, still(Command.RESET), still(Command.SAVE)]  # fmt: skip
    with EpisodeWriter(tmp_path / "t.hdf5", REACH) as writer:
        session = Teleop(env, Scripted(readings), writer, seed=4, speed=0.5)
        low, high = env.action_space.low, env.action_space.high
        assert session.action(np.array([1, -1, 0, 0, 0, 1])).tolist() == pytest.approx(
            [*(0.5 * high[:2] * [1, -1]), 0, 0, 0, 0.5 * high[5], low[6]]
        )
        session.start()
        z0 = env.unwrapped.robots["panda"].fk_frame().translation[2]
        session.tick()
        session.tick()
        assert (
            env.unwrapped.robots["panda"].fk_frame().translation[2] > z0 + 0.01
        )  # accelerating from rest
        session.tick()  # gripper: closed
        session.tick()  # save: demo_0 (seed 4), next seed 5
        assert (session.saved, session.seed) == (1, 5)
        left, right = session.texts()[0][2:]
        assert "saved demo 1 (seed 4)" in right and "8 / 2" in left
        assert "away / towards you  (-x / +x)" in right
        session.tick()
        session.tick()  # discard: seed 5 again
        assert session.seed == 5
        session.tick()
        session.tick()  # reset: seed 6
        session.tick()  # save of an empty episode: nothing written, next seed
        assert (session.saved, session.seed) == (1, 7)
    env.close()
    with DemoFile(tmp_path / "t.hdf5") as f:
        demo = f.demo(0)
    assert demo.seed == 4 and demo.num_samples == 3
    assert demo.actions[:, 2].tolist() == pytest.approx([0.5 * high[2]] * 2 + [0.0])
    assert demo.actions[:, 6].tolist() == [low[6], low[6], high[6]]  # closed after the toggle


def test_teleop_rejects_an_env_without_a_twist(tmp_path: Path) -> None:
    from demo_envs import Approach  # noqa: F401  (tests dir importable)

    env = make_env(REACH)
    with (
        EpisodeWriter(tmp_path / "x.hdf5", REACH) as writer,
        pytest.raises(ValueError, match=r"--speed must be in \(0, 1\], got 2"),
    ):
        Teleop(env, Scripted([]), writer, speed=2)
    env.close()
    r = cli("teleop", REACH, "--device", "joystick", "--out", str(tmp_path / "y.hdf5"))
    assert r.returncode == 2 and "no device named 'joystick'" in r.stderr
    assert not (tmp_path / "y.hdf5").exists()


def test_help_lists_the_keys() -> None:
    r = cli("teleop", "--help")
    assert "9 / 3   up / down" in r.stdout and "Enter   save the episode" in r.stdout


def test_a_held_key_moves_the_tcp_and_enter_saves(display: str, tmp_path: Path) -> None:  # noqa: F811
    xdotool = tool("xdotool")
    out = tmp_path / "teleop.hdf5"
    env = {**os.environ, "DISPLAY": display, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "mjkdl.demos", "teleop", REACH, "--out", str(out), "--demos", "1"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            found = subprocess.run([xdotool, "search", "--onlyvisible", "--name", "^MuJoCo"],
                                   capture_output=True, text=True, env=env)  # fmt: skip
            if found.stdout.strip():
                break
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.2)
        time.sleep(1.0)
        subprocess.run([xdotool, "keydown", "KP_9"], env=env, check=True)
        time.sleep(1.0)
        subprocess.run([xdotool, "keyup", "KP_9"], env=env, check=True)
        time.sleep(0.3)
        subprocess.run([xdotool, "key", "KP_Enter"], env=env, check=True)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, stderr
    assert f"{out}: 1 demos saved" in stdout
    with DemoFile(out) as f:
        demo = f.demo(0)
    tcp = demo.obs["panda_tcp_pos"]
    rise = tcp[-1, 2] - tcp[0, 2]
    drift = np.abs(tcp[-1, :2] - tcp[0, :2]).max()
    assert rise > 0.15 and drift < rise / 3, (rise, drift)
    up = demo.actions[:, 2] > 0
    assert 5 <= up.sum() <= 15  # about a second of 0.1 s steps
    assert np.all(demo.actions[:, [0, 1, 3, 4, 5]] == 0)
