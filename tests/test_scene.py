"""The `Scene` runtime owner: clock, actuators, poses, free bodies, closing."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import ROOT, base_spec

import mjkdl as mjk
from mjkdl import scene as scene_module

CUBE_POSE = [0.35, 0.10, 0.725, 1.0, 0.0, 0.0, 0.0]


def _cube_qpos(scene: mjk.Scene) -> tuple[int, int]:
    m = scene.model
    j = m.joint("cube").id
    return m.jnt_qposadr[j], m.jnt_dofadr[j]


def _small_scene() -> mjk.Scene:
    cube = mjk.SceneObject(
        name="cube", shape=mjk.Shape.BOX, size=[0.02, 0.02, 0.02], mass=0.1, pos=[0, 0, 0.02]
    )
    return mjk.Scene.build(base_spec(objects=[cube]))


def test_mujoco_version():
    assert mjk.mujoco_version() == mujoco.__version__


def test_clock(tutorial_scene):
    scene = tutorial_scene()
    assert scene.timestep() == 0.002
    assert scene.time() == 0.0
    scene.step()
    assert scene.time() == pytest.approx(0.002, abs=1e-15)
    scene.step(10)
    assert scene.time() == pytest.approx(11 * 0.002, abs=1e-12)
    scene.step(np.int64(3))
    assert scene.time() == pytest.approx(14 * 0.002, abs=1e-12)
    scene.step(0)
    assert scene.time() == pytest.approx(14 * 0.002, abs=1e-12)


@pytest.mark.parametrize("n", [2**31, np.int64(2**40)])
def test_step_refuses_more_steps_than_mujoco_counts(n):
    with _small_scene() as scene:
        with pytest.raises(mjk.SpecError) as err:
            scene.step(n)
        assert str(err.value) == (
            f"step(n): n must be at most 2147483647 (MuJoCo counts steps in a C int), got {n!r}; "
            "step in several calls"
        )
        assert scene.time() == 0.0


@pytest.mark.parametrize("n", [-1, 2.5, "3", 2.0, 1.0])
def test_step_rejects_bad_counts(n):
    message = f"step(n): n must be a non-negative integer, got {n!r}"
    with _small_scene() as scene, pytest.raises(mjk.SpecError, match=f"^{re.escape(message)}$"):
        scene.step(n)
    assert scene.closed


def test_step_matches_mujoco(tutorial_scene):
    scene = tutorial_scene()
    m = scene.model
    data = mujoco.MjData(m)
    mujoco.mj_forward(m, data)
    scene.step(25)
    mujoco.mj_step(m, data, 25)
    np.testing.assert_array_equal(scene.data.qpos, data.qpos)
    assert scene.time() == data.time


def test_forward_updates_poses(tutorial_scene):
    scene = tutorial_scene()
    data = scene.data
    i = scene.body_id("bracelet_link")
    before = data.xpos[i].copy()
    data.qpos[scene.model.joint("joint_2").qposadr[0]] += 0.3
    np.testing.assert_array_equal(data.xpos[i], before)  # nothing recomputed yet
    scene.forward()
    assert np.linalg.norm(data.xpos[i] - before) > 0.05


def test_actuators(tutorial_scene):
    scene = tutorial_scene()
    assert scene.has_actuator("joint_1")
    assert scene.has_actuator("g_fingers_actuator")
    assert not scene.has_actuator("fingers_actuator")
    assert not scene.has_actuator("joint_8")
    scene.set_actuator_ctrl("joint_3", 1.25)
    scene.set_actuator_ctrl("g_fingers_actuator", 200)
    assert scene.data.ctrl[scene.actuator_id("joint_3")] == 1.25
    assert scene.data.ctrl[scene.actuator_id("g_fingers_actuator")] == 200.0


def test_set_actuator_ctrl_unknown_name_lists_close_matches(tutorial_scene):
    scene = tutorial_scene()
    with pytest.raises(KeyError, match=r"actuator named 'joint_8'.*close matches: .*joint_7"):
        scene.set_actuator_ctrl("joint_8", 0.0)
    with pytest.raises(KeyError, match=r"'fingers_actuator'.*g_fingers_actuator"):
        scene.set_actuator_ctrl("fingers_actuator", 0.0)


@pytest.mark.parametrize("value", [float("nan"), float("inf")])
def test_set_actuator_ctrl_rejects_non_finite(tutorial_scene, value):
    scene = tutorial_scene()
    with pytest.raises(ValueError, match=r"set_actuator_ctrl\('joint_1'\).*finite"):
        scene.set_actuator_ctrl("joint_1", value)
    assert scene.data.ctrl[scene.actuator_id("joint_1")] == 0.0


def test_body_and_site_frames_match_mujoco(tutorial_scene):
    scene = tutorial_scene()
    data = scene.data
    mujoco.mj_resetDataKeyframe(scene.model, data, scene.model.key("home").id)
    scene.forward()
    for name in ("base_link", "bracelet_link", "g_base", "cube"):
        frame = scene.body_frame(name)
        assert isinstance(frame, pin.SE3)
        i = scene.body_id(name)
        np.testing.assert_array_equal(frame.translation, data.xpos[i])
        np.testing.assert_array_equal(frame.rotation, data.xmat[i].reshape(3, 3))
    for name in ("pinch_site", "g_pinch", "table/table_top"):
        frame = scene.site_frame(name)
        i = scene.site_id(name)
        np.testing.assert_array_equal(frame.translation, data.site_xpos[i])
        np.testing.assert_array_equal(frame.rotation, data.site_xmat[i].reshape(3, 3))
    # a copy, not a view: stepping does not change a frame already returned
    frame = scene.body_frame("bracelet_link")
    before = frame.translation.copy()
    data.xpos[scene.body_id("bracelet_link")] += 1.0
    np.testing.assert_array_equal(frame.translation, before)


def test_frames_unknown_names(tutorial_scene):
    scene = tutorial_scene()
    with pytest.raises(KeyError, match=r"body named 'base_lnk'.*base_link"):
        scene.body_frame("base_lnk")
    with pytest.raises(KeyError, match=r"site named 'pinch'.*g_pinch"):
        scene.site_frame("pinch")


@pytest.mark.parametrize("name", [None, 3, b"joint_1"])
def test_lookups_refuse_names_that_are_not_text(tutorial_scene, name):
    # MuJoCo's mj_name2id crashes the interpreter on None: no lookup may reach it with one.
    scene = tutorial_scene()
    with pytest.raises(mjk.SpecTypeError) as err:
        scene.has_actuator(name)
    assert str(err.value) == f"has_actuator(name) must be a string, got {name!r}"
    with pytest.raises(mjk.SpecTypeError) as err:
        scene.remove_object(name)
    assert str(err.value) == f"remove_object(name) must be a string, got {name!r}"
    for call, kind in (
        (scene.body_frame, "body"),
        (scene.site_frame, "site"),
        (scene.actuator_id, "actuator"),
        (lambda n: scene.set_actuator_ctrl(n, 0.0), "actuator"),
        (lambda n: scene.set_body_pose(n, [0.0, 0.0, 0.0]), "body"),
    ):
        with pytest.raises(mjk.SpecTypeError) as err:
            call(name)
        assert str(err.value) == f"{kind} name in the scene must be a string, got {name!r}"


def test_a_name_cut_by_a_nul_byte_is_not_found(tutorial_scene):
    # MuJoCo reads names as C strings: "base_link\0x" would find base_link.
    scene = tutorial_scene()
    with pytest.raises(KeyError) as err:
        scene.body_frame("base_link\x00x")
    assert err.value.args[0].startswith("no body named 'base_link\\x00x' in the scene")
    with pytest.raises(mjk.SpecError) as err:
        scene.has_actuator("joint_1\x00")
    assert str(err.value) == "has_actuator(name) contains a NUL byte: 'joint_1\\x00'"


def test_set_body_pose_free_cube(tutorial_scene):
    scene = tutorial_scene()
    adr, dof = _cube_qpos(scene)
    np.testing.assert_allclose(scene.data.qpos[adr : adr + 7], CUBE_POSE, atol=1e-12)
    scene.data.qvel[dof : dof + 6] = [0.1, 0.2, 0.3, 1.0, 2.0, 3.0]

    scene.set_body_pose("cube", [0.4, -0.1, 0.9], [2.0, 0.0, 0.0, 2.0])
    np.testing.assert_allclose(scene.data.qpos[adr : adr + 3], [0.4, -0.1, 0.9], atol=0)
    half = np.sqrt(0.5)
    np.testing.assert_allclose(scene.data.qpos[adr + 3 : adr + 7], [half, 0, 0, half], atol=1e-15)
    np.testing.assert_array_equal(scene.data.qvel[dof : dof + 6], np.zeros(6))
    scene.forward()
    frame = scene.body_frame("cube")
    np.testing.assert_allclose(frame.translation, [0.4, -0.1, 0.9], atol=1e-15)
    rz90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(frame.rotation, rz90, atol=1e-12)

    scene.data.qvel[dof : dof + 6] = 1.0
    scene.set_body_pose("cube", [0.3, 0.0, 0.8])  # quat=None keeps the orientation
    np.testing.assert_allclose(scene.data.qpos[adr : adr + 3], [0.3, 0.0, 0.8], atol=0)
    np.testing.assert_allclose(scene.data.qpos[adr + 3 : adr + 7], [half, 0, 0, half], atol=1e-15)
    np.testing.assert_array_equal(scene.data.qvel[dof : dof + 6], np.zeros(6))


def test_set_body_pose_errors(tutorial_scene):
    scene = tutorial_scene()
    with pytest.raises(ValueError, match=r"set_body_pose\('base_link'\).*no free joint"):
        scene.set_body_pose("base_link", [0, 0, 0])
    with pytest.raises(ValueError, match=r"'table/table'.*no free joint"):
        scene.set_body_pose("table/table", [0, 0, 0])
    with pytest.raises(KeyError, match=r"body named 'cub'.*cube"):
        scene.set_body_pose("cub", [0, 0, 0])
    with pytest.raises(ValueError, match=r"set_body_pose\('cube'\)\.pos.*3 values"):
        scene.set_body_pose("cube", [0, 0])
    with pytest.raises(ValueError, match=r"set_body_pose\('cube'\)\.quat.*4 values"):
        scene.set_body_pose("cube", [0, 0, 0], [1, 0, 0])
    with pytest.raises(ValueError, match=r"set_body_pose\('cube'\)\.quat.*non-zero"):
        scene.set_body_pose("cube", [0, 0, 0], [0, 0, 0, 0])
    with pytest.raises(ValueError, match=r"set_body_pose\('cube'\)\.pos.*finite"):
        scene.set_body_pose("cube", [0, float("nan"), 0])
    adr, _ = _cube_qpos(scene)
    np.testing.assert_allclose(scene.data.qpos[adr : adr + 7], CUBE_POSE, atol=1e-12)


CLOSED_CALLS = {
    "model": lambda s: s.model,
    "data": lambda s: s.data,
    "spec": lambda s: s.spec,
    "time": lambda s: s.time(),
    "timestep": lambda s: s.timestep(),
    "step": lambda s: s.step(),
    "step(5)": lambda s: s.step(5),
    "forward": lambda s: s.forward(),
    "refresh_poses": lambda s: s.refresh_poses(),
    "camera_names": lambda s: s.camera_names(),
    "has_actuator": lambda s: s.has_actuator("joint_1"),
    "set_actuator_ctrl": lambda s: s.set_actuator_ctrl("joint_1", 0.0),
    "body_frame": lambda s: s.body_frame("cube"),
    "site_frame": lambda s: s.site_frame("pinch_site"),
    "set_body_pose": lambda s: s.set_body_pose("cube", [0, 0, 1]),
    "body_id": lambda s: s.body_id("cube"),
    "site_id": lambda s: s.site_id("pinch_site"),
    "actuator_id": lambda s: s.actuator_id("joint_1"),
    "create_robot": lambda s: s.create_robot("base_link", "bracelet_link"),
    "describe": lambda s: s.describe(),
    "remove_robot": lambda s: s.remove_robot(None),
    "add_object": lambda s: s.add_object(
        mjk.SceneObject(name="ball", shape=mjk.Shape.SPHERE, size=[0.02], mass=0.1)
    ),
    "remove_object": lambda s: s.remove_object("cube"),
    "enter": lambda s: s.__enter__(),
    "auto_reset": lambda s: s.auto_reset,
    "auto_reset=": lambda s: setattr(s, "auto_reset", True),
}


def test_closed_scene_raises_everywhere(tutorial_scene):
    scene = tutorial_scene()
    assert not scene.closed
    scene.close()
    assert scene.closed
    public = {n for n in dir(scene) if not n.startswith("_")} - {"build", "close", "closed"}
    assert public <= {name.split("(")[0] for name in CLOSED_CALLS}, "untested public method"
    for name, call in CLOSED_CALLS.items():
        with pytest.raises(RuntimeError, match="closed"):
            call(scene)
            pytest.fail(f"{name} did not raise on a closed scene")
    scene.close()  # twice is harmless
    assert scene.closed


def test_context_manager_closes_even_on_exception():
    with _small_scene() as scene:
        assert scene.time() == 0.0
    assert scene.closed

    with pytest.raises(ZeroDivisionError), _small_scene() as scene:
        scene.step()
        1 / 0  # noqa: B018
    assert scene.closed
    with pytest.raises(RuntimeError):
        scene.time()


def test_build_rejects_non_spec():
    with pytest.raises(ValueError, match="SceneSpec"):
        mjk.Scene.build({"timestep": 0.002})


def test_build_keeps_a_private_copy_of_the_spec():
    spec = base_spec(
        objects=[mjk.SceneObject(name="b", shape=mjk.Shape.SPHERE, size=[0.1], mass=1.0)]
    )
    with mjk.Scene.build(spec) as scene:
        spec.objects[0].name = "renamed"
        spec.timestep = 0.5
        assert scene.spec.objects[0].name == "b"
        assert scene.spec.timestep == 0.002
        assert scene.timestep() == 0.002


# ---------------------------------------------------------------------- divergence


def _ball_env() -> mjk.Env:
    ball = mjk.SceneObject(
        name="ball", shape=mjk.Shape.SPHERE, size=[0.05], mass=0.2, pos=[0, 0, 0.5]
    )
    return mjk.Env.build(base_spec(timestep=0.01, objects=[ball]))


def test_divergence_raises_naming_the_warning_and_the_time():
    with _ball_env() as env:
        env.step(7)
        env.data.qvel[2] = np.nan
        pattern = r"by t = 0\.08 s: Nan, Inf or huge value in QVEL at DOF 2"
        with pytest.raises(mjk.SimulationError, match=pattern) as err:
            env.step()
        assert isinstance(err.value, RuntimeError) and isinstance(err.value, mjk.MjkdlError)
        assert err.value.time == pytest.approx(0.08, abs=1e-12)  # 8 steps of 10 ms
        assert err.value.warnings["mjWARN_BADQVEL"] == (1, 2)  # once, at DOF 2
        assert np.isnan(env.data.qvel[2])  # kept for inspection, not silently reset
        with pytest.raises(mjk.SimulationError, match=r"by t = 0\.09 s.*mjWARN_BADQVEL x1"):
            env.step()  # still NaN: raises again
        env.reset()
        env.step(3)
        assert env.time() == pytest.approx(0.03, abs=1e-12)


def test_divergence_inside_step_n_and_bad_ctrl_are_reported(tutorial_scene):
    scene = tutorial_scene()
    scene.data.ctrl[0] = np.inf
    with pytest.raises(mjk.SimulationError, match=r"CTRL.*mjWARN_BADCTRL"):
        scene.step(5)
    with _ball_env() as env:
        env.data.qpos[0] = 1e300
        with pytest.raises(mjk.SimulationError, match=r"QPOS.*mjWARN_BADQPOS") as err:
            env.step(4)
        assert err.value.time == pytest.approx(0.04, abs=1e-12)


def test_auto_reset_is_mujocos_own_silent_reset():
    with _ball_env() as env:
        assert env.auto_reset is False
        assert env.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_AUTORESET
        env.auto_reset = True
        env.step(5)
        env.data.qvel[2] = np.nan
        m = env.model
        reference = mujoco.MjData(m)  # MuJoCo alone on the same model and state
        mujoco.mj_setState(m, reference, _full_state(m, env.data), _STATE)
        env.step()
        mujoco.mj_step(m, reference)
        assert env.time() == reference.time == pytest.approx(0.01, abs=1e-12)  # reset, 1 step
        np.testing.assert_array_equal(env.data.qpos, reference.qpos)
        assert env.data.warning[mujoco.mjtWarning.mjWARN_BADQVEL].number == 1
        env.step(3)  # keeps going without raising
        with pytest.raises(ValueError, match="auto_reset must be True or False"):
            env.auto_reset = 1


_STATE = mujoco.mjtState.mjSTATE_INTEGRATION


def _full_state(m: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
    state = np.empty(mujoco.mj_stateSize(m, _STATE))
    mujoco.mj_getState(m, d, state, _STATE)
    return state


def test_mujoco_log_goes_to_the_documented_place_not_the_working_directory(tmp_path):
    """MuJoCo's default handler appends warnings to ./MUJOCO_LOG.TXT; mjkdl moves the file."""
    work, log = tmp_path / "work", tmp_path / "logs" / "mujoco.txt"
    work.mkdir()
    script = (
        "import numpy as np, mujoco, mjkdl as mjk\n"
        "print(mjk.mujoco_log_path())\n"
        "m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><body><freejoint/>"
        '<geom size="0.1"/></body></worldbody></mujoco>\')\n'
        "d = mujoco.MjData(m)\n"
        "d.qvel[0] = np.nan\n"
        "mujoco.mj_step(m, d)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MJKDL_MUJOCO_LOG": str(log)}
    done = subprocess.run(
        [sys.executable, "-c", script],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[0] == str(log)
    assert "Nan, Inf or huge value in QVEL" in log.read_text()
    assert list(work.iterdir()) == []
    default = mjk.mujoco_log_path()  # this process: no MJKDL_MUJOCO_LOG set by the tests
    assert os.path.isabs(default) and Path(default).parent.is_dir()
    assert Path(default).parent != Path.cwd()


def test_auto_reset_choice_survives_a_rebuild():
    crate = mjk.SceneObject(
        name="crate", shape=mjk.Shape.BOX, size=[0.1] * 3, mass=1, pos=[1, 0, 1]
    )
    with _ball_env() as env:
        env.add_object(crate)
        assert env.auto_reset is False
        env.data.qvel[2] = np.nan
        with pytest.raises(mjk.SimulationError, match="mjWARN_BADQVEL"):
            env.step()
        env.reset()
        env.auto_reset = True
        env.remove_object("crate")
        assert env.auto_reset is True
        env.data.qvel[2] = np.nan
        env.step()  # MuJoCo's silent reset, as chosen
        assert env.time() == pytest.approx(0.01, abs=1e-12)


def _crowded_scene(memory: str) -> mjk.Scene:
    """30 boxes on a plane, compiled with a `<size memory>` too small for their contacts."""
    boxes = "".join(
        f'<body pos="{0.05 * i} 0 {0.05 + 0.001 * i}"><freejoint/>'
        '<geom type="box" size=".03 .03 .03"/></body>'
        for i in range(30)
    )
    model = mujoco.MjModel.from_xml_string(
        f'<mujoco><size memory="{memory}"/><worldbody><geom type="plane" size="1 1 .1"/>'
        f"{boxes}</worldbody></mujoco>"
    )
    return mjk.Scene(base_spec(), model)


def test_contact_overflow_and_arena_exhaustion_are_simulation_errors():
    with _crowded_scene("20K") as scene:
        with pytest.raises(mjk.SimulationError, match=r"Too many contacts.*mjWARN_CONTACTFULL"):
            scene.step()  # MuJoCo would drop contacts and carry on
        scene.data.qpos[2::7] += 1.0  # off the floor: the boxes' own overlaps exhaust the stack
        with pytest.raises(mjk.SimulationError, match=r"MuJoCo stopped .*mj_stackAlloc") as err:
            scene.step(3)  # MuJoCo raises its own FatalError here
        assert not isinstance(err.value, mujoco.FatalError)
        assert err.value.time == pytest.approx(0.002, abs=1e-12)  # after the first step


# ---------------------------------------------------------------------- MuJoCo's log, in-process


@pytest.fixture
def log_config():
    """MuJoCo's log configuration, put back as it was after the test."""
    config = mujoco.MjLogConfig.get()
    saved = (config.logfile, config.logto_file)
    yield
    config = mujoco.MjLogConfig.get()
    config.logfile, config.logto_file = saved
    config.set()


def _route_from(logfile: str) -> mujoco.MjLogConfig:
    config = mujoco.MjLogConfig.get()
    config.logfile, config.logto_file = logfile, True
    config.set()
    scene_module._route_mujoco_log()
    return mujoco.MjLogConfig.get()


def test_mujoco_log_is_routed_from_mujocos_default_only(log_config, tmp_path, monkeypatch):
    monkeypatch.delenv("MJKDL_MUJOCO_LOG", raising=False)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    default = tmp_path / f"mjkdl-{os.getuid()}" / "MUJOCO_LOG.TXT"
    for _ in range(2):  # the second time the folder exists already
        config = _route_from("MUJOCO_LOG.TXT")
        assert (config.logfile, config.logto_file) == (str(default), True)
        assert default.parent.is_dir()
        assert mjk.mujoco_log_path() == str(default)
    config = _route_from(str(tmp_path / "mine.txt"))  # the user's own choice is kept
    assert (config.logfile, config.logto_file) == (str(tmp_path / "mine.txt"), True)

    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MJKDL_MUJOCO_LOG", os.path.join("logs", "deep", "m.txt"))
    config = _route_from("MUJOCO_LOG.TXT")
    assert (config.logfile, config.logto_file) == (str(tmp_path / "logs" / "deep" / "m.txt"), True)
    assert (tmp_path / "logs" / "deep").is_dir()

    (tmp_path / "plain").write_text("")  # a file where the folder should be: no log file
    monkeypatch.setenv("MJKDL_MUJOCO_LOG", str(tmp_path / "plain" / "m.txt"))
    config = _route_from("MUJOCO_LOG.TXT")
    assert (config.logfile, config.logto_file) == (str(tmp_path / "plain" / "m.txt"), False)

    monkeypatch.delenv("MJKDL_MUJOCO_LOG")
    monkeypatch.delattr(os, "getuid")  # as on Windows
    config = _route_from("MUJOCO_LOG.TXT")
    assert (config.logfile, config.logto_file) == (str(tmp_path / "mjkdl" / "MUJOCO_LOG.TXT"), True)


# ---------------------------------------------------------------------- construction and messages


def test_compiled_model_keeps_its_own_disable_flags():
    xml = (
        "<mujoco><option><flag gravity='disable' contact='disable'/></option>"
        "<worldbody><body><freejoint/><geom size='.1'/></body></worldbody></mujoco>"
    )
    authored = mujoco.MjModel.from_xml_string(xml).opt.disableflags
    bits = mujoco.mjtDisableBit
    assert authored == bits.mjDSBL_GRAVITY | bits.mjDSBL_CONTACT
    with mjk.Scene(base_spec(), mujoco.MjModel.from_xml_string(xml)) as scene:
        assert scene.model.opt.disableflags == authored | bits.mjDSBL_AUTORESET


class _FakeRobot:
    def _release(self, why: str = "") -> None:
        pass


def test_create_robot_calls_the_registered_factory(monkeypatch):
    monkeypatch.setattr(scene_module, "_robot_factory", None)
    with _small_scene() as scene:
        message = "import mjkdl (or mjkdl.robot) to create robots"
        with pytest.raises(RuntimeError, match=f"^{re.escape(message)}$"):
            scene.create_robot("base", "tip")
        calls = []
        handle = _FakeRobot()

        def factory(*args, **kwargs):
            calls.append((args, kwargs))
            return handle

        scene_module.register_robot_factory(factory)
        tool = mjk.ToolFrameSpec(tcp_pos=[0, 0, 0.1])
        assert scene.create_robot("base", "tip", prefix="p_", tool=tool) is handle
        assert calls == [((scene, "base", "tip"), {"prefix": "p_", "tool": tool})]


def test_closed_scene_names_its_class():
    scene = _small_scene()
    scene.close()
    with pytest.raises(RuntimeError, match=r"^this Scene is closed$"):
        scene.forward()
    env = mjk.Env.build(base_spec())
    env.close()
    with pytest.raises(RuntimeError, match=r"^this Env is closed$"):
        env.forward()


def test_type_errors_name_the_type_given(tutorial_scene):
    with pytest.raises(mjk.SpecError, match=r"^build\(\) takes a SceneSpec, got dict$"):
        mjk.Scene.build({"timestep": 0.002})
    scene = tutorial_scene()
    message = r"^add_object\(\) takes a SceneObject, got str$"
    with pytest.raises(mjk.SpecError, match=message):
        scene.add_object("cube")
    message = "no object named 'cub' in the scene spec; close matches: cube"
    with pytest.raises(mjk.UnknownNameError) as err:
        scene.remove_object("cub")
    assert err.value.args[0] == message
    with pytest.raises(mjk.UnknownNameError) as err:
        scene.body_id("nope")
    assert err.value.args[0] == "no body named 'nope' in the scene"
    with pytest.raises(mjk.UnknownNameError) as err:
        scene.actuator_id("joint_9")
    assert err.value.args[0].startswith("no actuator named 'joint_9' in the scene; close matches")


def test_camera_names_are_mujocos(tutorial_scene):
    scene = tutorial_scene()
    m = scene.model
    expected = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_CAMERA, i) for i in range(m.ncam)]
    assert expected == ["task", "wrist"]
    assert scene.camera_names() == expected


@pytest.mark.parametrize("value", ["abc", None, [1.0, 2.0]])
def test_set_actuator_ctrl_rejects_non_numbers(tutorial_scene, value):
    scene = tutorial_scene()
    message = f"set_actuator_ctrl('joint_1'): value must be a finite number, got {value!r}"
    with pytest.raises(mjk.SpecError, match=f"^{re.escape(message)}$"):
        scene.set_actuator_ctrl("joint_1", value)
    assert scene.data.ctrl[scene.actuator_id("joint_1")] == 0.0


def test_add_object_keeps_a_private_copy_of_the_object():
    crate = mjk.SceneObject(
        name="crate", shape=mjk.Shape.BOX, size=[0.1, 0.1, 0.1], mass=1, pos=[1, 0, 1]
    )
    with _small_scene() as scene:
        scene.add_object(crate)
        crate.pos[0] = 5.0
        crate.size[1] = 0.5
        assert scene.spec.objects[-1].pos == [1, 0, 1]
        assert scene.spec.objects[-1].size == [0.1, 0.1, 0.1]


def test_remove_object_leaves_an_earlier_spec_alone():
    ball = mjk.SceneObject(name="ball", shape=mjk.Shape.SPHERE, size=[0.05], mass=0.2)
    crate = mjk.SceneObject(name="crate", shape=mjk.Shape.BOX, size=[0.1] * 3, mass=1)
    with mjk.Scene.build(base_spec(objects=[ball, crate])) as scene:
        earlier = scene.spec
        scene.remove_object("ball")
        earlier.objects[1].mass = 9.0  # not the scene's spec any more
        earlier.cameras.append(mjk.CameraSpec(name="late", pos=[0, 0, 1]))
        assert [o.name for o in scene.spec.objects] == ["crate"]
        assert scene.spec.objects[0].mass == 1
        assert scene.spec.cameras == []


# ---------------------------------------------------------------------- failure messages in full

FAILED_TAIL = (
    "The state is kept as it was for inspection; Env.reset() starts over (set "
    "scene.auto_reset = True for MuJoCo's silent reset instead)."
)


def test_divergence_message_lists_every_warning_in_full():
    unstable = "The simulation is unstable."
    with _ball_env() as env:
        env.data.qpos[0] = np.nan
        env.data.qvel[2] = np.nan
        with pytest.raises(mjk.SimulationError) as err:
            env.step()
    assert str(err.value) == (
        f"the simulation failed by t = 0.01 s: Nan, Inf or huge value in QPOS at DOF 0. "
        f"{unstable} (mjWARN_BADQPOS x1); Nan, Inf or huge value in QVEL at DOF 2. {unstable} "
        f"(mjWARN_BADQVEL x1); Nan, Inf or huge value in QACC at DOF 0. {unstable} "
        f"(mjWARN_BADQACC x1). {FAILED_TAIL}"
    )


FATAL_TAIL = (
    "The data is left half-computed; Env.reset() starts over (a model's <size memory=...> sets "
    "the arena)"
)


def test_fatal_error_message_in_full(monkeypatch):
    def fatal(message):
        def mj_step(m, d, n=1):
            d.time += 0.25
            raise mujoco.FatalError(message)

        return mj_step

    with _small_scene() as scene:
        monkeypatch.setattr(mujoco, "mj_step", fatal("mj_stackAlloc: out of memory\nmore\n"))
        with pytest.raises(mjk.SimulationError) as err:
            scene.step()
        assert str(err.value) == (
            f"MuJoCo stopped the simulation at t = 0.25 s: mj_stackAlloc: out of memory. "
            f"{FATAL_TAIL}"
        )
        assert (err.value.time, err.value.warnings) == (0.25, {})
        monkeypatch.setattr(mujoco, "mj_step", fatal("  "))  # MuJoCo said nothing
        with pytest.raises(mjk.SimulationError) as err:
            scene.step()
        expected = f"MuJoCo stopped the simulation at t = 0.5 s: fatal error. {FATAL_TAIL}"
        assert str(err.value) == expected


# ---------------------------------------------------------------------- placing bodies

PLACES = """
<mujoco>
  <worldbody>
    <body name="target" mocap="true" pos="0 0 1">
      <geom size=".01" contype="0" conaffinity="0"/>
    </body>
    <body name="first" pos="1 0 0"><freejoint name="first"/><geom size=".1"/></body>
    <body name="second" pos="2 0 0"><freejoint name="second"/><geom size=".1"/></body>
  </worldbody>
</mujoco>
"""


def test_set_body_pose_of_a_mocap_body_and_a_free_body_before_another():
    with mjk.Scene(base_spec(), mujoco.MjModel.from_xml_string(PLACES)) as scene:
        m, d = scene.model, scene.data
        assert m.body_mocapid[m.body("target").id] == 0
        scene.set_body_pose("target", [0.1, 0.2, 0.3], [0.0, 0.0, 0.0, 2.0])
        assert d.mocap_pos[0].tolist() == [0.1, 0.2, 0.3]
        assert d.mocap_quat[0].tolist() == [0.0, 0.0, 0.0, 1.0]
        scene.set_body_pose("target", [0.4, 0.5, 0.6])  # quat=None keeps the orientation
        assert d.mocap_pos[0].tolist() == [0.4, 0.5, 0.6]
        assert d.mocap_quat[0].tolist() == [0.0, 0.0, 0.0, 1.0]

        second = d.qpos[7:14].copy()
        d.qvel[6:12] = 0.5
        scene.set_body_pose("first", [1.0, 1.0, 1.0], [1e-12, 0.0, 0.0, 0.0])  # tiny: allowed
        assert d.qpos[:7].tolist() == [1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0]
        assert d.qpos[7:14].tolist() == second.tolist()
        assert d.qvel[6:12].tolist() == [0.5] * 6

        message = (
            "set_body_pose('world'): body has no free joint (only free objects and mocap bodies "
            "can be placed)"
        )
        with pytest.raises(mjk.SpecError, match=f"^{re.escape(message)}$"):
            scene.set_body_pose("world", [0, 0, 0])
