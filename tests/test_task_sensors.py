"""Task sensors: camera images, depth and intrinsics, body poses, wrenches, user sensors."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from conftest import menagerie

import mjkdl as mjk
from mjkdl.task import (
    BodyPoseSensor,
    CameraSensor,
    ContactSensor,
    RelativePositionSensor,
    TaskEnv,
    TaskSpec,
    intrinsics,
)
from mjkdl.task.registry import panda_arm, panda_scene

HEIGHT = 1.2  # the test camera's height over the floor
MARK = (0.15, 0.1)  # world x, y of a small red disc on the floor


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


def overhead_env(*sensors: object, fovy: float = 60.0) -> TaskEnv:
    """The Panda far away, and a camera `HEIGHT` m over the floor at (2, 0) looking down."""
    mark = mjk.SceneObject(
        name="mark",
        shape=mjk.Shape.CYLINDER,
        size=[0.03, 0.0005],
        rgba=[1, 0, 0, 1],
        pos=[2 + MARK[0], MARK[1], 0.0005],
        fixed=True,
    )
    scene = panda_scene([mark])
    scene.cameras.append(mjk.CameraSpec(name="down", pos=[2.0, 0.0, HEIGHT], fovy=fovy))
    scene.cameras.append(mjk.CameraSpec(name="down2", pos=[2.0, 0.0, HEIGHT], fovy=fovy))
    return TaskEnv(TaskSpec(scene=scene, arms=[panda_arm()], sensors=list(sensors)))


def test_intrinsics_follow_fovy_and_size() -> None:
    k = intrinsics(60.0, 640, 480)
    f = 240.0 / math.tan(math.radians(30.0))  # half the height over tan(fovy / 2)
    np.testing.assert_allclose(k, [[f, 0, 319.5], [0, f, 239.5], [0, 0, 1]], rtol=1e-15)


def test_depth_is_metres_along_the_optical_axis() -> None:
    env = overhead_env(CameraSensor("down", width=64, height=48, depth=True))
    obs, _ = env.reset(seed=0)
    depth = obs["down_depth"]
    assert depth.shape == (48, 64) and depth.dtype == np.float32
    # Every pixel sees the floor plane, HEIGHT metres down the optical axis (the mark's top,
    # 1 mm above the floor, covers a few pixels).
    assert float(np.median(depth)) == pytest.approx(HEIGHT, rel=1e-4)
    assert depth.min() >= HEIGHT - 0.001 - 2e-4 and depth.max() <= HEIGHT + 2e-4
    assert obs["down_rgb"].shape == (48, 64, 3) and obs["down_rgb"].dtype == np.uint8
    env.close()


def test_intrinsics_project_a_world_point_onto_its_pixel() -> None:
    env = overhead_env(CameraSensor("down", width=160, height=120), fovy=50.0)
    obs, _ = env.reset(seed=0)
    k = obs["down_intrinsics"]
    np.testing.assert_allclose(k, intrinsics(50.0, 160, 120))
    # Camera frame (x right, y down, z forward) of the mark: the camera looks down -z with
    # its y along world y, so image y is -world y.
    u, v, w = k @ np.array([MARK[0], -MARK[1], HEIGHT])
    rgb = obs["down_rgb"].astype(int)
    red = (rgb[..., 0] > 150) & (rgb[..., 1] < 80) & (rgb[..., 2] < 80)
    rows, cols = np.nonzero(red)
    assert len(rows) > 3
    assert cols.mean() == pytest.approx(u / w, abs=0.5)
    assert rows.mean() == pytest.approx(v / w, abs=0.5)
    env.close()


def test_cameras_of_one_size_share_a_renderer() -> None:
    env = overhead_env(
        CameraSensor("down", width=32, height=32),
        CameraSensor("down2", width=32, height=32, name="other"),
        CameraSensor("front", width=48, height=32),
    )
    assert env._renderers == {}  # made at the first frame, in the process that renders
    obs, _ = env.reset(seed=0)
    assert sorted(env._renderers) == [(32, 32), (48, 32)]
    diff = np.abs(obs["down_rgb"].astype(int) - obs["other_rgb"].astype(int))
    assert diff.mean() < 2.0  # same pose, same picture (up to the floor's reflection)
    assert obs["front_rgb"].shape == (32, 48, 3)
    env.close()


def test_wrist_camera_moves_with_the_arm() -> None:
    scene = panda_scene([])
    scene.cameras.append(
        mjk.CameraSpec(
            name="hand_down",
            pos=[0.1, 0, 0],
            euler=[180, 0, -90],
            fovy=90,
            attach_to=mjk.AttachTarget(mjk.AttachKind.Body, "hand"),
        )
    )
    env = TaskEnv(
        TaskSpec(
            scene=scene, arms=[panda_arm()], sensors=[CameraSensor("hand_down", 32, 32, depth=True)]
        )
    )
    before, _ = env.reset(seed=0)
    for _ in range(5):
        after, *_ = env.step(np.array([0, 0, 0.2, 0, 0, 0, 0]))
    # Looking down from the hand: the floor recedes by the 0.1 m the arm rose.
    centre = (slice(14, 18), slice(14, 18))
    rise = after["panda_tcp_pos"][2] - before["panda_tcp_pos"][2]
    assert rise == pytest.approx(0.1, abs=0.02)
    assert float(np.mean(after["hand_down_depth"][centre] - before["hand_down_depth"][centre])) == (
        pytest.approx(rise, abs=0.01)
    )
    env.close()


def test_body_pose_sensor_reads_the_placed_pose() -> None:
    ball = mjk.SceneObject(name="ball", shape=mjk.Shape.SPHERE, size=[0.03], mass=0.1)

    def place(env: TaskEnv, rng: np.random.Generator) -> None:
        env.scene.set_body_pose("ball", [0.4, -0.2, 0.5], [0.0, 0.0, 0.0, 1.0])

    env = TaskEnv(
        TaskSpec(
            scene=panda_scene([ball]),
            arms=[panda_arm()],
            sensors=[BodyPoseSensor("ball", name="goal")],
            initializers=[place],
        )
    )
    obs, _ = env.reset(seed=0)
    assert obs["goal_pose"].tolist() == [0.4, -0.2, 0.5, 0.0, 0.0, 0.0, 1.0]
    env.close()


FT_TOOL = """
<mujoco model="ft_tool">
  <worldbody>
    <body name="plate">
      <inertial pos="0 0 0.01" mass="0.2" diaginertia="1e-4 1e-4 1e-4"/>
      <geom type="cylinder" size="0.03 0.01" pos="0 0 0.01" contype="0" conaffinity="0"/>
      <site name="ft_site"/>
    </body>
  </worldbody>
  <sensor>
    <force name="force" site="ft_site"/>
    <torque name="torque" site="ft_site"/>
  </sensor>
</mujoco>
"""


def test_wrench_observation_is_the_tools_ft_sensor(tmp_path) -> None:
    xml = tmp_path / "ft_tool.xml"
    xml.write_text(FT_TOOL)
    scene = panda_scene([])
    scene.robots[0].attachments.append(
        mjk.AttachmentSpec(
            mjcf_path=str(xml),
            attach_to=mjk.AttachTarget(mjk.AttachKind.Body, "hand"),
            prefix="ft_",
            pos=[0, 0, 0.12],
        )
    )
    arm = panda_arm()
    arm.tool.tool_body = "ft_plate"
    arm.tool.ft_sensors = [mjk.ForceTorqueSensorSpec("wrist", "ft_force", "ft_torque")]
    env = TaskEnv(TaskSpec(scene=scene, arms=[arm]))
    assert env.observation_space["panda_wrench"].shape == (6,)
    env.reset(seed=0)
    for _ in range(5):
        obs, *_ = env.step(np.zeros(7))
    wrench = env.robots["panda"].ft_sensor("wrist")
    np.testing.assert_array_equal(obs["panda_wrench"][:3], wrench.linear)
    np.testing.assert_array_equal(obs["panda_wrench"][3:], wrench.angular)
    # The arm holds still: the sensor carries the plate's weight, 0.2 kg * 9.81 m/s^2.
    assert np.linalg.norm(obs["panda_wrench"][:3]) == pytest.approx(0.2 * 9.81, rel=1e-2)
    env.close()


class BallHeight:
    """A user sensor: the z of body `ball`."""

    def __init__(self, shape: tuple[int, ...] = (1,)) -> None:
        self.shape = shape

    def space(self, env: TaskEnv):
        from gymnasium import spaces

        return {"ball_z": spaces.Box(-np.inf, np.inf, self.shape, np.float64)}

    def read(self, env: TaskEnv):
        return {"ball_z": [env.scene.data.xpos[env.scene.body_id("ball")][2]]}


def test_user_sensors_follow_the_protocol() -> None:
    ball = mjk.SceneObject(
        name="ball", shape=mjk.Shape.SPHERE, size=[0.03], mass=0.1, pos=[0.5, 0, 0.3]
    )
    env = TaskEnv(TaskSpec(scene=panda_scene([ball]), arms=[panda_arm()], sensors=[BallHeight()]))
    obs, _ = env.reset(seed=0)
    assert obs["ball_z"].tolist() == [0.3]
    obs, *_ = env.step(np.zeros(7))
    assert obs["ball_z"][0] == pytest.approx(0.3 - 0.5 * 9.81 * 0.1**2, abs=2e-3)  # falling
    env.close()
    bad = TaskEnv(
        TaskSpec(scene=panda_scene([ball]), arms=[panda_arm()], sensors=[BallHeight((2,))])
    )
    with pytest.raises(ValueError, match=r"sensors\[0\]\.read\(env\)\['ball_z'\] has shape \(1,\)"):
        bad.reset(seed=0)
    bad.close()


@pytest.mark.parametrize(
    ("args", "error", "message"),
    [
        ((0, 128, 128), mjk.SpecError, "intrinsics: fovy_deg must lie in (0, 180) degrees, got 0"),
        (
            (180, 128, 128),
            mjk.SpecError,
            "intrinsics: fovy_deg must lie in (0, 180) degrees, got 180",
        ),
        ((None, 128, 128), mjk.SpecTypeError, "intrinsics: fovy_deg must be a number, got None"),
        (
            (45, "128", 128),
            mjk.SpecTypeError,
            "intrinsics: width must be a positive integer, got '128'",
        ),
        ((45, 128, 0), mjk.SpecError, "intrinsics: height must be a positive integer, got 0"),
        (
            (45, 128, 12.5),
            mjk.SpecTypeError,
            "intrinsics: height must be a positive integer, got 12.5",
        ),
    ],
)
def test_intrinsics_bad_arguments(args, error, message) -> None:
    with pytest.raises(error) as err:
        intrinsics(*args)
    assert str(err.value) == message


class Returns:
    """A user sensor returning `value` for a float `x` (1,) and a uint8 `n` (1,)."""

    def __init__(self) -> None:
        self.value: object = {"x": [0.0], "n": [0]}

    def space(self, env: TaskEnv):
        from gymnasium import spaces

        return {"x": spaces.Box(-1.0, 1.0, (1,)), "n": spaces.Box(0, 255, (1,), np.uint8)}

    def read(self, env: TaskEnv):
        return self.value


@pytest.mark.parametrize(
    ("value", "error", "message"),
    [
        (None, mjk.SpecTypeError, " must return a mapping of names to values, got None"),
        ([1], mjk.SpecTypeError, " must return a mapping of names to values, got [1]"),
        (
            {"x": ["abc"], "n": [0]},
            mjk.SpecTypeError,
            "['x'] holds <U3 values, which its space's float32 cannot take: ['abc']",
        ),
        (
            {"x": [1 + 1j], "n": [0]},
            mjk.SpecTypeError,
            "['x'] holds complex128 values, which its space's float32 cannot take: [(1+1j)]",
        ),
        (
            {"x": [[1], [1, 2]], "n": [0]},
            mjk.SpecTypeError,
            "['x'] must be an array of numbers, got [[1], [1, 2]]",
        ),
        (
            {"x": [0.0], "n": [300]},
            mjk.SpecError,
            "['n'] holds values outside uint8's range: [300]",
        ),
        ({"x": [0.0], "n": [-1]}, mjk.SpecError, "['n'] holds values outside uint8's range: [-1]"),
        (
            {"x": [0.0], "n": [2.5]},
            mjk.SpecTypeError,
            "['n'] holds float64 values, which its space's uint8 cannot take: [2.5]",
        ),
    ],
)
def test_user_sensor_values_must_fit_their_space(value, error, message) -> None:
    env = TaskEnv(TaskSpec(scene=panda_scene([]), arms=[panda_arm()], sensors=[Returns()]))
    env.reset(seed=0)
    env.task_spec.sensors[0].value = value
    with pytest.raises(error) as err:
        env.step(np.zeros(7))
    assert str(err.value) == "TaskSpec.sensors[0].read(env)" + message
    env.task_spec.sensors[0].value = {"x": np.float32([0.5]), "n": [7]}
    obs, _ = env.reset(seed=0)
    assert obs["x"].tolist() == [0.5] and obs["n"].tolist() == [7]
    env.close()


# ----------------------------------------------------------- contacts, relative positions


def cube_env(*sensors: object) -> TaskEnv:
    cube = mjk.SceneObject(
        name="cube", shape=mjk.Shape.BOX, size=[0.02] * 3, mass=0.05, pos=[0.5, 0.0, 0.03]
    )
    return TaskEnv(TaskSpec(scene=panda_scene([cube]), arms=[panda_arm()], sensors=list(sensors)))


def test_contact_sensor_reports_which_bodies_touch() -> None:
    env = cube_env(ContactSensor("cube", ["left_finger", "right_finger", "world"]))
    assert env.observation_space["cube_contacts"].shape == (3,)
    obs, _ = env.reset(seed=0)
    assert obs["cube_contacts"].tolist() == [0.0, 0.0, 0.0]  # the cube falls onto the floor
    for _ in range(3):
        obs, *_ = env.step(np.zeros(7))
    assert obs["cube_contacts"].tolist() == [0.0, 0.0, 1.0]
    env.close()


def test_readers_name_what_they_read() -> None:
    env = cube_env(ContactSensor("cube", ["left_finger", "world"]))
    model = env.scene.model
    arm, contacts = env.readers
    assert arm.tcp_reference == (int(mujoco.mjtObj.mjOBJ_XBODY), model.body("hand").id)
    pos, rot = arm.tcp_offset
    assert pos.tolist() == [0.0, 0.0, 0.1034] and rot.tolist() == np.eye(3).tolist()
    qadr, dadr = arm.joint_addresses
    joints = [model.joint(f"joint{i}") for i in range(1, 8)]
    assert qadr.tolist() == [int(j.qposadr[0]) for j in joints]
    assert dadr.tolist() == [int(j.dofadr[0]) for j in joints]
    assert arm.in_control_frame is False
    assert contacts.body == model.body("cube").id
    assert contacts.others == [model.body("left_finger").id, 0]
    env.close()


def test_relative_position_is_the_body_minus_the_tcp() -> None:
    env = cube_env(BodyPoseSensor("cube"), RelativePositionSensor("cube", "panda", name="c"))
    obs, _ = env.reset(seed=0)
    np.testing.assert_allclose(obs["c_rel"], obs["cube_pose"][:3] - obs["panda_tcp_pos"], 0, 1e-15)
    obs, *_ = env.step(np.array([0.2, 0, 0, 0, 0, 0, 0]))
    np.testing.assert_allclose(obs["c_rel"], obs["cube_pose"][:3] - obs["panda_tcp_pos"], 0, 1e-15)
    env.close()


@pytest.mark.parametrize(
    ("sensor", "error", "message"),
    [
        (ContactSensor("cub", ["left_finger"]), KeyError, "'cub' in TaskSpec.sensors[0].body"),
        (ContactSensor("cube", []), ValueError, "TaskSpec.sensors[0].others must name at least"),
        (ContactSensor("cube", "left_finger"), TypeError, "others must be a list of body names"),
        (
            ContactSensor("cube", ["left_fingr"]),
            KeyError,
            "'left_fingr' in TaskSpec.sensors[0].others[0]",
        ),
        (RelativePositionSensor("cube", "pand"), KeyError, "no arm named 'pand'"),
        (RelativePositionSensor(3, "panda"), TypeError, "TaskSpec.sensors[0].body"),
    ],
)
def test_bad_contact_and_relative_sensors_are_named(sensor, error, message) -> None:
    with pytest.raises(error) as caught:
        cube_env(sensor)
    assert message in str(caught.value)
