"""Chain: the Pinocchio model extracted from a compiled MuJoCo model, checked against MuJoCo."""

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from mjkdl.chain import Chain
from mjkdl.errors import SpecError, UnknownNameError

# Joint references (qpos0 != 0) on a tilted hinge, a tilted slide and a z hinge; gravcomp on tip.
REF_ARM = """
<mujoco>
  <worldbody>
    <body name="link1" pos="0.1 0 0.2">
      <joint name="j1" type="hinge" axis="0 1 1" ref="0.3" pos="0.05 0 0" range="-1 1"
             limited="true"/>
      <geom size="0.05" mass="1"/>
      <body name="link2" pos="0 0.3 0" quat="0.9 0.1 0.2 0.3">
        <joint name="j2" type="slide" axis="1 0 1" ref="0.2"/>
        <geom size="0.05" mass="0.5" pos="0.1 0 0"/>
        <body name="tip" pos="0.2 0 0.1" gravcomp="0.5">
          <joint name="j3" type="hinge" axis="0 0 1" ref="-0.4"/>
          <geom type="box" size="0.1 0.05 0.02" mass="0.7" pos="0.05 0.02 0"/>
          <site name="tcp" pos="0.1 0 0.05" quat="0.8 0 0.6 0"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

# A free object first (dofs 0-5), then a free base, a two-hinge arm and a ball-jointed hand.
FREE_BASE = """
<mujoco>
  <worldbody>
    <body name="obj" pos="1 0 0"><freejoint name="objfree"/><geom size="0.05" mass="0.2"/></body>
    <body name="base" pos="0 0 0.5">
      <freejoint name="basefree"/>
      <geom size="0.1" mass="2"/>
      <body name="l1" pos="0 0 0.1">
        <joint name="a1" axis="0 1 0" actuatorfrcrange="-7 7" actuatorfrclimited="true"/>
        <geom size="0.05" mass="1" pos="0 0 0.1"/>
        <body name="l2" pos="0 0 0.3">
          <joint name="a2" axis="1 0 0"/>
          <geom size="0.05" mass="1" pos="0 0.02 0.1"/>
          <body name="hand" pos="0 0 0.2">
            <joint name="wrist" type="ball"/>
            <geom size="0.03" mass="0.3" pos="0 0.01 0.05"/>
            <site name="grip" pos="0 0 0.1"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="a2" gear="2" forcerange="-3 3" forcelimited="true"/>
    <motor joint="a1" gear="1" forcerange="-10 10" forcelimited="true"/>
  </actuator>
</mujoco>
"""

# A mocap base carrying a one-hinge arm (qpos has a single entry).
MOCAP_BASE = """
<mujoco>
  <worldbody>
    <body name="mbase" mocap="true" pos="0 0 0.3">
      <geom size="0.1" contype="0" conaffinity="0"/>
      <body name="m1" pos="0 0.1 0.1">
        <joint name="mj" axis="0 1 0"/>
        <geom size="0.05" mass="1" pos="0.1 0 0"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

# Two trees tied by equality constraints: a joint coupling, bodies touching one side only,
# and the unnamed weld that joins the tip's tree to an ancestor of the base.
TWO_TREES = """
<mujoco>
  <worldbody>
    <body name="A">
      <joint name="ja" axis="0 0 1"/><geom size=".05" mass="1"/>
      <body name="A1" pos="0 0 .2">
        <joint name="ja1" axis="0 1 0"/><geom size=".05" mass="1"/>
      </body>
    </body>
    <body name="T" pos="1 0 0">
      <freejoint/><geom size=".05" mass="1"/>
      <body name="T1" pos="0 0 .2">
        <joint name="jt1" axis="0 1 0"/><geom size=".05" mass="1"/>
        <body name="T2" pos="0 0 .2"><geom size=".05" mass="1"/></body>
      </body>
    </body>
    <body name="C" pos="2 0 0"><freejoint/><geom size=".05" mass="1"/></body>
    <body name="D" pos="3 0 0"><joint name="jd" axis="0 0 1"/><geom size=".05" mass="1"/></body>
  </worldbody>
  <equality>
    <joint name="couple" joint1="ja" joint2="jt1"/>
    <weld name="c_to_a" body1="C" body2="A"/>
    <connect name="c_to_t1" body1="C" body2="T1" anchor="0 0 0"/>
    <weld body1="T2" body2="A"/>
  </equality>
</mujoco>
"""


def _compile(xml):
    return mujoco.MjModel.from_xml_string(xml)


@pytest.fixture(scope="module")
def ref_arm():
    m = _compile(REF_ARM)
    return m, Chain(m, "world", "tip", "tcp")


@pytest.fixture(scope="module")
def free_base():
    m = _compile(FREE_BASE)
    return m, Chain(m, "base", "l2")


@pytest.fixture(scope="module")
def mocap_base():
    m = _compile(MOCAP_BASE)
    return m, Chain(m, "mbase", "m1")


def _state(m, chain, d):
    q, v = np.zeros(chain.model.nq), np.zeros(chain.model.nv)
    chain.read_state(d, q, v)
    return q, v


def _pin_frames(chain, q, v):
    data = chain.model.createData()
    pin.forwardKinematics(chain.model, data, q, v)
    pin.updateFramePlacements(chain.model, data)
    return data


def _assert_body_matches(m, d, chain, data, body):
    """Frame pose and velocity of `body` equal MuJoCo's (world-aligned, at the body origin)."""
    b = m.body(body).id
    fid = chain.model.getFrameId(body)
    np.testing.assert_allclose(data.oMf[fid].translation, d.xpos[b], atol=1e-9)
    np.testing.assert_allclose(data.oMf[fid].rotation, d.xmat[b].reshape(3, 3), atol=1e-9)
    vel = np.zeros(6)
    mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_XBODY, b, vel, 0)
    twist = pin.getFrameVelocity(chain.model, data, fid, pin.LOCAL_WORLD_ALIGNED)
    np.testing.assert_allclose(twist.angular, vel[:3], atol=1e-9)
    np.testing.assert_allclose(twist.linear, vel[3:], atol=1e-9)


def test_joint_references_and_axes_match_mujoco_kinematics(ref_arm):
    m, chain = ref_arm
    d = mujoco.MjData(m)
    d.qpos[:] = [0.7, -0.15, 1.1]
    d.qvel[:] = [0.4, -0.3, 0.9]
    mujoco.mj_forward(m, d)
    q, v = _state(m, chain, d)
    data = _pin_frames(chain, q, v)
    for body in ("link1", "link2", "tip"):
        _assert_body_matches(m, d, chain, data, body)
    tcp = m.site("tcp").id
    np.testing.assert_allclose(data.oMf[chain.tcp_frame].translation, d.site_xpos[tcp], atol=1e-9)
    np.testing.assert_allclose(
        data.oMf[chain.tcp_frame].rotation, d.site_xmat[tcp].reshape(3, 3), atol=1e-9
    )


def test_body_frames_hang_off_their_parent_bodies_frames(ref_arm):
    m, chain = ref_arm
    frames = chain.model.frames
    for body in ("link2", "tip"):
        parent = m.body(int(m.body_parentid[m.body(body).id])).name
        assert frames[chain.model.getFrameId(body)].parentFrame == chain.model.getFrameId(parent)


def test_gravcomp_model_holds_mujoco_gravcomp_share(ref_arm):
    m, chain = ref_arm
    d = mujoco.MjData(m)
    d.qpos[:] = [0.2, 0.1, -0.5]
    mujoco.mj_forward(m, d)
    q, _ = _state(m, chain, d)
    gc = chain.gravcomp_model
    tau = pin.computeGeneralizedGravity(gc, gc.createData(), q)
    np.testing.assert_allclose(tau, d.qfrc_gravcomp, atol=1e-9)
    # The share is the gravcomp fraction (0.5) of the whole tip inertia, rotational part too.
    tip = m.body("tip").id
    rot = d.ximat[tip].reshape(3, 3)
    world_inertia = rot @ np.diag(m.body_inertia[tip]) @ rot.T
    share = gc.inertias[chain.model.getJointId("j3")]
    data = _pin_frames(chain, q, np.zeros(chain.model.nv))
    joint_rot = data.oMi[chain.model.getJointId("j3")].rotation
    assert share.mass == pytest.approx(0.5 * m.body_mass[tip])
    np.testing.assert_allclose(
        joint_rot @ share.inertia @ joint_rot.T,
        0.5 * world_inertia,
        atol=1e-12,
    )


def test_no_gravcomp_model_without_gravcomp(free_base):
    _, chain = free_base
    assert chain.gravcomp_model is None


def test_velocity_limits_are_symmetric():
    m = _compile(REF_ARM)
    chain = Chain(m, "world", "tip")
    chain.set_velocity_limits({"j1": 2.0, "j3": 1.5})
    np.testing.assert_array_equal(chain.model.upperVelocityLimit, [2.0, np.inf, 1.5])
    np.testing.assert_array_equal(chain.model.lowerVelocityLimit, [-2.0, -np.inf, -1.5])


def test_free_base_and_ball_tool_velocities_match_mujoco(free_base):
    m, chain = free_base
    d = mujoco.MjData(m)
    rng = np.random.default_rng(3)
    d.qpos[7:10] = [0.1, -0.2, 0.6]
    d.qpos[10:14] = [0.9, 0.2, -0.3, 0.1]
    d.qpos[14:16] = [0.5, -0.7]
    d.qpos[16:20] = [0.8, -0.1, 0.3, 0.4]
    d.qvel[:] = rng.normal(size=m.nv)
    mujoco.mj_forward(m, d)
    q, v = _state(m, chain, d)
    data = _pin_frames(chain, q, v)
    for body in ("base", "l2", "hand"):
        _assert_body_matches(m, d, chain, data, body)


def test_free_base_arm_entries_are_slices_after_the_base(free_base):
    _, chain = free_base
    assert chain.arm_q == slice(7, 9)
    assert chain.arm_v == slice(6, 8)


def test_effort_limits_after_a_free_base(free_base):
    _, chain = free_base
    # a1: min(actuatorfrcrange 7, forcerange 10 * gear 1); a2: forcerange 3 * gear 2.
    limit = np.full(chain.model.nv, np.inf)
    limit[chain.arm_v] = [7.0, 6.0]
    np.testing.assert_array_equal(chain.model.effortLimit, limit)
    np.testing.assert_array_equal(chain.model.lowerEffortLimit, -limit)


def test_mocap_base_state_matches_mujoco(mocap_base):
    m, chain = mocap_base
    d = mujoco.MjData(m)
    d.mocap_pos[0] = [0.3, -0.2, 0.5]
    d.mocap_quat[0] = [0.6, 0.0, 0.8, 0.0]
    d.qpos[0] = 0.4
    d.qvel[0] = -1.2
    mujoco.mj_forward(m, d)
    q, v = _state(m, chain, d)
    data = _pin_frames(chain, q, v)
    for body in ("mbase", "m1"):
        _assert_body_matches(m, d, chain, data, body)


BALL_ON_ARM = (
    '<mujoco><worldbody><body name="g1"><joint name="gj" axis="0 0 1"/>'
    '<geom size=".05" mass="1"/><body name="g2" pos="0 0 .2"><joint name="gball" '
    'type="ball"/><geom size=".05" mass="1"/></body></body></worldbody></mujoco>'
)
MOCAP_HELD = (
    '<mujoco><worldbody><body name="mb" mocap="true"><body name="b"><body name="e1">'
    '<joint name="ej"/><geom size=".05" mass="1"/></body></body></body>'
    '<body name="other" pos="1 0 0"><geom size=".05"/></body></worldbody>'
    '<equality><weld name="hold" body1="b" body2="other"/></equality></mujoco>'
)


@pytest.mark.parametrize(
    ("xml", "args", "error", "message"),
    [
        pytest.param(
            "TWO_TREES",
            ("A1", "T2"),
            SpecError,
            "base body 'A1' is not an ancestor of tip body 'T2': a chain runs from a base down "
            "to a tip in one kinematic tree (they are joined only by equality constraint '#3', "
            "which the Pinocchio model cannot represent)",
            id="trees joined by an equality",
        ),
        pytest.param(
            "TWO_TREES",
            ("A1", "D"),
            SpecError,
            "base body 'A1' is not an ancestor of tip body 'D': a chain runs from a base down "
            "to a tip in one kinematic tree",
            id="trees not joined",
        ),
        pytest.param(
            BALL_ON_ARM,
            ("world", "g2"),
            SpecError,
            "joint 'gball' is a mjJNT_BALL joint: the chain from base to tip takes only hinge "
            "and slide joints",
            id="ball joint on the arm",
        ),
        pytest.param(
            MOCAP_HELD,
            ("b", "e1"),
            SpecError,
            "base body 'b' is held by equality constraint 'hold', which the Pinocchio model "
            "cannot represent (it follows the kinematic tree only); mount the robot in the tree "
            "instead (RobotSpec.attach_to) or choose a base_body below the constraint",
            id="mocap base held by a weld",
        ),
        pytest.param(
            "FREE_BASE",
            ("base", "l2", "nosuch"),
            UnknownNameError,
            "no site named 'nosuch' in the model (tool.tcp_site); known: grip",
            id="unknown TCP site",
        ),
        pytest.param(
            "FREE_BASE",
            ("base", "l2", "grip"),
            SpecError,
            "TCP site 'grip' is on body 'hand', which moves relative to the chain through joints "
            "outside it (fingers, links beyond the tip): choose a site rigidly fixed to the "
            "chain or its tool",
            id="TCP site on a moving tool body",
        ),
    ],
)
def test_chains_pinocchio_cannot_model_are_refused_by_name(xml, args, error, message):
    m = _compile(globals().get(xml, xml))
    with pytest.raises(error) as err:
        Chain(m, *args)
    assert str(err.value) == message


@pytest.mark.parametrize(("base", "tip"), [("nosuch", "m1"), ("mbase", "nosuch")])
def test_unknown_body_lists_the_models_bodies(base, tip):
    m = _compile(MOCAP_BASE)
    with pytest.raises(UnknownNameError) as err:
        Chain(m, base, tip)
    assert str(err.value) == "no body named 'nosuch' in the model; known: world, mbase, m1"


def test_chain_without_joints_is_refused():
    m = _compile(
        '<mujoco><worldbody><body name="a"><geom size=".05" mass="1"/><body name="b" pos="0 0 .2">'
        '<geom size=".05" mass="1"/></body></body></worldbody></mujoco>'
    )
    with pytest.raises(SpecError) as err:
        Chain(m, "a", "b")
    assert str(err.value) == "the chain 'a' -> 'b' has no joints"


def test_world_base_keeps_only_the_tree_that_holds_the_arm():
    m = _compile(TWO_TREES)
    chain = Chain(m, "world", "D")
    # MuJoCo: D is a top-level body with the single hinge jd (qpos/qvel address 7/6 after the
    # hinges ja, ja1, jt1 and the free joints of T and C).
    d_id = m.body("D").id
    assert [f.name for f in chain.model.frames] == ["universe", "world", "D"]
    assert list(chain.model.names) == ["universe", "jd"]
    assert chain.q_span == slice(int(m.jnt_qposadr[m.joint("jd").id]), m.nq)
    assert chain.v_span == slice(int(m.jnt_dofadr[m.joint("jd").id]), m.nv)
    assert chain.model.frames[chain.tip_frame].name == m.body(d_id).name


def test_contiguous_hinge_chain_is_a_plain_copy_of_qpos_and_qvel(ref_arm):
    m, chain = ref_arm
    assert chain.q_span == slice(0, m.nq)
    assert chain.v_span == slice(0, m.nv)


def test_free_base_state_is_not_a_plain_copy(free_base):
    m, chain = free_base
    # MuJoCo's qvel for the base's free joint is contiguous with the arm (dofs 6..16), but its
    # linear part is in the world frame, so the state must go through read_state.
    base_dof = int(m.jnt_dofadr[m.joint("basefree").id])
    assert list(chain.v_index) == list(range(base_dof, m.nv))
    assert chain.q_span is None
    assert chain.v_span is None


# A mocap base held by a weld, after a joint equality and a site weld on bodies outside it.
HELD_AFTER_OTHER_EQUALITIES = """
<mujoco>
  <worldbody>
    <body name="mb" mocap="true">
      <body name="b"><body name="e1"><joint name="ej"/><geom size=".05" mass="1"/></body></body>
    </body>
    <body name="other" pos="1 0 0">
      <joint name="oj"/><geom size=".05" mass="1"/><site name="so"/>
    </body>
    <body name="third" pos="2 0 0"><geom size=".05" mass="1"/><site name="st"/></body>
  </worldbody>
  <equality>
    <joint joint1="ej" joint2="oj"/>
    <weld site1="so" site2="st"/>
    <weld name="hold" body1="b" body2="other"/>
  </equality>
</mujoco>
"""


def test_base_held_by_a_later_weld_is_refused():
    m = _compile(HELD_AFTER_OTHER_EQUALITIES)
    assert m.eq_objtype[1] == int(mujoco.mjtObj.mjOBJ_SITE)
    with pytest.raises(SpecError) as err:
        Chain(m, "b", "e1")
    assert str(err.value) == (
        "base body 'b' is held by equality constraint 'hold', which the Pinocchio model cannot "
        "represent (it follows the kinematic tree only); mount the robot in the tree instead "
        "(RobotSpec.attach_to) or choose a base_body below the constraint"
    )
