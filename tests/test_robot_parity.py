"""Every kinematic and dynamic quantity of a Robot equals MuJoCo's on the same model."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import pytest
from conftest import base_spec, gripper, gripper_tool, menagerie, table_object, tutorial_spec

import mjkdl as mjk
from mjkdl.urdf import example_robot_data_path

N_CONFIGS = 25
FK_TOL = 1e-9
DYN_TOL = 1e-8


@dataclass
class Case:
    scene: mjk.Scene
    robot: mjk.Robot
    tcp_site: str = ""  # compiled site name the TCP must match; else the tip body
    tip_body: str = ""


def _gen3_2f85() -> Case:
    scene = mjk.Scene.build(tutorial_spec())
    robot = scene.create_robot("base_link", "bracelet_link", tool=gripper_tool())
    return Case(scene, robot, tcp_site="g_pinch")


def _gen3_second_prefixed() -> Case:
    first = mjk.RobotSpec(path=menagerie("kinova_gen3"), pos=[-0.6, 0.0, 0.0])
    second = mjk.RobotSpec(
        path=menagerie("kinova_gen3"),
        prefix="r2_",
        pos=[0.6, 0.1, 0.0],
        euler=[0.0, 0.0, 180.0],
        attachments=[gripper()],
    )
    scene = mjk.Scene.build(base_spec(robots=[first, second]))
    robot = scene.create_robot("base_link", "bracelet_link", prefix="r2_", tool=gripper_tool())
    return Case(scene, robot, tcp_site="r2_g_pinch")


def _panda_hand() -> Case:
    arm = mjk.RobotSpec(path=menagerie("franka_emika_panda"), pos=[0.1, -0.2, 0.0])
    scene = mjk.Scene.build(base_spec(robots=[arm]))
    robot = scene.create_robot("link0", "hand")
    return Case(scene, robot, tip_body="hand")


def _iiwa_2f85_rotated() -> Case:
    grip = gripper()
    grip.attach_to = mjk.AttachTarget(mjk.AttachKind.Site, "attachment_site")
    arm = mjk.RobotSpec(
        path=menagerie("kuka_iiwa_14"),
        pos=[0.3, -0.4, 0.25],
        euler=[15.0, -10.0, 60.0],
        attachments=[grip],
    )
    scene = mjk.Scene.build(base_spec(robots=[arm]))
    robot = scene.create_robot("base", "link7", tool=gripper_tool())
    return Case(scene, robot, tcp_site="g_pinch")


def _xarm7_tcp() -> Case:
    arm = mjk.RobotSpec(path=menagerie("ufactory_xarm7"))
    scene = mjk.Scene.build(base_spec(robots=[arm]))
    robot = scene.create_robot("link_base", "link7", tool=mjk.ToolFrameSpec(tcp_site="link_tcp"))
    return Case(scene, robot, tcp_site="link_tcp")


def _ur5_urdf() -> Case:
    table = table_object()
    arm = mjk.RobotSpec(
        path=example_robot_data_path("ur_description/urdf/ur5_robot.urdf"),
        attach_to=mjk.AttachTarget(
            mjk.AttachKind.Site, mjk.scene_object_site_name(table, "table_top")
        ),
        euler=[0.0, 0.0, 30.0],
    )
    with pytest.warns(UserWarning, match="dae"):
        scene = mjk.Scene.build(base_spec(objects=[table], robots=[arm]))
    robot = scene.create_robot("base_link", "tool0")
    return Case(scene, robot, tip_body="tool0")


CASES: dict[str, Callable[[], Case]] = {
    "gen3+2f85": _gen3_2f85,
    "gen3 r2_+2f85": _gen3_second_prefixed,
    "panda+hand": _panda_hand,
    "iiwa14+2f85 rotated": _iiwa_2f85_rotated,
    "xarm7 link_tcp": _xarm7_tcp,
    "ur5 urdf": _ur5_urdf,
}


@pytest.fixture(params=list(CASES), scope="module")
def case(request) -> Case:
    c = CASES[request.param]()
    yield c
    c.scene.close()


def _randomize(case: Case, rng: np.random.Generator, moving: bool) -> None:
    """Random arm configuration within limits and random configurations of all other joints."""
    m, d = case.scene.model, case.scene.data
    d.qpos[:] = m.qpos0
    d.qvel[:] = 0.0
    for j in range(m.njnt):
        if int(m.jnt_type[j]) not in (
            int(mujoco.mjtJoint.mjJNT_HINGE),
            int(mujoco.mjtJoint.mjJNT_SLIDE),
        ):
            continue
        lo, hi = m.jnt_range[j] if m.jnt_limited[j] else (-np.pi, np.pi)
        d.qpos[m.jnt_qposadr[j]] = rng.uniform(lo, hi)
    if moving:
        d.qvel[case.robot._chain.dof_adr] = rng.normal(scale=1.5, size=case.robot.n_joints)
    mujoco.mj_forward(m, d)
    case.robot.update()


def _mj_jacobian(case: Case) -> np.ndarray:
    m, d = case.scene.model, case.scene.data
    jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    if case.tcp_site:
        mujoco.mj_jacSite(m, d, jp, jr, m.site(case.tcp_site).id)
    else:
        mujoco.mj_jacBody(m, d, jp, jr, m.body(case.tip_body).id)
    return np.vstack([jp, jr])[:, case.robot._chain.dof_adr]


def _mj_pose(case: Case) -> tuple[np.ndarray, np.ndarray]:
    d = case.scene.data
    if case.tcp_site:
        i = case.scene.site_id(case.tcp_site)
        return d.site_xpos[i], d.site_xmat[i].reshape(3, 3)
    i = case.scene.body_id(case.tip_body)
    return d.xpos[i], d.xmat[i].reshape(3, 3)


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-12))


def test_fk_matches_site_pose(case: Case) -> None:
    rng = np.random.default_rng(1)
    for _ in range(N_CONFIGS):
        _randomize(case, rng, moving=False)
        frame = case.robot.fk_frame()
        pos, rot = _mj_pose(case)
        assert np.abs(frame.translation - pos).max() <= FK_TOL
        angle = np.linalg.norm(mujoco_rotation_error(frame.rotation, rot))
        assert angle <= FK_TOL


def mujoco_rotation_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation vector of a^T b (radians)."""
    import pinocchio as pin

    return pin.log3(a.T @ b)


def test_fk_at_explicit_q_matches_after_forward(case: Case) -> None:
    rng = np.random.default_rng(2)
    _randomize(case, rng, moving=False)
    q = case.robot.jnt_pos_msr.copy()
    _randomize(case, rng, moving=False)  # the measured state moves elsewhere
    frame = case.robot.fk_frame(q)
    case.robot.set_joint_pos(q)
    pos, _ = _mj_pose(case)
    assert np.abs(frame.translation - pos).max() <= FK_TOL


def test_jacobian_matches_mj_jac(case: Case) -> None:
    rng = np.random.default_rng(3)
    for _ in range(N_CONFIGS):
        _randomize(case, rng, moving=False)
        assert np.abs(case.robot.jacobian() - _mj_jacobian(case)).max() <= FK_TOL


def test_gravity_matches_qfrc_bias_at_rest(case: Case) -> None:
    rng = np.random.default_rng(4)
    dofs = case.robot._chain.dof_adr
    for _ in range(N_CONFIGS):
        _randomize(case, rng, moving=False)
        assert _rel(case.robot.gravity_torques(), case.scene.data.qfrc_bias[dofs]) <= DYN_TOL


def test_bias_forces_match_with_arm_moving(case: Case) -> None:
    rng = np.random.default_rng(5)
    dofs = case.robot._chain.dof_adr
    for _ in range(N_CONFIGS):
        _randomize(case, rng, moving=True)
        assert _rel(case.robot.nonlinear_effects(), case.scene.data.qfrc_bias[dofs]) <= DYN_TOL


def test_mass_matrix_matches_full_m_with_armature(case: Case) -> None:
    rng = np.random.default_rng(6)
    m, d = case.scene.model, case.scene.data
    dofs = case.robot._chain.dof_adr
    full = np.zeros((m.nv, m.nv))
    for _ in range(N_CONFIGS):
        _randomize(case, rng, moving=False)
        mujoco.mj_fullM(m, d, full)
        assert _rel(case.robot.mass_matrix(), full[np.ix_(dofs, dofs)]) <= DYN_TOL


def test_ik_on_an_arm_not_contiguous_in_the_model() -> None:
    """IK moves the arm's joints only; the pendulum between them in q keeps its angle."""
    arm = mjk.RobotSpec(path=str(ASSETS / "branch_arm.xml"))
    with mjk.Scene.build(base_spec(robots=[arm])) as scene:
        robot = scene.create_robot("base", "l3", tool=mjk.ToolFrameSpec(tcp_site="tcp"))
        scene.data.qpos[1] = 0.7  # the pendulum
        robot.set_joint_pos([0.1, 0.2, 0.3])
        robot.update()
        target = robot.fk_frame(np.array([0.5, -0.4, 0.8]))
        result = robot.ik(target)
        assert result.success
        robot.set_joint_pos(result.q)
        site = scene.site_frame("tcp")
        assert np.abs(site.translation - target.translation).max() < 1e-6
        assert scene.data.qpos[1] == 0.7


def test_inverse_dynamics_matches_mujoco(case: Case) -> None:
    """RNEA equals MuJoCo's M(q) a + qfrc_bias with the other joints held still."""
    rng = np.random.default_rng(7)
    m, d = case.scene.model, case.scene.data
    dofs = case.robot._chain.dof_adr
    full = np.zeros((m.nv, m.nv))
    for _ in range(N_CONFIGS):
        _randomize(case, rng, moving=True)
        acc = rng.normal(size=case.robot.n_joints)
        mujoco.mj_fullM(m, d, full)
        expected = full[np.ix_(dofs, dofs)] @ acc + d.qfrc_bias[dofs]
        q, v = case.robot.jnt_pos_msr, case.robot.jnt_vel_msr
        assert _rel(case.robot.inverse_dynamics(q, v, acc), expected) <= DYN_TOL


# ---------------------------------------------------------------------------- in motion
#
# Every step of a simulation in which the arm swings, the fingers open and close and the base
# turns or tumbles, each quantity is compared with MuJoCo's at the *current* state: after
# mj_step, MuJoCo's own derived quantities are those of the state before integration, so the
# reference is a second MjData forwarded at the state the robot just read.

ASSETS = Path(__file__).resolve().parent / "assets"
MOTION_STEPS = 250
GRAVITY_TOL = 1e-9  # Nm, absolute
JAC_TOL = 1e-9
WORST: dict[str, dict[str, float]] = {}  # case -> quantity -> worst error, for the report


@dataclass
class Motion:
    case: Case
    drive: Callable[[mjk.Scene, int], None]  # moves the rest of the scene at step k
    moving: list[str]  # joints besides the arm's that must move during the run


def _toggle_fingers(actuator: str, closed: float) -> Callable[[mjk.Scene, int], None]:
    """Fingers open and close every 0.1 s (50 steps)."""

    def drive(scene: mjk.Scene, k: int) -> None:
        scene.set_actuator_ctrl(actuator, closed if (k // 50) % 2 == 0 else 0.0)

    return drive


def _gen3_motion(**scene_fields) -> Motion:
    spec = tutorial_spec()
    for field, value in scene_fields.items():
        setattr(spec, field, value)
    scene = mjk.Scene.build(spec)
    robot = scene.create_robot("base_link", "bracelet_link", tool=gripper_tool())
    robot.set_joint_pos(HOME_Q)
    return Motion(
        Case(scene, robot, tcp_site="g_pinch"),
        _toggle_fingers("g_fingers_actuator", 255.0),
        ["g_right_driver_joint", "g_left_follower_joint"],
    )


def _panda_motion() -> Motion:
    arm = mjk.RobotSpec(path=menagerie("franka_emika_panda"), pos=[0.1, -0.2, 0.0])
    scene = mjk.Scene.build(base_spec(robots=[arm]))
    robot = scene.create_robot("link0", "hand")
    robot.set_joint_pos([0.2, -0.3, 0.1, -2.0, 0.1, 1.8, 0.6])
    scene.data.qpos[7:9] = 0.04
    return Motion(
        Case(scene, robot, tip_body="hand"), _toggle_fingers("actuator8", 0.0), ["finger_joint1"]
    )


def _mounted_gen3(mount: mjk.SceneObject, **scene_fields) -> tuple[mjk.Scene, mjk.Robot]:
    site = mjk.scene_object_site_name(mount, "mount")
    arm = mjk.RobotSpec(
        path=menagerie("kinova_gen3"),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Site, site),
        attachments=[gripper()],
    )
    scene = mjk.Scene.build(base_spec(objects=[mount], robots=[arm], **scene_fields))
    robot = scene.create_robot("base_link", "bracelet_link", tool=gripper_tool())
    robot.set_joint_pos(HOME_Q)
    return scene, robot


def _torso_motion() -> Motion:
    torso = mjk.SceneObject(name="torso", mjcf_path=str(ASSETS / "torso.xml"), fixed=True)
    scene, robot = _mounted_gen3(torso)
    fingers = _toggle_fingers("g_fingers_actuator", 255.0)

    def drive(scene: mjk.Scene, k: int) -> None:
        fingers(scene, k)
        scene.set_actuator_ctrl("torso/yaw_motor", 40.0 * np.sin(0.02 * k))

    return Motion(
        Case(scene, robot, tcp_site="g_pinch"), drive, ["torso/yaw", "g_right_driver_joint"]
    )


def _free_base_motion() -> Motion:
    """A platform in free fall, tumbling, with the arm on it (no contacts in 0.5 s)."""
    platform = mjk.SceneObject(
        name="platform", mjcf_path=str(ASSETS / "platform.xml"), pos=[0.0, 0.0, 2.5]
    )
    scene, robot = _mounted_gen3(platform)
    scene.data.qvel[:6] = [0.3, -0.2, 0.5, 1.5, -1.0, 2.0]
    return Motion(
        Case(scene, robot, tcp_site="g_pinch"),
        _toggle_fingers("g_fingers_actuator", 255.0),
        ["platform", "g_right_driver_joint"],
    )


def _ball_mount_motion() -> Motion:
    """The arm on a ball joint (anchor off the body origin) that sways under it."""
    mount = mjk.SceneObject(name="ball", mjcf_path=str(ASSETS / "ball_mount.xml"), fixed=True)
    scene, robot = _mounted_gen3(mount)
    scene.data.qvel[:3] = [0.4, -0.3, 0.8]
    return Motion(
        Case(scene, robot, tcp_site="g_pinch"),
        _toggle_fingers("g_fingers_actuator", 255.0),
        ["g_right_driver_joint"],
    )


def _mocap_mount_motion() -> Motion:
    """The arm on a mocap body that is moved and turned every step."""
    arm = mjk.AttachmentSpec(
        mjcf_path=menagerie("kinova_gen3"),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Site, "mount"),
    )
    carrier = mjk.RobotSpec(path=str(ASSETS / "mocap_mount.xml"), attachments=[arm, gripper()])
    with pytest.warns(UserWarning, match="pending keyframes"):  # Gen3's, attached in a robot
        scene = mjk.Scene.build(base_spec(robots=[carrier]))
    robot = scene.create_robot("base_link", "bracelet_link", tool=gripper_tool())
    robot.set_joint_pos(HOME_Q)
    fingers = _toggle_fingers("g_fingers_actuator", 255.0)

    def drive(scene: mjk.Scene, k: int) -> None:
        fingers(scene, k)
        angle = 0.004 * k
        scene.data.mocap_pos[0] = [0.1 * np.sin(angle), 0.05 * k / MOTION_STEPS, 0.6]
        scene.data.mocap_quat[0] = [np.cos(angle), 0.3 * np.sin(angle), 0.0, np.sin(angle)]

    return Motion(Case(scene, robot, tcp_site="g_pinch"), drive, ["g_right_driver_joint"])


def _rigid_tool_motion() -> Motion:
    """A rigid 1.5 kg tool, centre of mass off axis: its weight must join the last link."""
    tool = mjk.AttachmentSpec(
        mjcf_path=str(ASSETS / "box_tool.xml"),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Site, "pinch_site"),
        prefix="bt_",
    )
    arm = mjk.RobotSpec(path=menagerie("kinova_gen3"), attachments=[tool])
    scene = mjk.Scene.build(base_spec(robots=[arm]))
    robot = scene.create_robot(
        "base_link",
        "bracelet_link",
        tool=mjk.ToolFrameSpec(tool_body="bt_block", tcp_site="bt_tcp"),
    )
    robot.set_joint_pos(HOME_Q)
    return Motion(Case(scene, robot, tcp_site="bt_tcp"), lambda scene, k: None, [])


def _gravcomp_motion() -> Motion:
    """Links MuJoCo partly holds up itself (gravcomp 0.5 through the actuator, 1 passive)."""
    arm = mjk.RobotSpec(path=str(ASSETS / "gravcomp_arm.xml"))
    scene = mjk.Scene.build(base_spec(robots=[arm]))
    robot = scene.create_robot("base", "l3")
    robot.set_joint_pos([0.4, -0.6, 0.3])
    return Motion(Case(scene, robot, tip_body="l3"), lambda scene, k: None, [])


def _branch_motion() -> Motion:
    """A passive pendulum on the first link: the arm's q entries are not contiguous."""
    arm = mjk.RobotSpec(path=str(ASSETS / "branch_arm.xml"))
    scene = mjk.Scene.build(base_spec(robots=[arm]))
    robot = scene.create_robot("base", "l3", tool=mjk.ToolFrameSpec(tcp_site="tcp"))
    assert isinstance(robot.arm_q, np.ndarray)  # the gathered path is the one under test
    robot.set_joint_pos([0.4, -0.6, 0.3])
    scene.data.qvel[1] = 3.0  # the pendulum swings
    return Motion(Case(scene, robot, tcp_site="tcp"), lambda scene, k: None, ["swing"])


HOME_Q = np.array([0.0, 0.2618, 3.1416, -2.2689, 0.0, 0.9599, 1.5708])
MOTIONS: dict[str, Callable[[], Motion]] = {
    "gen3+2f85": _gen3_motion,
    "panda+hand": _panda_motion,
    "gen3+2f85 on hinge torso": _torso_motion,
    "gen3+2f85 on free base": _free_base_motion,
    "gen3+2f85 on ball joint": _ball_mount_motion,
    "gen3+2f85 on mocap body": _mocap_mount_motion,
    "gen3+rigid 1.5 kg tool": _rigid_tool_motion,
    "gen3+2f85 gravity_z=-3.7": lambda: _gen3_motion(gravity_z=-3.7),
    "gravcomp arm": _gravcomp_motion,
    "arm with a pendulum branch": _branch_motion,
}


class _Reference:
    """MuJoCo's quantities at the current state of `data`, from a second MjData."""

    def __init__(self, case: Case) -> None:
        self.m = case.scene.model
        self.d = mujoco.MjData(self.m)
        self.full = np.zeros((self.m.nv, self.m.nv))
        self.case = case

    def at(self, data: mujoco.MjData, zero_velocity: bool) -> mujoco.MjData:
        d = self.d
        d.qpos[:], d.qvel[:], d.time = data.qpos, data.qvel, data.time
        d.mocap_pos[:], d.mocap_quat[:] = data.mocap_pos, data.mocap_quat
        if zero_velocity:
            d.qvel[:] = 0.0
        mujoco.mj_forward(self.m, d)
        return d


def _worst(store: dict[str, float], key: str, value: float) -> None:
    store[key] = max(store.get(key, 0.0), value)


@pytest.mark.parametrize("name", list(MOTIONS))
def test_parity_every_step_in_motion(name: str) -> None:
    motion = MOTIONS[name]()
    case, robot = motion.case, motion.case.robot
    scene = case.scene
    m, data = scene.model, scene.data
    dofs = robot._chain.dof_adr
    ref = _Reference(case)
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.gravity_compensation = True
    moving = {j: [] for j in motion.moving}
    worst: dict[str, float] = {}
    phase = np.linspace(0.0, 2.0, robot.n_joints)
    for k in range(MOTION_STEPS):
        motion.drive(scene, k)
        robot.update()
        for j in moving:
            moving[j].append(data.qpos[m.joint(j).qposadr[0]])
        # gravity: MuJoCo's bias at rest, less the share its gravcomp cancels
        d = ref.at(data, zero_velocity=True)
        expected = d.qfrc_bias[dofs] - d.qfrc_gravcomp[dofs]
        _worst(worst, "gravity", float(np.abs(robot.gravity_torques() - expected).max()))
        d = ref.at(data, zero_velocity=False)
        expected = d.qfrc_bias[dofs] - d.qfrc_gravcomp[dofs]
        _worst(worst, "nle", _rel(robot.nonlinear_effects(), expected))
        mujoco.mj_fullM(m, d, ref.full)
        block = ref.full[np.ix_(dofs, dofs)]
        _worst(worst, "mass", _rel(robot.mass_matrix(), block))
        acc = np.sin(phase + 0.1 * k)
        q, v = robot.jnt_pos_msr, robot.jnt_vel_msr
        _worst(worst, "rnea", _rel(robot.inverse_dynamics(q, v, acc), block @ acc + expected))
        jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        if case.tcp_site:
            i = m.site(case.tcp_site).id
            mujoco.mj_jacSite(m, d, jp, jr, i)
            pos, rot = d.site_xpos[i], d.site_xmat[i].reshape(3, 3)
        else:
            i = m.body(case.tip_body).id
            mujoco.mj_jacBody(m, d, jp, jr, i)
            pos, rot = d.xpos[i], d.xmat[i].reshape(3, 3)
        jac = np.vstack([jp, jr])[:, dofs]
        _worst(worst, "jacobian", float(np.abs(robot.jacobian() - jac).max()))
        frame = robot.fk_frame()
        fk = max(
            float(np.abs(frame.translation - pos).max()),
            float(np.linalg.norm(mujoco_rotation_error(frame.rotation, rot))),
        )
        _worst(worst, "fk", fk)
        robot.jnt_trq_cmd = 3.0 * np.sin(phase + 0.05 * k)
        robot.step()
    WORST[name] = worst
    print(name, {k: f"{v:.1e}" for k, v in worst.items()})
    for joint, trace in moving.items():  # the run did move what it claims to
        assert np.ptp(trace) > 1e-2, f"{joint} did not move"
    assert worst["gravity"] <= GRAVITY_TOL
    assert worst["jacobian"] <= JAC_TOL and worst["fk"] <= FK_TOL
    assert worst["nle"] <= DYN_TOL and worst["mass"] <= DYN_TOL and worst["rnea"] <= DYN_TOL
    scene.close()
