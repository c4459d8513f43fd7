"""Every kinematic and dynamic quantity of a Robot equals MuJoCo's on the same model."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

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
        if int(m.jnt_type[j]) not in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
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
