"""Env lifecycle: reset hooks and keyframes, rebuild-on-modify, closed handles."""

from __future__ import annotations

import contextlib
import ctypes
import gc
import re
import weakref

import mujoco
import numpy as np
import pytest
from conftest import HOME, base_spec, gripper_tool, table_object, two_link_arm

import mjkdl as mjk

CUBE_START = [0.35, 0.10, 0.725]


@pytest.fixture
def env_robot(tutorial_scene):
    env = tutorial_scene(mjk.Env)
    robot = env.create_robot("base_link", "bracelet_link", tool=gripper_tool())
    return env, robot


def _obstacle(name: str = "obstacle") -> mjk.SceneObject:
    return mjk.SceneObject(
        name=name,
        shape=mjk.Shape.BOX,
        size=[0.05, 0.05, 0.2],
        pos=[0.25, -0.35, 0.92],
        rgba=[0.8, 0.2, 0.2, 1.0],
        mass=0.5,
    )


# ---------------------------------------------------------------------- reset


def test_reset_runs_hook_that_poses_arm_and_cube(env_robot) -> None:
    env, robot = env_robot
    calls = []

    def on_reset(ctx: mjk.ResetContext) -> None:
        assert ctx.env is env and ctx.model is env.model and ctx.data is env.data
        calls.append(ctx.options)
        robot.set_joint_pos(HOME, call_forward=False)
        env.set_body_pose("cube", CUBE_START)

    env.on_reset = on_reset
    for _ in range(2):
        env.set_body_pose("cube", [0.1, 0.3, 0.9])
        env.step(20)
        info = env.reset()
        assert info.time == 0.0 and info.keyframe is None
        robot.update()
        assert np.allclose(robot.jnt_pos_msr, HOME, atol=0)
        assert np.allclose(env.body_frame("cube").translation, CUBE_START, atol=0)
    assert len(calls) == 2 and isinstance(calls[0], mjk.ResetOptions)


@pytest.mark.parametrize("key", [0, "home", 1, "retract"])
def test_keyframe_reset_restores_qpos_and_ctrl(tutorial_scene, key) -> None:
    env = tutorial_scene(mjk.Env)  # no robot registered: ctrl stays as the keyframe says
    m = env.model
    index = key if isinstance(key, int) else m.key(key).id
    env.data.qpos[:] = 0.3
    env.data.ctrl[:] = 0.7
    info = env.reset(mjk.ResetOptions(keyframe=key, use_keyframe=True))
    assert info.keyframe == index
    assert info.keyframe_name == m.key(index).name
    assert np.array_equal(env.data.qpos, m.key_qpos[index])
    assert np.array_equal(env.data.ctrl, m.key_ctrl[index])


def test_unknown_keyframe_lists_known(tutorial_scene) -> None:
    env = tutorial_scene(mjk.Env)
    with pytest.raises(KeyError, match=r"no keyframe named 'hme'.*home"):
        env.reset(mjk.ResetOptions(keyframe="hme", use_keyframe=True))
    with pytest.raises(KeyError, match="keyframe named '7'"):
        env.reset(mjk.ResetOptions(keyframe=7, use_keyframe=True))


def test_reset_syncs_commands_so_position_mode_holds(env_robot) -> None:
    env, robot = env_robot
    robot.ctrl_mode = mjk.CtrlMode.POSITION
    robot.jnt_pos_cmd = np.zeros(7)  # a stale command that must not survive the reset
    env.on_reset = lambda ctx: robot.set_joint_pos(HOME, call_forward=False)
    env.reset()
    assert np.array_equal(robot.jnt_pos_cmd, robot.jnt_pos_msr)
    assert np.array_equal(robot.jnt_vel_cmd, np.zeros(7))
    assert np.array_equal(robot.jnt_trq_cmd, np.zeros(7))
    for _ in range(100):  # no update(): the reset already applied the synced command
        env.step()
    robot.update()
    assert np.abs(robot.jnt_pos_msr - HOME).max() < 1e-6


@pytest.mark.parametrize("hook", [5, "reset_cube"])
def test_a_hook_that_cannot_be_called_is_refused_when_set(env_robot, hook) -> None:
    env, _ = env_robot
    with pytest.raises(mjk.SpecTypeError) as err:
        env.on_reset = hook
    assert str(err.value) == (
        f"on_reset must be a function of a ResetContext, or None; got {hook!r}"
    )
    assert env.on_reset is None
    assert env.reset().time == 0.0


def test_hook_error_names_hook_and_env_stays_usable(env_robot) -> None:
    env, robot = env_robot

    def broken_hook(ctx: mjk.ResetContext) -> None:
        raise ValueError("cube missing")

    env.on_reset = broken_hook
    with pytest.raises(mjk.ResetHookError, match="broken_hook raised ValueError: cube missing"):
        env.reset()
    env.on_reset = None
    assert env.reset().time == 0.0
    # Usable: stepping the env moves it exactly as MuJoCo alone moves the same state.
    m = env.model
    reference = mujoco.MjData(m)
    mujoco.mj_setState(m, reference, _integration_state(env), _STATE)
    env.step(20)
    mujoco.mj_step(m, reference, 20)
    assert env.time() == pytest.approx(0.04, abs=1e-12)
    np.testing.assert_array_equal(env.data.qpos, reference.qpos)
    robot.update()
    mujoco.mj_kinematics(m, reference)  # poses of the state reached, not of the last step's start
    site = reference.site_xpos[env.site_id("g_pinch")]
    np.testing.assert_allclose(robot.fk_frame().translation, site, rtol=0, atol=1e-9)


_STATE = mujoco.mjtState.mjSTATE_INTEGRATION


def _integration_state(env: mjk.Env) -> np.ndarray:
    state = np.empty(mujoco.mj_stateSize(env.model, _STATE))
    mujoco.mj_getState(env.model, env.data, state, _STATE)
    return state


# ---------------------------------------------------------------------- rebuild


def _state(env: mjk.Env) -> dict[str, np.ndarray]:
    d, m = env.data, env.model
    cube = m.jnt_qposadr[m.joint("cube").id]
    return {
        "qpos": d.qpos.copy(),
        "qvel": d.qvel.copy(),
        "ctrl": d.ctrl.copy(),
        "cube pose": d.qpos[cube : cube + 7].copy(),
        "time": np.array([d.time]),
    }


def test_add_then_remove_keeps_state_and_robot_handles(env_robot) -> None:
    env, robot = env_robot
    env.on_reset = lambda ctx: robot.set_joint_pos(HOME, call_forward=False)
    env.reset()
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    for _ in range(150):  # running, not at rest
        robot.update()
        robot.jnt_trq_cmd = 0.9 * robot.gravity_torques()
        robot.step()
    before = _state(env)
    nbody = env.model.nbody
    env.add_object(_obstacle())
    assert env.model.nbody == nbody + 1
    with_obstacle = _state(env)
    for key in ("time", "ctrl"):
        assert np.array_equal(with_obstacle[key], before[key])
    env.remove_object("obstacle")
    after = _state(env)
    for key, value in before.items():
        assert np.abs(after[key] - value).max() <= 1e-12, key
    robot.update()
    site = env.data.site_xpos[env.site_id("g_pinch")]
    assert np.abs(robot.fk_frame().translation - site).max() < 1e-12
    assert robot.ctrl_mode is mjk.CtrlMode.TORQUE
    assert env.model.actuator_gainprm[0, 0] == 1.0  # the new model is in TORQUE mode too
    assert env.on_reset is not None


def test_rebuild_keeps_a_free_objects_state_by_name(env_robot) -> None:
    env, _ = env_robot
    env.set_body_pose("cube", [0.2, -0.1, 0.9], [0.9, 0.1, 0.3, 0.2])
    env.data.qvel[env.model.jnt_dofadr[env.model.joint("cube").id] + 2] = -0.5
    env.forward()
    cube = env.data.qpos[env.model.jnt_qposadr[env.model.joint("cube").id] :][:7].copy()
    env.add_object(_obstacle())  # inserted before the robot: every address shifts
    j = env.model.joint("cube").id
    assert np.array_equal(env.data.qpos[env.model.jnt_qposadr[j] :][:7], cube)
    assert env.data.qvel[env.model.jnt_dofadr[j] + 2] == -0.5


def test_bad_add_object_leaves_env_running(env_robot) -> None:
    env, robot = env_robot
    model, data = env.model, env.data
    with pytest.raises(ValueError, match=r"duplicate object name 'cube'"):
        env.add_object(_obstacle("cube"))
    bad = _obstacle()
    bad.size = [0.05, 0.05]
    with pytest.raises(ValueError, match="size"):
        env.add_object(bad)
    with pytest.raises(FileNotFoundError, match=r"nowhere\.xml"):
        env.add_object(mjk.SceneObject(name="thing", mjcf_path="nowhere.xml"))
    with pytest.raises(KeyError, match=r"no object named 'cub'.*cube"):
        env.remove_object("cub")
    assert env.model is model and env.data is data
    env.step(10)
    robot.update()
    assert [o.name for o in env.spec.objects] == ["table", "cube"]


def _rss_mb() -> float:
    """Resident memory after returning freed heap pages to the OS (glibc), in MB."""
    gc.collect()
    with contextlib.suppress(OSError):
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    raise RuntimeError("no VmRSS")


@pytest.mark.skipif(not __import__("os").path.exists("/proc/self/status"), reason="needs /proc")
def test_two_hundred_rebuilds_do_not_grow_memory(tmp_path) -> None:
    arm_xml = tmp_path / "two_link.xml"
    arm_xml.write_text(two_link_arm('<actuator><motor joint="j1"/><motor joint="j2"/></actuator>'))
    spec = base_spec(objects=[table_object()], robots=[mjk.RobotSpec(path=str(arm_xml))])
    with mjk.Env.build(spec) as env:
        robot = env.create_robot("base", "l2")
        for _ in range(20):  # warm up allocator pools
            env.add_object(_obstacle())
            env.remove_object("obstacle")
        start = _rss_mb()
        for _ in range(200):
            env.add_object(_obstacle())
            env.remove_object("obstacle")
        grown = _rss_mb() - start
        robot.update()
    assert grown < 5.0, f"{grown:.1f} MB after 200 add/remove cycles"


# ---------------------------------------------------------------------- closed handles


def test_every_call_on_a_closed_env_raises(env_robot) -> None:
    env, robot = env_robot
    env.on_reset = lambda ctx: None
    env.close()
    assert env.on_reset is None  # the hook is dropped with the model
    env.close()  # twice is harmless
    calls = [
        lambda: env.model,
        lambda: env.data,
        lambda: env.spec,
        env.time,
        env.timestep,
        env.step,
        env.forward,
        env.camera_names,
        env.reset,
        lambda: env.has_actuator("joint_1"),
        lambda: env.set_actuator_ctrl("joint_1", 0.0),
        lambda: env.body_frame("cube"),
        lambda: env.site_frame("g_pinch"),
        lambda: env.set_body_pose("cube", [0, 0, 1]),
        lambda: env.create_robot("base_link", "bracelet_link"),
        lambda: env.add_object(_obstacle()),
        lambda: env.remove_object("cube"),
        robot.update,
        robot.step,
        robot.sync_commands,
        robot.fk_frame,
        robot.jacobian,
        robot.gravity_torques,
        robot.mass_matrix,
        robot.nonlinear_effects,
        lambda: robot.inverse_dynamics(HOME, np.zeros(7), np.zeros(7)),
        lambda: robot.ik(robot.fk_frame()),
        lambda: robot.set_joint_pos(HOME),
        lambda: robot.ft_sensor("x"),
        lambda: robot.n_joints,
        lambda: robot.joint_names,
        lambda: robot.joint_limits,
        lambda: robot.model,
        robot.kdl_chain,
        lambda: robot.jnt_pos_msr,
        lambda: robot.jnt_vel_msr,
        lambda: robot.jnt_trq_msr,
        lambda: robot.jnt_pos_cmd,
        lambda: setattr(robot, "jnt_pos_cmd", HOME),
        lambda: setattr(robot, "ctrl_mode", mjk.CtrlMode.TORQUE),
    ]
    for call in calls:
        with pytest.raises(RuntimeError, match="closed"):
            call()


def test_context_manager_closes_on_exception(tutorial_scene) -> None:
    env = tutorial_scene(mjk.Env)
    with pytest.raises(ZeroDivisionError), env:
        env.step()
        1 / 0  # noqa: B018
    assert env.closed
    with pytest.raises(RuntimeError, match="closed"):
        env.time()


def test_closed_env_releases_model_and_data(tutorial_scene) -> None:
    env = tutorial_scene(mjk.Env)
    robot = env.create_robot("base_link", "bracelet_link")
    env.step(3)
    model, data = weakref.ref(env.model), weakref.ref(env.data)
    env.close()
    with pytest.raises(RuntimeError, match="closed"):
        robot.update()
    del robot  # a live handle still refers to the arrays it was bound to
    gc.collect()
    assert data() is None and model() is None, "a closed env still holds MuJoCo's memory"


def test_reset_into_torque_mode_reads_no_leftover_servo_force(env_robot) -> None:
    env, robot = env_robot
    robot.update()  # POSITION servos configured, holding against gravity
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    env.reset(mjk.ResetOptions(keyframe="home", use_keyframe=True))
    assert np.array_equal(robot.jnt_trq_msr, np.zeros(7))


def test_gravity_stays_finite_when_a_hook_reads_before_forward(env_robot) -> None:
    env, robot = env_robot
    j = env.model.joint("g_right_driver_joint").id
    env.data.qpos[env.model.jnt_qposadr[j]] = 0.5  # fingers away from where reset puts them
    env.forward()
    robot.update()
    robot.gravity_torques()

    def hook(ctx: mjk.ResetContext) -> None:
        robot.set_joint_pos(HOME, call_forward=False)
        robot.fk_frame()  # reads before MuJoCo has forwarded the reset data

    env.on_reset = hook
    env.reset()
    robot.update()
    g = robot.gravity_torques()
    assert np.isfinite(g).all()
    assert np.allclose(g, env.data.qfrc_bias[:7], rtol=0, atol=1e-9)


# ---------------------------------------------------------------------- rebuild: nothing lost


def _edit_model_and_state(env: mjk.Env) -> dict[str, float]:
    """Run-time edits a user makes, through MuJoCo's own arrays; returns the values set."""
    m, d = env.model, env.data
    cube, link = env.body_id("cube"), env.body_id("forearm_link")
    cube_geom = m.geom("cube").id
    unnamed = int(np.flatnonzero(m.geom_bodyid == link)[0])  # Gen3's link geoms are unnamed
    assert m.geom(unnamed).name == ""
    assert m.neq == 3 and all(m.eq(e).name == "" for e in range(m.neq))  # the 2F-85's
    edits = {
        "forearm mass": m.body_mass[link] + 0.7,
        "cube friction": 0.31,
        "cube alpha": 0.25,
        "forearm geom margin": 0.004,
        "impratio": 3.0,
        "joint_3 damping": 2.5,
        "qfrc_applied joint_2": 4.0,
        "xfrc_applied cube z": 0.6,
    }
    m.body_mass[link] = edits["forearm mass"]
    m.geom_friction[cube_geom, 0] = edits["cube friction"]
    m.geom_rgba[cube_geom, 3] = edits["cube alpha"]
    m.geom_margin[unnamed] = edits["forearm geom margin"]
    m.opt.impratio = edits["impratio"]
    m.dof_damping[m.joint("joint_3").dofadr[0]] = edits["joint_3 damping"]
    d.qfrc_applied[m.joint("joint_2").dofadr[0]] = edits["qfrc_applied joint_2"]
    d.xfrc_applied[cube, 2] = edits["xfrc_applied cube z"]
    d.eq_active[1] = 0  # one of the gripper's unnamed connect constraints switched off
    return edits


def _read_edits(env: mjk.Env) -> dict[str, float]:
    m, d = env.model, env.data
    link = env.body_id("forearm_link")
    unnamed = int(np.flatnonzero(m.geom_bodyid == link)[0])
    return {
        "forearm mass": m.body_mass[link],
        "cube friction": m.geom_friction[m.geom("cube").id, 0],
        "cube alpha": m.geom_rgba[m.geom("cube").id, 3],
        "forearm geom margin": m.geom_margin[unnamed],
        "impratio": m.opt.impratio,
        "joint_3 damping": m.dof_damping[m.joint("joint_3").dofadr[0]],
        "qfrc_applied joint_2": d.qfrc_applied[m.joint("joint_2").dofadr[0]],
        "xfrc_applied cube z": d.xfrc_applied[env.body_id("cube"), 2],
    }


def test_rebuild_keeps_model_edits_applied_forces_and_eq_active(env_robot) -> None:
    env, robot = env_robot
    env.reset(mjk.ResetOptions(keyframe="home", use_keyframe=True))
    env.step(50)
    edits = _edit_model_and_state(env)
    # The reference: MuJoCo alone continuing on the edited model, state copied before rebuild.
    old_model = env.model
    reference = mujoco.MjData(old_model)
    mujoco.mj_copyData(reference, old_model, env.data)

    env.add_object(_obstacle())  # every address after the cube shifts
    after_add = _read_edits(env)
    assert np.array_equal(env.data.eq_active, [1, 0, 1])
    for key, value in edits.items():
        assert after_add[key] == pytest.approx(value, abs=1e-15), key
    assert env.model.body_mass[env.body_id("obstacle")] == pytest.approx(0.5)  # authored
    env.remove_object("obstacle")
    for key, value in edits.items():
        assert _read_edits(env)[key] == pytest.approx(value, abs=1e-15), key
    assert np.array_equal(env.data.eq_active, [1, 0, 1])

    # The rebuilt scene evolves exactly like MuJoCo on the edited old model.
    env.step(100)
    mujoco.mj_step(old_model, reference, 100)
    np.testing.assert_allclose(env.data.qpos, reference.qpos, rtol=0, atol=1e-12)
    np.testing.assert_allclose(env.data.qvel, reference.qvel, rtol=0, atol=1e-9)
    robot.update()


# ---------------------------------------------------------------------- rebuild: unnamed elements

# A robot with two unnamed bodies, each with an unnamed joint, three unnamed geoms and two
# unnamed motors on one joint, with a mocap target, a ball joint, an activation state and an
# (inactive, unnamed) weld; no camera.
RICH_ROBOT = """
<mujoco model="rich">
  <worldbody>
    <body name="target" mocap="true" pos="0.5 0 0.5">
      <geom type="sphere" size="0.01" contype="0" conaffinity="0"/>
    </body>
    <body name="lift" pos="0 2 0.5">
      <joint name="lift" type="slide" axis="0 0 1"/>
      <geom type="sphere" size="0.02"/>
    </body>
    <body pos="0 1 0.5">
      <joint axis="0 0 1"/>
      <geom type="sphere" size="0.02"/>
      <geom type="sphere" size="0.02" pos="0.05 0 0"/>
      <geom type="sphere" size="0.02" pos="0.1 0 0"/>
      <body name="arm" pos="0 0 0.1">
        <joint name="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02"/>
        <body name="wrist" pos="0.2 0 0">
          <joint name="ball" type="ball"/>
          <geom type="sphere" size="0.02"/>
          <body name="finger">
            <joint name="slide" type="slide" axis="1 0 0"/>
            <geom type="sphere" size="0.01"/>
          </body>
        </body>
      </body>
    </body>
    <body pos="0 -1 0.5">
      <joint type="slide" axis="0 0 1"/>
      <geom type="sphere" size="0.02"/>
    </body>
  </worldbody>
  <equality>
    <weld body1="arm" body2="wrist" active="false"/>
    <joint joint1="lift" active="false"/>
  </equality>
  <actuator>
    <motor joint="hinge"/>
    <motor joint="hinge"/>
    <position name="servo" joint="hinge" kp="10"/>
    <general name="integ" joint="hinge" dyntype="integrator" dynprm="1" gainprm="1"/>
  </actuator>
</mujoco>
"""
# An object with a slide joint, a motor of its own and an unnamed one, and an unnamed
# equality: in the rebuilt model they come before the robot's unnamed ones.
GADGET = """
<mujoco model="gadget">
  <worldbody>
    <body name="carriage">
      <joint name="slide" type="slide" axis="0 0 1"/>
      <geom type="box" size="0.02 0.02 0.02"/>
    </body>
  </worldbody>
  <equality><joint joint1="slide" active="false"/></equality>
  <actuator><motor name="push" joint="slide"/><motor joint="slide"/></actuator>
</mujoco>
"""


@pytest.fixture(scope="module")
def rich_files(tmp_path_factory) -> tuple[str, str]:
    folder = tmp_path_factory.mktemp("rich")
    (folder / "rich.xml").write_text(RICH_ROBOT)
    (folder / "gadget.xml").write_text(GADGET)
    return str(folder / "rich.xml"), str(folder / "gadget.xml")


def test_rebuild_matches_elements_by_name_past_unnamed_ones(rich_files) -> None:
    robot_xml, gadget_xml = rich_files
    # fixed: the robot's first joint is joint 0 until the gadget comes in before it
    crate = mjk.SceneObject(
        name="crate", shape=mjk.Shape.BOX, size=[0.1] * 3, mass=1, pos=[1, 0, 1], fixed=True
    )
    spec = base_spec(robots=[mjk.RobotSpec(path=robot_xml)], objects=[crate])
    with mjk.Env.build(spec) as env:
        m, d = env.model, env.data
        assert m.ncam == 0 and m.nmocap == 1 and m.na == 1
        first, second = _unnamed_joints(m)
        adr = {n: m.joint(n).qposadr[0] for n in ("hinge", "ball", "slide")}
        d.qpos[m.jnt_qposadr[first]] = 0.4
        d.qpos[m.jnt_qposadr[second]] = -0.2
        d.qfrc_applied[m.jnt_dofadr[second]] = 3.0
        d.xfrc_applied[m.jnt_bodyid[second]] = [0, 0, 9, 0, 0, 0]  # an unnamed body's
        d.qpos[adr["hinge"]] = 0.3
        d.qpos[adr["ball"] : adr["ball"] + 4] = [0.5, 0.5, 0.5, 0.5]
        d.qpos[adr["slide"]] = 0.07
        d.ctrl[:] = [1.5, 2.5, 0.25, -0.75]
        d.eq_active[_equality(m, "joint")] = 1  # switched on at run time
        d.act[0] = 0.125
        d.mocap_pos[0] = [0.1, 0.2, 0.3]
        d.mocap_quat[0] = [0, 1, 0, 0]
        d.xfrc_applied[0] = [1, 2, 3, 4, 5, 6]  # the world body's (MuJoCo ignores it)
        d.xfrc_applied[m.body("wrist").id] = [0, 0, 7, 0, 0, 0]
        middle_geom = int(np.flatnonzero(m.geom_bodyid == m.body("arm").id - 1)[1])
        m.geom_rgba[middle_geom] = [0.1, 0.2, 0.3, 0.4]
        m.eq_solref[_equality(m, "weld")] = [0.05, 0.5]
        m.body_mass[m.body("crate").id] = 3.5
        m.body_mass[m.body("target").id] = 0.75  # a world child after the new object

        gadget = mjk.SceneObject(name="gadget", mjcf_path=gadget_xml, fixed=True, pos=[0, -1, 0])
        env.add_object(gadget)  # its body and joint come before the robot's
        m, d = env.model, env.data
        adr = {n: m.joint(n).qposadr[0] for n in ("hinge", "ball", "slide", "gadget/slide")}
        first, second = _unnamed_joints(m)
        # unnamed elements are matched by their place: body (itself by its place), rank
        assert d.qpos[m.jnt_qposadr[first]] == 0.4
        assert d.qpos[m.jnt_qposadr[second]] == -0.2
        assert d.qfrc_applied[m.jnt_dofadr[second]] == 3.0
        assert list(d.xfrc_applied[m.jnt_bodyid[second]]) == [0, 0, 9, 0, 0, 0]
        assert d.qpos[adr["gadget/slide"]] == 0.0  # the new object's: MuJoCo's default
        assert d.qpos[adr["hinge"]] == 0.3
        assert list(d.qpos[adr["ball"] : adr["ball"] + 4]) == [0.5, 0.5, 0.5, 0.5]
        assert d.qpos[adr["slide"]] == 0.07
        names = [m.actuator(a).name for a in range(m.nu)]
        assert names == ["gadget/push", "", "", "", "servo", "integ"]
        assert list(d.ctrl) == [0.0, 0.0, 1.5, 2.5, 0.25, -0.75]
        assert list(d.act) == [0.125]
        assert list(d.mocap_pos[0]) == [0.1, 0.2, 0.3]
        assert list(d.mocap_quat[0]) == [0, 1, 0, 0]
        assert list(d.xfrc_applied[0]) == [1, 2, 3, 4, 5, 6]
        assert list(d.xfrc_applied[m.body("wrist").id]) == [0, 0, 7, 0, 0, 0]
        middle_geom = int(np.flatnonzero(m.geom_bodyid == m.body("arm").id - 1)[1])
        assert m.geom_rgba[middle_geom].tolist() == pytest.approx([0.1, 0.2, 0.3, 0.4])
        assert m.eq_solref[_equality(m, "weld")].tolist() == [0.05, 0.5]
        gadget_eq, lift_eq = np.flatnonzero(m.eq_type == mujoco.mjtEq.mjEQ_JOINT)
        assert m.eq_obj1id[gadget_eq] == m.joint("gadget/slide").id
        assert (d.eq_active[gadget_eq], d.eq_active[lift_eq]) == (0, 1)
        assert m.body_mass[m.body("crate").id] == 3.5
        assert m.body_mass[m.body("target").id] == 0.75


def test_rebuild_keeps_an_unnamed_equality_of_one_joint_apart_from_a_new_one(rich_files):
    gadget_xml = rich_files[1]
    first = mjk.SceneObject(name="g1", mjcf_path=gadget_xml, fixed=True)
    with mjk.Env.build(base_spec(objects=[first])) as env:
        assert (env.model.neq, env.model.eq_obj2id[0]) == (1, -1)  # ties g1/slide alone
        env.data.eq_active[0] = 1
        env.add_object(mjk.SceneObject(name="g2", mjcf_path=gadget_xml, fixed=True, pos=[1, 0, 0]))
        m, d = env.model, env.data
        ties = [m.joint(int(j)).name for j in m.eq_obj1id]
        assert ties == ["g1/slide", "g2/slide"]
        assert d.eq_active.tolist() == [1, 0]


def _unnamed_joints(m: mujoco.MjModel) -> list[int]:
    return [j for j in range(m.njnt) if not m.joint(j).name]


def _equality(m: mujoco.MjModel, kind: str) -> int:
    """The robot's one equality of type `kind` ("weld" or "joint"), the last of its type."""
    return int(np.flatnonzero(m.eq_type == getattr(mujoco.mjtEq, f"mjEQ_{kind.upper()}"))[-1])


def test_joint_sizes_match_mujocos_addresses() -> None:
    m = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><freejoint/><geom size='.1'/><body><joint type='ball'/>"
        "<geom size='.1'/><body><joint type='slide'/><geom size='.1'/><body><joint/>"
        "<geom size='.1'/><body><joint type='ball'/><geom size='.1'/></body></body></body>"
        "</body></body></worldbody></mujoco>"
    )
    qend = [*m.jnt_qposadr[1:], m.nq]
    vend = [*m.jnt_dofadr[1:], m.nv]
    for j in range(m.njnt):
        expected = (qend[j] - m.jnt_qposadr[j], vend[j] - m.jnt_dofadr[j])
        assert mjk.scene.joint_sizes(int(m.jnt_type[j])) == expected, m.jnt_type[j]
    assert [int(t) for t in m.jnt_type] == [0, 1, 2, 3, 1]


# ---------------------------------------------------------------- keyframes and hooks, in full


def test_keyframe_id_accepts_names_and_in_range_integers_only(tutorial_scene) -> None:
    env = tutorial_scene(mjk.Env)
    m = env.model
    assert [m.key(k).name for k in range(m.nkey)] == ["home", "retract"]
    assert env.keyframe_id("retract") == 1
    assert env.keyframe_id(np.int64(1)) == 1
    for key in (2, -1, "7"):
        with pytest.raises(mjk.UnknownNameError) as err:
            env.keyframe_id(key)
        where = " in the scene" if isinstance(key, str) else " in the scene (2 keyframes)"
        assert err.value.args[0] == f"no keyframe named '{key}'{where}; known: home, retract"
    for key in (True, 1.0, None):
        with pytest.raises(mjk.SpecTypeError) as err:
            env.keyframe_id(key)
        assert str(err.value) == f"keyframe must be an index or a name, got {key!r}"
    with pytest.raises(mjk.SpecTypeError) as err:  # "no" is not False
        env.reset(mjk.ResetOptions(keyframe=1, use_keyframe="no"))
    assert str(err.value) == "ResetOptions.use_keyframe must be True or False, got 'no'"
    message = "reset() takes ResetOptions, got dict"
    with pytest.raises(mjk.SpecError, match=f"^{re.escape(message)}$"):
        env.reset({"keyframe": "home"})


class _Hook:
    def __call__(self, ctx: mjk.ResetContext) -> None:
        raise ValueError("cube missing")

    def __repr__(self) -> str:
        return "Hook()"


def test_hook_error_names_the_hooks_module_and_qualified_name(tutorial_scene) -> None:
    env = tutorial_scene(mjk.Env)

    def broken_hook(ctx: mjk.ResetContext) -> None:
        raise ValueError("cube missing")

    where = f"{__name__}.test_hook_error_names_the_hooks_module_and_qualified_name.<locals>"
    nowhere = eval("lambda ctx: 1 / 0", {"__name__": "not_a_module"})  # no module to find
    cases = [
        (broken_hook, f"{where}.broken_hook raised ValueError: cube missing"),
        (_Hook(), f"{__name__}.Hook() raised ValueError: cube missing"),  # no __qualname__
        (nowhere, "<lambda> raised ZeroDivisionError: division by zero"),
    ]
    for hook, text in cases:
        env.on_reset = hook
        with pytest.raises(mjk.ResetHookError) as err:
            env.reset()
        assert err.value.args[0] == f"reset hook {text}"
        assert type(err.value.__cause__) is (ZeroDivisionError if hook is nowhere else ValueError)


# ---------------------------------------------------------------------- a robot on an object

SERVOS = (
    '<actuator><position name="s1" joint="j1" kp="50" ctrlrange="-1 1"/>'
    '<position name="s2" joint="j2" kp="20" kv="2"/></actuator>'
)


@pytest.fixture(scope="module")
def arm_object_xml(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("arm") / "arm.xml"
    path.write_text(two_link_arm(SERVOS))
    return str(path)


def _arm_object_env(arm_object_xml: str) -> tuple[mjk.Env, mjk.Robot]:
    arm = mjk.SceneObject(name="arm", mjcf_path=arm_object_xml, fixed=True)
    env = mjk.Env.build(base_spec(objects=[arm]))
    return env, env.create_robot("base", "l2", prefix="arm/")


def test_closing_a_robot_gives_its_actuators_back_as_authored(arm_object_xml) -> None:
    authored = mujoco.MjModel.from_xml_string(two_link_arm(SERVOS))
    env, robot = _arm_object_env(arm_object_xml)
    with env:
        m = env.model
        robot.ctrl_mode = mjk.CtrlMode.TORQUE
        robot.update()
        env.step()
        assert m.actuator_biasprm[:, :3].tolist() == [[0.0] * 3] * 2  # a motor now
        assert m.actuator_ctrllimited.tolist() == [0, 0]
        robot.close()
        for field in ("gaintype", "biastype", "gainprm", "biasprm", "ctrllimited"):
            name = f"actuator_{field}"
            assert getattr(m, name).tolist() == getattr(authored, name).tolist(), field
        assert m.actuator_biasprm[:, :3].tolist() == [[0.0, -50.0, 0.0], [0.0, -20.0, -2.0]]
        assert m.actuator_ctrllimited.tolist() == [1, 0]
        other = mjk.Env.build(base_spec())
        with other, pytest.raises(mjk.SpecError) as err:
            other.remove_robot(robot)
        assert err.value.args[0] == "remove_robot: this Robot is not registered with this scene"


def test_a_rebuild_that_removes_a_robots_chain_keeps_the_old_model(arm_object_xml) -> None:
    env, robot = _arm_object_env(arm_object_xml)
    with env:
        model, data, spec = env.model, env.data, env.spec
        robot.ctrl_mode = mjk.CtrlMode.TORQUE
        robot.jnt_trq_cmd = [0.5, -0.25]
        message = "no body named 'arm/base' in the model; known: world"
        with pytest.raises(mjk.UnknownNameError, match=f"^{re.escape(message)}$"):
            env.remove_object("arm")
        assert env.model is model and env.data is data and env.spec is spec
        assert [o.name for o in env.spec.objects] == ["arm"]
        robot.step()  # the handle drives the old model's actuators
        assert data.ctrl.tolist() == [0.5, -0.25]
        assert model.actuator_gainprm[:, 0].tolist() == [1.0, 1.0]
        robot.update()
        assert robot.jnt_pos_msr.tolist() == data.qpos.tolist()
        data.qvel[0] = np.nan
        with pytest.raises(mjk.SimulationError, match="mjWARN_BADQVEL"):
            env.step()  # the fault counters watch the old data again


def test_a_body_that_became_mocap_in_the_file_starts_where_the_file_puts_it(tmp_path) -> None:
    path = tmp_path / "stand.xml"
    body = '<body name="target" pos="0.5 0 0.5"{}><geom size="0.01" contype="0"/></body>'
    xml = "<mujoco><worldbody><body name='post'><geom size='0.1'/></body>{}</worldbody></mujoco>"
    path.write_text(xml.format(body.format("")))
    with mjk.Env.build(base_spec(robots=[mjk.RobotSpec(path=str(path))])) as env:
        assert env.model.nmocap == 0
        path.write_text(xml.format(body.format(' mocap="true"')))  # edited on disk meanwhile
        env.add_object(_obstacle())  # recompiles the robot from its file
        assert env.model.nmocap == 1
        assert env.data.mocap_pos[0].tolist() == [0.5, 0.0, 0.5]


def test_a_rebuild_keeps_run_time_option_edits_and_takes_the_files_new_options(tmp_path) -> None:
    path = tmp_path / "post.xml"
    xml = "<mujoco><option impratio='{}'/><worldbody><body name='post'><geom size='0.1'/></body>"
    path.write_text(xml.format(5) + "</worldbody></mujoco>")
    with mjk.Env.build(base_spec(robots=[mjk.RobotSpec(path=str(path))])) as env:
        assert env.model.opt.impratio == 5.0
        env.model.opt.timestep = 0.001  # a run-time edit
        path.write_text(xml.format(7) + "</worldbody></mujoco>")  # edited on disk meanwhile
        env.add_object(_obstacle())
        assert (env.model.opt.timestep, env.model.opt.impratio) == (0.001, 7.0)
