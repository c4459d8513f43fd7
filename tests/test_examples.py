"""Every example runs headless as a user would start it and prints the outcome it promises."""

from __future__ import annotations

import math
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


def run_example(name: str, *args: str, timeout: float = 120.0, cwd: Path = ROOT) -> str:
    """Run `examples/<name>.py --headless *args` in a fresh interpreter (in `cwd`); return
    its stdout."""
    env = dict(os.environ, MUJOCO_GL="egl")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    proc = subprocess.run(
        [sys.executable, str(EXAMPLES / f"{name}.py"), "--headless", *args],
        cwd=cwd,
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
        *("--out", str(video), "--width", "320", "--height", "240", "--fps", "20"),
    )
    assert "result: success" in out
    assert video.is_file() and video.stat().st_size > 10_000
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(video))
    simulated = number(r"fps, ", out)
    assert seconds == pytest.approx(simulated, abs=0.2)
    assert frames == pytest.approx(20 * simulated, abs=3)


def test_record_video_writes_into_the_current_directory(tmp_path: Path) -> None:
    import imageio_ffmpeg

    out = run_example(
        "record_video", *("--width", "160", "--height", "120", "--duration", "0.5"), cwd=tmp_path
    )
    # 0.5 s of the task, then the 0.5 s tail
    assert "\nvideo: pick_place.mp4 (160x120 at 30 fps, 1.00 s simulated" in out
    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(tmp_path / "pick_place.mp4"))
    assert frames == pytest.approx(30, abs=1)


# ---------------------------------------------------------------------- task environments


def test_rl_environment() -> None:
    menagerie("franka_emika_panda")
    out = run_example("rl_environment", "--duration", "4")
    assert "wrist_cam_depth: (64, 64) float32" in out and "goal_pose: (7,) float64" in out
    assert number("simulated:", out) == pytest.approx(4.0)
    # The agent hovers 0.1 m above the ball: ReachReward's 0.5 * (1 - tanh(d / 0.25)).
    distance = number("distance:", out)
    assert distance == pytest.approx(0.1, abs=0.01)
    assert number("reward:", out) == pytest.approx(0.5 * (1 - math.tanh(distance / 0.25)), abs=2e-4)
    near, far = numbers(r"wrist depth:", out)[0], number(r"\.\. ", out)
    assert 0.0 < near < far < 1.0


def test_random_agent() -> None:
    menagerie("franka_emika_panda")
    import gymnasium as gym

    import mjkdl.task

    out = run_example("random_agent", "--episodes", "2", "--duration", "1", "--seed", "5")
    assert number("episodes:", out) == 2
    env = gym.make("mjkdl/PandaReach-v0")  # the same seeded episodes, in this process
    expected = [mjkdl.task.run_episode(env, s, max_steps=10).total_reward for s in (5, 6)]
    env.close()
    assert numbers(r"return", out)[:2] == pytest.approx(expected, abs=1e-4)
    assert numbers(r"steps", out)[:2] == [10, 10]


def test_ray_rollouts() -> None:
    menagerie("franka_emika_panda")
    pytest.importorskip("ray")
    out = run_example(
        "ray_rollouts", "--episodes", "4", "--actors", "2", "--duration", "0.3", "--verify"
    )
    assert number("episodes:", out) == 4
    assert numbers(r"steps", out)[:4] == [3, 3, 3, 3]
    assert "matches sequential: True" in out


# ---------------------------------------------------------------------- control layer (Panda)


@pytest.fixture
def _panda() -> None:
    menagerie("franka_emika_panda")


@pytest.mark.usefixtures("_panda")
@pytest.mark.parametrize("frame", ["", "link0"])
def test_cartesian_velocity(frame: str) -> None:
    out = run_example("cartesian_velocity", "--duration", "6.3", "--control-frame", frame)
    assert f"control frame: {frame or 'world'}" in out
    assert number("simulated:", out) == pytest.approx(6.3, abs=0.01)
    # The integrated command stays on the eight; the arm trails it by the servos' 0.1 s lag.
    assert number("max command path error:", out) < 0.003
    assert number("max measured path error:", out) < 0.02
    assert number("max out-of-plane drift:", out) < 0.002
    assert number("max TCP rotation:", out) < 0.5
    assert "QP status: optimal" in out


@pytest.mark.usefixtures("_panda")
def test_joint_velocity() -> None:
    out = run_example("joint_velocity", "--duration", "6.3")
    assert "mode: VELOCITY" in out
    assert number("max joint velocity error:", out) < 0.005
    assert number("max joint position error:", out) < 0.005


@pytest.mark.usefixtures("_panda")
@pytest.mark.parametrize("seed", [0, 3])
def test_gripper(seed: int) -> None:
    out = run_example("gripper", "--duration", "6", "--seed", str(seed))
    opened, closed = (int(x) for x in re.search(r"actions: (\d+) open, (\d+) closed", out).groups())
    assert opened + closed == 10 and opened > 0 and closed > 0
    assert numbers("opening when open:", out)[0] > 0.99
    # Closed on the 5 cm box: each finger stops 2.5 cm out of its 4 cm stroke, not at 0.
    lo, hi = (float(x) for x in re.search(r"when closed: ([\d.]+) to ([\d.]+)", out).groups())
    assert 0.025 / 0.04 - 0.02 < lo <= hi < 0.025 / 0.04 + 0.02
    assert number("box moved:", out) < 0.005


@pytest.mark.usefixtures("_panda")
def test_custom_gripper() -> None:
    out = run_example("custom_gripper", "--duration", "8")
    assert "TCP at g_pinch" in out
    lo, hi = (float(x) for x in re.search(r"opening range: ([\d.]+) to ([\d.]+)", out).groups())
    assert lo < 0.08 and hi > 0.97
    assert number("opening lags the action by", out) < 0.5
    assert number(r"mean error then", out) < 0.03


@pytest.mark.usefixtures("_panda")
def test_two_arm_robot() -> None:
    out = run_example("two_arm_robot", "--duration", "8")
    lo, hi = (
        float(x) for x in re.search(r"torso turned: ([-\d.]+) to ([-\d.]+) deg", out).groups()
    )
    assert lo < -55 and hi > 55
    for arm in ("left", "right"):
        line = re.search(
            rf"{arm}: x in the torso frame ([-+\d.]+) to ([-+\d.]+) m, "
            r"max off-axis ([\d.]+) m",
            out,
        )
        assert line, out
        x_lo, x_hi, off = (float(x) for x in line.groups())
        assert x_lo < -0.09 and x_hi > 0.08  # ±0.1 m commanded, open loop
        assert off < 0.005  # the motion stays on the torso's x while it turns ±60°


@pytest.mark.usefixtures("_panda")
def test_multiple_robots() -> None:
    out = run_example("multiple_robots", "--duration", "3")
    for name, pose in (
        ("r1", r"\(\+0.00, \+0.00\) m, yaw \+0"),
        ("r2", r"\(\+1.00, -0.80\) m, yaw \+135"),
        ("r3", r"\(\+1.00, \+0.80\) m, yaw -135"),
    ):
        assert re.search(rf"{name}: base at {pose} deg, 7 joints, QP optimal", out), out
    assert number("max difference between the motions in the base frames:", out) < 0.002


@pytest.mark.usefixtures("_panda")
def test_plan_shelves() -> None:
    out = run_example("plan_shelves")
    legs = re.findall(r"^(.+): planned in \d+ ms, ([\d.]+) s, max error ([\d.]+) mrad", out, re.M)
    assert [leg[0] for leg in legs] == [
        "down to the cube",
        "lift",
        "around the wall to shelf B",
        "down to shelf B",
        "retreat",
        "back around the wall",
    ]
    assert max(float(leg[2]) for leg in legs) < 5.0  # the follower tracks within 5 mrad
    assert numbers("cube at z", out)[2] > 0.45  # carried high, over or around the wall
    assert number("place error:", out) < 0.02
    assert "result: success" in out
