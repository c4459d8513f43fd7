"""Every example runs headless as a user would start it and prints the outcome it promises."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT, menagerie

import mjkdl as mjk

EXAMPLES = ROOT / "examples"
PICK_PLACE_STATES = [
    "HOME",
    "PRE-GRASP",
    "GRASP",
    "CLOSE",
    "LIFT",
    "CARRY",
    "PLACE",
    "RELEASE",
    "RETREAT",
    "DONE",
]
NUMBER = r"([-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)"


@pytest.fixture(scope="module", autouse=True)
def _models() -> None:
    """The examples need the Menagerie Gen3 and 2F-85 (skipped when they are not here)."""
    menagerie("kinova_gen3")
    menagerie("robotiq_2f85")


def run_example(name: str, *args: str, timeout: float = 120.0) -> str:
    """Run `examples/<name>.py --headless *args` in a fresh interpreter; return its stdout."""
    env = dict(os.environ, MUJOCO_GL="egl")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    proc = subprocess.run(
        [sys.executable, str(EXAMPLES / f"{name}.py"), "--headless", *args],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert proc.returncode == 0, f"{name} exited {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    return proc.stdout


def numbers(label: str, out: str) -> list[float]:
    """Every number printed right after `label` (a regex), in order; at least one."""
    found = [float(x) for x in re.findall(label + r"\s*" + NUMBER, out)]
    assert found, f"no {label!r} in the output:\n{out}"
    return found


def number(label: str, out: str) -> float:
    (value,) = numbers(label, out)
    return value


def test_tutorial_demo() -> None:
    out = run_example("tutorial_demo", "--duration", "1")
    assert f"MuJoCo {mjk.mujoco_version()}" in out
    assert "joints: 7 (joint_1, " in out
    assert re.search(r"cameras: .*\btask\b", out)
    assert number("simulated:", out) == pytest.approx(1.0, abs=0.01)
    assert number("TCP drift:", out) < 1e-4


def test_position_control() -> None:
    out = run_example("position_control", "--duration", "3", "--move", "1")
    assert "mode: POSITION" in out
    assert number("max tracking error:", out) < 0.15
    assert number("poses reached:", out) >= 1
    assert number("worst error on arrival:", out) < 0.005


def test_gravity_comp() -> None:
    out = run_example("gravity_comp", "--duration", "0.5", "--poses", "2")
    drifts = numbers("TCP drift", out)
    assert len(drifts) == 2 and max(drifts) < 1e-4
    assert max(numbers(r"\|gravity - qfrc_bias\|", out)) < 1e-8


def test_impedance() -> None:
    out = run_example("impedance", "--duration", "3")
    assert number("max joint tracking error:", out) < 0.05
    assert number("max TCP tracking error:", out) < 0.03


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_pick_place(seed: int) -> None:
    out = run_example("pick_place", "--seed", str(seed), "--reset-at", "6")
    x, y = map(float, re.search(r"cube start: \(([\d.]+), ([\d.]+)\)", out).groups())
    assert (x, y) != (0.35, 0.1) and abs(x - 0.35) <= 0.02 and abs(y - 0.1) <= 0.02
    # The reset came with the cube in the gripper; the task started over and finished.
    assert re.search(r"reset at t=6\.\d+ s in state (LIFT|CARRY)", out), out
    assert number(r"in state \w+, cube", out) > 0.01
    states = re.sub(r" \d+\.\d", "", re.search(r"states: (.*)", out).group(1))
    assert states == " > ".join(PICK_PLACE_STATES)
    assert number("lifted:", out) >= 0.05
    assert number("place error:", out) <= 0.02
    assert "result: success" in out


def test_pick_place_stopped_by_duration_says_so_and_succeeds() -> None:
    out = run_example("pick_place", "--duration", "1")  # exits 0, else run_example fails
    assert "stopped after 1.0 s" in out and "FAILURE" not in out
    assert "result: not finished (stopped in state PRE-GRASP)" in out
    assert number("simulated:", out) == pytest.approx(1.0, abs=1e-9)


def test_dual_arm() -> None:
    out = run_example("dual_arm", "--duration", "2")
    assert "r2_joint_1..r2_joint_7" in out and "joint_1..joint_7" in out
    errors = numbers("max tracking error", out)
    assert len(errors) == 2 and max(errors) < 0.02


def test_modify_scene() -> None:
    out = run_example("modify_scene", "--duration", "1.5")
    assert "added 'pillar'" in out and "removed 'pillar'" in out
    for label in (r"\|dq\|", r"\|dv\|", "time"):
        assert numbers(label, out) == [0.0, 0.0]
    assert number("max tracking error:", out) < 0.02


def test_urdf_robot() -> None:
    out = run_example("urdf_robot", "--duration", "1")
    assert "joints: 6 (shoulder_pan_joint" in out
    assert number("tool0 drift:", out) < 1e-4


def test_record_video(tmp_path: Path) -> None:
    import imageio_ffmpeg

    video = tmp_path / "pick_place.mp4"
    out = run_example(
        "record_video",
        *("--output", str(video), "--width", "320", "--height", "240", "--fps", "20", "--preview"),
    )
    assert "result: success" in out
    assert video.is_file() and video.stat().st_size > 10_000
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(video))
    simulated = number(r"fps, ", out)
    assert seconds == pytest.approx(simulated, abs=0.2)
    assert frames == pytest.approx(20 * simulated, abs=3)
