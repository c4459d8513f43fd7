"""Robot handle: ports, control modes, tool handling and its errors."""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import HOME, base_spec, gripper_tool, menagerie, table_object, two_link_arm

import mjkdl as mjk
from mjkdl.urdf import example_robot_data_path, load_urdf

ASSETS_DIR = Path(__file__).resolve().parent / "assets"


@pytest.fixture
def gen3(tutorial_scene):
    scene = tutorial_scene()
    robot = scene.create_robot("base_link", "bracelet_link", tool=gripper_tool())
    robot.set_joint_pos(HOME)
    robot.sync_commands()
    return scene, robot


@pytest.fixture
def ur5():
    table = table_object()
    arm = mjk.RobotSpec(
        path=example_robot_data_path("ur_description/urdf/ur5_robot.urdf"),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Site, "table/table_top"),
    )
    scene = mjk.Scene.build(base_spec(objects=[table], robots=[arm]))
    robot = scene.create_robot("base_link", "tool0")
    robot.set_joint_pos([0.3, -1.2, 1.4, -1.5, -1.57, 0.2])
    robot.sync_commands()
    yield scene, robot
    scene.close()


def _run(scene: mjk.Scene, robot: mjk.Robot, seconds: float, control=None) -> float:
    """Run the update/command/step loop; return the largest joint error to the pos command."""
    worst = 0.0
    end = scene.time() + seconds
    while scene.time() < end:
        robot.update()
        if control is not None:
            control(robot)
        robot.step()
        worst = max(worst, float(np.abs(robot.jnt_pos_msr - robot.jnt_pos_cmd).max()))
    return worst


# ---------------------------------------------------------------------- description


def test_chain_description(gen3) -> None:
    _, robot = gen3
    assert robot.n_joints == 7
    assert robot.joint_names == [f"joint_{i}" for i in range(1, 8)]
    limits = robot.joint_limits
    assert limits.shape == (7, 2)
    assert limits[1].tolist() == [-2.24, 2.24]
    assert np.isinf(limits[0]).all()
    assert robot.has_tcp_frame
    assert robot.kdl_chain() is robot.model
    # The model holds the arm first, then the 2F-85's eight passive finger joints.
    assert robot.model.nq == robot.model.nv == 15
    assert robot.arm_q == robot.arm_v == slice(0, 7)
    assert [robot.model.names[j] for j in range(1, 8)] == robot.joint_names
    assert robot.model.names[8].startswith("g_")


def test_world_as_base_leaves_other_trees_out(tutorial_scene) -> None:
    scene = tutorial_scene()
    robot = scene.create_robot("world", "bracelet_link")
    # The arm and its gripper's fingers; the cube's free joint is not in the arm's model.
    assert robot.model.nq == 15
    assert not [name for name in robot.model.names if "cube" in name]
    robot.set_joint_pos(HOME)
    np.testing.assert_allclose(robot.gravity_torques(), scene.data.qfrc_bias[:7], atol=1e-9)


def test_no_tool_means_fk_at_tip(tutorial_scene) -> None:
    scene = tutorial_scene()
    robot = scene.create_robot("base_link", "bracelet_link")
    robot.update()
    assert not robot.has_tcp_frame
    tip = scene.body_frame("bracelet_link")
    assert np.abs(robot.fk_frame().translation - tip.translation).max() < 1e-12


# ---------------------------------------------------------------------- ports


def test_measured_ports_follow_update_and_are_read_only(gen3) -> None:
    scene, robot = gen3
    assert np.allclose(robot.jnt_pos_msr, HOME)
    with pytest.raises(ValueError, match="read-only"):
        robot.jnt_pos_msr[0] = 1.0
    scene.data.qpos[0] = 0.5
    assert robot.jnt_pos_msr[0] == pytest.approx(0.0)  # not before update()
    robot.update()
    assert robot.jnt_pos_msr[0] == pytest.approx(0.5)


@pytest.mark.parametrize("port", ["jnt_pos_cmd", "jnt_vel_cmd", "jnt_trq_cmd"])
def test_command_ports_check_length_and_finiteness(gen3, port: str) -> None:
    _, robot = gen3
    setattr(robot, port, [0.1] * 7)
    assert getattr(robot, port).tolist() == [0.1] * 7
    with pytest.raises(ValueError, match=f"{port} needs 7 values"):
        setattr(robot, port, [0.0] * 6)
    with pytest.raises(ValueError, match=f"{port} must be finite"):
        setattr(robot, port, [0.0] * 6 + [np.nan])
    with pytest.raises(ValueError, match=f"{port} must be finite"):
        setattr(robot, port, np.array([np.inf] + [0.0] * 6))
    assert getattr(robot, port).tolist() == [0.1] * 7  # a rejected value changes nothing


def test_torque_port_is_actuator_torque_limited_by_forcerange(gen3) -> None:
    _, robot = gen3
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.update()
    robot.jnt_trq_cmd = [500.0, 0, 0, 0, -500.0, 0, 0]
    robot.step()
    robot.update()
    # Gen3's actuators: forcerange ±105 (joints 1-4) and ±52 (joints 5-7).
    assert robot.jnt_trq_msr[0] == pytest.approx(105.0)
    assert robot.jnt_trq_msr[4] == pytest.approx(-52.0)
    assert np.allclose(robot.jnt_trq_msr[[1, 2, 3, 5, 6]], 0.0)


def test_torque_mode_position_actuators_do_not_fight(gen3) -> None:
    scene, robot = gen3
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    for _ in range(50):  # zero torque: the arm falls, and no servo pulls it back
        robot.update()
        robot.step()
    robot.update()
    assert np.abs(robot.jnt_pos_msr - HOME).max() > 1e-3
    assert np.abs(scene.data.qfrc_actuator[:7]).max() == 0.0


# ---------------------------------------------------------------------- modes


def test_gravity_compensation_holds_tcp(gen3) -> None:
    """The tutorial scene: fingers commanded open, TCP drift < 1e-4 m over 2 s."""
    scene, robot = gen3
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    scene.set_actuator_ctrl("g_fingers_actuator", 0.0)
    robot.update()
    start = robot.fk_frame().translation.copy()

    def gravity(r: mjk.Robot) -> None:
        r.jnt_trq_cmd = r.gravity_torques(-9.81)

    _run(scene, robot, 2.0, gravity)
    robot.update()
    assert np.linalg.norm(robot.fk_frame().translation - start) < 1e-4


def test_position_hold_gen3(gen3) -> None:
    scene, robot = gen3
    robot.ctrl_mode = mjk.CtrlMode.POSITION
    assert _run(scene, robot, 2.0) < 1e-3


def test_position_hold_urdf_ur5_with_motor_actuators(ur5) -> None:
    scene, robot = ur5
    authored = load_urdf(example_robot_data_path("ur_description/urdf/ur5_robot.urdf"))
    assert all(a.biastype == mujoco.mjtBias.mjBIAS_NONE for a in authored.actuators)  # motors
    robot.ctrl_mode = mjk.CtrlMode.POSITION
    assert _run(scene, robot, 2.0) < 1e-3


@pytest.mark.parametrize("fixture", ["gen3", "ur5"])
def test_velocity_mode_tracks_constant_velocity(fixture: str, request) -> None:
    scene, robot = request.getfixturevalue(fixture)
    v = np.linspace(0.15, -0.15, robot.n_joints)
    robot.ctrl_mode = mjk.CtrlMode.VELOCITY
    robot.jnt_vel_cmd = v
    q0 = robot.jnt_pos_msr.copy()
    _run(scene, robot, 0.2)
    t0, qa = scene.time(), robot.jnt_pos_msr.copy()
    worst = 0.0
    while scene.time() < t0 + 0.5:
        robot.update()
        robot.step()
        worst = max(worst, float(np.abs(robot.jnt_vel_msr - v).max()))
    # Within 1 % of the fastest joint's 0.15 rad/s: a servo 5 % off (7.5e-3) fails.
    assert worst < 1.5e-3
    travelled = robot.jnt_pos_msr - qa
    np.testing.assert_allclose(travelled, v * (scene.time() - t0), rtol=0, atol=7.5e-4)
    assert not np.allclose(robot.jnt_pos_msr, q0)


def test_mode_switch_takes_effect_on_next_update(gen3) -> None:
    scene, robot = gen3
    robot.update()  # POSITION: position servos
    kp = scene.model.actuator_gainprm[0, 0]
    assert scene.model.actuator_biasprm[0, 1] == -kp
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    assert scene.model.actuator_biasprm[0, 1] == -kp  # not yet
    robot.update()
    assert scene.model.actuator_gainprm[0, 0] == 1.0
    assert np.all(scene.model.actuator_biasprm[:7] == 0.0)
    robot.ctrl_mode = mjk.CtrlMode.POSITION
    robot.update()
    assert scene.model.actuator_gainprm[0, 0] == kp  # the authored servo gain comes back


def test_command_applies_in_the_same_step(gen3) -> None:
    scene, robot = gen3
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.update()
    robot.jnt_trq_cmd = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]
    robot.step()
    assert scene.data.qfrc_actuator[:7].tolist() == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]


# ---------------------------------------------------------------------- dynamics helpers


def test_gravity_override_scales_torques(gen3) -> None:
    _, robot = gen3
    robot.update()
    g = robot.gravity_torques()
    assert np.allclose(robot.gravity_torques(-9.81 / 2), g / 2, atol=1e-12)
    assert np.allclose(robot.gravity_torques(0.0), 0.0)
    assert np.allclose(robot.gravity_torques(), g)  # the override does not stick


def test_tool_inertia_follows_finger_configuration(gen3) -> None:
    scene, robot = gen3
    robot.update()
    open_g = robot.gravity_torques()
    for j in range(scene.model.njnt):
        if scene.model.joint(j).name.startswith("g_"):
            scene.data.qpos[scene.model.jnt_qposadr[j]] = scene.model.jnt_range[j, 1]
    scene.forward()
    robot.update()
    closed_g = robot.gravity_torques()
    assert np.abs(closed_g - open_g).max() > 1e-4
    assert np.allclose(closed_g, scene.data.qfrc_bias[:7], rtol=0, atol=1e-9)


def test_ik_solves_reachable_target(gen3) -> None:
    _, robot = gen3
    q_goal = np.array(HOME) + np.array([0.3, -0.2, 0.1, 0.25, -0.3, 0.2, 0.1])
    target = robot.fk_frame(q_goal)
    result = robot.ik(target)
    assert result.success
    reached = robot.fk_frame(result.q)
    assert np.linalg.norm(reached.translation - target.translation) < 1e-6
    assert np.linalg.norm(pin.log3(reached.rotation.T @ target.rotation)) < 1e-5
    lim = robot.joint_limits
    assert np.all(result.q >= lim[:, 0]) and np.all(result.q <= lim[:, 1])


# ---------------------------------------------------------------------- gravity, limits


def _mujoco_gravity(scene: mjk.Scene, dofs) -> np.ndarray:
    """MuJoCo's gravity torques at the scene's current qpos (a second MjData, at rest)."""
    data = mujoco.MjData(scene.model)
    data.qpos[:] = scene.data.qpos
    mujoco.mj_forward(scene.model, data)
    return (data.qfrc_bias - data.qfrc_gravcomp)[dofs]


def test_gravity_compensation_applies_command_plus_gravity(gen3) -> None:
    scene, robot = gen3
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.gravity_compensation = True
    scene.set_actuator_ctrl("g_fingers_actuator", 255.0)
    extra = np.linspace(-1.0, 1.0, 7)
    robot.jnt_trq_cmd = extra
    for _ in range(200):  # the fingers close meanwhile
        robot.update()
        expected = extra + _mujoco_gravity(scene, np.arange(7))
        np.testing.assert_allclose(scene.data.ctrl[:7], expected, rtol=0, atol=1e-9)
        robot.step()
        np.testing.assert_allclose(scene.data.qfrc_actuator[:7], expected, rtol=0, atol=1e-9)


def test_gravity_compensation_loop_holds_the_arm(gen3) -> None:
    scene, robot = gen3
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.gravity_compensation = True
    scene.set_actuator_ctrl("g_fingers_actuator", 255.0)
    for _ in range(500):
        robot.update()
        robot.step()
    robot.update()
    held = np.abs(robot.jnt_pos_msr - HOME).max()
    assert held < 5e-3  # what the closing fingers' reaction moves it
    robot.gravity_compensation = False  # without it the same loop lets the arm fall
    for _ in range(500):
        robot.update()
        robot.step()
    robot.update()
    assert np.abs(robot.jnt_pos_msr - HOME).max() > 20 * held


def test_gravity_compensation_is_for_torque_mode_only(gen3) -> None:
    _, robot = gen3
    with pytest.raises(ValueError, match="gravity_compensation works in TORQUE mode only"):
        robot.gravity_compensation = True
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.gravity_compensation = True
    with pytest.raises(ValueError, match="VELOCITY: gravity_compensation is on"):
        robot.ctrl_mode = mjk.CtrlMode.VELOCITY
    with pytest.raises(ValueError, match="True or False"):
        robot.gravity_compensation = "yes"


def test_gravcomp_bodies_are_not_compensated_twice() -> None:
    """MuJoCo cancels half of l1's and all of l2's weight itself; the Robot adds the rest."""
    arm = mjk.RobotSpec(path=str(ASSETS_DIR / "gravcomp_arm.xml"), pos=[0.0, 0.0, 1.0])
    with mjk.Scene.build(base_spec(robots=[arm])) as scene:
        robot = scene.create_robot("base", "l3")
        robot.set_joint_pos([0.4, -0.6, 0.3])
        robot.ctrl_mode = mjk.CtrlMode.TORQUE
        robot.gravity_compensation = True
        for _ in range(500):
            robot.update()
            robot.step()
        robot.update()
        assert np.abs(robot.jnt_pos_msr - [0.4, -0.6, 0.3]).max() < 1e-6
        # l2 is fully held by MuJoCo: gravity on j2 is l3's weight alone, by hand:
        # 0.3 kg at the capsule's middle, 0.05 m from j2's axis through l3's anchor.
        data = scene.data
        l3 = scene.body_id("l3")
        lever = data.xipos[l3] - data.xanchor[scene.model.joint("j2").id]
        axis = data.xaxis[scene.model.joint("j2").id]
        by_hand = -axis @ np.cross(lever, [0.0, 0.0, -9.81 * 0.3])
        assert robot.gravity_torques()[1] == pytest.approx(by_hand, abs=1e-9)


def test_effort_limits_come_from_the_actuators(gen3, ur5) -> None:
    _, robot = gen3
    # Gen3's actuators: forcerange ±105 (joints 1-4) and ±52 (joints 5-7); the 2F-85's
    # fingers have none of their own (a tendon actuator drives them).
    assert robot.model.effortLimit.tolist() == [105.0] * 4 + [52.0] * 3 + [np.inf] * 8
    assert robot.model.lowerEffortLimit[:7].tolist() == [-105.0] * 4 + [-52.0] * 3
    _, arm = ur5
    urdf = ET.parse(example_robot_data_path("ur_description/urdf/ur5_robot.urdf"))
    effort = {
        j.get("name"): float(j.find("limit").get("effort"))
        for j in urdf.iter("joint")
        if j.find("limit") is not None
    }
    assert arm.model.effortLimit.tolist() == [effort[name] for name in arm.joint_names]
    speed = {
        j.get("name"): float(j.find("limit").get("velocity"))
        for j in urdf.iter("joint")
        if j.find("limit") is not None
    }
    assert arm.model.velocityLimit.tolist() == [speed[name] for name in arm.joint_names]
    assert np.isinf(robot.model.velocityLimit).all()  # MJCF robots carry none
    geared = mjk.RobotSpec(path=str(ASSETS_DIR / "gravcomp_arm.xml"))
    with mjk.Scene.build(base_spec(robots=[geared])) as scene:
        # m1: forcerange ±10 with gear 2
        assert scene.create_robot("base", "l3").model.effortLimit.tolist() == [20.0, 8.0, 3.0]


def test_reload_inertias_follows_run_time_mass_edits(gen3) -> None:
    scene, robot = gen3
    robot.update()
    dofs = np.arange(7)
    scene.model.body_mass[scene.body_id("bracelet_link")] += 0.8
    scene.model.body_ipos[scene.body_id("half_arm_2_link")] += [0.01, 0.0, 0.02]
    scene.forward()
    assert np.abs(robot.gravity_torques() - _mujoco_gravity(scene, dofs)).max() > 1e-2
    robot.reload_inertias()
    np.testing.assert_allclose(robot.gravity_torques(), _mujoco_gravity(scene, dofs), atol=1e-9)


def test_env_reset_reloads_inertias(tutorial_scene) -> None:
    env = tutorial_scene(mjk.Env)
    robot = env.create_robot("base_link", "bracelet_link", tool=gripper_tool())
    env.model.body_mass[env.body_id("g_base")] *= 2.0
    env.reset()
    robot.set_joint_pos(HOME)
    np.testing.assert_allclose(
        robot.gravity_torques(), _mujoco_gravity(env, np.arange(7)), rtol=0, atol=1e-9
    )


def test_gravity_compensation_survives_a_rebuild(gen3) -> None:
    scene, robot = gen3
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.gravity_compensation = True
    robot.update()
    scene.add_object(mjk.SceneObject(name="ball", shape=mjk.Shape.SPHERE, size=[0.02], mass=0.1))
    expected = _mujoco_gravity(scene, np.arange(7))
    robot.step()  # the first step on the new model already carries gravity
    np.testing.assert_allclose(scene.data.qfrc_actuator[:7], expected, rtol=0, atol=1e-9)


@pytest.mark.parametrize("mode", ["seed", "gravity_compensation", "position"])
def test_control_loops_retain_no_memory(gen3, mode: str) -> None:
    """Nothing accumulates per step: 2000 more steps leave no more memory allocated."""
    import tracemalloc

    _, robot = gen3
    robot.ctrl_mode = mjk.CtrlMode.POSITION if mode == "position" else mjk.CtrlMode.TORQUE
    robot.gravity_compensation = mode == "gravity_compensation"
    home = np.array(HOME)

    def run(steps: int) -> None:
        for _ in range(steps):
            robot.update()
            if mode == "seed":
                robot.jnt_trq_cmd = robot.gravity_torques()
            elif mode == "position":
                robot.jnt_pos_cmd = home
            robot.step()

    tracemalloc.start()
    run(100)
    before = tracemalloc.take_snapshot()
    run(2000)
    after = tracemalloc.take_snapshot()
    tracemalloc.stop()
    mjkdl_files = [s for s in after.compare_to(before, "filename") if "mjkdl" in str(s)]
    assert sum(s.size_diff for s in mjkdl_files) <= 0


def test_scene_does_not_import_the_robot_layer() -> None:
    """Imports flow one way: scene.py names Robot for type checking only."""
    import ast

    import mjkdl.scene

    tree = ast.parse(Path(mjkdl.scene.__file__).read_text())
    guarded = {
        id(node)
        for block in ast.walk(tree)
        if isinstance(block, ast.If) and "TYPE_CHECKING" in ast.unparse(block.test)
        for node in ast.walk(block)
    }
    imports = [
        node.module
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and id(node) not in guarded
    ]
    assert "robot" not in imports and "chain" not in imports and "ik" not in imports


# ---------------------------------------------------------------------- lifecycle


def test_close_releases_the_joints_for_a_new_handle(gen3) -> None:
    scene, first = gen3
    authored = scene.model.actuator_gainprm[:7].copy()
    first.ctrl_mode = mjk.CtrlMode.TORQUE
    first.update()
    assert scene.model.actuator_biasprm[0, 1] == 0.0  # a motor now
    first.close()
    assert np.array_equal(scene.model.actuator_gainprm[:7], authored)  # servos again
    with pytest.raises(RuntimeError, match="this Robot is closed"):
        first.update()
    second = scene.create_robot("base_link", "bracelet_link")
    second.ctrl_mode = mjk.CtrlMode.TORQUE
    second.update()
    second.jnt_trq_cmd = np.full(7, 0.5)
    second.step()
    assert scene.data.qfrc_actuator[:7].tolist() == [0.5] * 7
    scene.remove_robot(second)
    with pytest.raises(RuntimeError, match="closed"):
        second.jnt_trq_cmd = np.zeros(7)
    with pytest.raises(ValueError, match="not registered"):
        scene.remove_robot(second)


def test_rebuild_binds_only_live_handles(tutorial_scene, monkeypatch) -> None:
    scene = tutorial_scene()
    for _ in range(20):
        scene.create_robot("base_link", "bracelet_link").close()
    live = scene.create_robot("base_link", "bracelet_link")
    bound = []
    original = mjk.Robot._bind

    def counting(self, model, data):
        bound.append(self)
        original(self, model, data)

    monkeypatch.setattr(mjk.Robot, "_bind", counting)
    scene.add_object(mjk.SceneObject(name="ball", shape=mjk.Shape.SPHERE, size=[0.02], mass=0.1))
    assert bound == [live]


# ---------------------------------------------------------------------- errors


def test_unknown_bodies_list_close_matches(tutorial_scene) -> None:
    scene = tutorial_scene()
    with pytest.raises(KeyError, match="bracelet_link"):
        scene.create_robot("base_link", "bracelet_lnk")
    with pytest.raises(KeyError, match=r"no body named 'bse_link'.*base_link"):
        scene.create_robot("bse_link", "bracelet_link")


@pytest.mark.parametrize(
    ("args", "kw", "field"),
    [
        ((None, "bracelet_link"), {}, "base_body"),
        (("base_link", 5), {}, "tip_body"),
        (("base_link", "bracelet_link"), {"prefix": None}, "prefix"),
        (("base_link", "bracelet_link"), {"tool": "g_base"}, "tool"),
    ],
)
def test_create_robot_argument_types(tutorial_scene, args, kw, field) -> None:
    scene = tutorial_scene()
    with pytest.raises(ValueError, match=field):
        scene.create_robot(*args, **kw)


def test_base_must_be_an_ancestor_of_tip(tutorial_scene) -> None:
    scene = tutorial_scene()
    with pytest.raises(ValueError, match="not an ancestor"):
        scene.create_robot("bracelet_link", "base_link")


def test_tool_errors(tutorial_scene) -> None:
    scene = tutorial_scene()
    with pytest.raises(KeyError, match="g_pinc"):
        scene.create_robot("base_link", "bracelet_link", tool=mjk.ToolFrameSpec(tcp_site="g_pinc"))
    with pytest.raises(ValueError, match="not on the chain or below its tip"):
        scene.create_robot(
            "base_link", "bracelet_link", tool=mjk.ToolFrameSpec(tcp_site="table/table_top")
        )
    with pytest.raises(ValueError, match="moves relative to the chain through joints"):
        scene.create_robot(
            "base_link", "half_arm_1_link", tool=mjk.ToolFrameSpec(tcp_site="g_pinch")
        )
    with pytest.raises(ValueError, match="not mounted below the tip"):
        scene.create_robot(
            "base_link", "bracelet_link", tool=mjk.ToolFrameSpec(tool_body="shoulder_link")
        )
    robot = scene.create_robot("base_link", "bracelet_link")
    with pytest.raises(KeyError, match="no force/torque sensor named 'wrist'"):
        robot.ft_sensor("wrist")


def test_base_held_by_an_equality_constraint_is_refused() -> None:
    platform = mjk.SceneObject(
        name="platform", mjcf_path=str(ASSETS_DIR / "platform_welded.xml"), pos=[0, 0, 0.5]
    )
    site = mjk.scene_object_site_name(platform, "mount")
    arm = mjk.RobotSpec(
        path=menagerie("kinova_gen3"), attach_to=mjk.AttachTarget(mjk.AttachKind.Site, site)
    )
    scene = mjk.Scene.build(base_spec(objects=[platform], robots=[arm]))
    with scene, pytest.raises(ValueError, match="held by equality constraint 'platform/hold'"):
        scene.create_robot("base_link", "bracelet_link")


def test_joint_type_pinocchio_cannot_represent_is_named(tutorial_scene) -> None:
    scene = tutorial_scene()
    finger = scene.model.joint("g_right_driver_joint").id
    scene.model.jnt_type[finger] = 7  # no such MuJoCo joint type: as a future one would be
    with pytest.raises(ValueError, match=r"'g_right_driver_joint'.*cannot represent"):
        scene.create_robot("base_link", "bracelet_link")


@pytest.mark.parametrize("port", ["jnt_pos_cmd", "jnt_vel_cmd", "jnt_trq_cmd"])
def test_commands_mujoco_would_zero_are_refused(gen3, port: str) -> None:
    _, robot = gen3
    for huge in (1e300, 2e10):
        with pytest.raises(ValueError, match=rf"{port} must be within ±1e\+10"):
            setattr(robot, port, [huge] + [0.0] * 6)
    setattr(robot, port, np.full(7, 9e9))  # several large values, each accepted
    assert getattr(robot, port).tolist() == [9e9] * 7


def test_set_joint_pos_outside_the_range_names_the_joint(gen3) -> None:
    scene, robot = gen3
    q = np.array(HOME)
    q[1] = 2.5  # joint_2's range is ±2.24
    with pytest.raises(ValueError, match=r"joint 'joint_2' at 2.5 is outside its range"):
        robot.set_joint_pos(q)
    assert scene.data.qpos[1] == pytest.approx(HOME[1])  # nothing written


def test_ik_refuses_a_target_that_is_not_finite(gen3) -> None:
    _, robot = gen3
    for bad in (np.nan, np.inf):
        target = robot.fk_frame()
        target.translation = np.array([0.3, bad, 0.5])
        with pytest.raises(ValueError, match="target must be finite"):
            robot.ik(target)


FT_TOOL = """
<mujoco model="ft_tool">
  <worldbody>
    <body name="plate">
      <inertial pos="0 0 0.01" mass="0.2" diaginertia="1e-4 1e-4 1e-4"/>
      <geom type="cylinder" size="0.03 0.01" pos="0 0 0.01"/>
      <site name="ft_site" pos="0 0 0"/>
      <site name="mount" pos="0 0 0.02"/>
    </body>
  </worldbody>
  <sensor>
    <force name="force" site="ft_site"/>
    <torque name="torque" site="ft_site"/>
  </sensor>
</mujoco>
"""


def _gen3_with_ft_plate(tmp_path) -> mjk.Scene:
    """A Gen3 with a small plate carrying force and torque sensors at its pinch site."""
    tool_xml = tmp_path / "ft_tool.xml"
    tool_xml.write_text(FT_TOOL)
    ft = mjk.AttachmentSpec(
        mjcf_path=str(tool_xml),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Site, "pinch_site"),
        prefix="ft_",
    )
    arm = mjk.RobotSpec(path=menagerie("kinova_gen3"), attachments=[ft])
    return mjk.Scene.build(base_spec(robots=[arm]))


def test_ft_sensor_reads_site_frame_wrench(tmp_path) -> None:
    scene = _gen3_with_ft_plate(tmp_path)
    sensor = mjk.ForceTorqueSensorSpec(
        name="wrist", force_sensor="ft_force", torque_sensor="ft_torque"
    )
    tool = mjk.ToolFrameSpec(tool_body="ft_plate", tcp_site="ft_mount", ft_sensors=[sensor])
    robot = scene.create_robot("base_link", "bracelet_link", tool=tool)
    robot.set_joint_pos(HOME)
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.update()
    robot.jnt_trq_cmd = robot.gravity_torques()
    robot.update()
    scene.forward()  # gravity-compensated: the arm does not accelerate
    wrench = robot.ft_sensor("wrist")
    assert isinstance(wrench, pin.Force)
    # At rest the parent holds the 0.2 kg plate up: its weight, upwards, at the plate's centre
    # of mass, in the sensor site's axes (computed from the plate's mass and pose only).
    site = scene.site_id("ft_ft_site")
    rot = scene.data.site_xmat[site].reshape(3, 3)
    weight = np.array([0.0, 0.0, 0.2 * 9.81])
    com = scene.data.xipos[scene.body_id("ft_plate")] - scene.data.site_xpos[site]
    np.testing.assert_allclose(wrench.linear, rot.T @ weight, rtol=0, atol=1e-6)
    np.testing.assert_allclose(wrench.angular, rot.T @ np.cross(com, weight), rtol=0, atol=1e-8)
    assert np.linalg.norm(wrench.angular) == pytest.approx(0.01 * 0.2 * 9.81, rel=1e-6)
    scene.close()


def test_closed_scene_makes_robot_raise(tutorial_scene) -> None:
    scene = tutorial_scene()
    robot = scene.create_robot("base_link", "bracelet_link")
    scene.close()
    for call in (
        robot.update,
        robot.step,
        robot.fk_frame,
        robot.jacobian,
        robot.gravity_torques,
        lambda: robot.jnt_pos_msr,
        lambda: setattr(robot, "jnt_trq_cmd", [0.0] * 7),
        lambda: setattr(robot, "ctrl_mode", mjk.CtrlMode.TORQUE),
    ):
        with pytest.raises(RuntimeError, match="closed"):
            call()


def _passive_robot(tmp_path, actuators: str) -> tuple[mjk.Scene, mjk.Robot]:
    path = tmp_path / "arm.xml"
    path.write_text(two_link_arm(actuators))
    scene = mjk.Scene.build(base_spec(robots=[mjk.RobotSpec(path=str(path))]))
    return scene, scene.create_robot("base", "l2")


def test_unactuated_chain_takes_torques_as_applied_forces(tmp_path) -> None:
    scene, robot = _passive_robot(tmp_path, "")
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.update()
    robot.jnt_trq_cmd = [0.5, -0.25]
    robot.step()
    assert scene.data.qfrc_applied[:2].tolist() == [0.5, -0.25]
    robot.update()
    assert robot.jnt_trq_msr.tolist() == [0.5, -0.25]
    robot.ctrl_mode = mjk.CtrlMode.POSITION
    with pytest.raises(ValueError, match="POSITION mode needs an actuator on every joint"):
        robot.update()
    scene.close()


def test_partly_actuated_chain_is_refused_for_control_only(tmp_path) -> None:
    scene, robot = _passive_robot(tmp_path, '<actuator><motor joint="j1"/></actuator>')
    robot.set_joint_pos([0.3, 0.2])
    assert robot.jacobian().shape == (6, 2)  # kinematics still work
    with pytest.raises(ValueError, match="joints j2 have no actuator"):
        robot.update()
    scene.close()


def test_every_robots_commands_apply_in_the_same_step() -> None:
    first = mjk.RobotSpec(path=menagerie("kinova_gen3"), pos=[-0.6, 0.0, 0.0])
    second = mjk.RobotSpec(path=menagerie("kinova_gen3"), prefix="r2_", pos=[0.6, 0.0, 0.0])
    with mjk.Scene.build(base_spec(robots=[first, second])) as scene:
        a = scene.create_robot("base_link", "bracelet_link")
        b = scene.create_robot("base_link", "bracelet_link", prefix="r2_")
        for robot in (a, b):
            robot.ctrl_mode = mjk.CtrlMode.TORQUE
            robot.update()
        a.jnt_trq_cmd = np.full(7, 1.0)
        b.jnt_trq_cmd = np.full(7, 2.0)
        a.step()  # steps the scene: b's command goes out in this step too
        assert scene.data.qfrc_actuator[:7].tolist() == [1.0] * 7
        assert scene.data.qfrc_actuator[7:14].tolist() == [2.0] * 7


def test_second_handle_reads_but_may_not_drive_the_same_joints(gen3) -> None:
    scene, first = gen3
    first.ctrl_mode = mjk.CtrlMode.TORQUE
    first.update()
    reader = scene.create_robot("base_link", "half_arm_2_link")
    reader.set_joint_pos([0.3, -0.4, 0.2])  # reading and setting state is fine
    tip = scene.body_frame("half_arm_2_link")
    assert np.abs(reader.fk_frame().translation - tip.translation).max() < 1e-12
    assert reader.jnt_pos_msr.tolist() == [0.3, -0.4, 0.2]
    with pytest.raises(ValueError, match="already driven by the Robot 'base_link'"):
        reader.update()
    assert scene.model.actuator_gainprm[0, 0] == 1.0  # the first handle's TORQUE mode stands


def test_mode_change_then_step_applies_the_new_mode(gen3) -> None:
    scene, robot = gen3
    robot.update()  # POSITION
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.jnt_trq_cmd = np.full(7, 0.5)
    robot.step()
    assert scene.data.qfrc_actuator[:7].tolist() == [0.5] * 7


def test_unused_handle_leaves_actuators_alone(tutorial_scene) -> None:
    scene = tutorial_scene()
    authored = scene.model.actuator_biasprm[:7].copy()
    scene.data.ctrl[:7] = HOME
    robot = scene.create_robot("base_link", "bracelet_link")
    scene.step(5)
    robot.fk_frame()
    assert np.array_equal(scene.model.actuator_biasprm[:7], authored)
    assert np.array_equal(scene.data.ctrl[:7], HOME)


def test_gravity_override_must_be_a_finite_number(gen3) -> None:
    _, robot = gen3
    for bad, why in (("abc", "a number"), (np.nan, "finite"), (np.inf, "finite")):
        with pytest.raises(ValueError) as err:
            robot.gravity_torques(bad)
        assert str(err.value) == f"gravity_torques: gravity_z must be {why}, got {bad!r}"


def test_ft_sensor_kind_is_checked(tmp_path) -> None:
    scene = _gen3_with_ft_plate(tmp_path)
    swapped = mjk.ForceTorqueSensorSpec(
        name="wrist", force_sensor="ft_torque", torque_sensor="ft_force"
    )
    with pytest.raises(ValueError, match="'ft_torque' is not a force sensor"):
        scene.create_robot(
            "base_link", "bracelet_link", tool=mjk.ToolFrameSpec(ft_sensors=[swapped])
        )
    scene.close()


UNNAMED = """
<mujoco>
  <worldbody>
    <body name="base">
      <body pos="0 0 0.1">
        <joint axis="0 0 1"/>
        <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.02"/>
        <body pos="0.5 0 0">
          <joint axis="0 1 0"/>
          <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/>
          <body name="tip" pos="0.3 0 0">
            <body pos="0.01 0 0.1">
              <geom type="sphere" size="0.02"/>
              <site name="tcp"/>
            </body>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_unnamed_bodies_keep_the_tcp_where_mujoco_has_it(tmp_path) -> None:
    path = tmp_path / "unnamed.xml"
    path.write_text(UNNAMED)
    with mjk.Scene.build(base_spec(robots=[mjk.RobotSpec(path=str(path))])) as scene:
        robot = scene.create_robot("base", "tip", tool=mjk.ToolFrameSpec(tcp_site="tcp"))
        robot.set_joint_pos([0.4, -0.3])
        site = scene.data.site_xpos[scene.site_id("tcp")]
        assert np.abs(robot.fk_frame().translation - site).max() < 1e-12


# ---------------------------------------------------------------------- TCP offsets


def _euler_matrix(deg) -> np.ndarray:
    """MuJoCo's default intrinsic xyz Euler angles (degrees) as a rotation matrix."""
    rx, ry, rz = (
        pin.AngleAxis(np.radians(a), axis).matrix() for a, axis in zip(deg, np.eye(3), strict=True)
    )
    return rx @ ry @ rz


@pytest.mark.parametrize(
    ("tcp_pos", "tcp_euler"),
    [([0.0, 0.0, 0.1034], [0.0, 0.0, 0.0]), ([0.01, -0.02, 0.1], [10, -20, 45])],
)
def test_tcp_offset_from_the_tip_body_matches_mujoco(tcp_pos, tcp_euler) -> None:
    """Panda's hand has no site: the TCP is an offset from the `hand` body."""
    arm = mjk.RobotSpec(path=menagerie("franka_emika_panda"))
    tool = mjk.ToolFrameSpec(tcp_pos=tcp_pos, tcp_euler=tcp_euler)
    with mjk.Scene.build(base_spec(robots=[arm])) as scene:
        robot = scene.create_robot("link0", "hand", tool=tool)
        assert robot.has_tcp_frame
        model, data = scene.model, scene.data
        hand = scene.body_id("hand")
        dofs = [model.joint(n).dofadr[0] for n in robot.joint_names]
        lower, upper = robot.joint_limits.T
        rng = np.random.default_rng(7)
        jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        for _ in range(20):
            robot.set_joint_pos(rng.uniform(lower, upper))
            rot = data.xmat[hand].reshape(3, 3) @ _euler_matrix(tcp_euler)
            point = data.xpos[hand] + data.xmat[hand].reshape(3, 3) @ np.asarray(tcp_pos)
            tcp = robot.fk_frame()
            assert np.abs(tcp.translation - point).max() < 1e-9
            assert np.abs(tcp.rotation - rot).max() < 1e-9
            mujoco.mj_jac(model, data, jacp, jacr, point, hand)
            expected = np.vstack([jacp[:, dofs], jacr[:, dofs]])
            assert np.abs(robot.jacobian() - expected).max() < 1e-9


def test_tcp_offset_from_a_site_matches_mujoco(gen3) -> None:
    scene, _ = gen3
    pos, euler = [0.0, 0.01, 0.02], [0.0, 30.0, -15.0]
    tool = mjk.ToolFrameSpec(tool_body="g_base", tcp_site="g_pinch", tcp_pos=pos, tcp_euler=euler)
    robot = scene.create_robot("base_link", "bracelet_link", tool=tool)
    model, data = scene.model, scene.data
    site = scene.site_id("g_pinch")
    body = model.site_bodyid[site]
    dofs = [model.joint(n).dofadr[0] for n in robot.joint_names]
    lower, upper = robot.joint_limits.T
    rng = np.random.default_rng(8)
    jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    for _ in range(20):
        robot.set_joint_pos(rng.uniform(np.maximum(lower, -3.0), np.minimum(upper, 3.0)))
        site_rot = data.site_xmat[site].reshape(3, 3)
        point = data.site_xpos[site] + site_rot @ np.asarray(pos)
        tcp = robot.fk_frame()
        assert np.abs(tcp.translation - point).max() < 1e-9
        assert np.abs(tcp.rotation - site_rot @ _euler_matrix(euler)).max() < 1e-9
        mujoco.mj_jac(model, data, jacp, jacr, point, body)
        expected = np.vstack([jacp[:, dofs], jacr[:, dofs]])
        assert np.abs(robot.jacobian() - expected).max() < 1e-9


# ---------------------------------------------------------------------- small arms, every path

_OMEGA = 2 * np.pi * 10.0  # the synthesised servo's bandwidth (10 Hz)


def _small_arm(body_l2: str, side: str, actuators: str) -> str:
    """Two links on y axes (l1: j1, l2: j2); `side` is a branch on l1 declared before l2."""
    return f"""
<mujoco model="small_arm">
  <worldbody>
    <body name="base" pos="0 0 1">
      <geom type="cylinder" size="0.05 0.02"/>
      <body name="l1" pos="0 0 0.05">
        <joint name="j1" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0.05" size="0.02" mass="1"/>
        {side}
        <body name="l2" pos="0.3 0 0.05" {body_l2}>
          <joint name="j2" axis="0 1 0"/>
          <geom type="capsule" fromto="0 0 0 0.25 0 0.1" size="0.02" mass="0.5"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>{actuators}</actuator>
</mujoco>
"""


_SIDE = """<body name="bob" pos="0.15 0 0">
          <joint name="swing" axis="1 0 0"/>
          <geom type="capsule" fromto="0 0 0 0 0 -0.2" size="0.01" mass="0.4"
                contype="0" conaffinity="0"/>
        </body>"""
_MOTORS = '<motor name="m1" joint="j1" gear="2"/><motor name="m2" joint="j2"/>'
# update()'s fast paths (contiguous actuators), the general path (chain actuators 0 and 2,
# arm dofs 0 and 2, arm not contiguous in the model), and gravcomp bodies (general path).
_ARMS = {
    "fast": _small_arm("", "", _MOTORS),
    "general": _small_arm(
        "",
        _SIDE,
        '<motor name="m1" joint="j1" gear="2"/><motor name="ms" joint="swing"/>'
        '<motor name="m2" joint="j2"/>',
    ),
    "gravcomp": _small_arm('gravcomp="0.5"', "", _MOTORS),
}


def _arm_scene(tmp_path, xml: str, **kw) -> mjk.Scene:
    path = tmp_path / "arm.xml"
    path.write_text(xml)
    return mjk.Scene.build(base_spec(robots=[mjk.RobotSpec(path=str(path), **kw)]))


def _ids(scene: mjk.Scene, robot: mjk.Robot) -> tuple[np.ndarray, np.ndarray]:
    """The chain's actuators and dofs, found by name in MuJoCo's model."""
    model = scene.model
    joints = [model.joint(n).id for n in robot.joint_names]
    acts = [next(a for a in range(model.nu) if model.actuator_trnid[a, 0] == j) for j in joints]
    return np.array(acts), np.array([model.jnt_dofadr[j] for j in joints])


def _want_ctrl(scene, acts, dofs, mode, gravcomp, ff, cmd) -> np.ndarray:
    """The controls each mode should write, from MuJoCo's gravity and the actuators' gains."""
    g = _mujoco_gravity(scene, dofs)
    if mode is mjk.CtrlMode.TORQUE:
        return cmd + g if gravcomp else np.array(cmd, dtype=float)
    gear = scene.model.actuator_gear[acts, 0]
    k = -scene.model.actuator_biasprm[acts, 1 if mode is mjk.CtrlMode.POSITION else 2]
    return cmd + g / (gear * gear * k) if ff else np.array(cmd, dtype=float)


_PORTS = {
    mjk.CtrlMode.TORQUE: "jnt_trq_cmd",
    mjk.CtrlMode.POSITION: "jnt_pos_cmd",
    mjk.CtrlMode.VELOCITY: "jnt_vel_cmd",
}
_CASES = {
    "torque": (mjk.CtrlMode.TORQUE, False, True),
    "gravity_compensation": (mjk.CtrlMode.TORQUE, True, True),
    "position": (mjk.CtrlMode.POSITION, False, True),
    "position_no_feedforward": (mjk.CtrlMode.POSITION, False, False),
    "velocity": (mjk.CtrlMode.VELOCITY, False, True),
}


@pytest.mark.parametrize("case", list(_CASES))
@pytest.mark.parametrize("arm", list(_ARMS))
def test_every_mode_writes_mujocos_controls_on_every_path(tmp_path, arm: str, case: str) -> None:
    mode, gravcomp, ff = _CASES[case]
    with _arm_scene(tmp_path, _ARMS[arm]) as scene:
        model, data = scene.model, scene.data
        mass0 = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, mass0)  # at the state the handle is built in
        robot = scene.create_robot("base", "l2")
        acts, dofs = _ids(scene, robot)
        robot.set_joint_pos([0.4, -0.7])
        robot.sync_commands()
        robot.update()  # POSITION first: its feed-forward and gravity are then not zero
        robot.ctrl_mode = mode
        robot.gravity_compensation = gravcomp
        robot.gravity_feedforward = ff
        robot.update()  # configures the actuators for the mode
        gear = np.array([2.0, 1.0])
        gain, bias = np.zeros((2, 10)), np.zeros((2, 10))
        mass = mass0[dofs, dofs]
        if mode is mjk.CtrlMode.TORQUE:
            gain[:, 0] = 1.0 / gear
        elif mode is mjk.CtrlMode.POSITION:
            kp, kv = mass * _OMEGA**2 / gear**2, 2 * mass * _OMEGA / gear**2
            gain[:, 0], bias[:, 1], bias[:, 2] = kp * gear, -kp, -kv
        else:
            kv = 2 * mass * _OMEGA / gear**2
            gain[:, 0], bias[:, 2] = kv * gear, -kv
        np.testing.assert_allclose(model.actuator_gainprm[acts], gain, rtol=1e-12, atol=0)
        np.testing.assert_allclose(model.actuator_biasprm[acts], bias, rtol=1e-12, atol=0)
        assert robot.actuator_ids.tolist() == acts.tolist()
        # What the feed-forward adds to the setpoint per N·m: 1/(gear² k) for a servo.
        k = {mjk.CtrlMode.POSITION: -bias[:, 1], mjk.CtrlMode.VELOCITY: -bias[:, 2]}.get(mode)
        scale = np.ones(2) if k is None else 1.0 / (gear**2 * k)
        np.testing.assert_allclose(robot.gravity_feedforward_scale, scale, rtol=1e-12, atol=0)
        assert not model.actuator_ctrllimited[acts].any()
        held = {mjk.CtrlMode.POSITION: [0.4, -0.7]}.get(mode, [0.0, 0.0])
        want = _want_ctrl(scene, acts, dofs, mode, gravcomp, ff, held)
        np.testing.assert_allclose(data.ctrl[acts], want, rtol=0, atol=1e-9)
        for other in sorted(set(_PORTS.values()) - {_PORTS[mode]}):
            setattr(robot, other, np.array([5.0, -7.0]))  # a port the mode does not drive
            with pytest.warns(mjk.IgnoredCommandWarning, match=f"^{other} was written"):
                robot.step()
            np.testing.assert_allclose(data.ctrl[acts], want, rtol=0, atol=1e-9)
        robot.update()
        cmd = np.array([0.3, -0.2])
        setattr(robot, _PORTS[mode], cmd)
        want = _want_ctrl(scene, acts, dofs, mode, gravcomp, ff, cmd)
        robot.step()
        np.testing.assert_allclose(data.ctrl[acts], want, rtol=0, atol=1e-9)
        if mode is mjk.CtrlMode.TORQUE:
            np.testing.assert_allclose(data.qfrc_actuator[dofs], want, rtol=0, atol=1e-9)
        for _ in range(2):  # the state has moved: every update() writes the mode anew
            robot.update()
            want = _want_ctrl(scene, acts, dofs, mode, gravcomp, ff, cmd)
            np.testing.assert_allclose(data.ctrl[acts], want, rtol=0, atol=1e-9)
            assert robot.jnt_pos_msr.tolist() == data.qpos[dofs].tolist()
            assert robot.jnt_vel_msr.tolist() == data.qvel[dofs].tolist()
            assert robot.jnt_trq_msr.tolist() == data.qfrc_actuator[dofs].tolist()
            robot.step()
        robot.set_joint_pos([-0.5, 0.9])
        robot.update()
        want = _want_ctrl(scene, acts, dofs, mode, gravcomp, ff, cmd)
        np.testing.assert_allclose(data.ctrl[acts], want, rtol=0, atol=1e-9)


def test_command_assignment_starts_driving(tmp_path) -> None:
    with _arm_scene(tmp_path, _ARMS["fast"]) as scene:
        robot = scene.create_robot("base", "l2")
        acts, dofs = _ids(scene, robot)
        robot.jnt_pos_cmd = [0.3, -0.2]  # the first use of the handle
        q0 = scene.data.qpos.copy()
        robot.step()
        assert (scene.model.actuator_biasprm[acts, 1] < 0).all()  # position servos now
        moved = scene.data.qpos.copy()
        scene.data.qpos[:] = q0  # the feed-forward is the gravity before the step
        want = _want_ctrl(scene, acts, dofs, mjk.CtrlMode.POSITION, False, True, [0.3, -0.2])
        scene.data.qpos[:] = moved
        np.testing.assert_allclose(scene.data.ctrl[acts], want, rtol=0, atol=1e-9)


def test_sync_commands_holds_the_measured_state(tmp_path) -> None:
    assert mjk.Robot.jnt_pos_cmd.__doc__ == "Joint position command (POSITION mode)."
    with _arm_scene(tmp_path, _ARMS["fast"]) as scene:
        robot = scene.create_robot("base", "l2")
        robot.jnt_vel_cmd = [0.5, 0.25]
        robot.jnt_trq_cmd = [1.5, -2.5]
        robot.set_joint_pos([0.4, -0.7])
        robot.sync_commands()
        assert robot.jnt_pos_cmd.tolist() == [0.4, -0.7]
        assert robot.jnt_vel_cmd.tolist() == [0.0, 0.0]
        assert robot.jnt_trq_cmd.tolist() == [0.0, 0.0]


def test_command_values_are_checked_on_every_path(tmp_path) -> None:
    with _arm_scene(tmp_path, _ARMS["fast"]) as scene:
        robot = scene.create_robot("base", "l2")
        robot.ctrl_mode = mjk.CtrlMode.TORQUE
        robot.update()  # the fast path: float64 arrays of the right shape skip _assign
        with pytest.raises(mjk.SpecError) as err:
            robot.jnt_trq_cmd = np.array(["a", "b"])
        assert str(err.value) == (
            "jnt_trq_cmd must hold real numbers, got array(['a', 'b'], dtype='<U1')"
        )
        with pytest.raises(mjk.SpecError) as err:
            robot.jnt_pos_cmd = ["a", "b"]
        assert str(err.value) == "jnt_pos_cmd must hold real numbers, got ['a', 'b']"
        with pytest.raises(mjk.SpecError) as err:
            robot.jnt_trq_cmd = np.ones(1)
        assert str(err.value) == "jnt_trq_cmd needs 2 values (one per joint), got shape (1,)"
        with pytest.raises(mjk.SpecError) as err:
            robot.set_joint_pos(np.array(["a", "b"]))
        assert str(err.value) == (
            "set_joint_pos(q) must hold real numbers, got array(['a', 'b'], dtype='<U1')"
        )
        robot.jnt_trq_cmd = [1e10, 1e10]  # MuJoCo's largest control is still one
        assert robot.jnt_trq_cmd.tolist() == [1e10, 1e10]
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # its square overflows: no warning, a clear error
            with pytest.raises(mjk.SpecError, match=r"jnt_trq_cmd must be within ±1e\+10 "):
                robot.jnt_trq_cmd = [1e200, 0.0]
        for call, name in (
            (lambda: robot.jacobian(q=[0.0]), "q"),
            (lambda: robot.mass_matrix(q=[0.0]), "q"),
            (lambda: robot.nonlinear_effects(v=[0.0]), "v"),
            (lambda: robot.inverse_dynamics([0.0, 0.0], [0.0], [0.0, 0.0]), "v"),
            (lambda: robot.inverse_dynamics([0.0, 0.0], [0.0, 0.0], [0.0]), "a"),
        ):
            with pytest.raises(mjk.SpecError) as err:
                call()
            assert str(err.value) == f"{name} needs 2 values (one per joint), got shape (1,)"


@pytest.mark.parametrize(
    ("value", "shown"),
    [
        ([True, False], "[True, False]"),
        (np.array([1j, 0]), "array([0.+1.j, 0.+0.j])"),
        (["1", "2"], "['1', '2']"),
        ([[1.0], [2.0, 3.0]], "[[1.0], [2.0, 3.0]]"),
        ([None, 1.0], "[None, 1.0]"),
    ],
)
def test_commands_and_arguments_refuse_what_is_not_a_real_number(tmp_path, value, shown) -> None:
    with _arm_scene(tmp_path, _ARMS["fast"]) as scene:
        robot = scene.create_robot("base", "l2")
        for call, name in (
            (lambda: setattr(robot, "jnt_trq_cmd", value), "jnt_trq_cmd"),
            (lambda: setattr(robot, "jnt_pos_cmd", value), "jnt_pos_cmd"),
            (lambda: robot.fk_frame(value), "q"),
            (lambda: robot.set_joint_pos(value), "set_joint_pos(q)"),
        ):
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # no ComplexWarning on the way
                with pytest.raises(mjk.SpecError) as err:
                    call()
            assert str(err.value) == f"{name} must hold real numbers, got {shown}"
        assert robot.jnt_trq_cmd.tolist() == [0.0, 0.0]  # nothing of it was kept


def test_infinite_positions_are_refused_like_nan(tmp_path) -> None:
    with _arm_scene(tmp_path, _ARMS["fast"]) as scene:
        robot = scene.create_robot("base", "l2")
        for call, name in (
            (lambda q: robot.fk_frame(q), "q"),
            (lambda q: robot.jacobian(q), "q"),
            (lambda q: robot.mass_matrix(q), "q"),
            (lambda q: robot.nonlinear_effects(v=q), "v"),
            (lambda q: robot.set_joint_pos(q), "set_joint_pos(q)"),
        ):
            for bad in ([np.inf, 0.0], [0.0, -np.inf]):
                with pytest.raises(mjk.SpecError) as err:
                    call(bad)
                assert str(err.value) == f"{name} must be finite, got {np.array(bad)!r}"
        assert robot.fk_frame([1e150, 0.0]) is not None  # finite, however large, is a position


def test_robot_switches_and_lookups_refuse_wrong_types(tmp_path) -> None:
    with _arm_scene(tmp_path, _ARMS["fast"]) as scene:
        robot = scene.create_robot("base", "l2")
        with pytest.raises(mjk.SpecError) as err:
            robot.gravity_feedforward = "no"
        assert str(err.value) == "gravity_feedforward must be True or False, got 'no'"
        assert robot.gravity_feedforward is True
        robot.gravity_feedforward = np.False_
        assert robot.gravity_feedforward is False
        with pytest.raises(mjk.SpecError) as err:
            robot.gravity_torques(gravity_z=True)
        assert str(err.value) == "gravity_torques: gravity_z must be a number, got True"
        with pytest.raises(mjk.SpecError) as err:
            robot.gravity_torques(gravity_z="-9.81")
        assert str(err.value) == "gravity_torques: gravity_z must be a number, got '-9.81'"
        with pytest.raises(mjk.SpecError) as err:
            robot.set_joint_pos([0.0, 0.0], call_forward="no")
        assert str(err.value) == "set_joint_pos: call_forward must be True or False, got 'no'"
        for name, shown in ((3, "'3'"), (["wrist"], "\"['wrist']\"")):
            with pytest.raises(KeyError) as err:
                robot.ft_sensor(name)
            assert err.value.args[0].startswith(f"no force/torque sensor named {shown}")
        robot.close()
        for attempt in (
            lambda: robot.gravity_feedforward,
            lambda: setattr(robot, "gravity_feedforward", True),
        ):
            with pytest.raises(RuntimeError, match="this Robot is closed"):
                attempt()


def test_dynamics_at_an_explicit_state_match_mujoco(tmp_path) -> None:
    with _arm_scene(tmp_path, _ARMS["fast"]) as scene:
        robot = scene.create_robot("base", "l2")
        scene.data.qvel[:2] = [0.2, 0.1]
        robot.set_joint_pos([0.4, -0.7])
        robot.update()  # measured: a state other than the one asked about
        q, v, a = np.array([-0.3, 1.1]), np.array([0.5, -0.8]), np.array([1.0, 2.0])
        model, data = scene.model, mujoco.MjData(scene.model)
        data.qpos[:2], data.qvel[:2] = q, v
        mujoco.mj_forward(model, data)
        data.qacc[:2] = a
        mujoco.mj_inverse(model, data)
        mass = np.zeros((2, 2))
        mujoco.mj_fullM(model, data, mass)
        jacp, jacr = np.zeros((3, 2)), np.zeros((3, 2))
        mujoco.mj_jacBody(model, data, jacp, jacr, scene.body_id("l2"))
        np.testing.assert_allclose(robot.jacobian(q), np.vstack([jacp, jacr]), atol=1e-12)
        np.testing.assert_allclose(robot.mass_matrix(q), mass, atol=1e-12)
        np.testing.assert_allclose(robot.nonlinear_effects(q, v), data.qfrc_bias, atol=1e-12)
        np.testing.assert_allclose(robot.inverse_dynamics(q, v, a), data.qfrc_inverse, atol=1e-12)


def test_gravity_with_gravcomp_bodies_after_edits_matches_mujoco(tmp_path) -> None:
    with _arm_scene(tmp_path, _ARMS["gravcomp"]) as scene:
        robot = scene.create_robot("base", "l2")
        robot.set_joint_pos([0.4, -0.7])
        dofs = np.arange(2)
        scene.model.opt.gravity[:] = [1.5, -0.5, -9.81]
        robot.reload_inertias()
        np.testing.assert_allclose(
            robot.gravity_torques(), _mujoco_gravity(scene, dofs), atol=1e-12
        )
        scene.model.opt.gravity[2] = -4.0
        want = _mujoco_gravity(scene, dofs)
        scene.model.opt.gravity[2] = -9.81
        np.testing.assert_allclose(robot.gravity_torques(-4.0), want, atol=1e-12)


def test_authored_position_servos_keep_their_gains(tmp_path) -> None:
    actuators = (
        '<general name="g1" joint="j1" gainprm="50" biasprm="0 -50 -5"/>'  # no bias: a motor
        '<position name="p2" joint="j2" kp="0.5" kv="0.1"/>'
    )
    with _arm_scene(tmp_path, _small_arm("", "", actuators)) as scene:
        mass = np.zeros((2, 2))
        mujoco.mj_fullM(scene.model, scene.data, mass)
        robot = scene.create_robot("base", "l2")
        robot.update()
        gain, bias = scene.model.actuator_gainprm, scene.model.actuator_biasprm
        assert gain[0, 0] == pytest.approx(mass[0, 0] * _OMEGA**2, rel=1e-12)
        assert bias[0, 2] == pytest.approx(-2 * mass[0, 0] * _OMEGA, rel=1e-12)
        assert [gain[1, 0], bias[1, 1], bias[1, 2]] == [0.5, -0.5, -0.1]


def test_nonlinear_effects_of_a_moving_free_base_match_mujoco(tmp_path) -> None:
    free = _ARMS["fast"].replace('pos="0 0 1">', 'pos="0 0 1"><freejoint name="float"/>', 1)
    with _arm_scene(tmp_path, free) as scene:
        robot = scene.create_robot("base", "l2")
        data = scene.data
        data.qpos[7:9] = [0.4, -0.7]
        data.qvel[:8] = [0.3, -0.2, 0.5, 0.4, 0.7, -0.6, 0.5, -0.8]
        mujoco.mj_forward(scene.model, data)
        robot.update()
        np.testing.assert_allclose(robot.nonlinear_effects(), data.qfrc_bias[6:8], atol=1e-12)


def test_control_errors_name_the_joints(tmp_path) -> None:
    with _arm_scene(tmp_path, _small_arm("", "", "")) as scene:
        robot = scene.create_robot("base", "l2")
        with pytest.raises(mjk.SpecError) as err:
            robot.update()
        assert str(err.value) == (
            "POSITION mode needs an actuator on every joint; none drives j1, j2 "
            "(TORQUE mode applies the torques as qfrc_applied)"
        )
    with _arm_scene(tmp_path, _small_arm("", "", '<motor joint="j1"/>')) as scene:
        robot = scene.create_robot("base", "l2")
        robot.ctrl_mode = mjk.CtrlMode.TORQUE
        with pytest.raises(mjk.SpecError) as err:
            robot.update()
        assert str(err.value) == (
            "joints j2 have no actuator while the rest of the chain has: a Robot drives all "
            "chain joints through actuators, or none (TORQUE mode then applies the torques as "
            "qfrc_applied)"
        )


def test_a_later_handle_drives_and_an_earlier_one_is_refused(tmp_path) -> None:
    with _arm_scene(tmp_path, _ARMS["fast"]) as scene:
        reader = scene.create_robot("base", "l2")  # first in the scene's list
        driver = scene.create_robot("base", "l2")
        driver.update()
        with pytest.raises(mjk.SpecError) as err:
            reader.update()
        assert str(err.value) == (
            "joints j1, j2 are already driven by the Robot 'base' -> 'l2'; one Robot per joint may "
            "control (any number may read; close() the other to take over)"
        )


def test_closed_handles_say_why(tmp_path) -> None:
    scene = _arm_scene(tmp_path, _ARMS["fast"])
    robot = scene.create_robot("base", "l2")
    other = scene.create_robot("base", "l2")
    robot.close()
    with pytest.raises(RuntimeError) as err:
        robot.step()
    assert str(err.value) == "this Robot is closed"
    scene.close()
    with pytest.raises(RuntimeError) as err:
        other.jacobian()
    assert str(err.value) == "this Robot's scene is closed"


def test_a_rebuild_applies_the_commands_at_the_new_state(tmp_path) -> None:
    with _arm_scene(tmp_path, _ARMS["fast"]) as scene:
        robot = scene.create_robot("base", "l2")
        robot.update()
        robot.jnt_pos_cmd = np.array([0.6, -0.6])  # far away: the arm moves in one step
        robot.step()
        scene.add_object(
            mjk.SceneObject(name="ball", shape=mjk.Shape.SPHERE, size=[0.02], mass=0.1)
        )
        acts, dofs = _ids(scene, robot)  # on the new model
        want = _want_ctrl(scene, acts, dofs, mjk.CtrlMode.POSITION, False, True, [0.6, -0.6])
        robot.step()  # the feed-forward of the state the rebuild carried over
        np.testing.assert_allclose(scene.data.ctrl[acts], want, rtol=0, atol=1e-9)


# ---------------------------------------------------------------------- ignored command ports


@pytest.mark.parametrize(
    ("mode", "port", "acting"),
    [
        ("TORQUE", "jnt_pos_cmd", "jnt_trq_cmd"),
        ("POSITION", "jnt_vel_cmd", "jnt_pos_cmd"),
        ("VELOCITY", "jnt_trq_cmd", "jnt_vel_cmd"),
    ],
)
def test_a_port_the_mode_ignores_warns_once_at_the_step(gen3, mode, port, acting) -> None:
    _, robot = gen3
    robot.ctrl_mode = mjk.CtrlMode[mode]
    robot.update()
    value = np.full(7, 0.1)
    setattr(robot, port, value)  # a float64 array: the descriptor's fast path
    with pytest.warns(mjk.IgnoredCommandWarning) as caught:
        robot.step()
    assert len(caught) == 1
    message = str(caught[0].message)
    assert f"{port} was written" in message
    assert f"is in {mode} mode, which applies {acting} only" in message
    assert "'base_link' -> 'bracelet_link'" in message
    assert caught[0].filename == __file__  # points at the user's call, not into mjkdl
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # once per robot and port
        for _ in range(3):
            robot.update()
            setattr(robot, port, value.tolist())  # a list: the checked slow path
            robot.step()


def test_the_warning_names_the_mode_that_uses_the_port(gen3) -> None:
    _, robot = gen3
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.update()
    robot.jnt_vel_cmd = [0.0] * 7
    with pytest.warns(mjk.IgnoredCommandWarning, match=r"mjk\.CtrlMode\.VELOCITY to use"):
        robot.update()


def test_a_port_written_before_its_mode_is_set_does_not_warn(gen3) -> None:
    _, robot = gen3
    robot.update()  # POSITION
    robot.jnt_trq_cmd = robot.gravity_torques()  # ready for the switch below
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        robot.update()
        robot.step()
        robot.jnt_trq_cmd = robot.gravity_torques()
        robot.step()


def test_internal_writers_never_warn(tutorial_scene) -> None:
    scene = tutorial_scene(mjk.Env)
    robot = scene.create_robot("base_link", "bracelet_link", tool=gripper_tool())
    scene.on_reset = lambda ctx: robot.set_joint_pos(HOME)
    scene.reset()
    controller = mjk.CartesianVelocityController(robot)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for mode in (mjk.CtrlMode.POSITION, mjk.CtrlMode.VELOCITY, mjk.CtrlMode.TORQUE):
            robot.ctrl_mode = mode
            for _ in range(3):
                robot.update()
                if mode is not mjk.CtrlMode.TORQUE:
                    controller.command([0.01, 0, 0, 0, 0, 0])
                robot.step()
            robot.sync_commands()
            scene.reset()
            robot.step()


def test_the_warning_is_per_robot(gen3) -> None:
    scene, robot = gen3
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.update()
    robot.jnt_pos_cmd = HOME
    with pytest.warns(mjk.IgnoredCommandWarning):
        robot.step()
    robot.close()
    other = scene.create_robot("base_link", "bracelet_link", tool=gripper_tool())
    other.ctrl_mode = mjk.CtrlMode.TORQUE
    other.update()
    other.jnt_pos_cmd = HOME
    with pytest.warns(mjk.IgnoredCommandWarning):
        other.step()


def test_last_update_time_stamps_the_measured_ports(gen3) -> None:
    scene, robot = gen3
    robot.update()
    start = robot.last_update_time
    assert start == scene.time()
    for _ in range(5):
        robot.step()
    assert robot.last_update_time == start  # measured ports are as old as the stamp says
    assert scene.time() - robot.last_update_time == pytest.approx(5 * scene.timestep())
    robot.update()
    assert robot.last_update_time == scene.time()


def test_a_stray_write_warns_even_when_the_mode_is_set_again(gen3) -> None:
    _, robot = gen3
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.update()
    robot.jnt_pos_cmd = np.array(HOME)
    robot.ctrl_mode = mjk.CtrlMode.TORQUE  # the same mode: update() could take its fast path
    with pytest.warns(mjk.IgnoredCommandWarning, match="^jnt_pos_cmd was written"):
        robot.update()  # applies the commands, so it is the one that warns
        robot.step()
