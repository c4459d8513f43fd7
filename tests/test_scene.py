"""The `Scene` runtime owner: clock, actuators, poses, free bodies, closing."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import base_spec

import mjkdl as mjk

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


@pytest.mark.parametrize("n", [-1, 2.5, "3"])
def test_step_rejects_bad_counts(n):
    with _small_scene() as scene, pytest.raises(ValueError, match=r"step\(n\)"):
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
    "remove_robot": lambda s: s.remove_robot(None),
    "add_object": lambda s: s.add_object(
        mjk.SceneObject(name="ball", shape=mjk.Shape.SPHERE, size=[0.02], mass=0.1)
    ),
    "remove_object": lambda s: s.remove_object("cube"),
    "enter": lambda s: s.__enter__(),
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
