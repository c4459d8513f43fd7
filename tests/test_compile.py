"""Scene compilation (issue #2): mounting, offsets, primitives, cameras, MjSpec traps, errors."""

from __future__ import annotations

import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import (
    ASSETS,
    HOME,
    ROOT,
    base_spec,
    gripper,
    menagerie,
    table_object,
    tutorial_spec,
    two_link_arm,
)

import mjkdl as mjk
from mjkdl.compile import build_mjspec, compile_mjspec, compile_scene, euler_quat
from mjkdl.urdf import example_robot_data_path

TOL = 1e-12
OFFSET_POS = [0.01, -0.02, 0.03]
OFFSET_EULER = [10.0, 20.0, 30.0]


# ----------------------------------------------------------------------------- helpers


def _rot_xyz(euler_deg) -> np.ndarray:
    """Intrinsic x-y-z rotation, written out independently of MuJoCo."""
    a, b, c = np.deg2rad(euler_deg)
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
    return rx @ ry @ rz


def _se3(pos, euler_deg) -> pin.SE3:
    return pin.SE3(_rot_xyz(euler_deg), np.asarray(pos, dtype=float))


def _assert_se3(actual: pin.SE3, expected: pin.SE3, tol: float = TOL) -> None:
    np.testing.assert_allclose(actual.translation, expected.translation, rtol=0, atol=tol)
    np.testing.assert_allclose(actual.rotation, expected.rotation, rtol=0, atol=tol)


def _same_quat(a, b, tol: float = TOL) -> None:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if np.dot(a, b) < 0:
        b = -b
    np.testing.assert_allclose(a, b, rtol=0, atol=tol)


def _xml_euler_quat(euler_deg) -> np.ndarray:
    """The body quaternion MuJoCo's XML parser makes of `euler` in degrees."""
    e = " ".join(repr(float(v)) for v in euler_deg)
    model = mujoco.MjModel.from_xml_string(
        f'<mujoco><worldbody><body name="b" euler="{e}"><geom size="0.1"/></body>'
        "</worldbody></mujoco>"
    )
    return model.body_quat[1].copy()


def _build(spec: mjk.SceneSpec) -> mjk.Scene:
    return mjk.Scene.build(spec)


def _build_object(path) -> mjk.Scene:
    """A scene holding the MJCF file `path` as its one object, named `o`."""
    return _build(base_spec(objects=[mjk.SceneObject(name="o", mjcf_path=str(path))]))


def _table_site(table: mjk.SceneObject) -> mjk.AttachTarget:
    return mjk.AttachTarget(mjk.AttachKind.Site, mjk.scene_object_site_name(table, "table_top"))


def _gen3_on_table(**robot_kw) -> mjk.SceneSpec:
    table = table_object()
    arm = mjk.RobotSpec(path=menagerie("kinova_gen3"), attach_to=_table_site(table), **robot_kw)
    return base_spec(objects=[table], robots=[arm])


def _gripper_authored_pose() -> pin.SE3:
    """base_mount's pose relative to the 2F-85's own worldbody, read from its XML."""
    root = ET.parse(menagerie("robotiq_2f85")).getroot()
    mount = root.find("worldbody/body[@name='base_mount']")
    assert mount is not None
    assert mount.get("quat") is None and mount.get("euler") is None
    pos = np.array([float(v) for v in mount.get("pos", "0 0 0").split()])
    return pin.SE3(np.eye(3), pos)


def _patched_gripper(tmp_path: Path, impratio: str) -> Path:
    """A copy of the 2F-85 XML with another impratio, its meshes read from the original."""
    original = Path(menagerie("robotiq_2f85"))
    text = original.read_text()
    assert 'impratio="10"' in text and 'meshdir="assets"' in text
    text = text.replace('impratio="10"', f'impratio="{impratio}"')
    text = text.replace('meshdir="assets"', f'meshdir="{original.parent / "assets"}"')
    path = tmp_path / "2f85_patched.xml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def tutorial():
    scene = mjk.Scene.build(tutorial_spec())
    yield scene
    scene.close()


# ----------------------------------------------------------------------------- mounting


def test_gen3_base_sits_exactly_on_table_top(tutorial):
    top = tutorial.site_frame("table/table_top")
    assert top.translation[2] == pytest.approx(0.7, abs=TOL)
    _assert_se3(tutorial.body_frame("base_link"), top)


def test_gripper_sits_on_pinch_site_with_its_authored_offset(tutorial):
    authored = _gripper_authored_pose()
    np.testing.assert_allclose(authored.translation, [0, 0, 0.007], rtol=0, atol=TOL)
    expected = tutorial.site_frame("pinch_site") * authored
    _assert_se3(tutorial.body_frame("g_base_mount"), expected)


def test_attachment_offset_moves_it_by_exactly_that_transform():
    def mount_pose(**offset) -> tuple[pin.SE3, pin.SE3]:
        att = gripper()
        for key, value in offset.items():
            setattr(att, key, value)
        with _build(_gen3_on_table(attachments=[att])) as scene:
            return scene.body_frame("g_base_mount"), scene.site_frame("pinch_site")

    without, site = mount_pose()
    with_offset, site_again = mount_pose(pos=OFFSET_POS, euler=OFFSET_EULER)
    _assert_se3(site_again, site)
    offset = _se3(OFFSET_POS, OFFSET_EULER)
    authored = _gripper_authored_pose()
    # The offset moves the gripper's model frame (base_mount minus its authored pos) ...
    _assert_se3(with_offset * authored.inverse(), without * authored.inverse() * offset)
    # ... which puts base_mount at site * offset * authored.
    _assert_se3(with_offset, site * offset * authored)
    assert np.linalg.norm(with_offset.translation - without.translation) > 0.02


@pytest.mark.parametrize("on_table", [False, True], ids=["world", "table_top"])
def test_robot_offset_moves_it_by_exactly_that_transform(on_table):
    gen3 = menagerie("kinova_gen3")

    def base_pose(**offset) -> pin.SE3:
        if on_table:
            spec = _gen3_on_table(**offset)
        else:
            spec = base_spec(robots=[mjk.RobotSpec(path=gen3, **offset)])
        with _build(spec) as scene:
            return scene.body_frame("base_link")

    without = base_pose()
    if not on_table:
        _assert_se3(without, pin.SE3.Identity())
    with_offset = base_pose(pos=OFFSET_POS, euler=OFFSET_EULER)
    _assert_se3(with_offset, without * _se3(OFFSET_POS, OFFSET_EULER))


def test_robot_mounted_on_a_body(tmp_path):
    table = table_object()
    on_body = mjk.RobotSpec(
        path=menagerie("kinova_gen3"),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Body, "table/table"),
        pos=[0, 0, 0.1],
    )
    with _build(base_spec(objects=[table], robots=[on_body])) as scene:
        expected = scene.body_frame("table/table") * _se3([0, 0, 0.1], [0, 0, 0])
        _assert_se3(scene.body_frame("base_link"), expected)


def test_robot_mounted_on_a_frame(tmp_path):
    path = tmp_path / "stand.xml"
    path.write_text(
        '<mujoco><compiler angle="degree"/><worldbody><body name="stand">'
        '<geom type="box" size="0.1 0.1 0.1"/>'
        '<frame name="mount" pos="0.05 0 0.1" euler="0 0 90"/></body></worldbody></mujoco>'
    )
    stand = mjk.SceneObject(name="stand", mjcf_path=str(path), pos=[1, 0, 0], fixed=True)
    robot = mjk.RobotSpec(
        path=menagerie("kinova_gen3"),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Frame, "stand/mount"),
    )
    with _build(base_spec(objects=[stand], robots=[robot])) as scene:
        _assert_se3(scene.body_frame("base_link"), _se3([1.05, 0, 0.1], [0, 0, 90]))


# ----------------------------------------------------------------------------- primitives


SHAPES = {
    mjk.Shape.BOX: ("box", [0.03, 0.02, 0.01]),
    mjk.Shape.SPHERE: ("sphere", [0.04]),
    mjk.Shape.CYLINDER: ("cylinder", [0.03, 0.05]),
    mjk.Shape.CAPSULE: ("capsule", [0.02, 0.06]),
    mjk.Shape.ELLIPSOID: ("ellipsoid", [0.03, 0.04, 0.05]),
}


@pytest.mark.parametrize("shape", list(SHAPES), ids=lambda s: s.name)
def test_primitive_matches_equivalent_mjcf(shape):
    xml_type, size = SHAPES[shape]
    pos, euler = [0.3, -0.2, 0.9], [15.0, -40.0, 75.0]
    rgba, friction, mass = [0.1, 0.2, 0.3, 0.4], [0.7, 0.01, 0.002], 0.25
    obj = mjk.SceneObject(
        name="thing",
        shape=shape,
        size=size,
        rgba=rgba,
        mass=mass,
        friction=friction,
        condim=mjk.Condim.Rolling,
        pos=pos,
        euler=euler,
    )
    fixed = mjk.SceneObject(name="post", shape=shape, size=size, mass=mass, fixed=True)
    ref = mujoco.MjModel.from_xml_string(
        f'<mujoco><worldbody><body name="thing" pos="{" ".join(map(str, pos))}" '
        f'euler="{" ".join(map(str, euler))}"><freejoint/>'
        f'<geom type="{xml_type}" size="{" ".join(map(str, size))}" mass="{mass}" '
        f'rgba="{" ".join(map(str, rgba))}" friction="{" ".join(map(str, friction))}" '
        'condim="6"/></body></worldbody></mujoco>'
    )
    with _build(base_spec(objects=[obj, fixed], add_floor=False)) as scene:
        m = scene.model
        b = scene.body_id("thing")
        g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "thing")
        assert m.body_mass[b] == pytest.approx(mass, abs=TOL)
        assert m.body_mass[scene.body_id("post")] == pytest.approx(mass, abs=TOL)
        np.testing.assert_allclose(m.body_pos[b], pos, rtol=0, atol=TOL)
        _same_quat(m.body_quat[b], ref.body_quat[1])
        _same_quat(m.body_quat[b], _xml_euler_quat(euler))
        np.testing.assert_allclose(m.body_inertia[b], ref.body_inertia[1], rtol=1e-9, atol=0)
        assert m.geom_type[g] == ref.geom_type[0]
        np.testing.assert_allclose(m.geom_size[g], ref.geom_size[0], rtol=0, atol=TOL)
        np.testing.assert_allclose(m.geom_rgba[g], rgba, rtol=0, atol=1e-7)
        np.testing.assert_allclose(m.geom_friction[g], friction, rtol=0, atol=TOL)
        assert m.geom_condim[g] == 6
        # free objects get one free joint, fixed ones none
        assert m.body_jntnum[b] == 1
        assert m.jnt_type[m.body_jntadr[b]] == mujoco.mjtJoint.mjJNT_FREE
        assert m.body_jntnum[scene.body_id("post")] == 0
        assert m.njnt == 1


def test_primitive_default_condim_and_partial_friction():
    obj = mjk.SceneObject(name="c", shape=mjk.Shape.SPHERE, size=[0.02], mass=0.1, friction=[0.4])
    with _build(base_spec(objects=[obj])) as scene:
        g = mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_GEOM, "c")
        assert scene.model.geom_condim[g] == 3
        np.testing.assert_allclose(scene.model.geom_friction[g], [0.4, 0.005, 0.0001])


def test_fixed_primitive_with_zero_mass_builds():
    obj = mjk.SceneObject(name="wall", shape=mjk.Shape.BOX, size=[0.1, 0.1, 0.1], fixed=True)
    with _build(base_spec(objects=[obj])) as scene:
        assert scene.model.njnt == 0
        assert scene.model.body_mass[scene.body_id("wall")] > 0  # MuJoCo's density


@pytest.mark.parametrize(
    "euler",
    [[0, 0, 0], [90, 0, 0], [0, 90, 0], [0, 0, 90], [30, 45, 60], [-120, 10, 170], [45, 90, -30]],
)
def test_euler_is_intrinsic_xyz_degrees_like_mujoco_xml(euler):
    obj = mjk.SceneObject(
        name="o", shape=mjk.Shape.BOX, size=[0.1, 0.1, 0.1], mass=1.0, euler=euler
    )
    with _build(base_spec(objects=[obj])) as scene:
        b = scene.body_id("o")
        _same_quat(scene.model.body_quat[b], _xml_euler_quat(euler))
        np.testing.assert_allclose(
            scene.body_frame("o").rotation, _rot_xyz(euler), rtol=0, atol=1e-12
        )


DOOR_XML = """<mujoco><worldbody><body name="frame"><geom type="box" size="0.1 0.1 0.1"/>
<body name="leaf" pos="0 0 0.3" euler="0 0 45"><joint name="hinge" axis="0 0 1" range="-90 90"/>
<geom type="box" size="0.1 0.02 0.1"/><site name="knob" euler="90 0 0"/></body></body>
</worldbody><keyframe><key name="ajar" qpos="0.5"/></keyframe></mujoco>"""


def test_mjcf_object_keeps_its_own_degree_angles(tmp_path):
    """The scene compiles in radians; a child authored in degrees must be converted."""
    path = tmp_path / "door.xml"
    path.write_text(DOOR_XML)
    ref = mujoco.MjModel.from_xml_path(str(path))
    door = mjk.SceneObject(name="door", mjcf_path=str(path), pos=[1, 0, 0], fixed=True)
    with _build(base_spec(objects=[door])) as scene:
        m = scene.model
        np.testing.assert_allclose(m.jnt_range[0], [-np.pi / 2, np.pi / 2], atol=1e-12)
        leaf = scene.body_id("door/leaf")
        _same_quat(m.body_quat[leaf], ref.body_quat[ref.body("leaf").id])
        _same_quat(m.site_quat[scene.site_id("door/knob")], _xml_euler_quat([90, 0, 0]))
        assert m.key("door/ajar").qpos[0] == 0.5
        _assert_se3(scene.body_frame("door/leaf"), _se3([1, 0, 0.3], [0, 0, 45]))


# ----------------------------------------------------------------------------- cameras, robots


def test_cameras_listed_with_pos_and_fovy(tutorial):
    assert sorted(tutorial.camera_names()) == ["task", "wrist"]
    m = tutorial.model
    cam = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, "task")
    np.testing.assert_allclose(m.cam_pos[cam], [0.1, -0.9, 1.45], rtol=0, atol=TOL)
    assert m.cam_fovy[cam] == pytest.approx(45.0)
    _same_quat(m.cam_quat[cam], _xml_euler_quat([35.0, 0.0, 5.0]))
    wrist = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, "wrist")
    assert m.cam_fovy[wrist] == pytest.approx(41.83792730009236)


def test_two_gen3_with_prefix():
    gen3 = menagerie("kinova_gen3")
    robots = [
        mjk.RobotSpec(path=gen3),
        mjk.RobotSpec(path=gen3, prefix="r2_", pos=[0.0, 1.0, 0.0]),
    ]
    with _build(base_spec(robots=robots)) as scene:
        m = scene.model
        scene.body_id("base_link")
        scene.body_id("r2_base_link")
        assert m.njnt == 14
        assert sum(m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE for j in range(m.njnt)) == 14
        keys = [m.key(k).name for k in range(m.nkey)]
        assert "home" in keys and "r2_home" in keys
        assert m.key_qpos.shape == (m.nkey, m.nq) == (4, 14)
        r2_home = m.key("r2_home").qpos
        adr = [m.jnt_qposadr[m.joint(f"r2_joint_{i}").id] for i in range(1, 8)]
        np.testing.assert_allclose(r2_home[adr], HOME, atol=1e-4)
        _assert_se3(scene.body_frame("r2_base_link"), _se3([0, 1, 0], [0, 0, 0]))


# ----------------------------------------------------------------------------- MjSpec traps


def test_gripper_options_survive_attachment(tutorial):
    opt = tutorial.model.opt
    assert opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert opt.impratio == pytest.approx(10.0)
    assert opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST


def test_conflicting_attachment_options_raise(tmp_path):
    patched = _patched_gripper(tmp_path, "5")
    second = mjk.AttachmentSpec(
        mjcf_path=str(patched),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Body, "base_link"),
        prefix="h_",
    )
    spec = base_spec(
        robots=[mjk.RobotSpec(path=menagerie("kinova_gen3"), attachments=[gripper(), second])]
    )
    with pytest.raises(mjk.BuildError, match=r"(?s)attachments\[1\].*2f85_patched\.xml.*impratio"):
        _build(spec)


def _two_robots_with_grippers(tmp_path, impratio: str) -> list[mjk.RobotSpec]:
    """Two Gen3s: one with the stock 2F-85, one with a copy whose impratio is patched."""
    other = mjk.AttachmentSpec(
        mjcf_path=str(_patched_gripper(tmp_path, impratio)),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Site, "pinch_site"),
    )
    gen3 = menagerie("kinova_gen3")
    return [
        mjk.RobotSpec(path=gen3, attachments=[gripper()]),
        mjk.RobotSpec(path=gen3, prefix="r2_", pos=[0, 1, 0], attachments=[other]),
    ]


def test_conflicting_robot_options_raise(tmp_path):
    with pytest.raises(ValueError, match=r"(?s)robots\[1\].*impratio"):
        _build(base_spec(robots=_two_robots_with_grippers(tmp_path, "5")))


def test_same_options_in_two_attachments_are_fine(tmp_path):
    with _build(base_spec(robots=_two_robots_with_grippers(tmp_path, "10"))) as scene:
        assert scene.model.opt.impratio == pytest.approx(10.0)


def test_attach_notices_stay_out_of_stdout_and_mujoco_log(tmp_path, monkeypatch, capfd):
    """MuJoCo's C handler would print them and append them to ./MUJOCO_LOG.TXT."""
    monkeypatch.chdir(tmp_path)
    with _build(tutorial_spec()) as scene:
        assert scene.model.opt.impratio == pytest.approx(10.0)
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    assert mujoco.get_mju_user_warning() is None  # MuJoCo's own handler is back
    assert "Attach conflict" not in capfd.readouterr().out


def _bad_qpos_inside_the_notice_filter() -> None:
    """A MuJoCo C-level warning (mj_checkPos on a NaN qpos) where compile_mjspec compiles."""
    m = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><joint/><geom size='.1'/></body></worldbody></mujoco>"
    )
    d = mujoco.MjData(m)
    d.qpos[0] = np.nan
    with mjk.compile._quiet_attach_notices():
        mujoco.mj_checkPos(m, d)


BAD_QPOS = "Nan, Inf or huge value in QPOS at DOF 0. The simulation is unstable. Time = 0.0000."


def test_other_mujoco_notices_come_back_as_python_warnings(tmp_path, monkeypatch, capfd):
    monkeypatch.chdir(tmp_path)
    with pytest.warns(UserWarning) as warned:
        _bad_qpos_inside_the_notice_filter()
    assert [(w.category, str(w.message)) for w in warned] == [(UserWarning, f"MuJoCo: {BAD_QPOS}")]
    assert list(tmp_path.iterdir()) == []  # MuJoCo's own handler would write MUJOCO_LOG.TXT
    assert BAD_QPOS not in capfd.readouterr().out


def test_a_mujoco_notice_points_at_the_caller_of_the_compiling_function():
    with pytest.warns(UserWarning) as warned:
        _bad_qpos_inside_the_notice_filter()
    assert warned[0].filename == __file__


def test_welded_gen3_has_no_contacts_at_rest(tutorial):
    m = tutorial.model
    data = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, data, m.key("home").id)
    mujoco.mj_forward(m, data)
    assert data.ncon == 0
    base, shoulder = tutorial.body_id("base_link"), tutorial.body_id("shoulder_link")
    signatures = set(m.exclude_signature[: m.nexclude].tolist())
    assert (min(base, shoulder) << 16) + max(base, shoulder) in signatures
    assert m.nexclude == 7  # the 2F-85's own six plus base_link/shoulder_link


def test_without_the_exclusion_gen3_base_touches_its_shoulder():
    """The exclusion is what removes the contacts (guards against a vacuous pass above)."""
    s = build_mjspec(tutorial_spec())
    for exclude in [
        e for e in s.excludes if {e.bodyname1, e.bodyname2} == {"base_link", "shoulder_link"}
    ]:
        s.delete(exclude)
    with pytest.warns(UserWarning):
        m = s.compile()
    data = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, data, m.key("home").id)
    mujoco.mj_forward(m, data)
    assert data.ncon == 4


def test_keyframes_survive_attachment(tutorial):
    m = tutorial.model
    assert m.nkey == 2
    assert m.key_qpos.shape == (m.nkey, m.nq)
    root = ET.parse(menagerie("kinova_gen3")).getroot()
    authored = [float(v) for v in root.find("keyframe/key[@name='home']").get("qpos").split()]
    home = m.key("home").qpos
    adr = [m.jnt_qposadr[m.joint(f"joint_{i}").id] for i in range(1, 8)]
    np.testing.assert_allclose(home[adr], authored, rtol=0, atol=TOL)
    cube = m.jnt_qposadr[m.joint("cube").id]
    np.testing.assert_allclose(home[cube : cube + 7], [0.35, 0.10, 0.725, 1, 0, 0, 0], atol=TOL)


def test_offscreen_buffer_fits_1080p(tutorial):
    assert tutorial.model.vis.global_.offwidth >= 1920
    assert tutorial.model.vis.global_.offheight >= 1080


# ----------------------------------------------------------------------------- URDF robots


@pytest.mark.parametrize(
    ("relative", "prefix", "root", "motors"),
    [
        ("ur_description/urdf/ur5_robot.urdf", "ur_", "base_link", 6),
        ("panda_description/urdf/panda.urdf", "p_", "panda_link0", 8),
    ],
    ids=["ur5", "panda"],
)
def test_urdf_robot_on_table(relative, prefix, root, motors):
    table = table_object()
    robot = mjk.RobotSpec(
        path=str(example_robot_data_path(relative)), prefix=prefix, attach_to=_table_site(table)
    )
    scene = _build(base_spec(objects=[table], robots=[robot]))  # .dae meshes convert quietly
    with scene:
        m = scene.model
        _assert_se3(scene.body_frame(prefix + root), scene.site_frame("table/table_top"))
        assert np.count_nonzero(m.geom_type == mujoco.mjtGeom.mjGEOM_MESH) >= 2 * motors
        assert m.nu == motors
        for a in range(m.nu):
            name = m.actuator(a).name
            assert name.startswith(prefix)
            assert m.joint(m.actuator_trnid[a, 0]).name == name
        assert all(m.joint(j).name.startswith(prefix) for j in range(m.njnt))
        # one motor per joint, except a mimic joint (Panda's second finger) tied by an equality
        assert m.nu + m.neq == m.njnt


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("field", ["timestep", "add_floor", "add_skybox"])
def test_required_fields_named(field):
    spec = base_spec(**{field: None})
    with pytest.raises(mjk.SpecError, match=f"SceneSpec.{field}"):
        _build(spec)


@pytest.mark.parametrize("value", ["fast", 0.0, -1e-3, float("nan")])
def test_bad_timestep_named(value):
    with pytest.raises(mjk.SpecError, match=r"SceneSpec\.timestep"):
        _build(base_spec(timestep=value))


@pytest.mark.parametrize(
    ("field", "value"),
    [("timestep", "0.004"), ("timestep", True), ("gravity_z", "-9.81"), ("add_floor", "no")],
)
def test_no_silent_coercion(field, value):
    """Text is not read as a number and "no" is not a true floor flag (issue #13)."""
    with pytest.raises(mjk.SpecError, match=rf"SceneSpec\.{field} must be"):
        _build(base_spec(**{field: value}))


def test_missing_object_file(tmp_path):
    path = tmp_path / "nothere.xml"
    obj = mjk.SceneObject(name="o", mjcf_path=str(path))
    with pytest.raises(FileNotFoundError, match=r"nothere\.xml") as err:
        _build(base_spec(objects=[obj]))
    assert "objects[0]" in str(err.value)


@pytest.mark.parametrize("suffix", [".xml", ".urdf"])
def test_missing_robot_file(tmp_path, suffix):
    path = tmp_path / f"nothere{suffix}"
    with pytest.raises(FileNotFoundError, match=f"robots\\[0\\].*nothere\\{suffix}"):
        _build(base_spec(robots=[mjk.RobotSpec(path=str(path))]))


def test_missing_attachment_file(tmp_path):
    att = mjk.AttachmentSpec(
        mjcf_path=str(tmp_path / "nothere.xml"),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Site, "pinch_site"),
    )
    robot = mjk.RobotSpec(path=menagerie("kinova_gen3"), attachments=[att])
    with pytest.raises(FileNotFoundError, match=r"attachments\[0\].*nothere\.xml"):
        _build(base_spec(robots=[robot]))


MESH_XML = """<mujoco><asset><mesh name="m" file="nope.stl"/></asset>
<worldbody><body name="b"><geom type="mesh" mesh="m"/></body></worldbody></mujoco>"""


@pytest.mark.parametrize("as_robot", [False, True], ids=["object", "robot"])
def test_missing_mesh_named(tmp_path, as_robot):
    path = tmp_path / "meshy.xml"
    path.write_text(MESH_XML)
    if as_robot:
        spec = base_spec(robots=[mjk.RobotSpec(path=str(path))])
    else:
        spec = base_spec(objects=[mjk.SceneObject(name="o", mjcf_path=str(path), fixed=True)])
    at_fault = r"robots\[0\]\.path" if as_robot else r"objects\[0\] \('o'\)\.mjcf_path"
    with pytest.raises(mjk.ModelFileError, match=rf"{at_fault}: mesh file of m in .*meshy\.xml"):
        _build(spec)
    with pytest.raises(FileNotFoundError, match=r"not found: .*nope\.stl"):
        _build(spec)


@pytest.mark.parametrize(
    ("field", "value"),
    [("rgba", [1, 0, 0, 1]), ("friction", [0.5]), ("condim", mjk.Condim.Rolling)],
)
def test_primitive_only_fields_on_an_mjcf_object_are_refused(field, value):
    table = mjk.SceneObject(name="t", mjcf_path=str(ASSETS / "table.xml"), fixed=True)
    setattr(table, field, value)
    with pytest.raises(mjk.SpecError) as err:
        _build(base_spec(objects=[table]))
    assert str(err.value) == (
        f"objects[0] ('t').{field} applies to primitive objects only; an MJCF object keeps what "
        f"its file gives (edit the file, or model.geom_{field} after building)"
    )
    setattr(table, field, getattr(mjk.SceneObject(), field))  # the defaults are not "set"
    with _build(base_spec(objects=[table])) as scene:
        assert scene.model.body("t/table").name == "t/table"


def test_mesh_named_by_a_uri_is_refused_like_a_missing_file(tmp_path):
    # MuJoCo reads "mem://x.obj" as the path "mem:/x.obj"; Python has no resource providers,
    # so it is a missing file, reported with the object and model at fault.
    path = tmp_path / "uri.xml"
    path.write_text(MESH_XML.replace("nope.stl", "mem://x.obj"))
    spec = base_spec(objects=[mjk.SceneObject(name="o", mjcf_path=str(path), fixed=True)])
    with pytest.raises(mjk.ModelFileError) as err:
        _build(spec)
    assert str(err.value).startswith(
        f"objects[0] ('o').mjcf_path: mesh file of m in {path} not found: "
    )
    assert str(err.value).endswith("mem:/x.obj")


@pytest.mark.parametrize(
    ("kind", "name", "suggestion"),
    [
        (mjk.AttachKind.Site, "pinch_sit", "pinch_site"),
        (mjk.AttachKind.Body, "bracelet_lnk", "bracelet_link"),
        (mjk.AttachKind.Frame, "no_frame", ""),
    ],
)
def test_unknown_attachment_target(kind, name, suggestion):
    att = mjk.AttachmentSpec(
        mjcf_path=menagerie("robotiq_2f85"), attach_to=mjk.AttachTarget(kind, name)
    )
    robot = mjk.RobotSpec(path=menagerie("kinova_gen3"), attachments=[att])
    with pytest.raises(KeyError, match=f"{kind.value} named '{name}'.*{suggestion}") as err:
        _build(base_spec(robots=[robot]))
    assert "attachments[0]" in str(err.value)


@pytest.mark.parametrize(
    ("kind", "name", "suggestion"),
    [
        (mjk.AttachKind.Site, "table/table_tp", "table/table_top"),
        (mjk.AttachKind.Body, "table/tabel", "table/table"),
    ],
)
def test_unknown_robot_target(kind, name, suggestion):
    robot = mjk.RobotSpec(path=menagerie("kinova_gen3"), attach_to=mjk.AttachTarget(kind, name))
    with pytest.raises(KeyError, match=f"{kind.value} named '{name}'.*{suggestion}"):
        _build(base_spec(objects=[table_object()], robots=[robot]))


def _prim(**kw) -> mjk.SceneObject:
    fields = {"name": "p", "shape": mjk.Shape.BOX, "size": [0.1, 0.1, 0.1], "mass": 1.0}
    fields.update(kw)
    return mjk.SceneObject(**fields)


@pytest.mark.parametrize(
    ("obj", "pattern"),
    [
        (_prim(size=[0.1, -0.1, 0.1]), r"objects\[0\].*\.size.*positive"),
        (_prim(size=[0.1, 0.1]), r"objects\[0\].*\.size.*3 values"),
        (_prim(shape=mjk.Shape.SPHERE, size=[0.1, 0.1]), r"\.size \(SPHERE\).*1 values"),
        (_prim(size=[0.1, 0.0, 0.1]), r"\.size.*positive"),
        (_prim(pos=[0, 0]), r"objects\[0\] \('p'\)\.pos.*3 values"),
        (_prim(euler=[0, 0, 0, 0]), r"objects\[0\] \('p'\)\.euler.*3 values"),
        (_prim(rgba=[1, 0, 0]), r"\.rgba.*4 values"),
        (_prim(rgba=[1, 0, 0, 1.5]), r"\.rgba.*\[0, 1\]"),
        (_prim(rgba=[-0.1, 0, 0, 1]), r"\.rgba.*\[0, 1\]"),
        (_prim(shape=None), r"objects\[0\] \('p'\)\.shape"),
        (_prim(mass=0.0), r"\.mass.*positive"),
        (_prim(mass=-1.0, fixed=True), r"\.mass"),
        (_prim(pos=[0, float("nan"), 0]), r"\.pos.*finite"),
        (_prim(pos=[[0, 0, 1]]), r"\.pos must be a flat list of 3 numbers"),
        (_prim(condim=None), r"\.condim must be 1, 3, 4 or 6"),
        (_prim(name=5), r"objects\[0\]\.name must be a string"),
        (
            _prim(mjcf_path=str(ASSETS / "table.xml")),
            r"either mjcf_path or a primitive",
        ),
    ],
    ids=[
        "negative-size",
        "short-size",
        "sphere-size",
        "zero-size",
        "pos-length",
        "euler-length",
        "rgba-length",
        "rgba-high",
        "rgba-low",
        "no-shape",
        "zero-mass-free",
        "negative-mass-fixed",
        "nan-pos",
        "nested-pos",
        "condim-none",
        "name-not-text",
        "mjcf-and-primitive",
    ],
)
def test_bad_primitive(obj, pattern):
    with pytest.raises(ValueError, match=pattern):
        _build(base_spec(objects=[obj]))


@pytest.mark.parametrize(("field", "value"), [("pos", [0, 0]), ("euler", [0, 0, 0, 0])])
def test_bad_attachment_and_robot_offsets(field, value):
    att = gripper()
    setattr(att, field, value)
    robot = mjk.RobotSpec(path=menagerie("kinova_gen3"), attachments=[att])
    with pytest.raises(ValueError, match=rf"attachments\[0\]\.{field}.*3 values"):
        _build(base_spec(robots=[robot]))
    robot = mjk.RobotSpec(path=menagerie("kinova_gen3"), **{field: value})
    with pytest.raises(ValueError, match=rf"robots\[0\]\.{field}.*3 values"):
        _build(base_spec(robots=[robot]))


def test_attachment_without_target_and_robot_without_path():
    att = mjk.AttachmentSpec(mjcf_path=menagerie("robotiq_2f85"))
    robot = mjk.RobotSpec(path=menagerie("kinova_gen3"), attachments=[att])
    with pytest.raises(ValueError, match=r"robots\[0\]\.attachments\[0\]\.attach_to is unset"):
        _build(base_spec(robots=[robot]))
    with pytest.raises(ValueError, match=r"robots\[0\]\.path is empty"):
        _build(base_spec(robots=[mjk.RobotSpec()]))
    robot = mjk.RobotSpec(path=menagerie("kinova_gen3"), attach_to="table/table_top")
    with pytest.raises(ValueError, match=r"robots\[0\]\.attach_to must be an AttachTarget"):
        _build(base_spec(robots=[robot]))


def test_duplicate_object_names():
    with pytest.raises(ValueError, match="duplicate object name 'p'"):
        _build(base_spec(objects=[_prim(), _prim(pos=[1, 0, 0])]))


def test_duplicate_camera_names():
    cams = [
        mjk.CameraSpec(name="c", pos=[0, 0, 1], fovy=45),
        mjk.CameraSpec(name="c", pos=[1, 0, 1], fovy=45),
    ]
    with pytest.raises(mjk.SpecError, match=r"cameras\[1\]\.name: duplicate camera name 'c'"):
        _build(base_spec(cameras=cams))


def test_camera_name_clashing_with_robot_camera():
    cam = mjk.CameraSpec(name="wrist", pos=[0, 0, 1], fovy=45)
    robot = mjk.RobotSpec(path=menagerie("kinova_gen3"))
    with pytest.raises(ValueError, match="'wrist'"):
        _build(base_spec(robots=[robot], cameras=[cam]))


@pytest.mark.parametrize(
    ("cam", "pattern"),
    [
        (mjk.CameraSpec(name="c", fovy=45), r"cameras\[0\] \('c'\)\.pos is required"),
        (mjk.CameraSpec(name="c", pos=[0, 0, 1]), r"cameras\[0\] \('c'\)\.fovy is required"),
        (mjk.CameraSpec(name="c", pos=[0, 0, 1], fovy=0), r"\.fovy must lie in"),
        (mjk.CameraSpec(name="c", pos=[0, 1], fovy=45), r"\.pos must have 3"),
    ],
    ids=["no-pos", "no-fovy", "zero-fovy", "short-pos"],
)
def test_bad_camera(cam, pattern):
    with pytest.raises(ValueError, match=pattern):
        _build(base_spec(cameras=[cam]))


def test_second_robot_without_prefix_suggests_one():
    gen3 = menagerie("kinova_gen3")
    robots = [mjk.RobotSpec(path=gen3), mjk.RobotSpec(path=gen3, pos=[0, 1, 0])]
    with pytest.raises(ValueError, match=r"robots\[1\].*prefix"):
        _build(base_spec(robots=robots))


def test_mjcf_object_with_free_joint(tmp_path):
    path = tmp_path / "free.xml"
    path.write_text(
        '<mujoco><worldbody><body name="b"><freejoint name="loose"/><geom size="0.1"/>'
        "</body></worldbody></mujoco>"
    )
    for fixed in (False, True):
        obj = mjk.SceneObject(name="o", mjcf_path=str(path), fixed=fixed)
        with pytest.raises(ValueError, match=r"objects\[0\].*free\.xml.*free joint.*loose"):
            _build(base_spec(objects=[obj]))


def test_table_asset_compiles_alone():
    model = mujoco.MjModel.from_xml_path(str(ASSETS / "table.xml"))
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "table_top")
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.site_xpos[site], [0, 0, 0], atol=TOL)
    top = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "top")
    # the top surface is the site plane: geom centre - half thickness == 0
    assert model.geom_pos[top][2] + model.geom_size[top][2] == pytest.approx(0.0, abs=TOL)
    for leg in ("leg_fl", "leg_fr", "leg_bl", "leg_br"):
        g = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, leg)
        # legs reach the floor (z = -0.7) from the underside of the top (z = -0.04)
        assert model.geom_pos[g][2] - model.geom_size[g][2] == pytest.approx(-0.7, abs=TOL)
        assert model.geom_pos[g][2] + model.geom_size[g][2] == pytest.approx(-0.04, abs=TOL)


@pytest.mark.parametrize(
    ("spec_kw", "pattern"),
    [
        ({"robots": [None]}, r"SceneSpec\.robots\[0\] must be a RobotSpec"),
        ({"objects": "table"}, r"SceneSpec\.objects must be a list of SceneObject"),
        ({"cameras": [mjk.SceneObject()]}, r"SceneSpec\.cameras\[0\] must be a CameraSpec"),
    ],
)
def test_spec_lists_hold_the_right_types(spec_kw, pattern):
    with pytest.raises(ValueError, match=pattern):
        _build(base_spec(**spec_kw))


def test_robot_prefix_and_target_name_types():
    gen3 = menagerie("kinova_gen3")
    with pytest.raises(ValueError, match=r"robots\[0\]\.prefix must be a string"):
        _build(base_spec(robots=[mjk.RobotSpec(path=gen3, prefix=None)]))
    target = mjk.AttachTarget(mjk.AttachKind.Site, None)
    with pytest.raises(ValueError, match=r"robots\[0\]\.attach_to\.name must be a string"):
        _build(base_spec(robots=[mjk.RobotSpec(path=gen3, attach_to=target)]))


# ----------------------------------------------------------------------------- wrist cameras


def _euler_matrix(deg) -> np.ndarray:
    """MuJoCo's default intrinsic xyz Euler angles (degrees) as a rotation matrix."""
    rx, ry, rz = (
        pin.AngleAxis(np.radians(a), axis).matrix() for a, axis in zip(deg, np.eye(3), strict=True)
    )
    return rx @ ry @ rz


def _wrist_camera_spec() -> mjk.SceneSpec:
    arm = mjk.RobotSpec(path=menagerie("kinova_gen3"), attachments=[gripper()])
    cameras = [
        mjk.CameraSpec(
            name="on_body",
            pos=[0.05, 0.0, -0.03],
            euler=[180.0, 0.0, -90.0],
            fovy=60.0,
            attach_to=mjk.AttachTarget(mjk.AttachKind.Body, "bracelet_link"),
        ),
        mjk.CameraSpec(
            name="on_site",
            pos=[0.0, 0.08, -0.1],
            euler=[20.0, -10.0, 35.0],
            fovy=70.0,
            attach_to=mjk.AttachTarget(mjk.AttachKind.Site, "g_pinch"),
        ),
    ]
    return base_spec(robots=[arm], cameras=cameras)


def test_wrist_cameras_follow_their_body_and_site():
    offsets = {
        "on_body": ([0.05, 0.0, -0.03], [180.0, 0.0, -90.0]),
        "on_site": ([0.0, 0.08, -0.1], [20.0, -10.0, 35.0]),
    }
    with _build(_wrist_camera_spec()) as scene:
        robot = scene.create_robot("base_link", "bracelet_link")
        model, data = scene.model, scene.data
        body, site = scene.body_id("bracelet_link"), scene.site_id("g_pinch")
        rng = np.random.default_rng(11)
        for _ in range(5):
            robot.set_joint_pos(rng.uniform(-2.0, 2.0, 7))
            scene.step(20)  # moving, not only placed
            scene.forward()
            hosts = {
                "on_body": (data.xpos[body], data.xmat[body].reshape(3, 3)),
                "on_site": (data.site_xpos[site], data.site_xmat[site].reshape(3, 3)),
            }
            for name, (pos, euler) in offsets.items():
                cam = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, name)
                host_pos, host_rot = hosts[name]
                expected_pos = host_pos + host_rot @ np.array(pos)
                assert np.abs(data.cam_xpos[cam] - expected_pos).max() < 1e-12
                expected_rot = host_rot @ _euler_matrix(euler)
                assert np.abs(data.cam_xmat[cam].reshape(3, 3) - expected_rot).max() < 1e-12


@pytest.mark.parametrize(
    ("kind", "name", "pattern"),
    [
        (mjk.AttachKind.Body, "bracelet_lnk", r"no body named 'bracelet_lnk'.*bracelet_link"),
        (mjk.AttachKind.Site, "g_pnch", r"no site named 'g_pnch'.*g_pinch"),
    ],
)
def test_camera_on_unknown_mount_is_named(kind, name, pattern):
    spec = _wrist_camera_spec()
    spec.cameras[0].attach_to = mjk.AttachTarget(kind, name)
    with pytest.raises(mjk.UnknownNameError, match=pattern) as err:
        _build(spec)
    assert "cameras[0]" in str(err.value)
    spec.cameras[0].attach_to = mjk.AttachTarget(mjk.AttachKind.Frame, "bracelet_link")
    with pytest.raises(mjk.SpecError, match=r"cameras\[0\].*must be an AttachTarget.*of kind Body"):
        _build(spec)


# ----------------------------------------------------------------------------- spec validation
# validate_scene_spec runs before any file is opened, so robots may name files that don't exist.


def _arm(**kw) -> mjk.RobotSpec:
    return mjk.RobotSpec(path="arm.xml", **kw)


def _att(**kw) -> mjk.AttachmentSpec:
    fields = {"mjcf_path": "tool.xml", "attach_to": mjk.AttachTarget(mjk.AttachKind.Site, "s")}
    fields.update(kw)
    return mjk.AttachmentSpec(**fields)


def _cam(**kw) -> mjk.CameraSpec:
    fields = {"name": "c", "pos": [0.0, 0.0, 1.0], "fovy": 45.0}
    fields.update(kw)
    return mjk.CameraSpec(**fields)


BAD_SPECS = {
    "floor-flag-text": ({"add_skybox": "no"}, r"SceneSpec\.add_skybox must be True or False"),
    "floor-flag-int": ({"add_floor": 1}, r"SceneSpec\.add_floor must be True or False"),
    "timestep-huge": ({"timestep": 2.0}, r"SceneSpec\.timestep must lie in \[1e-06, 1\]"),
    "gravity-huge": ({"gravity_z": -1e300}, r"SceneSpec\.gravity_z \(magnitude\) must lie"),
    "size-1e300": ({"objects": [_prim(size=[1e300, 0.1, 0.1])]}, r"\('p'\)\.size \(BOX\).*lie in"),
    "size-tiny": ({"objects": [_prim(size=[1e-9, 0.1, 0.1])]}, r"\('p'\)\.size \(BOX\).*lie in"),
    "size-text": ({"objects": [_prim(size=["0.1", 0.1, 0.1])]}, r"\.size.*list of numbers"),
    "pos-bool": ({"objects": [_prim(pos=[True, 0, 0])]}, r"\('p'\)\.pos must be a list of numbers"),
    "pos-huge": ({"objects": [_prim(pos=[0, 0, 1e300])]}, r"\('p'\)\.pos values must lie within"),
    "euler-huge": ({"objects": [_prim(euler=[1e300, 0, 0])]}, r"\('p'\)\.euler values"),
    "pos-none": ({"objects": [_prim(pos=None)]}, r"\('p'\)\.pos must be a list of numbers"),
    "pos-text-array": ({"objects": [_prim(pos=np.array(["1", "2", "3"]))]}, r"\.pos must hold"),
    "mass-1e300": ({"objects": [_prim(mass=1e300)]}, r"\('p'\)\.mass must lie in"),
    "mass-bool": ({"objects": [_prim(mass=True)]}, r"\('p'\)\.mass must be a number"),
    "friction-huge": ({"objects": [_prim(friction=[1e300])]}, r"\('p'\)\.friction values"),
    "condim-bool": ({"objects": [_prim(condim=True)]}, r"\('p'\)\.condim must be 1, 3, 4 or 6"),
    "fixed-text": ({"objects": [_prim(fixed="yes")]}, r"\('p'\)\.fixed must be True or False"),
    "shape-text": ({"objects": [_prim(shape="box")]}, r"\('p'\)\.shape must be a Shape"),
    "object-floor": ({"objects": [_prim(name="floor")]}, r"objects\[0\]\.name: 'floor' is"),
    "object-reserved": ({"objects": [_prim(name="mjkdl_sun")]}, r"objects\[0\]\.name: .*reserved"),
    "object-nul": ({"objects": [_prim(name="a\x00b")]}, r"objects\[0\]\.name contains a NUL"),
    "object-empty": ({"objects": [_prim(name="")]}, r"objects\[0\]\.name is empty"),
    "object-path-nul": (
        {"objects": [mjk.SceneObject(name="o", mjcf_path="a\x00.xml")]},
        r"objects\[0\] \('o'\)\.mjcf_path contains a NUL",
    ),
    "object-path-int": (
        {"objects": [mjk.SceneObject(name="o", mjcf_path=3)]},
        r"objects\[0\] \('o'\)\.mjcf_path must be a path",
    ),
    "duplicate-object": (
        {"objects": [_prim(), _prim(name="q"), _prim()]},
        r"objects\[2\]\.name: duplicate object name 'p' \(objects\[0\] has it too\)",
    ),
    "robot-path-none": ({"robots": [mjk.RobotSpec(path=None)]}, r"robots\[0\]\.path must be"),
    "robot-prefix-reserved": ({"robots": [_arm(prefix="mjkdl_")]}, r"robots\[0\]\.prefix: .*res"),
    "robot-srdf-int": ({"robots": [_arm(srdf=5)]}, r"robots\[0\]\.srdf must be a path"),
    "robot-floating-text": ({"robots": [_arm(floating="no")]}, r"robots\[0\]\.floating must be"),
    "robot-euler-nan": ({"robots": [_arm(euler=[0, np.nan, 0])]}, r"robots\[0\]\.euler.*finite"),
    "robot-target-kind": (
        {"robots": [_arm(attach_to=mjk.AttachTarget("site", "s"))]},
        r"robots\[0\]\.attach_to must be an AttachTarget",
    ),
    "attachment-pos": (
        {"robots": [_arm(attachments=[_att(), _att(pos=[0, 0, "1"])])]},
        r"robots\[0\]\.attachments\[1\]\.pos must be a list of numbers",
    ),
    "attachment-target-nul": (
        {"robots": [_arm(attachments=[_att(attach_to=mjk.AttachTarget(name="s\x00"))])]},
        r"robots\[0\]\.attachments\[0\]\.attach_to\.name contains a NUL",
    ),
    "attachment-empty-path": (
        {"robots": [_arm(attachments=[_att(mjcf_path="")])]},
        r"robots\[0\]\.attachments\[0\]\.mjcf_path is empty",
    ),
    "attachments-not-list": (
        {"robots": [_arm(attachments=_att())]},
        r"robots\[0\]\.attachments must be a list of AttachmentSpec",
    ),
    "camera-fovy-bool": ({"cameras": [_cam(fovy=True)]}, r"cameras\[0\] \('c'\)\.fovy must be a"),
    "camera-target-name": (
        {"cameras": [_cam(attach_to=mjk.AttachTarget(mjk.AttachKind.Body, None))]},
        r"cameras\[0\] \('c'\)\.attach_to\.name must be a string",
    ),
    "camera-on-frame": (
        {"cameras": [_cam(attach_to=mjk.AttachTarget(mjk.AttachKind.Frame, "f"))]},
        r"cameras\[0\] \('c'\)\.attach_to must be .* of kind Body, Site",
    ),
    "camera-reserved": ({"cameras": [_cam(name="mjkdl_cam")]}, r"cameras\[0\]\.name: .*reserved"),
}


@pytest.mark.parametrize(("spec_kw", "pattern"), list(BAD_SPECS.values()), ids=list(BAD_SPECS))
def test_bad_spec_field_is_named(spec_kw, pattern):
    with pytest.raises(mjk.SpecError, match=pattern) as err:
        _build(base_spec(**spec_kw))
    assert isinstance(err.value, ValueError)


def test_floor_name_is_free_without_a_floor():
    spec = base_spec(add_floor=False, objects=[_prim(name="floor")])
    with _build(spec) as scene:
        assert scene.model.body(scene.body_id("floor")).mass[0] == pytest.approx(1.0)


def test_numpy_numbers_and_flags_are_accepted():
    obj = _prim(size=np.full(3, 0.1), pos=(np.float32(0.5), np.int64(0), 1), fixed=np.bool_(False))
    spec = base_spec(timestep=np.float64(0.004), add_floor=np.bool_(True), objects=[obj])
    with _build(spec) as scene:
        assert scene.timestep() == 0.004
        np.testing.assert_allclose(scene.body_frame("p").translation, [0.5, 0, 1], atol=0)


# ----------------------------------------------------------------------------- files


def test_missing_include_is_a_file_not_found_naming_it(tmp_path):
    path = tmp_path / "with_include.xml"
    path.write_text(
        '<mujoco><include file="parts/missing.xml"/>'
        '<worldbody><body name="b"><geom size="0.1"/></body></worldbody></mujoco>'
    )
    spec = base_spec(robots=[mjk.RobotSpec(path=str(path))])
    with pytest.raises(mjk.ModelFileError, match=r"robots\[0\]\.path: file 'parts/missing\.xml'"):
        _build(spec)
    with pytest.raises(FileNotFoundError, match=r"not found: .*parts/missing\.xml"):
        _build(spec)


def test_included_file_is_checked_too(tmp_path):
    (tmp_path / "part.xml").write_text(
        '<mujocoinclude><asset><mesh name="m" file="gone.stl"/></asset></mujocoinclude>'
    )
    path = tmp_path / "main.xml"
    path.write_text(
        '<mujoco><include file="part.xml"/>'
        '<worldbody><body name="b"><geom type="mesh" mesh="m"/></body></worldbody></mujoco>'
    )
    obj = mjk.SceneObject(name="o", mjcf_path=str(path), fixed=True)
    with pytest.raises(mjk.ModelFileError, match=r"objects\[0\] \('o'\).*gone\.stl"):
        _build(base_spec(objects=[obj]))


FIFO_CASES = {
    "mesh": ('<asset><mesh name="m" file="pipe.stl"/></asset>', "mesh file of m"),
    "texture": ('<asset><texture name="t" type="2d" file="pipe.stl"/></asset>', "texture file"),
    "include": ('<include file="pipe.stl"/>', "file 'pipe.stl' included"),
}


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs named pipes")
@pytest.mark.parametrize("case", list(FIFO_CASES))
def test_fifo_asset_is_refused_without_hanging(tmp_path, case):
    """MuJoCo would block forever reading a FIFO; run in a child so a hang fails the test."""
    os.mkfifo(tmp_path / "pipe.stl")
    element, expected = FIFO_CASES[case]
    model = tmp_path / "fifo.xml"
    model.write_text(
        f'<mujoco>{element}<worldbody><body name="b"><geom size="0.1"/></body></worldbody></mujoco>'
    )
    script = (
        "import mjkdl as mjk\n"
        f"obj = mjk.SceneObject(name='o', mjcf_path={str(model)!r}, fixed=True)\n"
        "spec = mjk.SceneSpec(timestep=0.002, add_floor=False, add_skybox=False, objects=[obj])\n"
        "try:\n    mjk.Scene.build(spec)\n"
        "except mjk.ModelFileError as err:\n    print(err)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    assert "objects[0] ('o').mjcf_path" in done.stdout and expected in done.stdout
    assert "pipe.stl is not a regular file" in done.stdout


def test_model_path_that_is_a_directory_is_named(tmp_path):
    with pytest.raises(mjk.ModelFileError, match=r"robots\[0\]\.path: model file .* not a regular"):
        _build(base_spec(robots=[mjk.RobotSpec(path=str(tmp_path))]))


def test_two_small_robots_without_prefixes_name_the_second(tmp_path):
    """MuJoCo's attach lets this clash through to compile, which cannot say whose it is."""
    path = tmp_path / "arm.xml"
    path.write_text(two_link_arm())
    robots = [mjk.RobotSpec(path=str(path)), mjk.RobotSpec(path=str(path), pos=[0, 1, 0])]
    with pytest.raises(mjk.BuildError, match=r"robots\[1\]\.path .*repeated name 'base'.*prefix"):
        _build(base_spec(robots=robots))


@pytest.mark.parametrize(
    "spec_kw",
    [{"add_floor": "no"}, {"objects": [_prim(mass="1")]}, {"cameras": [_cam(pos="0 0 1")]}],
)
def test_wrong_types_are_also_type_errors(spec_kw):
    with pytest.raises(TypeError) as err:
        _build(base_spec(**spec_kw))
    assert isinstance(err.value, mjk.SpecError) and isinstance(err.value, ValueError)


def test_array_where_an_enum_or_mass_belongs_is_named():
    """Found by the fuzz test: NumPy arrays compared with `in`/`!=` have no truth value."""
    target = mjk.AttachTarget(np.array(["1", "2"]), "s")
    with pytest.raises(mjk.SpecTypeError, match=r"robots\[0\]\.attach_to must be an AttachTarget"):
        _build(base_spec(robots=[_arm(attach_to=target)]))
    part = mjk.SceneObject(name="o", mjcf_path="part.xml", mass=np.array([1.0, 2.0]))
    with pytest.raises(mjk.SpecError, match=r"objects\[0\] \('o'\): give either mjcf_path or"):
        _build(base_spec(objects=[part]))


# ----------------------------------------------------------------------------- environment

_ENVIRONMENT_XML = """
<mujoco>
  <visual><headlight ambient="0.3 0.3 0.3" diffuse="0.5 0.5 0.5"/></visual>
  <asset>
    <texture name="mjkdl_sky" type="skybox" builtin="gradient" rgb1="0.4 0.6 0.8"
             rgb2="0 0 0" width="512" height="3072"/>
    <texture name="mjkdl_grid" type="2d" builtin="checker" rgb1="0.2 0.3 0.4"
             rgb2="0.1 0.2 0.3" mark="edge" markrgb="0.8 0.8 0.8" width="300" height="300"/>
    <material name="mjkdl_grid" texture="mjkdl_grid" texrepeat="5 5" texuniform="true"
              reflectance="0.2"/>
  </asset>
  <worldbody>
    <light name="mjkdl_sun" pos="0 -1 3" dir="0 0.3 -1" type="directional"
           diffuse="0.6 0.6 0.6" castshadow="true"/>
    <geom name="floor" type="plane" size="0 0 0.05" material="mjkdl_grid"/>
  </worldbody>
</mujoco>
"""


def test_environment_matches_equivalent_mjcf():
    """Headlight, sun, skybox and floor read back exactly as the same scene written in MJCF."""
    ours = compile_scene(base_spec(add_floor=True, add_skybox=True))
    xml = mujoco.MjModel.from_xml_string(_ENVIRONMENT_XML)
    np.testing.assert_array_equal(ours.vis.headlight.ambient, xml.vis.headlight.ambient)
    np.testing.assert_array_equal(ours.vis.headlight.diffuse, xml.vis.headlight.diffuse)
    assert ours.nlight == 1 and ours.ntex == 2 and ours.nmat == 1
    assert ours.light(0).name == "mjkdl_sun"
    for field in ("pos", "dir", "type", "diffuse", "castshadow", "ambient", "specular"):
        name = "light_" + field
        np.testing.assert_array_equal(getattr(ours, name), getattr(xml, name))
    assert [ours.texture(i).name for i in range(2)] == ["mjkdl_sky", "mjkdl_grid"]
    for field in ("type", "width", "height", "nchannel", "adr", "data"):
        np.testing.assert_array_equal(getattr(ours, f"tex_{field}"), getattr(xml, f"tex_{field}"))
    assert ours.material(0).name == "mjkdl_grid"
    for field in ("texid", "texrepeat", "texuniform", "reflectance", "rgba"):
        np.testing.assert_array_equal(getattr(ours, f"mat_{field}"), getattr(xml, f"mat_{field}"))
    floor = ours.geom("floor")
    assert floor.type[0] == mujoco.mjtGeom.mjGEOM_PLANE
    np.testing.assert_array_equal(floor.size, xml.geom("floor").size)
    assert floor.matid[0] == 0


# ----------------------------------------------------------------------------- compile errors

TETRA_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"


def test_mesh_removed_before_compiling_is_a_model_file_error(tmp_path):
    (tmp_path / "tetra.obj").write_text(TETRA_OBJ)
    path = tmp_path / "meshy.xml"
    path.write_text(MESH_XML.replace("nope.stl", "tetra.obj"))
    s = build_mjspec(base_spec(objects=[mjk.SceneObject(name="o", mjcf_path=str(path))]))
    (tmp_path / "tetra.obj").unlink()
    with pytest.raises(mjk.ModelFileError) as err:
        compile_mjspec(s)
    assert str(err.value) == (
        "MuJoCo could not read a model file: Error: Error opening file 'tetra.obj'"
    )


def test_compile_error_is_a_build_error_with_mujocos_message(tmp_path):
    path = tmp_path / "mat.xml"
    path.write_text(
        '<mujoco><worldbody><body name="b"><geom size="0.1" material="nope"/></body>'
        "</worldbody></mujoco>"
    )
    with pytest.raises(mjk.BuildError) as err:
        _build_object(path)
    assert not isinstance(err.value, FileNotFoundError)
    assert str(err.value) == (
        "MuJoCo could not compile the scene: Error: material 'o/nope' not found in geom 1\n"
        "Element name '', id 1, line 1"
    )


def test_mjcf_objects_with_conflicting_options_name_the_second(tmp_path):
    objects = []
    for i, impratio in enumerate(["2", "3"]):
        path = tmp_path / f"o{i}.xml"
        path.write_text(
            f'<mujoco><option impratio="{impratio}"/><worldbody><body name="b">'
            '<geom size="0.1"/></body></worldbody></mujoco>'
        )
        objects.append(mjk.SceneObject(name=f"o{i}", mjcf_path=str(path)))
    with pytest.raises(mjk.BuildError) as err:
        _build(base_spec(objects=objects))
    assert str(err.value) == (
        "objects[1] ('o1').mjcf_path: MuJoCo cannot attach it: Error: Attach conflict when "
        "attaching to 'mjkdl_scene', policy is 'merge'\nimpratio: parent has 2, child has 3"
    )


def test_mjcf_object_free_joints_all_listed(tmp_path):
    path = tmp_path / "free.xml"
    path.write_text(
        '<mujoco><worldbody><body name="a"><freejoint name="loose"/><geom size="0.1"/></body>'
        '<body name="b"><freejoint/><geom size="0.1"/></body></worldbody></mujoco>'
    )
    with pytest.raises(mjk.SpecError) as err:
        _build_object(path)
    assert str(err.value) == (
        f"objects[0] ('o'): {path} has a free joint (loose, (unnamed)); remove it, mjkdl adds "
        "one to the object unless fixed=True"
    )


def test_mjcf_object_body_is_named_placed_and_free(tmp_path):
    path = tmp_path / "box.xml"
    path.write_text(
        '<mujoco><worldbody><body name="b"><geom size="0.1"/></body></worldbody></mujoco>'
    )
    obj = mjk.SceneObject(name="o", mjcf_path=str(path), pos=OFFSET_POS, euler=OFFSET_EULER)
    model = compile_scene(base_spec(add_floor=False, objects=[obj]))
    body = model.body("o")
    np.testing.assert_allclose(body.pos, OFFSET_POS, rtol=0, atol=TOL)
    _same_quat(body.quat, _xml_euler_quat(OFFSET_EULER))
    assert model.body("o/b").parentid[0] == body.id
    joint = model.joint("o")
    assert joint.type[0] == mujoco.mjtJoint.mjJNT_FREE and joint.bodyid[0] == body.id


@pytest.mark.parametrize("euler", [[0.0, 0.0, 90.0], [0.0, 0.0, 1e-6]], ids=["quarter", "tiny"])
def test_rotation_only_robot_offset_is_applied(tmp_path, euler):
    """A rotation without a translation is still an offset, however small."""
    path = tmp_path / "arm.xml"
    path.write_text(two_link_arm())
    model = compile_scene(base_spec(robots=[mjk.RobotSpec(path=str(path), euler=euler)]))
    np.testing.assert_array_equal(model.body("base").pos, [0, 0, 0])
    _same_quat(model.body("base").quat, _xml_euler_quat(euler), tol=1e-15)


# ----------------------------------------------------------------------------- welded contacts

PLATED_ARM = """<mujoco><worldbody><body name="base">{joint}<geom size="0.05"/>
<body name="plate" pos="0 0 0.05"><geom size="0.04"/>
<body name="l1" pos="0 0 0.05"><joint name="j1"/><geom size="0.03"/>
<body name="l2" pos="0 0 0.05"><joint name="j2"/><geom size="0.02"/></body></body></body>
</body></worldbody></mujoco>"""


@pytest.mark.parametrize(
    ("mount", "excluded"),
    [("world", {("a/plate", "a/l1")}), ("freejoint", set()), ("free_object", set())],
)
def test_contacts_excluded_only_below_a_world_welded_base(tmp_path, mount, excluded):
    """The first jointed body under a welded chain is excluded from its parent, nothing else."""
    path = tmp_path / "arm.xml"
    path.write_text(PLATED_ARM.format(joint="<freejoint/>" if mount == "freejoint" else ""))
    robot = mjk.RobotSpec(path=str(path), prefix="a/")
    objects = []
    if mount == "free_object":
        objects = [_prim(name="cart", shape=mjk.Shape.SPHERE, size=[0.1])]
        robot.attach_to = mjk.AttachTarget(mjk.AttachKind.Body, "cart")
    model = compile_scene(base_spec(add_floor=False, objects=objects, robots=[robot]))
    pairs = {
        (model.body(sig >> 16).name, model.body(sig & 0xFFFF).name)
        for sig in model.exclude_signature[: model.nexclude].tolist()
    }
    assert pairs == excluded


# ----------------------------------------------------------------------------- asset files


@pytest.mark.parametrize(
    ("asset", "what"),
    [
        ('<skin name="s" file="gone.skn"/>', "skin file of s"),
        ('<texture name="t" type="2d" file="gone.png"/>', "texture file of t"),
        ('<texture name="c" type="cube" fileright="gone.png"/>', "texture file of c"),
        ('<hfield name="h" file="gone.png" size="1 1 1 1"/>', "height field file of h"),
        ('<texture type="cube" fileleft="gone.png"/>', "texture file of an unnamed texture"),
    ],
    ids=["skin", "texture", "cube_face", "hfield", "unnamed_cube"],
)
def test_missing_asset_file_named_with_its_kind(tmp_path, asset, what):
    path = tmp_path / "assets.xml"
    path.write_text(
        f'<mujoco><asset>{asset}</asset><worldbody><body name="b"><geom size="0.1"/></body>'
        "</worldbody></mujoco>"
    )
    gone = "gone.skn" if "skin" in asset else "gone.png"
    with pytest.raises(mjk.ModelFileError) as err:
        _build_object(path)
    assert str(err.value) == (
        f"objects[0] ('o').mjcf_path: {what} in {path} not found: {tmp_path / gone}"
    )


def test_builtin_texture_needs_no_file(tmp_path):
    path = tmp_path / "builtin.xml"
    path.write_text(
        '<mujoco><asset><texture name="t" type="2d" builtin="flat" width="8" height="8"/>'
        '</asset><worldbody><body name="b"><geom size="0.1"/></body></worldbody></mujoco>'
    )
    model = compile_scene(base_spec(objects=[mjk.SceneObject(name="o", mjcf_path=str(path))]))
    assert model.texture("o/t").width[0] == 8


def test_missing_file_included_by_an_included_file_is_named(tmp_path):
    (tmp_path / "parts").mkdir()
    (tmp_path / "parts" / "a.xml").write_text(
        '<mujocoinclude><include file="parts/missing.xml"/></mujocoinclude>'
    )
    path = tmp_path / "main.xml"
    path.write_text(
        '<mujoco><include file=""/><include file="parts/a.xml"/>'
        '<worldbody><body name="b"><geom size="0.1"/></body></worldbody></mujoco>'
    )
    with pytest.raises(mjk.ModelFileError) as err:
        _build_object(path)
    assert str(err.value) == (
        f"objects[0] ('o').mjcf_path: file 'parts/missing.xml' included by "
        f"{tmp_path / 'parts' / 'a.xml'} not found: {tmp_path / 'parts' / 'missing.xml'}"
    )


def test_include_cycle_is_left_to_mujoco(tmp_path):
    (tmp_path / "a.xml").write_text('<mujocoinclude><include file="b.xml"/></mujocoinclude>')
    (tmp_path / "b.xml").write_text('<mujocoinclude><include file="a.xml"/></mujocoinclude>')
    path = tmp_path / "main.xml"
    path.write_text('<mujoco><include file="a.xml"/></mujoco>')
    with pytest.raises(mjk.BuildError) as err:
        _build_object(path)
    assert str(err.value).startswith(f"objects[0] ('o').mjcf_path: MuJoCo cannot read {path}: ")


def test_mesh_files_are_not_taken_for_includes(tmp_path):
    (tmp_path / "assets").mkdir()
    (tmp_path / "assets" / "tetra.obj").write_text(TETRA_OBJ)
    (tmp_path / "part.xml").write_text(
        '<mujocoinclude><worldbody><body name="b"><geom type="mesh" mesh="m"/></body>'
        "</worldbody></mujocoinclude>"
    )
    path = tmp_path / "main.xml"
    path.write_text(
        '<mujoco><compiler meshdir="assets"/><include file="part.xml"/>'
        '<asset><mesh name="m" file="tetra.obj"/></asset></mujoco>'
    )
    model = compile_scene(base_spec(objects=[mjk.SceneObject(name="o", mjcf_path=str(path))]))
    assert model.mesh("o/m").vertnum[0] == 4


# ----------------------------------------------------------------------------- mounts and cameras

SITES_XML = """<mujoco><compiler angle="radian"/>
<worldbody><body name="b" pos="0.1 0.2 0.3"><geom size="0.05"/>
<site name="turned" pos="0.01 0.02 0.03" quat="0.5 0.5 0.5 0.5"/>
<site name="spun" pos="0.01 0 0" euler="0.3 0.2 0.1"/>
<frame pos="0 0 0.1" euler="0.1 0.2 0.3"><site name="framed" pos="0.04 0 0"/></frame>
</body></worldbody></mujoco>"""
# The same in degrees (MuJoCo's default unit) and another Euler sequence: the scene compiles in
# radians, so a site's angles must be read in the unit of the file it comes from.
SITES_DEGREES_XML = """<mujoco><compiler angle="degree" eulerseq="zyx"/>
<worldbody><body name="b" pos="0.1 0.2 0.3"><geom size="0.05"/>
<site name="spun" pos="0.01 0 0" euler="30 20 90"/>
<site name="axis" axisangle="0 1 1 120"/>
<frame euler="0 90 0"><site name="framed" pos="0.04 0 0" euler="45 0 0"/></frame>
</body></worldbody></mujoco>"""


@pytest.mark.parametrize(
    "unit, site",
    [("radian", s) for s in ("turned", "framed", "spun")]
    + [("degree", s) for s in ("spun", "axis", "framed")],
)
def test_camera_on_a_site_sits_exactly_on_it(tmp_path, unit, site):
    path = tmp_path / "sites.xml"
    path.write_text(SITES_XML if unit == "radian" else SITES_DEGREES_XML)
    obj = mjk.SceneObject(name="o", mjcf_path=str(path), fixed=True, euler=[10, 20, 30])
    cam = mjk.CameraSpec(
        name="c",
        attach_to=mjk.AttachTarget(mjk.AttachKind.Site, f"o/{site}"),
        pos=[0, 0, 0],
        euler=[0, 0, 0],
        fovy=60.0,
    )
    model = compile_scene(base_spec(objects=[obj], cameras=[cam]))
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)
    np.testing.assert_allclose(data.cam("c").xpos, data.site(f"o/{site}").xpos, atol=1e-12)
    np.testing.assert_allclose(data.cam("c").xmat, data.site(f"o/{site}").xmat, atol=1e-12)
    assert model.cam_fovy[model.camera("c").id] == 60.0


def test_unknown_mounts_are_named_with_field_and_place(tmp_path):
    arm = tmp_path / "arm.xml"
    arm.write_text(two_link_arm())
    on_table = mjk.AttachTarget(mjk.AttachKind.Body, "tabel")
    robot = mjk.RobotSpec(path=str(arm), attach_to=on_table)
    with pytest.raises(mjk.UnknownNameError) as err:
        _build(base_spec(objects=[_prim(name="table")], robots=[robot]))
    assert str(err.value) == (
        "no body named 'tabel' in the scene (robots[0].attach_to); close matches: table"
    )
    box = tmp_path / "box.xml"
    box.write_text(
        '<mujoco><worldbody><body name="x"><geom size="0.01"/></body></worldbody></mujoco>'
    )
    att = mjk.AttachmentSpec(
        mjcf_path=str(box), attach_to=mjk.AttachTarget(mjk.AttachKind.Body, "l3")
    )
    with pytest.raises(mjk.UnknownNameError) as err:
        _build(base_spec(robots=[mjk.RobotSpec(path=str(arm), attachments=[att])]))
    assert str(err.value) == (
        "no body named 'l3' in the robot (robots[0].attachments[0].attach_to); "
        "close matches: l2, l1"
    )


# ----------------------------------------------------------------------------- MuJoCo notices


def test_compiling_restores_the_users_warning_handler_and_keeps_other_warnings():
    s = build_mjspec(base_spec())
    s.compiler.settotalmass = 2.0  # deprecated: MuJoCo warns when compiling
    notices: list[str] = []
    mujoco.set_mju_user_warning(notices.append)
    try:
        with pytest.warns(UserWarning, match=r"^compiler attribute 'settotalmass' is deprecated"):
            compile_mjspec(s)
        assert mujoco.get_mju_user_warning() == notices.append
    finally:
        mujoco.set_mju_user_warning(None)
    assert notices == []


def test_model_path_below_a_file_is_named_with_the_os_reason(tmp_path):
    (tmp_path / "a.xml").write_text("<mujoco/>")
    path = tmp_path / "a.xml" / "b.xml"
    with pytest.raises(mjk.ModelFileError) as err:
        _build_object(path)
    assert str(err.value) == (
        f"objects[0] ('o').mjcf_path: model file {path} cannot be read: Not a directory"
    )


def test_euler_quat_names_the_field_of_a_bad_vector():
    with pytest.raises(mjk.SpecError) as err:
        euler_quat([1, 2], "tool.tcp_euler")
    assert str(err.value) == "tool.tcp_euler must have 3 values, got 2: [1, 2]"


def test_scene_model_name_and_gravity():
    model = compile_scene(base_spec(add_floor=False, gravity_z=-3.5))
    assert model.names.split(b"\0")[0] == b"mjkdl_scene"  # MuJoCo stores the model name first
    np.testing.assert_array_equal(model.opt.gravity, [0.0, 0.0, -3.5])


def test_floor_and_skybox_flags_each_add_only_their_own_assets():
    floor_only = compile_scene(base_spec(add_floor=True, add_skybox=False))
    assert [floor_only.texture(i).name for i in range(floor_only.ntex)] == ["mjkdl_grid"]
    assert floor_only.ngeom == 1 and floor_only.geom(0).name == "floor"
    sky_only = compile_scene(base_spec(add_floor=False, add_skybox=True))
    assert [sky_only.texture(i).name for i in range(sky_only.ntex)] == ["mjkdl_sky"]
    assert sky_only.ngeom == 0 and sky_only.nmat == 0


def test_a_marker_shows_but_neither_collides_nor_falls():
    goal = mjk.SceneObject(
        name="goal", shape=mjk.Shape.SPHERE, size=[0.02], rgba=[1, 0, 0, 0.5], marker=True
    )
    ball = mjk.SceneObject(name="ball", shape=mjk.Shape.SPHERE, size=[0.02], mass=0.1)
    scene = _build(
        mjk.SceneSpec(timestep=0.002, add_floor=True, add_skybox=False, objects=[goal, ball])
    )
    m, d = scene.model, scene.data
    body = m.body("goal").id
    assert m.body_mocapid[body] == 0 and m.body_jntnum[body] == 0
    geom = m.geom("goal").id
    assert m.geom_contype[geom] == 0 and m.geom_conaffinity[geom] == 0
    assert m.geom_rgba[geom].tolist() == [1, 0, 0, 0.5]
    scene.set_body_pose("goal", [0.3, 0.0, 0.5])
    scene.set_body_pose("ball", [0.3, 0.0, 0.55])  # dropped through the marker
    scene.step(200)
    np.testing.assert_array_equal(d.xpos[body], [0.3, 0.0, 0.5])
    assert d.xpos[m.body("ball").id][2] < 0.1  # fell through the marker
    scene.close()


@pytest.mark.parametrize(
    ("fields", "error", "message"),
    [
        ({"fixed": True}, mjk.SpecError, "objects[0] ('m'): a marker is a massless primitive"),
        ({"mass": 0.1}, mjk.SpecError, "give it no mjcf_path, fixed or mass"),
        ({"marker": "yes"}, mjk.SpecTypeError, "objects[0] ('m').marker must be True or False"),
    ],
)
def test_bad_markers_are_refused(fields, error, message):
    obj = mjk.SceneObject(name="m", shape=mjk.Shape.SPHERE, size=[0.02], marker=True)
    for k, v in fields.items():
        setattr(obj, k, v)
    spec = mjk.SceneSpec(timestep=0.002, add_floor=True, add_skybox=False, objects=[obj])
    with pytest.raises(error) as caught:
        _build(spec)
    assert message in str(caught.value)


# ------------------------------------------------------------------ contact options


def test_physics_options_reach_the_compiled_model_over_the_models_own() -> None:
    """Unset fields keep what the models say (the 2F-85's elliptic cone and impratio 10);
    set ones win over them, whatever order the robots were attached in."""
    arm = mjk.RobotSpec(path=menagerie("kinova_gen3"), attachments=[gripper()])
    own = compile_scene(base_spec(robots=[arm]))
    assert own.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC and own.opt.impratio == 10.0
    assert own.opt.noslip_iterations == 0 and own.opt.iterations == 100
    physics = mjk.PhysicsOptions(cone="pyramidal", impratio=3.0, noslip_iterations=5, iterations=50)
    model = compile_scene(base_spec(robots=[arm], physics=physics))
    assert model.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    assert (model.opt.impratio, model.opt.noslip_iterations, model.opt.iterations) == (3.0, 5, 50)
    bare = compile_scene(base_spec(physics=mjk.PhysicsOptions.grasping()))
    assert bare.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC and bare.opt.impratio == 10.0


@pytest.mark.parametrize(
    ("physics", "error", "message"),
    [
        ("elliptic", mjk.SpecTypeError, "SceneSpec.physics must be a PhysicsOptions, got str"),
        (
            mjk.PhysicsOptions(cone="Elliptic"),
            mjk.SpecError,
            "SceneSpec.physics.cone must be None or one of ['pyramidal', 'elliptic'], "
            "got 'Elliptic'",
        ),
        (
            mjk.PhysicsOptions(impratio=0.5),
            mjk.SpecError,
            "SceneSpec.physics.impratio must be at least 1 (or None), got 0.5",
        ),
        (
            mjk.PhysicsOptions(impratio="10"),
            mjk.SpecTypeError,
            "SceneSpec.physics.impratio must be a number, got '10'",
        ),
        (
            mjk.PhysicsOptions(noslip_iterations=2.5),
            mjk.SpecError,
            "SceneSpec.physics.noslip_iterations must be None or a non-negative integer, got 2.5",
        ),
        (
            mjk.PhysicsOptions(iterations=0),
            mjk.SpecError,
            "SceneSpec.physics.iterations must be at least 1 (or None), got 0",
        ),
    ],
)
def test_bad_physics_options_are_named(physics, error, message) -> None:
    with pytest.raises(error) as err:
        compile_scene(base_spec(physics=physics))
    assert str(err.value) == message
