"""TaskEnv: spaces from the spec, episodes, actuation modes, observations, bad input."""

from __future__ import annotations

import math
import re
from collections.abc import Iterator

import gymnasium as gym
import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import menagerie

import mjkdl as mjk
from mjkdl.task import (
    Actuation,
    ArmSpec,
    BodyPoseSensor,
    CameraSensor,
    Lifted,
    ReachReward,
    TaskEnv,
    TaskSpec,
)
from mjkdl.task.registry import PANDA_HOME, panda_arm, panda_reach_spec, panda_scene

PANDA_FORCES = [87.0] * 4 + [12.0] * 3


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


def make(**kw) -> TaskEnv:
    """A Panda task: `arms`/`scene`/... override the defaults (one Cartesian arm, a ball)."""
    ball = mjk.SceneObject(
        name="ball", shape=mjk.Shape.SPHERE, size=[0.03], mass=0.1, pos=[0.5, 0.0, 0.032]
    )
    fields = {
        "scene": panda_scene([ball]),
        "arms": [panda_arm()],
        "sensors": [BodyPoseSensor("ball")],
    }
    fields.update(kw)
    return TaskEnv(TaskSpec(**fields))


@pytest.fixture
def env() -> Iterator[TaskEnv]:
    e = make()
    yield e
    e.close()


ARM_KEYS = ["joint_pos", "joint_vel", "joint_torques", "tcp_pos", "tcp_quat", "tcp_vel", "gripper"]


def test_spaces_follow_the_spec_exactly(env: TaskEnv) -> None:
    obs_space = env.observation_space.spaces
    assert list(obs_space) == [f"panda_{k}" for k in ARM_KEYS] + ["ball_pose", "time"]
    shapes = {k: v.shape for k, v in obs_space.items()}
    assert shapes == {
        "panda_joint_pos": (7,),
        "panda_joint_vel": (7,),
        "panda_joint_torques": (7,),
        "panda_tcp_pos": (3,),
        "panda_tcp_quat": (4,),
        "panda_tcp_vel": (6,),
        "panda_gripper": (1,),
        "ball_pose": (7,),
        "time": (1,),
    }
    assert all(v.dtype == np.float64 for v in obs_space.values())
    box = env.action_space
    assert box.shape == (7,) and box.dtype == np.float32
    assert box.low.tolist() == [-0.5] * 3 + [-1.0] * 3 + [0.0]
    assert box.high.tolist() == [0.5] * 3 + [1.0] * 3 + [1.0]
    assert env.action_labels == [f"panda.{k}" for k in ("vx", "vy", "vz", "wx", "wy", "wz")] + [
        "panda.gripper"
    ]
    obs, info = env.reset(seed=0)
    assert list(obs) == list(obs_space) and env.observation_space.contains(obs)
    assert info == {"is_success": False, "diverged": False}


def test_joint_actuation_bounds_come_from_the_model() -> None:
    arms = [
        ArmSpec("p", "link0", "hand", actuation=Actuation.JOINT_POSITION, home=PANDA_HOME),
        ArmSpec(
            "v",
            "link0",
            "hand",
            prefix="b/",
            actuation=Actuation.JOINT_VELOCITY,
            max_angular_velocity=0.7,
        ),
        ArmSpec("t", "link0", "hand", prefix="c/", actuation=Actuation.JOINT_TORQUE),
    ]
    path = menagerie("franka_emika_panda")
    scene = mjk.SceneSpec(
        timestep=0.002,
        add_floor=True,
        add_skybox=False,
        robots=[
            mjk.RobotSpec(path=path),
            mjk.RobotSpec(path=path, prefix="b/", pos=[0, 1, 0]),
            mjk.RobotSpec(path=path, prefix="c/", pos=[0, 2, 0]),
        ],
    )
    env = TaskEnv(TaskSpec(scene=scene, arms=arms))
    model = env.scene.model
    ranges = np.array([model.joint(f"joint{i}").range for i in range(1, 8)])
    box = env.action_space
    assert box.shape == (21,)
    np.testing.assert_array_equal(box.low[:7], ranges[:, 0].astype(np.float32))
    np.testing.assert_array_equal(box.high[:7], ranges[:, 1].astype(np.float32))
    assert box.high[7:14].tolist() == pytest.approx([0.7] * 7)  # Panda's MJCF has no limit
    assert box.high[14:].tolist() == PANDA_FORCES  # the actuators' forcerange
    assert box.low[14:].tolist() == [-f for f in PANDA_FORCES]
    env.close()


def test_reset_with_a_seed_repeats_the_episode() -> None:
    a = make(initializers=panda_reach_spec().initializers[:1])
    b = make(initializers=panda_reach_spec().initializers[:1])
    rng = np.random.default_rng(5)
    actions = [rng.uniform(a.action_space.low, a.action_space.high) for _ in range(5)]
    runs = []
    for env in (a, b, a):
        obs, _ = env.reset(seed=11)
        trace = [obs["panda_joint_pos"]]
        for act in actions:
            obs, reward, *_ = env.step(act)
            trace += [obs["panda_tcp_pos"], obs["ball_pose"], np.array([reward])]
        runs.append(np.concatenate(trace))
    np.testing.assert_array_equal(runs[0], runs[1])
    np.testing.assert_array_equal(runs[0], runs[2])
    other, _ = a.reset(seed=12)
    assert not np.allclose(other["panda_joint_pos"], runs[0][:7])
    a.close()
    b.close()


def test_truncated_exactly_at_the_time_limit() -> None:
    env = make(control_timestep=0.1, time_limit=0.3)
    env.reset(seed=0)
    zero = np.zeros(7)
    flags = [env.step(zero)[3] for _ in range(3)]
    assert flags == [False, False, True]
    assert env.scene.time() == pytest.approx(0.3, abs=1e-12)
    assert env.elapsed_steps == 3 and env.control_timestep == pytest.approx(0.1)
    env.close()


def test_the_envs_layout_is_readable() -> None:
    env = make(time_limit=0.3, success=lambda obs: True, success_hold=0.2)
    assert (env.control_substeps, env.time_limit_steps, env.success_hold_steps) == (50, 3, 2)
    low, high = env.action_bounds
    arm = env.task_spec.arms[0]
    assert high.tolist() == [arm.max_linear_velocity] * 3 + [arm.max_angular_velocity] * 3 + [1]
    assert low.tolist() == [*(-high[:6]).tolist(), 0.0]
    low[0] = 9.0
    assert env.action_bounds[0][0] != 9.0  # a copy
    [eff] = env.effectors
    assert eff.robot is env.robots["panda"] and eff.gripper is env.grippers["panda"]
    assert (eff.slice, eff.grip_index) == (slice(0, 6), 6)
    assert [type(r).__name__ for r in env.readers] == ["ArmReader", "PoseReader"]
    env.close()
    assert make(time_limit=None).time_limit_steps is None


def test_one_step_is_control_timestep_of_physics(env: TaskEnv) -> None:
    obs, _ = env.reset(seed=0)
    obs, *_ = env.step(np.zeros(7))
    assert obs["time"][0] == pytest.approx(0.1, abs=1e-12)
    assert env.scene.data.time == pytest.approx(50 * 0.002, abs=1e-12)


def test_actions_are_clipped_into_the_space() -> None:
    envs = [make(), make()]
    inside = np.array([0.5, -0.5, 0, 0, 0, 1.0, 1.0])
    beyond = np.array([3.0, -7.0, 0, 0, 0, 5.0, 9.0])
    out = []
    for env, act in zip(envs, (inside, beyond), strict=True):
        env.reset(seed=1)
        out.append([env.step(act)[0]["panda_joint_pos"] for _ in range(3)])
        env.close()
    np.testing.assert_array_equal(np.array(out[0]), np.array(out[1]))


def test_cartesian_velocity_moves_the_tcp_along_the_control_frame() -> None:
    # The arm stands turned by 90 degrees about z; "link0" axes: its x is the world's y.
    path = menagerie("franka_emika_panda")
    scene = panda_scene([])
    scene.robots = [mjk.RobotSpec(path=path, euler=[0, 0, 90])]
    arm = panda_arm()
    arm.control_frame = "link0"
    env = TaskEnv(TaskSpec(scene=scene, arms=[arm]))
    obs, _ = env.reset(seed=0)
    start = obs["panda_tcp_pos"]
    for _ in range(10):
        obs, *_ = env.step(np.array([0.1, 0, 0, 0, 0, 0, 0]))
    moved = obs["panda_tcp_pos"] - start
    assert moved[1] == pytest.approx(0.1, abs=0.01)  # 1 s at 0.1 m/s, along world y
    assert abs(moved[0]) < 0.005 and abs(moved[2]) < 0.005
    # The velocity observation is along the control frame: x there.
    robot, data = env.robots["panda"], env.scene.data
    robot.update()
    world = robot.jacobian() @ robot.jnt_vel_msr
    rot = data.xmat[env.scene.body_id("link0")].reshape(3, 3)
    np.testing.assert_allclose(obs["panda_tcp_vel"][:3], rot.T @ world[:3], atol=1e-9)
    np.testing.assert_allclose(obs["panda_tcp_vel"][3:], rot.T @ world[3:], atol=1e-9)
    env.close()


def test_tcp_observations_match_pinocchio(env: TaskEnv) -> None:
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    robot = env.robots["panda"]
    for _ in range(5):
        obs, *_ = env.step(rng.uniform(env.action_space.low, env.action_space.high))
        robot.update()
        tcp = robot.fk_frame()
        np.testing.assert_allclose(obs["panda_tcp_pos"], tcp.translation, atol=1e-9)
        quat = obs["panda_tcp_quat"]
        expected = pin.Quaternion(tcp.rotation).coeffs()  # x, y, z, w
        sign = np.sign(quat[0] * expected[3]) or 1.0
        np.testing.assert_allclose(quat, sign * np.roll(expected, 1), atol=1e-9)
        np.testing.assert_array_equal(obs["panda_joint_pos"], robot.jnt_pos_msr)
        np.testing.assert_array_equal(obs["panda_joint_vel"], robot.jnt_vel_msr)
        np.testing.assert_allclose(
            obs["panda_tcp_vel"], robot.jacobian() @ robot.jnt_vel_msr, atol=1e-9
        )


def test_gripper_observation_follows_the_action(env: TaskEnv) -> None:
    obs, _ = env.reset(seed=0)
    # Open from the first observation, although MuJoCo's qpos0 has the fingers shut.
    assert obs["panda_gripper"][0] == pytest.approx(1.0, abs=0.002)
    assert env.scene.data.time == 0.0
    for _ in range(10):
        obs, *_ = env.step(np.zeros(7))  # 0: open
    assert obs["panda_gripper"][0] == pytest.approx(1.0, abs=0.02)
    close = np.zeros(7)
    close[6] = 1.0
    for _ in range(10):
        obs, *_ = env.step(close)
    assert obs["panda_gripper"][0] < 0.05


def test_a_held_gripper_takes_no_action_entry_and_keeps_its_command() -> None:
    """`GripperSpec.held`: the fingers start at the held command (half closed, the ctrl
    linear in it) and stay there whatever the arm does; the action is the twist alone."""
    arm = panda_arm()
    assert arm.gripper is not None
    arm.gripper.held, arm.gripper.binary = 0.5, False
    env = make(arms=[arm])
    assert env.action_labels == [f"panda.{a}" for a in ("vx", "vy", "vz", "wx", "wy", "wz")]
    assert env.effectors[0].grip_index == -1
    obs, _ = env.reset(seed=0)
    assert obs["panda_gripper"][0] == pytest.approx(0.5, abs=0.01)
    for _ in range(10):
        obs, *_ = env.step(np.full(6, 0.1))
    assert obs["panda_gripper"][0] == pytest.approx(0.5, abs=0.01)


def test_joint_position_actuation_tracks_the_command() -> None:
    arm = panda_arm()
    arm.actuation, arm.gripper = Actuation.JOINT_POSITION, None
    env = make(arms=[arm])
    obs, _ = env.reset(seed=0)
    target = np.array(PANDA_HOME) + 0.2
    for _ in range(20):
        obs, *_ = env.step(target)
    np.testing.assert_allclose(obs["panda_joint_pos"], target, atol=0.01)
    env.close()


def test_zero_torque_holds_the_arm_against_gravity() -> None:
    arm = panda_arm()
    arm.actuation = Actuation.JOINT_TORQUE
    env = make(arms=[arm])
    obs, _ = env.reset(seed=0)
    start = obs["panda_tcp_pos"]
    for _ in range(10):
        obs, *_ = env.step(np.zeros(8))
    assert np.linalg.norm(obs["panda_tcp_pos"] - start) < 0.01
    env.close()


def test_observations_are_the_agents_own(env: TaskEnv) -> None:
    obs, _ = env.reset(seed=0)
    keep = obs["panda_joint_pos"].copy()
    obs["panda_joint_pos"][:] = 99.0
    nxt, *_ = env.step(np.zeros(7))
    assert not np.shares_memory(nxt["panda_joint_pos"], obs["panda_joint_pos"])
    assert np.abs(nxt["panda_joint_pos"] - keep).max() < 0.01


def test_divergence_ends_the_episode_without_nan(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # MuJoCo logs its warning to MUJOCO_LOG.TXT here

    def blow_up(env: TaskEnv, rng: np.random.Generator) -> None:
        env.scene.data.qvel[:] = 1e12

    env = make(initializers=[blow_up])
    first, _ = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(np.zeros(7))
    assert terminated and info["diverged"] and not truncated and reward == 0.0
    assert "BADQVEL" in info["error"] or "diverge" in info["error"].lower()
    assert all(np.isfinite(v).all() for v in obs.values())
    np.testing.assert_array_equal(obs["panda_joint_pos"], first["panda_joint_pos"])
    with pytest.raises(RuntimeError, match="diverged"):
        env.step(np.zeros(7))
    env.task_spec.initializers = []
    obs, _ = env.reset(seed=0)
    assert not env.step(np.zeros(7))[2]
    env.close()


# ---------------------------------------------------------------------- bad input


def test_wrong_action_shape_names_the_layout(env: TaskEnv) -> None:
    env.reset(seed=0)
    with pytest.raises(mjk.SpecError, match=r"shape \(7,\).*panda\.vx.*panda\.gripper.*\(6,\)"):
        env.step(np.zeros(6))
    with pytest.raises(ValueError, match="numbers"):
        env.step(["a"] * 7)


def test_nan_action_names_the_entry(env: TaskEnv) -> None:
    env.reset(seed=0)
    act = np.zeros(7)
    act[4] = np.nan
    with pytest.raises(mjk.SpecError, match=r"finite.*panda\.wy=nan"):
        env.step(act)


def test_step_before_reset_and_after_close(env: TaskEnv) -> None:
    with pytest.raises(RuntimeError, match="before reset"):
        env.step(np.zeros(7))
    env.close()
    env.close()  # twice is fine
    for call in (lambda: env.step(np.zeros(7)), lambda: env.reset(seed=0), env.render):
        with pytest.raises(RuntimeError, match="closed"):
            call()


@pytest.mark.parametrize(
    ("change", "error", "message"),
    [
        (lambda s: setattr(s.arms[0], "tip_body", "hnad"), KeyError, r"arms\[0\].*'hnad'.*hand"),
        (lambda s: setattr(s.arms[0].gripper, "actuator", "act8"), KeyError, r"gripper.*act8"),
        (lambda s: setattr(s.arms[0], "control_frame", "lnk0"), KeyError, r"control_frame.*lnk0"),
        (
            lambda s: s.sensors.append(BodyPoseSensor("bal")),
            KeyError,
            r"sensors\[1\]\.body.*'bal'.*ball",
        ),
        (
            lambda s: s.sensors.append(CameraSensor("frnt")),
            KeyError,
            r"sensors\[1\]\.camera.*'frnt'.*front",
        ),
        (
            lambda s: s.sensors.append(CameraSensor("front", width=0)),
            ValueError,
            r"sensors\[1\]\.width",
        ),
        (lambda s: s.sensors.append(object()), ValueError, r"sensors\[1\] must be"),
        (
            lambda s: s.sensors.append(BodyPoseSensor("ball")),
            ValueError,
            r"'ball_pose'.*sensors\[0\] and TaskSpec\.sensors\[1\]",
        ),
        (lambda s: setattr(s, "control_timestep", 0.003), ValueError, "whole number"),
        (lambda s: setattr(s, "time_limit", -1.0), ValueError, "time_limit"),
        (lambda s: setattr(s.arms[0], "home", [0.0] * 3), ValueError, r"arms\[0\]\.home"),
        (lambda s: setattr(s.arms[0], "actuation", "cartesian"), ValueError, "Actuation"),
        (lambda s: s.arms.append(panda_arm()), ValueError, "unique"),
        (lambda s: setattr(s, "arms", []), ValueError, "non-empty"),
        (lambda s: setattr(s, "sensors", BodyPoseSensor("ball")), ValueError, "sensors must be"),
    ],
)
def test_bad_specs_name_the_field(change, error, message) -> None:
    ball = mjk.SceneObject(name="ball", shape=mjk.Shape.SPHERE, size=[0.03], mass=0.1)
    spec = TaskSpec(scene=panda_scene([ball]), arms=[panda_arm()], sensors=[BodyPoseSensor("ball")])
    change(spec)
    with pytest.raises(error) as err:
        TaskEnv(spec)
    for fragment in message.split(".*"):  # each piece, in any order
        assert re.search(fragment, str(err.value)), (fragment, str(err.value))


def test_bad_constructor_arguments() -> None:
    with pytest.raises(ValueError, match="TaskSpec"):
        TaskEnv("panda")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="render_mode"):
        make_kw = {"scene": panda_scene([]), "arms": [panda_arm()]}
        TaskEnv(TaskSpec(**make_kw), render_mode="video")
    with pytest.raises(KeyError, match="'nope' in render_camera; known: front"):
        TaskEnv(TaskSpec(scene=panda_scene([]), arms=[panda_arm()]), render_camera="nope")


def test_reset_rejects_options(env: TaskEnv) -> None:
    with pytest.raises(ValueError, match="options"):
        env.reset(seed=0, options={"keyframe": 0})
    env.reset(seed=0, options={})


def test_rgb_array_render_shows_the_named_camera() -> None:
    env = TaskEnv(
        TaskSpec(scene=panda_scene([]), arms=[panda_arm()]),
        render_mode="rgb_array",
        render_camera="front",
        render_width=160,
        render_height=120,
    )
    env.reset(seed=0)
    img = env.render()
    assert img.shape == (120, 160, 3) and img.dtype == np.uint8
    ref = mujoco.Renderer(env.scene.model, 120, 160)
    for flag in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION):
        ref.scene.flags[flag] = 0  # off unless render_shadows=True
    ref.update_scene(env.scene.data, camera="front")
    np.testing.assert_array_equal(img, ref.render())
    ref.close()
    env.close()
    assert math.isfinite(float(img.mean()))


def test_one_step_episodes_repeat(env: TaskEnv) -> None:
    # The controller's state must not leak from an episode that ended at its first step.
    act = np.array([0.4, -0.3, 0.2, 0.5, -0.5, 0.8, 1.0])
    runs = []
    for _ in range(3):
        env.reset(seed=9)
        runs.append(env.step(act)[0]["panda_joint_pos"])
    np.testing.assert_array_equal(runs[0], runs[1])
    np.testing.assert_array_equal(runs[0], runs[2])


class _Clock:
    """A user sensor whose observation name clashes with the env's own `time`."""

    def space(self, env):
        from gymnasium import spaces

        return {"time": spaces.Box(0, 1, (1,))}

    def read(self, env):
        return {"time": [0.0]}


def test_a_sensor_cannot_take_the_envs_time() -> None:
    with pytest.raises(ValueError, match=r"'time' is produced by both the env.*sensors\[1\]"):
        make(sensors=[BodyPoseSensor("ball"), _Clock()])


def test_two_arms_take_their_slices_of_the_action() -> None:
    path = menagerie("franka_emika_panda")
    scene = panda_scene([])
    scene.robots.append(mjk.RobotSpec(path=path, prefix="r/", pos=[0.0, 1.0, 0.0]))
    right = panda_arm("right")
    right.prefix = "r/"
    env = TaskEnv(TaskSpec(scene=scene, arms=[panda_arm("left"), right]))
    assert env.action_space.shape == (14,)
    assert env.action_labels[7:] == [f"right.{k}" for k in ("vx", "vy", "vz", "wx", "wy", "wz")] + [
        "right.gripper"
    ]
    assert env.grippers["right"].actuator == "r/actuator8"
    obs, _ = env.reset(seed=0)
    start = {k: obs[f"{k}_tcp_pos"] for k in ("left", "right")}
    act = np.zeros(14)
    act[9] = 0.1  # right arm up at 0.1 m/s, the left one still; both hands open
    for _ in range(5):
        obs, *_ = env.step(act)
    assert obs["right_tcp_pos"][2] - start["right"][2] == pytest.approx(0.05, abs=0.01)
    assert np.linalg.norm(obs["left_tcp_pos"] - start["left"]) < 0.003
    assert obs["left_gripper"][0] > 0.9 and obs["right_gripper"][0] > 0.9
    act[6] = 1.0  # the left hand closes (0.05 m/s a finger: 25 of 40 mm), the right stays open
    for _ in range(5):
        obs, *_ = env.step(act)
    assert obs["left_gripper"][0] == pytest.approx(0.375, abs=0.03)
    assert obs["right_gripper"][0] > 0.9
    env.close()


def test_render_without_a_mode_warns(env: TaskEnv) -> None:
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None


def test_a_scene_that_raises_on_divergence_ends_the_episode(env: TaskEnv, monkeypatch) -> None:
    # Scene.step raises mjk.SimulationError (MuJoCo's auto-reset is off): the env ends the
    # episode with the scene's message.
    def diverge(n: int = 1) -> None:
        raise mjk.SimulationError(
            "the simulation failed by t = 0.05 s: NaN in QACC", 0.05, {"mjWARN_BADQACC": (1, 0)}
        )

    first, _ = env.reset(seed=0)
    monkeypatch.setattr(env.scene, "step", diverge)
    obs, reward, terminated, truncated, info = env.step(np.zeros(7))
    assert reward == 0.0 and not truncated
    assert terminated and info == {
        "is_success": False,
        "diverged": True,
        "error": "the simulation failed by t = 0.05 s: NaN in QACC",
    }
    np.testing.assert_array_equal(obs["panda_tcp_pos"], first["panda_tcp_pos"])
    with pytest.raises(RuntimeError, match=r"NaN in QACC.*reset"):
        env.step(np.zeros(7))


def test_the_env_follows_a_rebuilt_scene(env: TaskEnv) -> None:
    obs, _ = env.reset(seed=0)
    env.scene.add_object(
        mjk.SceneObject(
            name="block", shape=mjk.Shape.BOX, size=[0.05] * 3, mass=0.5, pos=[0.0, 0.6, 0.5]
        )
    )
    for _ in range(3):
        obs, *_ = env.step(np.array([0, 0, 0.1, 0, 0, 0, 0]))
    # New arrays behind the observations: they still follow the simulation.
    assert obs["time"][0] == pytest.approx(0.3)
    env.robots["panda"].update()
    np.testing.assert_allclose(
        obs["panda_tcp_pos"], env.robots["panda"].fk_frame().translation, atol=1e-9
    )
    block = env.scene.data.xpos[env.scene.body_id("block")]
    assert block[2] < 0.5 - 0.3  # falling
    env.scene.remove_object("ball")  # the ball_pose sensor's body
    with pytest.raises(KeyError, match=r"'ball' in TaskSpec\.sensors\[0\]\.body"):
        env.step(np.zeros(7))


def test_an_episode_records_at_real_speed(env: TaskEnv, tmp_path) -> None:
    import imageio_ffmpeg

    path = tmp_path / "episode.mp4"
    with mjk.VideoRecorder.open(env.scene, path, 160, 120, fps=1 / env.control_timestep) as rec:
        rec.use_camera("front")
        env.reset(seed=0)
        rec.record_frame()
        for _ in range(20):
            env.step(np.array([0, 0.2, 0, 0, 0, 0, 0]))
            rec.record_frame()
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(path))
    assert frames == 21 and seconds == pytest.approx(2.1, abs=0.05)  # one frame per step


HOME_TEXT = [str(x) for x in PANDA_HOME]


def _gripper(field: str, value: object):
    return lambda s: setattr(s.arms[0].gripper, field, value)


@pytest.mark.parametrize(
    ("change", "error", "message"),
    [
        (
            _gripper("actuator", None),
            mjk.SpecTypeError,
            "TaskSpec.arms[0].gripper.actuator must be a string, got None",
        ),
        (
            _gripper("actuator", 8),
            mjk.SpecTypeError,
            "TaskSpec.arms[0].gripper.actuator must be a string, got 8",
        ),
        (
            _gripper("binary", "no"),
            mjk.SpecTypeError,
            "TaskSpec.arms[0].gripper.binary must be True or False, got 'no'",
        ),
        (
            _gripper("held", 1.5),
            mjk.SpecError,
            "TaskSpec.arms[0].gripper.held must be None (the action commands the gripper) or "
            "a command in [0, 1] (0 open, 1 closed), got 1.5",
        ),
        (
            _gripper("held", "closed"),
            mjk.SpecTypeError,
            "TaskSpec.arms[0].gripper.held must be a number, got 'closed'",
        ),
        (
            lambda s: setattr(s.arms[0], "prefix", None),
            mjk.SpecTypeError,
            "TaskSpec.arms[0].prefix must be a string, got None",
        ),
        (
            lambda s: setattr(s, "control_timestep", 1e7),
            mjk.SpecError,
            "TaskSpec.control_timestep (1e+07 s) is more than 2147483647 physics timesteps "
            "(0.002 s), MuJoCo's limit per control step",
        ),
        (
            lambda s: setattr(s.arms[0], "home", HOME_TEXT),
            mjk.SpecTypeError,
            f"TaskSpec.arms[0].home must be a list of numbers, got {HOME_TEXT!r}",
        ),
        (
            lambda s: setattr(s.arms[0], "home", [complex(x) for x in PANDA_HOME]),
            mjk.SpecTypeError,
            "TaskSpec.arms[0].home must be a list of numbers, got "
            f"{[complex(x) for x in PANDA_HOME]!r}",
        ),
        (
            lambda s: setattr(s.arms[0], "home", "abcdefg"),
            mjk.SpecTypeError,
            "TaskSpec.arms[0].home must be a list of numbers, got 'abcdefg'",
        ),
        (
            lambda s: setattr(s.arms[0], "max_linear_velocity", 1e40),
            mjk.SpecError,
            "TaskSpec.arms[0].max_linear_velocity must be at most 1000, got 1e+40",
        ),
        (
            lambda s: setattr(s.arms[0], "max_angular_velocity", 1e39),
            mjk.SpecError,
            "TaskSpec.arms[0].max_angular_velocity must be at most 1000, got 1e+39",
        ),
        (
            lambda s: s.sensors.append(CameraSensor("front", depth="no")),
            mjk.SpecTypeError,
            "TaskSpec.sensors[1].depth must be True or False, got 'no'",
        ),
        (
            lambda s: s.sensors.append(CameraSensor("front", shadows="no")),
            mjk.SpecTypeError,
            "TaskSpec.sensors[1].shadows must be True or False, got 'no'",
        ),
        (
            lambda s: s.sensors.append(CameraSensor("front", reflections=1)),
            mjk.SpecTypeError,
            "TaskSpec.sensors[1].reflections must be True or False, got 1",
        ),
        (
            lambda s: s.sensors.append(CameraSensor("front", name=5)),  # type: ignore[arg-type]
            mjk.SpecTypeError,
            "TaskSpec.sensors[1].name must be a string, got 5",
        ),
        (
            lambda s: s.sensors.append(BodyPoseSensor("ball", name=5)),  # type: ignore[arg-type]
            mjk.SpecTypeError,
            "TaskSpec.sensors[1].name must be a string, got 5",
        ),
    ],
)
def test_bad_spec_values_are_refused_by_name(change, error, message) -> None:
    ball = mjk.SceneObject(name="ball", shape=mjk.Shape.SPHERE, size=[0.03], mass=0.1)
    spec = TaskSpec(scene=panda_scene([ball]), arms=[panda_arm()], sensors=[BodyPoseSensor("ball")])
    change(spec)
    with pytest.raises(error) as err:
        TaskEnv(spec)
    assert str(err.value) == message


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"render_width": -5}, mjk.SpecError, "render_width must be a positive integer, got -5"),
        (
            {"render_height": "x", "render_mode": "human"},
            mjk.SpecTypeError,
            "render_height must be a positive integer, got 'x'",
        ),
        (
            {"render_width": 0, "render_mode": "rgb_array"},
            mjk.SpecError,
            "render_width must be a positive integer, got 0",
        ),
        (
            {"render_width": True, "render_mode": "rgb_array"},
            mjk.SpecTypeError,
            "render_width must be a positive integer, got True",
        ),
        ({"render_camera": 3}, mjk.SpecTypeError, "render_camera must be a camera name, got 3"),
    ],
)
def test_bad_render_arguments_are_refused_by_name(kwargs, error, message) -> None:
    with pytest.raises(error) as err:
        TaskEnv(TaskSpec(scene=panda_scene([]), arms=[panda_arm()]), **kwargs)
    assert str(err.value) == message


@pytest.fixture(scope="module")
def started() -> Iterator[TaskEnv]:
    """One env in an episode, shared by tests whose bad input changes nothing."""
    menagerie("franka_emika_panda")
    e = make()
    e.reset(seed=0)
    yield e
    e.close()


COMPLEX_ACTION = np.full(7, 0.1 + 1j)


@pytest.mark.parametrize(
    "action",
    [
        ["0.1"] * 7,
        [True] * 7,
        [0.1] * 6 + [True],
        np.ones(7, dtype=bool),
        COMPLEX_ACTION,
        [0.1 + 1j] * 7,
        [None] * 7,
        [[0.1], [0.1, 0.2]] + [0.1] * 5,
    ],
)
def test_actions_must_be_real_numbers(started: TaskEnv, action) -> None:
    with pytest.raises(mjk.SpecTypeError) as err:
        started.step(action)
    assert str(err.value) == f"action must hold real numbers, got {action!r}"


@pytest.mark.parametrize(
    ("field", "fn", "error", "message"),
    [
        ("reward", lambda o: "high", mjk.SpecTypeError, "must be a number, got 'high'"),
        ("reward", lambda o: None, mjk.SpecTypeError, "must be a number, got None"),
        (
            "reward",
            lambda o: np.zeros(2),
            mjk.SpecTypeError,
            "must be a number, got array([0., 0.])",
        ),
        ("reward", lambda o: math.nan, mjk.SpecError, "must be finite, got nan"),
        ("reward", lambda o: True, mjk.SpecTypeError, "must be a number, got True"),
        (
            "terminated",
            lambda o: np.array([True, False]),
            mjk.SpecTypeError,
            "must be True or False, got array([ True, False])",
        ),
        ("terminated", lambda o: "no", mjk.SpecTypeError, "must be True or False, got 'no'"),
        ("terminated", lambda o: 1, mjk.SpecTypeError, "must be True or False, got 1"),
    ],
)
def test_reward_and_termination_must_return_their_types(
    started: TaskEnv, field, fn, error, message
) -> None:
    setattr(started.task_spec, field, fn)
    try:
        with pytest.raises(error) as err:
            started.step(np.zeros(7))
    finally:
        setattr(started.task_spec, field, None)
    assert str(err.value) == f"TaskSpec.{field}(obs) {message}"


@pytest.mark.parametrize(
    ("options", "seed", "message"),
    [
        ([1], 0, "reset(options=...) must be a mapping or None, got [1]"),
        ("abc", 0, "reset(options=...) must be a mapping or None, got 'abc'"),
        (0, 0, "reset(options=...) must be a mapping or None, got 0"),
        (None, True, "reset(seed=...) must be an integer or None, got True"),
        (None, np.True_, "reset(seed=...) must be an integer or None, got np.True_"),
    ],
)
def test_reset_arguments_are_checked(started: TaskEnv, options, seed, message) -> None:
    with pytest.raises(mjk.SpecTypeError) as err:
        started.reset(seed=seed, options=options)
    assert str(err.value) == message
    started.reset(seed=0)  # the episode the other tests share


@pytest.mark.parametrize(
    ("fields", "error", "message"),
    [
        (
            {"reward": ReachReward("panda_tcp_ps", "ball_pose")},
            mjk.UnknownNameError,
            "no observation named 'panda_tcp_ps' in TaskSpec.reward (ReachReward.a); "
            "close matches: panda_tcp_pos, panda_tcp_vel, panda_tcp_quat, panda_joint_pos, "
            "panda_gripper",
        ),
        (
            {"terminated": Lifted("panda_gripper", rest_z=0.0, lift=0.1)},
            mjk.SpecError,
            "TaskSpec.terminated (Lifted.key): observation 'panda_gripper' has no x, y, z "
            "(shape (1,))",
        ),
    ],
)
def test_reward_helpers_observations_are_checked_at_build(fields, error, message) -> None:
    with pytest.raises(error) as err:
        make(**fields)
    assert str(err.value) == message


# ------------------------------------------------------------- success, termination, actions


def test_success_fills_info_and_ends_the_episode_after_the_hold() -> None:
    high = {"v": False}

    def success(obs) -> bool:
        return high["v"]

    env = make(success=success, terminate_on_success=True, success_hold=0.2, time_limit=1.0)
    env.reset(seed=0)
    *_, terminated, _, info = env.step(np.zeros(7))
    assert info["is_success"] is False and not terminated
    high["v"] = True
    ends = []
    for _ in range(3):
        *_, terminated, _, info = env.step(np.zeros(7))
        ends.append((info["is_success"], terminated))
    # Held at the first success step, 0.1 s later, 0.2 s later: the third ends it.
    assert ends == [(True, False), (True, False), (True, True)]
    env.close()


def test_the_step_that_ends_on_success_pays_for_the_steps_it_cuts_off() -> None:
    env = make(
        reward=lambda obs: 0.25,
        success=lambda obs: obs["time"][0] > 0.25,
        terminate_on_success=True,
        time_limit=1.0,
    )
    env.reset(seed=0)
    rewards = [env.step(np.zeros(7))[1] for _ in range(3)]
    # Success at the third of ten steps: its 0.25 counts for it and the seven cut off.
    assert rewards == [0.25, 0.25, 0.25 * 8]
    env.close()


def test_normalised_actions_map_onto_the_bounds() -> None:
    arm = panda_arm()
    arm.actuation = Actuation.JOINT_POSITION
    env = make(arms=[arm], normalize_actions=True)
    low, high = env.robots["panda"].joint_limits.T
    assert env.action_space == mjk_box(-1.0, 1.0, 8)
    env.reset(seed=0)
    target = np.array([0.5, -0.5, 0.0, -0.2, 0.1, 0.6, -0.9, 1.0])
    for _ in range(25):
        obs, *_ = env.step(target)
    expected = low + (target[:7] + 1) / 2 * (high - low)
    np.testing.assert_allclose(env.robots["panda"].jnt_pos_cmd, expected, atol=1e-12)
    assert obs["panda_gripper"][0] < 0.1  # +1: closed
    env.close()


def mjk_box(low: float, high: float, n: int):
    from gymnasium import spaces

    return spaces.Box(low, high, (n,), np.float32)


@pytest.mark.parametrize(
    ("fields", "error", "message"),
    [
        ({"success": 3}, ValueError, "TaskSpec.success must be callable or None, got 3"),
        (
            {"terminate_on_success": True},
            ValueError,
            "TaskSpec.terminate_on_success needs a TaskSpec.success callable",
        ),
        ({"terminate_on_success": "yes"}, TypeError, "TaskSpec.terminate_on_success"),
        ({"success_hold": -0.1}, ValueError, "TaskSpec.success_hold must be a non-negative"),
        ({"success_hold": "1"}, TypeError, "TaskSpec.success_hold must be a number"),
        ({"normalize_actions": 1}, TypeError, "TaskSpec.normalize_actions"),
        ({"time_limit": 0}, ValueError, "TaskSpec.time_limit must be a positive number of "),
    ],
)
def test_bad_success_fields_are_refused_by_name(fields: dict, error: type, message: str) -> None:
    with pytest.raises(error) as caught:
        make(**fields)
    assert message in str(caught.value)


def test_a_success_that_returns_no_bool_is_named() -> None:
    env = make(success=lambda obs: "yes")
    with pytest.raises(TypeError, match=r"TaskSpec\.success\(obs\)"):
        env.reset(seed=0)
    env.close()


FREE_MOTORS = """<mujoco><worldbody><body name="base"><geom size="0.05"/>
<body name="l1" pos="0 0 0.1"><joint name="j1" axis="0 1 0"/><geom size="0.03" mass="1"/>
</body></body></worldbody><actuator><motor joint="j1"/></actuator></mujoco>"""


def test_normalising_unbounded_torques_is_refused(tmp_path) -> None:
    arm_file = tmp_path / "arm.xml"
    arm_file.write_text(FREE_MOTORS)
    scene = mjk.SceneSpec(
        timestep=0.002, add_floor=False, add_skybox=False, robots=[mjk.RobotSpec(path=arm_file)]
    )
    arm = ArmSpec("a", "base", "l1", actuation=Actuation.JOINT_TORQUE)
    with pytest.raises(ValueError, match=r"normalize_actions: action entries \['a\.j1'\] have"):
        TaskEnv(TaskSpec(scene=scene, arms=[arm], normalize_actions=True))


def test_without_a_time_limit_only_a_wrapper_ends_episodes() -> None:
    env = make(time_limit=None)
    env.reset(seed=0)
    for _ in range(150):
        *_, truncated, _ = env.step(np.zeros(7))
        assert not truncated
    env.close()


def test_hidden_observations_reach_the_reward_but_not_the_agent() -> None:
    seen = []
    env = make(hide=["panda_joint_torques", "time"], reward=lambda obs: seen.append(obs) or 0.0)
    assert "panda_joint_torques" not in env.observation_space.spaces
    obs, _ = env.reset(seed=0)
    assert list(obs) == list(env.observation_space.spaces) and "time" not in obs
    obs, *_ = env.step(np.zeros(7))
    assert "panda_joint_torques" not in obs and seen[-1]["time"][0] == pytest.approx(0.1)
    assert seen[-1]["panda_joint_torques"].shape == (7,)
    env.close()


@pytest.mark.parametrize(
    ("hide", "error", "message"),
    [
        (["panda_joint_torqes"], KeyError, "'panda_joint_torqes' in TaskSpec.hide[0]"),
        ("time", TypeError, "TaskSpec.hide must be a list of observation names"),
    ],
)
def test_hiding_unknown_observations_is_refused(hide, error, message) -> None:
    with pytest.raises(error) as caught:
        make(hide=hide)
    assert message in str(caught.value)


def test_recorded_camera_frames_are_of_the_recorded_states(tmp_path) -> None:
    """A wrist camera moves with the hand: every recorded frame is the frame of the state
    recorded with it, bit for bit, rendered again the way state replay renders it."""
    from mjkdl.demos import DemoFile, collect, replay
    from mjkdl.demos.hdf5 import STATE
    from mjkdl.record import offscreen_renderer

    out = tmp_path / "wrist.hdf5"
    cams = {"camera_names": ["wrist", "front"], "camera_size": [48, 64], "max_episode_steps": 8}
    collect("mjkdl/PandaPickCube-v0", "demo_envs:approach", out, episodes=1,
            keep_failures=True, env_kwargs=cams, progress=False)  # fmt: skip
    env = gym.make("mjkdl/PandaPickCube-v0", **cams).unwrapped
    model, data = env.scene.model, env.scene.data
    with DemoFile(out) as demos:
        demo = demos.demo(0)
        assert demo.num_samples == 8
        renderer = offscreen_renderer(model, 64, 48, shadows=False, reflections=False)
        worst = {}
        for cam in ("wrist", "front"):
            diffs = []
            for t in range(demo.num_samples):
                mujoco.mj_setState(model, data, demo.states[t], STATE)
                mujoco.mj_forward(model, data)
                renderer.update_scene(data, camera=cam)
                frame = renderer.render().astype(np.int16)
                diffs.append(int(np.abs(frame - demo.obs[f"{cam}_rgb"][t]).max()))
            worst[cam] = diffs
        renderer.close()
        # The hand moves between the frames: a lag of one physics step would show.
        assert np.abs(np.diff(demo.obs["wrist_rgb"].astype(np.int16), axis=0)).max() > 50
    env.close()
    assert worst == {"wrist": [0] * 8, "front": [0] * 8}
    assert replay(out, 0, mode="states").max_pixel_error == 0


def test_scene_poses_follow_the_state_a_step_reached() -> None:
    """After `Scene.step`, `refresh_poses` (and the frame getters, renderers and viewer
    that call it) give the bodies' and a wrist camera's poses `mj_forward` gives for the
    state reached, not those of one timestep before."""
    spec = panda_reach_spec()
    with mjk.Env.build(spec.scene) as scene:
        model, data = scene.model, scene.data
        data.ctrl[:7] = np.array(PANDA_HOME) + 0.5  # the arm swings towards it
        scene.step(20)
        ref = mujoco.MjData(model)
        mujoco.mj_setState(model, ref, _state(model, data), mujoco.mjtState.mjSTATE_INTEGRATION)
        mujoco.mj_forward(model, ref)
        cam, hand = model.camera("wrist").id, model.body("hand").id
        assert not np.array_equal(data.cam_xpos[cam], ref.cam_xpos[cam])  # as mj_step leaves it
        assert np.array_equal(scene.body_frame("hand").translation, ref.xpos[hand])
        assert np.array_equal(data.cam_xpos[cam], ref.cam_xpos[cam])
        assert np.array_equal(data.xpos, ref.xpos)
        assert np.array_equal(data.site_xpos, ref.site_xpos)
        assert np.abs(data.qvel).max() > 0.1  # moving: a lag would differ


def _state(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    out = np.empty(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_INTEGRATION))
    mujoco.mj_getState(model, data, out, mujoco.mjtState.mjSTATE_INTEGRATION)
    return out
