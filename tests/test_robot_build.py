"""Robot construction: chain binding, actuation discovery, tool/sensor checks, release."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from conftest import base_spec, deadline

import mjkdl as mjk

ARM = """
<mujoco model="arm">
  <compiler angle="radian"/>
  <worldbody>
    <body name="base">
      <geom type="cylinder" size="0.05 0.02"/>
      <body name="l1" pos="0 0 0.05">
        <joint name="j1" axis="0 0 1" range="-1 1"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="1"/>
        {branch}
        <body name="l2" pos="0.3 0 0">
          <joint name="j2" axis="0 1 0" range="-2 0.5"/>
          <geom type="capsule" fromto="0 0 0 0.25 0 0" size="0.02" mass="0.5"/>
          <site name="ft_site"/>
          <body name="hand" pos="0.25 0 0">
            <geom type="sphere" size="0.03" mass="0.2"/>
            <site name="tcp" pos="0.03 0 0"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>{actuators}</actuator>
  <sensor>
    <force name="force" site="ft_site"/>
    <torque name="torque" site="ft_site"/>
  </sensor>
</mujoco>
"""
# Declared j2 first: the chain's actuators are [1, 0], not contiguous in MuJoCo's ctrl.
MOTORS = '<motor name="m2" joint="j2" gear="2"/><motor name="m1" joint="j1" gear="3"/>'
SERVOS = (
    '<position name="p1" joint="j1" kp="0.5" kv="0.1"/>'
    '<position name="p2" joint="j2" kp="80" gear="2"/>'
)
# A finger on l1, declared before l2: the arm's joints are j1 and j2, apart in q and v.
BRANCH = """
        <body name="finger" pos="0.1 0 0">
          <joint name="jf" axis="1 0 0" range="-0.5 0.5"/>
          <geom type="box" size="0.01 0.01 0.01" mass="0.05"/>
        </body>
"""
BALL = mjk.SceneObject(name="ball", shape=mjk.Shape.SPHERE, size=[0.02], mass=0.1, pos=[1, 0, 1])


@pytest.fixture(scope="module")
def build(tmp_path_factory):
    """Builds a scene of ARM with `actuators` (and the ball first); closes them all at the end."""
    built: list[mjk.Scene] = []
    folder = tmp_path_factory.mktemp("arms")

    def make(actuators: str = MOTORS, branch: str = "", objects=(BALL,)) -> mjk.Scene:
        path = folder / f"arm{len(built)}.xml"
        path.write_text(ARM.format(actuators=actuators, branch=branch))
        spec = base_spec(robots=[mjk.RobotSpec(path=str(path))], objects=list(objects))
        scene = mjk.Scene.build(spec)
        built.append(scene)
        return scene

    yield make
    for scene in built:
        scene.close()


@pytest.fixture(scope="module")
def motors(build):
    return build(MOTORS)


@pytest.fixture(scope="module")
def servos(build):
    return build(SERVOS)


def _diag_mass(scene: mjk.Scene, joints) -> np.ndarray:
    """MuJoCo's own joint-space inertia diagonal of `joints` at the scene's current qpos."""
    data = mujoco.MjData(scene.model)
    data.qpos[:] = scene.data.qpos
    mujoco.mj_forward(scene.model, data)
    full = np.zeros((scene.model.nv, scene.model.nv))
    mujoco.mj_fullM(scene.model, data, full)
    return np.diag(full)[[scene.model.joint(name).dofadr[0] for name in joints]]


# ---------------------------------------------------------------------- arguments


@pytest.mark.parametrize(
    ("args", "kw", "message"),
    [
        ((None, "hand"), {}, "create_robot: base_body must be a string, got None"),
        (("base", 5), {}, "create_robot: tip_body must be a string, got 5"),
        (("base", "hand"), {"prefix": None}, "create_robot: prefix must be a string, got None"),
        (("base", "hand"), {"tool": "tcp"}, "tool must be a ToolFrameSpec, got str"),
    ],
)
def test_argument_errors_name_the_argument(motors, args, kw, message) -> None:
    with pytest.raises(ValueError) as err:
        motors.create_robot(*args, **kw)
    assert str(err.value) == message


def test_robot_built_directly_takes_names_without_prefix(motors) -> None:
    robot = mjk.Robot(motors, "base", "hand")
    assert robot.joint_names == ["j1", "j2"]
    assert robot.gravity_compensation is False  # a bool, off until asked for
    robot.close()


@pytest.mark.parametrize(
    ("tool", "message"),
    [
        (
            mjk.ToolFrameSpec(tcp_pos=[0.0, 0.1]),
            "tool.tcp_pos must have 3 values, got 2: [0.0, 0.1]",
        ),
        (mjk.ToolFrameSpec(tcp_euler=[90.0]), "tool.tcp_euler must have 3 values, got 1: [90.0]"),
    ],
)
def test_tcp_offset_errors_name_the_field(motors, tool, message) -> None:
    with pytest.raises(ValueError) as err:
        motors.create_robot("base", "hand", tool=tool)
    assert str(err.value) == message


def _ft(name: object = "wrist", force: object = "force", torque: object = "torque"):
    """An F/T pair of the `motors` scene's sensors, with one field possibly wrong."""
    return mjk.ForceTorqueSensorSpec(name=name, force_sensor=force, torque_sensor=torque)


@pytest.mark.parametrize(
    ("tool", "message"),
    [
        (mjk.ToolFrameSpec(tool_body=None), "tool.tool_body must be a string, got None"),
        (mjk.ToolFrameSpec(tcp_site=3), "tool.tcp_site must be a string, got 3"),
        (
            mjk.ToolFrameSpec(ft_sensors=None),
            "tool.ft_sensors must be a list of ForceTorqueSensorSpec, got None",
        ),
        (
            mjk.ToolFrameSpec(ft_sensors=["wrist"]),
            "tool.ft_sensors[0] must be a ForceTorqueSensorSpec, got 'wrist'",
        ),
        (
            mjk.ToolFrameSpec(ft_sensors=[_ft(), _ft(name=5)]),
            "tool.ft_sensors[1].name must be a string, got 5",
        ),
        (
            mjk.ToolFrameSpec(ft_sensors=[_ft(name="")]),
            "tool.ft_sensors[0].name is empty: ft_sensor(name) reads the pair by it",
        ),
        (
            mjk.ToolFrameSpec(ft_sensors=[_ft(), _ft()]),
            "tool.ft_sensors[1].name: duplicate 'wrist' (tool.ft_sensors[0] has it too)",
        ),
        (
            mjk.ToolFrameSpec(ft_sensors=[_ft(force=None)]),
            "tool.ft_sensors[0].force_sensor must be a string, got None",
        ),
        (
            mjk.ToolFrameSpec(ft_sensors=[_ft(torque="")]),
            "tool.ft_sensors[0].torque_sensor is empty: name the MuJoCo torque sensor",
        ),
    ],
)
def test_tool_field_errors_name_the_field(motors, tool, message) -> None:
    with pytest.raises(ValueError) as err:
        motors.create_robot("base", "hand", tool=tool)
    assert str(err.value) == message
    assert not motors._robots  # nothing half-made stays registered


def test_tool_is_copied_so_later_edits_do_not_reach_the_handle(build) -> None:
    scene = build(MOTORS)
    tool = mjk.ToolFrameSpec(tcp_site="tcp")
    robot = scene.create_robot("base", "hand", tool=tool)
    # Edited after the handle was made: a sensor that does not exist in the model.
    tool.ft_sensors.append(
        mjk.ForceTorqueSensorSpec(name="wrist", force_sensor="nope", torque_sensor="nope")
    )
    scene.add_object(mjk.SceneObject(name="cube", shape=mjk.Shape.BOX, size=[0.02] * 3, mass=0.1))
    with pytest.raises(KeyError) as err:  # the rebuild bound the handle's own, empty, list
        robot.ft_sensor("wrist")
    assert err.value.args[0] == "no force/torque sensor named 'wrist' in tool.ft_sensors"


# ---------------------------------------------------------------------- tool body


def test_unknown_tool_body_lists_close_matches(motors) -> None:
    with pytest.raises(KeyError) as err:
        motors.create_robot("base", "l2", tool=mjk.ToolFrameSpec(tool_body="hnd"))
    first = err.value.args[0].splitlines()[0]
    assert first == "no body named 'hnd' in the model (tool.tool_body); close matches: hand"


@pytest.mark.parametrize("body", ["world", "base", "ball"])
def test_tool_body_not_below_the_tip_is_refused(motors, body) -> None:
    # world is body 0; base is the root of the arm's tree, ball (body 1) of another tree.
    assert motors.model.body(1).name == "ball"
    with deadline(2.0, "create_robot"), pytest.raises(ValueError) as err:
        motors.create_robot("base", "hand", tool=mjk.ToolFrameSpec(tool_body=body))
    assert str(err.value) == f"tool.tool_body {body!r} is not mounted below the tip 'hand'"


# ---------------------------------------------------------------------- F/T sensors


@pytest.mark.parametrize(
    ("force", "torque", "message"),
    [
        ("forc", "torque", "no sensor named 'forc' in ft_sensors 'wrist'; close matches: force"),
        ("force", "torq", "no sensor named 'torq' in ft_sensors 'wrist'; close matches: torque"),
        ("x", "torque", "no sensor named 'x' in ft_sensors 'wrist'; known: force, torque"),
    ],
)
def test_unknown_ft_sensor_lists_the_sensors(motors, force, torque, message) -> None:
    sensor = mjk.ForceTorqueSensorSpec(name="wrist", force_sensor=force, torque_sensor=torque)
    with pytest.raises(KeyError) as err:
        motors.create_robot("base", "hand", tool=mjk.ToolFrameSpec(ft_sensors=[sensor]))
    assert err.value.args[0].splitlines()[0] == message


def test_torque_sensor_of_the_wrong_kind_is_named(motors) -> None:
    sensor = mjk.ForceTorqueSensorSpec(name="wrist", force_sensor="force", torque_sensor="force")
    with pytest.raises(ValueError) as err:
        motors.create_robot("base", "hand", tool=mjk.ToolFrameSpec(ft_sensors=[sensor]))
    assert str(err.value) == "ft_sensors 'wrist': sensor 'force' is not a torque sensor"


def test_unknown_ft_sensor_reading_names_the_tool_field(motors) -> None:
    robot = motors.create_robot("base", "hand")
    with pytest.raises(KeyError) as err:
        robot.ft_sensor("wrist")
    assert err.value.args[0] == "no force/torque sensor named 'wrist' in tool.ft_sensors"
    robot.close()


# ---------------------------------------------------------------------- actuation


def test_motor_servo_gains_are_a_10hz_critically_damped_servo(motors) -> None:
    model = motors.model
    robot = motors.create_robot("base", "hand")
    robot.ctrl_mode = mjk.CtrlMode.POSITION
    robot.update()
    mass = _diag_mass(motors, ["j1", "j2"])  # at q = 0, where the handle was made
    omega = 2 * math.pi * 10.0
    gear = np.array([3.0, 2.0])  # j1 is driven by m1 (actuator 1), j2 by m2 (actuator 0)
    kp = mass * omega**2 / gear**2
    kv = 2 * mass * omega / gear**2
    ids = [1, 0]
    np.testing.assert_allclose(model.actuator_gainprm[ids, 0], kp * gear, rtol=1e-9)
    np.testing.assert_allclose(model.actuator_biasprm[ids, 1], -kp, rtol=1e-9)
    np.testing.assert_allclose(model.actuator_biasprm[ids, 2], -kv, rtol=1e-9)
    robot.close()


def test_position_servo_gains_are_the_actuators_own(servos) -> None:
    model = servos.model
    robot = servos.create_robot("base", "hand")
    robot.ctrl_mode = mjk.CtrlMode.POSITION
    robot.update()
    # p1 keeps its kp = 0.5 and kv = 0.1; p2 (kp = 80, no kv) gets a critically damped kv.
    mass = _diag_mass(servos, ["j2"])[0]
    kv2 = 2 * math.sqrt(80 * mass) / 2.0
    np.testing.assert_allclose(model.actuator_gainprm[:, 0], [0.5, 80 * 2.0], rtol=1e-12)
    np.testing.assert_allclose(model.actuator_biasprm[:, 1], [-0.5, -80], rtol=1e-12)
    np.testing.assert_allclose(model.actuator_biasprm[:, 2], [-0.1, -kv2], rtol=1e-9)
    robot.close()


@pytest.mark.parametrize(
    ("actuators", "message"),
    [
        (
            '<motor name="a" joint="j1"/><motor name="b" joint="j1"/><motor joint="j2"/>',
            "joint 'j1' is driven by several actuators (a, b); "
            "a Robot drives each joint through exactly one",
        ),
        (
            '<motor joint="j1"/><general name="f" joint="j2" dyntype="filter" dynprm="0.1"/>',
            "actuator 'f' has activation dynamics; control modes need direct (dyntype none) "
            "actuators",
        ),
        ('<motor joint="j1"/><motor name="z" joint="j2" gear="0"/>', "actuator 'z' has zero gear"),
    ],
)
def test_actuators_a_robot_cannot_drive_are_named(build, actuators, message) -> None:
    scene = build(actuators)
    with pytest.raises(ValueError) as err:
        scene.create_robot("base", "hand")
    assert str(err.value) == message


def test_commands_reach_actuators_declared_out_of_order(motors) -> None:
    robot = motors.create_robot("base", "hand")
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.update()
    robot.jnt_trq_cmd = np.array([0.5, -0.25])
    robot.step()
    dofs = [motors.model.joint(name).dofadr[0] for name in ("j1", "j2")]
    assert motors.data.qfrc_actuator[dofs].tolist() == [0.5, -0.25]
    robot.close()


# ---------------------------------------------------------------------- rebuild


def test_rebuild_keeps_commands_views_and_the_mode(build) -> None:
    scene = build(MOTORS)
    robot = scene.create_robot("base", "hand")
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.update()
    robot.jnt_pos_cmd = np.array([0.1, 0.2])
    robot.jnt_vel_cmd = np.array([0.3, 0.4])
    robot.jnt_trq_cmd = np.array([0.5, 0.6])
    with pytest.warns(mjk.IgnoredCommandWarning) as ignored:  # TORQUE ignores the other two
        robot.step()
    assert sorted(str(w.message)[:11] for w in ignored) == ["jnt_pos_cmd", "jnt_vel_cmd"]
    views = robot.jnt_pos_msr, robot.jnt_vel_msr, robot.jnt_trq_msr, robot.q, robot.v
    scene.add_object(mjk.SceneObject(name="cube", shape=mjk.Shape.BOX, size=[0.02] * 3, mass=0.1))
    assert robot.jnt_pos_cmd.tolist() == [0.1, 0.2]
    assert robot.jnt_vel_cmd.tolist() == [0.3, 0.4]
    assert robot.jnt_trq_cmd.tolist() == [0.5, 0.6]
    # The rebuilt model's actuators are motors again at once, as TORQUE mode made them.
    model = scene.model
    np.testing.assert_allclose(model.actuator_gainprm[[1, 0], 0], [1 / 3, 1 / 2], rtol=1e-12)
    assert not model.actuator_biasprm[:2].any()
    # Views taken before the rebuild still follow the measured state.
    j1, j2 = (scene.model.joint(n) for n in ("j1", "j2"))
    scene.data.qpos[[j1.qposadr[0], j2.qposadr[0]]] = [0.7, -0.8]
    scene.data.qvel[[j1.dofadr[0], j2.dofadr[0]]] = [0.9, -1.0]
    robot.step()
    robot.update()
    dofs = [j1.dofadr[0], j2.dofadr[0]]
    pos, vel, trq, q, v = views
    assert pos.tolist() == scene.data.qpos[[j1.qposadr[0], j2.qposadr[0]]].tolist()
    assert vel.tolist() == scene.data.qvel[dofs].tolist()
    assert trq.tolist() == scene.data.qfrc_actuator[dofs].tolist() == [0.5, 0.6]
    assert q.tolist() == pos.tolist() and v.tolist() == vel.tolist()
    robot.close()


# ---------------------------------------------------------------------- release


def test_closing_a_reading_handle_leaves_the_driving_one_alone(motors) -> None:
    driver = motors.create_robot("base", "hand")
    reader = motors.create_robot("base", "hand")
    driver.ctrl_mode = mjk.CtrlMode.TORQUE
    driver.update()
    reader.close()
    np.testing.assert_allclose(motors.model.actuator_gainprm[[1, 0], 0], [1 / 3, 1 / 2])
    driver.close()


def test_closing_a_handle_restores_only_its_own_actuators(motors) -> None:
    model = motors.model
    authored = model.actuator_gainprm.copy(), model.actuator_biasprm.copy()
    first = motors.create_robot("base", "l1")  # j1, actuator m1 (1)
    second = motors.create_robot("l1", "hand")  # j2, actuator m2 (0)
    for robot in (first, second):
        robot.ctrl_mode = mjk.CtrlMode.TORQUE
        robot.update()
    first.close()
    assert model.actuator_gainprm[0, 0] == 0.5  # m2 is still second's motor, 1 / gear
    assert model.actuator_gainprm[1].tolist() == authored[0][1].tolist()
    assert model.actuator_biasprm[1].tolist() == authored[1][1].tolist()
    second.close()
    assert model.actuator_gainprm.tolist() == authored[0].tolist()


def test_closed_handle_says_it_is_closed(motors) -> None:
    robot = motors.create_robot("base", "hand")
    robot.close()
    with pytest.raises(RuntimeError) as err:
        robot.update()
    assert str(err.value) == "this Robot is closed"


# ---------------------------------------------------------------------- state and IK


def test_set_joint_pos_accepts_the_range_ends_and_checks_the_length(motors) -> None:
    robot = motors.create_robot("base", "hand")
    for q in ([-1.0, -2.0], [1.0, 0.5]):  # j1's and j2's range ends, inclusive
        robot.set_joint_pos(q)
        assert robot.jnt_pos_msr.tolist() == q
    with pytest.raises(ValueError) as err:
        robot.set_joint_pos([0.0, 0.0, 0.0])
    assert str(err.value) == "set_joint_pos(q) needs 2 values (one per joint), got shape (3,)"
    robot.set_joint_pos([0.0, 0.0])
    robot.close()


def test_set_joint_pos_updates_gathered_ports(build) -> None:
    scene = build(MOTORS, branch=BRANCH)
    robot = scene.create_robot("base", "hand")
    assert robot.arm_q.tolist() == [0, 2]  # j1, jf, j2: the arm is not contiguous
    robot.set_joint_pos([0.25, -0.5])
    assert robot.jnt_pos_msr.tolist() == [0.25, -0.5]  # without an update()
    robot.close()


def test_ik_checks_q0(motors) -> None:
    robot = motors.create_robot("base", "hand")
    with pytest.raises(ValueError) as err:
        robot.ik(robot.fk_frame(), q0=[0.0, 0.0, 0.0])
    assert str(err.value) == "q0 needs 2 values (one per joint), got shape (3,)"
    robot.close()


# ---------------------------------------------------------------------- URDF velocity limits

_LINK = (
    '<link name="{}"><inertial><mass value="1"/>'
    '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
)
_JOINT = (
    '<joint name="{}" type="revolute"><parent link="{}"/><child link="{}"/>'
    '<origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>{}</joint>'
)
# In file order: a velocity that is not a number, then 0.5, none, 0 and a continuous joint.
_LIMITS = [
    ("ja", '<limit lower="-1" upper="1" effort="5" velocity="abc"/>'),
    ("jb", '<limit lower="-1" upper="1" effort="5" velocity="0.5"/>'),
    ("jc", '<limit lower="-1" upper="1" effort="5"/>'),
    ("jd", '<limit lower="-1" upper="1" effort="5" velocity="0"/>'),
    ("je", '<limit lower="-1" upper="1" effort="5" velocity="2.5"/>'),
]


@pytest.fixture(scope="module")
def urdf_scene(tmp_path_factory, build):
    """An MJCF arm first, then a URDF chain l0 -> l5 with the `_LIMITS` joints (prefix u_)."""
    links = [f"l{i}" for i in range(len(_LIMITS) + 1)]
    joints = [
        _JOINT.format(name, links[i], links[i + 1], limit)
        for i, (name, limit) in enumerate(_LIMITS)
    ]
    path = tmp_path_factory.mktemp("urdf") / "chain.urdf"
    path.write_text(
        '<robot name="chain">'
        + "".join(_LINK.format(n) for n in links)
        + "".join(joints)
        + "</robot>"
    )
    mjcf = tmp_path_factory.mktemp("mjcf") / "arm.xml"
    mjcf.write_text(ARM.format(actuators=MOTORS, branch=""))
    robots = [
        mjk.RobotSpec(path=str(mjcf)),
        mjk.RobotSpec(path=str(path), prefix="u_", pos=[1.0, 0.0, 0.0]),
    ]
    scene = mjk.Scene.build(base_spec(robots=robots))
    yield scene, path
    scene.close()


def test_urdf_velocity_limits_are_the_files(urdf_scene) -> None:
    import xml.etree.ElementTree as ET

    scene, path = urdf_scene
    robot = scene.create_robot("l0", "l5", prefix="u_")
    assert robot.joint_names == ["u_ja", "u_jb", "u_jc", "u_jd", "u_je"]
    # Read back from the file: only positive numbers are limits, anything else is none.
    limit = {j.get("name"): j.find("limit").get("velocity") for j in ET.parse(path).iter("joint")}
    assert limit == {"ja": "abc", "jb": "0.5", "jc": None, "jd": "0", "je": "2.5"}
    inf = np.inf
    assert robot.model.velocityLimit[robot.arm_v].tolist() == [inf, 0.5, inf, inf, 2.5]
    assert robot.model.lowerVelocityLimit[robot.arm_v].tolist() == [-inf, -0.5, -inf, -inf, -2.5]
    robot.close()


def test_urdf_file_gone_after_the_build_means_no_velocity_limits(build, tmp_path) -> None:
    path = tmp_path / "gone.urdf"
    links = ["a", "b"]
    path.write_text(
        '<robot name="gone">'
        + "".join(_LINK.format(n) for n in links)
        + _JOINT.format("j", "a", "b", _LIMITS[1][1])
        + "</robot>"
    )
    with mjk.Scene.build(base_spec(robots=[mjk.RobotSpec(path=str(path))])) as scene:
        path.unlink()
        robot = scene.create_robot("a", "b")
        assert robot.model.velocityLimit.tolist() == [np.inf]


# ---------------------------------------------------------------------- unactuated chains


def test_step_of_an_unactuated_chain_in_position_mode_names_the_problem(build) -> None:
    """step() gives update()'s error, not NumPy's shape mismatch on an empty ctrl index."""
    scene = build("")
    robot = scene.create_robot("base", "hand")
    robot.jnt_pos_cmd = np.array([0.1, 0.2])
    try:
        with pytest.raises(mjk.SpecError) as err:
            robot.step()
        assert str(err.value) == (
            "POSITION mode needs an actuator on every joint; none drives j1, j2 "
            "(TORQUE mode applies the torques as qfrc_applied)"
        )
    finally:
        robot.close()
