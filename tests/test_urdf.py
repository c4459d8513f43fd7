"""URDF loading: meshes, actuators, limits, kinematics against Pinocchio, errors, attaching."""

from __future__ import annotations

import importlib.metadata
import struct
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
import trimesh

import mjkdl as mjk
from mjkdl.errors import BuildError, ModelFileError, SpecError
from mjkdl.urdf import (
    UnreadableMeshWarning,
    example_robot_data_path,
    load_urdf,
    mesh_cache_dir,
    root_links,
)

UR5 = "ur_description/urdf/ur5_robot.urdf"
PANDA = "panda_description/urdf/panda.urdf"
UR5_JOINTS = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
]
INERTIAL = (
    '<inertial><mass value="1"/>'
    '<inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>'
)


def _compile(relative: str, **kw) -> mujoco.MjModel:
    return load_urdf(example_robot_data_path(relative), **kw).compile()


def _write_stl(path: Path) -> None:
    """A binary STL tetrahedron (MuJoCo reads binary STL only)."""
    vertices = [(0, 0, 0), (0.1, 0, 0), (0, 0.1, 0), (0, 0, 0.1)]
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as out:
        out.write(b"\0" * 80 + struct.pack("<I", len(faces)))
        for face in faces:
            out.write(struct.pack("<3f", 0, 0, 0))
            for index in face:
                out.write(struct.pack("<3f", *vertices[index]))
            out.write(b"\0\0")


def _write_urdf(path: Path, link_body: str, extra: str = "") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        f'<robot name="tiny"><link name="base">{INERTIAL}</link>'
        f'<link name="arm">{link_body}{INERTIAL}</link>'
        '<joint name="hinge" type="revolute"><parent link="base"/><child link="arm"/>'
        '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="5" velocity="1"/></joint>'
        f"{extra}</robot>"
    )
    return path


def _mesh(element: str, uri: str) -> str:
    return f'<{element}><geometry><mesh filename="{uri}"/></geometry></{element}>'


def _mesh_geoms_per_body(model: mujoco.MjModel) -> dict[str, int]:
    counts: dict[str, int] = {}
    for geom in range(model.ngeom):
        if model.geom_type[geom] == mujoco.mjtGeom.mjGEOM_MESH:
            name = model.body(model.geom_bodyid[geom]).name
            counts[name] = counts.get(name, 0) + 1
    return counts


def _expected_mesh_geoms(urdf: Path, element: str = "*") -> dict[str, int]:
    """Per link, its `<visual>`/`<collision>` elements (`element`) that hold a mesh."""
    counts = {}
    for link in ET.parse(urdf).getroot().findall("link"):
        total = len(link.findall(f"{element}/geometry/mesh"))
        if total:
            counts[link.get("name")] = total
    return counts


def _world_aabb(model: mujoco.MjModel, data: mujoco.MjData, geom: int) -> np.ndarray:
    """[min, max] corners of a mesh geom's vertices in the world."""
    mesh = model.geom_dataid[geom]
    start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
    rotation = data.geom_xmat[geom].reshape(3, 3)
    points = model.mesh_vert[start : start + count] @ rotation.T + data.geom_xpos[geom]
    return np.array([points.min(axis=0), points.max(axis=0)])


def _self_contacts(model: mujoco.MjModel, data: mujoco.MjData, bodies: set[int]) -> int:
    return sum(
        model.geom_bodyid[c.geom1] in bodies and model.geom_bodyid[c.geom2] in bodies
        for c in data.contact[: data.ncon]
    )


def _joint_range(model: mujoco.MjModel, name: str) -> list[float]:
    return model.joint(name).range.tolist()


def test_ur5_bodies_joints_and_motors() -> None:
    model = _compile(UR5)
    assert [model.body(b).name for b in range(model.nbody) if model.body_parentid[b] == 0] == [
        "world",
        "base_link",
    ]
    assert model.body("tool0").id > 0 and model.body("ee_link").id > 0
    assert model.njnt == 6 and model.neq == 0
    assert [model.actuator(a).name for a in range(model.nu)] == UR5_JOINTS
    assert np.all(model.actuator_gear[:, 0] == 1)
    assert model.actuator_ctrlrange.tolist() == [[-150, 150]] * 3 + [[-28, 28]] * 3
    assert model.actuator_forcerange.tolist() == model.actuator_ctrlrange.tolist()
    assert _joint_range(model, "elbow_joint") == [-3.14159265359, 3.14159265359]
    assert _joint_range(model, "wrist_3_joint") == [-6.28318530718, 6.28318530718]
    assert model.jnt_limited.tolist() == [1] * 6


def test_ur5_mesh_geoms_match_the_urdf() -> None:
    path = example_robot_data_path(UR5)
    model = _compile(UR5)
    assert _mesh_geoms_per_body(model) == _expected_mesh_geoms(path)
    assert sum(_expected_mesh_geoms(path).values()) == 14
    visual = (model.geom_contype == 0) & (model.geom_conaffinity == 0)
    assert model.geom_group[visual].tolist() == [2] * 7
    assert model.geom_group[~visual].tolist() == [3] * 8  # 7 meshes and ee_link's box
    assert model.nmesh == 14  # 7 converted .dae visuals, 7 .stl collision meshes


def test_ur5_dae_visuals_are_converted_and_line_up_with_the_collision_meshes() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing is dropped or replaced any more
        spec = load_urdf(example_robot_data_path(UR5))
    visuals = [Path(m.file) for m in spec.meshes if Path(m.file).suffix == ".obj"]
    assert len(visuals) == 7
    assert all(f.parent == mesh_cache_dir() and f.is_file() for f in visuals)
    model = spec.compile()
    data = mujoco.MjData(model)
    data.qpos[:] = [0.3, -1.2, 1.4, -1.5, -1.57, 0.2]
    mujoco.mj_forward(model, data)
    for body in _mesh_geoms_per_body(model):
        geoms = [g for g in range(model.ngeom) if model.body(model.geom_bodyid[g]).name == body]
        visual, collision = (next(g for g in geoms if model.geom_group[g] == k) for k in (2, 3))
        # The visual (COLLADA, converted) and collision (STL) meshes are separate files of
        # the same part: their world bounding boxes agree to the millimetre.
        diff = np.abs(_world_aabb(model, data, visual) - _world_aabb(model, data, collision))
        assert diff.max() < 1e-3, body


def test_panda_arm_fingers_and_mimic() -> None:
    path = example_robot_data_path(PANDA)
    model = _compile(PANDA)
    arm = [f"panda_joint{i}" for i in range(1, 8)]
    assert model.njnt == 9
    assert [model.actuator(a).name for a in range(model.nu)] == [*arm, "panda_finger_joint1"]
    assert model.actuator_ctrlrange.tolist() == [[-87, 87]] * 4 + [[-12, 12]] * 3 + [[-100, 100]]
    assert model.neq == 1
    assert model.equality(0).name == "panda_finger_joint2"
    assert model.eq_type[0] == mujoco.mjtEq.mjEQ_JOINT
    assert model.eq_obj1id[0] == model.joint("panda_finger_joint2").id
    assert model.eq_obj2id[0] == model.joint("panda_finger_joint1").id
    assert model.eq_data[0, :5].tolist() == [0, 1, 0, 0, 0]
    assert _joint_range(model, "panda_joint4") == [-3.0718, -0.0698]
    assert _joint_range(model, "panda_finger_joint2") == [0.0, 0.04]
    assert model.dof_damping[model.joint("panda_joint1").dofadr[0]] == 0.003
    assert model.dof_damping[model.joint("panda_finger_joint1").dofadr[0]] == 0.3
    assert _mesh_geoms_per_body(model) == _expected_mesh_geoms(path)
    assert _mesh_geoms_per_body(model)["panda_leftfinger"] == 1  # finger.dae, converted
    assert model.body("panda_hand_tcp").id > 0
    assert model.body(model.body_parentid[model.body("panda_link0").id]).name == "world"


def test_ur5_kinematics_match_pinocchio() -> None:
    path = example_robot_data_path(UR5)
    model = _compile(UR5)
    data = mujoco.MjData(model)
    pin_model = pin.buildModelFromUrdf(str(path))
    pin_data = pin_model.createData()
    rng = np.random.default_rng(0)
    bodies = [model.body(b).name for b in range(1, model.nbody)]
    assert len(bodies) == 10
    for _ in range(10):
        q = pin.neutral(pin_model)
        for joint in range(model.njnt):
            low, high = model.jnt_range[joint]
            value = rng.uniform(low, high)
            data.qpos[model.jnt_qposadr[joint]] = value
            q[pin_model.joints[pin_model.getJointId(model.joint(joint).name)].idx_q] = value
        mujoco.mj_forward(model, data)
        pin.framesForwardKinematics(pin_model, pin_data, q)
        pin.updateFramePlacements(pin_model, pin_data)
        for name in bodies:
            placement = pin_data.oMf[pin_model.getFrameId(name, pin.FrameType.BODY)]
            body = model.body(name).id
            pin_quat = pin.Quaternion(placement.rotation).coeffs()  # x, y, z, w
            mj_quat = data.xquat[body][[1, 2, 3, 0]]
            assert np.max(np.abs(data.xpos[body] - placement.translation)) < 1e-9
            assert np.max(np.abs(data.xmat[body].reshape(3, 3) - placement.rotation)) < 1e-9
            assert 1 - abs(float(np.dot(mj_quat, pin_quat))) < 1e-9


def test_package_uri_through_ros_package_path(tmp_path: Path, monkeypatch) -> None:
    _write_stl(tmp_path / "ws" / "fakepkg" / "meshes" / "box.stl")
    body = _mesh("collision", "package://fakepkg/meshes/box.stl")
    urdf = _write_urdf(tmp_path / "elsewhere" / "tiny.urdf", body)
    for entry in (tmp_path / "ws", tmp_path / "ws" / "fakepkg"):
        monkeypatch.setenv("ROS_PACKAGE_PATH", f"/nonexistent:{entry}")
        spec = load_urdf(urdf)
        assert spec.meshes[0].file == str(tmp_path / "ws" / "fakepkg" / "meshes" / "box.stl")
        assert spec.compile().nmesh == 1


def test_package_uri_through_urdf_ancestor(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    _write_stl(tmp_path / "fakepkg" / "meshes" / "box.stl")
    body = _mesh("collision", "package://fakepkg/meshes/box.stl")
    model = load_urdf(_write_urdf(tmp_path / "fakepkg" / "urdf" / "tiny.urdf", body)).compile()
    assert _mesh_geoms_per_body(model) == {"arm": 1}


def test_relative_and_file_uri_meshes(tmp_path: Path) -> None:
    stl = tmp_path / "pkg" / "meshes" / "box.stl"
    _write_stl(stl)
    body = _mesh("visual", "../meshes/box.stl") + _mesh("collision", f"file://{stl}")
    spec = load_urdf(_write_urdf(tmp_path / "pkg" / "urdf" / "tiny.urdf", body))
    assert [mesh.file for mesh in spec.meshes] == [str(stl)]
    assert spec.strippath is False and spec.meshdir == ""
    model = spec.compile()
    assert model.geom_group.tolist() == [2, 3]
    assert model.geom_contype.tolist() == [0, 1]


def test_unreadable_visual_replaced_by_collision_mesh(tmp_path: Path) -> None:
    _write_stl(tmp_path / "meshes" / "arm.stl")
    for other in ("arm.3ds", "decal.3ds"):  # neither MuJoCo nor trimesh reads .3ds
        (tmp_path / "meshes" / other).write_bytes(b"MM")
    decal = _mesh("visual", "meshes/decal.3ds")  # dropped: the collision mesh is drawn once
    visual = (
        '<visual><geometry><mesh filename="meshes/arm.3ds"/></geometry>'
        '<material name="red"><color rgba="1 0 0 1"/></material></visual>'
    )
    collision = (
        '<collision><origin xyz="0 0 0.5"/>'
        '<geometry><mesh filename="meshes/arm.stl"/></geometry></collision>'
    )
    urdf = _write_urdf(tmp_path / "tiny.urdf", visual + collision + decal)
    expected = r"replaced by collision meshes: arm\.3ds; dropped: decal\.3ds$"
    with pytest.warns(UnreadableMeshWarning, match=expected):
        model = load_urdf(urdf).compile()
    visual_geom = next(g for g in range(model.ngeom) if model.geom_group[g] == 2)
    assert model.geom_type[visual_geom] == mujoco.mjtGeom.mjGEOM_MESH
    assert model.body(model.geom_bodyid[visual_geom]).name == "arm"
    assert model.geom_contype[visual_geom] == 0 and model.geom_conaffinity[visual_geom] == 0
    collision_geom = next(g for g in range(model.ngeom) if model.geom_group[g] == 3)
    assert model.geom_pos[visual_geom].tolist() == model.geom_pos[collision_geom].tolist()
    assert model.geom_pos[visual_geom][2] > 0.5  # the origin, plus the mesh centre MuJoCo adds
    assert model.geom_rgba[visual_geom].tolist() == [1, 0, 0, 1]
    assert _mesh_geoms_per_body(model) == {"arm": 2}


def test_unreadable_mesh_without_collision_mesh_is_dropped(tmp_path: Path) -> None:
    (tmp_path / "arm.3ds").write_bytes(b"MM")
    (tmp_path / "tool.wrl").write_text("#VRML V2.0 utf8")
    body = _mesh("visual", "arm.3ds") + _mesh("collision", "tool.wrl")
    urdf = _write_urdf(tmp_path / "tiny.urdf", body)
    with pytest.warns(UnreadableMeshWarning) as record:
        model = load_urdf(urdf).compile()
    assert len(record) == 1
    assert str(record[0].message).endswith("dropped: tool.wrl, arm.3ds")
    assert model.ngeom == 0


def _write_dae(path: Path, extents: list[float], unit: float = 1.0) -> Path:
    """A COLLADA box written by trimesh, its lengths in units of `unit` metres."""
    text = trimesh.exchange.dae.export_collada(trimesh.creation.box(extents=extents))
    text = text.decode() if isinstance(text, bytes) else text
    text = text.replace("<asset>", f'<asset><unit name="u" meter="{unit}"/>', 1)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


@pytest.mark.parametrize(("unit", "extents"), [(1.0, [0.1, 0.2, 0.3]), (0.001, [40, 60, 80])])
def test_dae_meshes_convert_to_metres_in_the_cache(tmp_path, monkeypatch, unit, extents):
    monkeypatch.setenv("MJKDL_CACHE_DIR", str(tmp_path / "cache"))
    dae = _write_dae(tmp_path / "meshes" / "part.dae", extents, unit)
    body = _mesh("visual", "meshes/part.dae") + _mesh("collision", "meshes/part.dae")
    urdf = _write_urdf(tmp_path / "tiny.urdf", body)
    spec = load_urdf(urdf)
    files = {Path(m.file) for m in spec.meshes}
    assert len(files) == 1  # one conversion shared by the visual and the collision geom
    converted = files.pop()
    assert converted.parent == tmp_path / "cache" / "meshes"
    assert mesh_cache_dir() == tmp_path / "cache" / "meshes"
    model = spec.compile()
    assert model.mesh_vertnum.tolist() == [8]
    size = np.ptp(model.mesh_vert, axis=0)
    assert np.allclose(sorted(size), sorted(np.array(extents) * unit), rtol=0, atol=1e-7)
    stamp = converted.stat().st_mtime_ns
    load_urdf(urdf)  # same content: the cached file is reused, not rewritten
    assert converted.stat().st_mtime_ns == stamp
    _write_dae(dae, [0.5, 0.5, 0.5])  # new content: a new cache entry
    assert {Path(m.file) for m in load_urdf(urdf).meshes} != {converted}


def test_malformed_dae_names_file_and_link(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("MJKDL_CACHE_DIR", str(tmp_path / "cache"))
    (tmp_path / "arm.dae").write_text("<COLLADA><library_geometries>")
    urdf = _write_urdf(tmp_path / "tiny.urdf", _mesh("visual", "arm.dae"))
    with pytest.raises(ModelFileError) as info:
        load_urdf(urdf)
    message = str(info.value)
    assert message.startswith(f"{urdf}: mesh {tmp_path / 'arm.dae'} of link 'arm' cannot be read")
    assert not (tmp_path / "cache" / "meshes").exists() or not any(
        (tmp_path / "cache" / "meshes").iterdir()
    )


def test_unwritable_mesh_cache_says_how_to_move_it(tmp_path, monkeypatch) -> None:
    blocker = tmp_path / "cache"
    blocker.write_text("a file where the cache folder should be")
    monkeypatch.setenv("MJKDL_CACHE_DIR", str(blocker))
    _write_dae(tmp_path / "part.dae", [0.1, 0.1, 0.1])
    urdf = _write_urdf(tmp_path / "tiny.urdf", _mesh("visual", "part.dae"))
    with pytest.raises(ModelFileError) as info:
        load_urdf(urdf)
    message = str(info.value)
    assert f"cannot write its converted copy to {blocker / 'meshes'}" in message
    assert message.endswith("set MJKDL_CACHE_DIR to a writable folder")


def test_missing_dae_names_uri_and_link(tmp_path: Path) -> None:
    urdf = _write_urdf(tmp_path / "tiny.urdf", _mesh("visual", "meshes/gone.dae"))
    with pytest.raises(ModelFileError, match=r"mesh 'meshes/gone\.dae' of link 'arm' not found"):
        load_urdf(urdf)


@pytest.mark.parametrize("effort", ["nan", "inf", "-5", "lots"])
def test_bad_effort_names_joint_and_file(tmp_path: Path, effort: str) -> None:
    urdf = _write_urdf(tmp_path / "tiny.urdf", "")
    urdf.write_text(urdf.read_text().replace('effort="5"', f'effort="{effort}"'))
    with pytest.raises(SpecError) as info:
        load_urdf(urdf)
    assert str(info.value).startswith(f"{urdf}: joint 'hinge' has effort '{effort}'")


def test_continuous_joint_is_unlimited_and_keeps_dynamics(tmp_path: Path) -> None:
    extra = (
        f'<link name="wheel">{INERTIAL}</link>'
        '<joint name="spin" type="continuous"><parent link="arm"/><child link="wheel"/>'
        '<limit lower="-1" upper="1"/><dynamics damping="0.5" friction="0.25"/></joint>'
    )
    model = load_urdf(_write_urdf(tmp_path / "tiny.urdf", "", extra)).compile()
    spin = model.joint("spin")
    assert model.jnt_limited[spin.id] == 0
    assert model.dof_damping[spin.dofadr[0]] == 0.5
    assert model.dof_frictionloss[spin.dofadr[0]] == 0.25
    assert model.actuator("spin").ctrllimited[0] == 0
    assert model.actuator("spin").forcelimited[0] == 0
    assert model.actuator("hinge").ctrlrange.tolist() == [-5, 5]


def test_missing_urdf_names_the_path(tmp_path: Path) -> None:
    missing = tmp_path / "nope.urdf"
    with pytest.raises(ModelFileError) as info:
        load_urdf(missing)
    assert str(info.value) == f"URDF file not found: {missing}"


def test_missing_mesh_names_uri_and_link(tmp_path: Path) -> None:
    urdf = _write_urdf(tmp_path / "tiny.urdf", _mesh("collision", "package://nopkg/m/x.stl"))
    with pytest.raises(ModelFileError) as info:
        load_urdf(urdf)
    assert "'package://nopkg/m/x.stl'" in str(info.value)
    assert "'arm'" in str(info.value)


def test_mujoco_rejection_is_a_build_error(tmp_path: Path) -> None:
    extra = '<joint name="bad" type="fixed"><parent link="ghost"/><child link="base"/></joint>'
    urdf = _write_urdf(tmp_path / "tiny.urdf", "", extra)
    with pytest.raises(BuildError, match="URDF joint parent or child missing") as info:
        load_urdf(urdf)
    assert str(urdf) in str(info.value)


def test_non_urdf_xml_is_a_spec_error(tmp_path: Path) -> None:
    path = tmp_path / "scene.xml"
    path.write_text("<mujoco/>")
    with pytest.raises(SpecError, match="root element is <mujoco>"):
        load_urdf(path)


def test_example_robot_data_path_suggests_close_matches() -> None:
    assert example_robot_data_path(UR5).name == "ur5_robot.urdf"
    with pytest.raises(ModelFileError) as info:
        example_robot_data_path("ur_description/urdf/ur5_robot.urd")
    assert "close matches: ur_description/urdf/ur5_robot.urdf" in str(info.value)


def test_example_robot_data_missing_package(monkeypatch) -> None:
    def not_installed(name: str) -> None:
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, "distribution", not_installed)
    with pytest.raises(ModelFileError, match="pip install example-robot-data"):
        example_robot_data_path(UR5)


def test_attach_into_parent_with_prefix_and_frame() -> None:
    parent = mujoco.MjSpec()
    frame = parent.worldbody.add_frame(pos=[1, 0, 0])
    parent.attach(load_urdf(example_robot_data_path(UR5)), prefix="r_", frame=frame)
    model = parent.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert data.xpos[model.body("r_base_link").id].tolist() == [1, 0, 0]
    assert [model.actuator(a).name for a in range(model.nu)] == [f"r_{j}" for j in UR5_JOINTS]
    assert _joint_range(model, "r_elbow_joint") == [-3.14159265359, 3.14159265359]
    assert model.nmesh == 14


def test_attach_two_pandas_to_sites() -> None:
    parent = mujoco.MjSpec.from_string("<mujoco/>")  # MJCF default: angles in degrees
    for prefix, y in (("left_", 0.5), ("right_", -0.5)):
        site = parent.worldbody.add_site(name=f"{prefix}mount", pos=[0, y, 0])
        parent.attach(load_urdf(example_robot_data_path(PANDA)), prefix=prefix, site=site)
    model = parent.compile()
    assert model.nu == 16 and model.neq == 2
    assert model.equality(1).name == "right_panda_finger_joint2"
    assert _joint_range(model, "right_panda_joint4") == [-3.0718, -0.0698]
    assert model.body_pos[model.body("left_panda_link0").id].tolist() == [0, 0.5, 0]


# ----------------------------------------------------------------------------- contacts

SWING = (
    '<collision><origin xyz="0.15 0 0.05"/><geometry><box size="0.2 0.04 0.04"/></geometry>'
    "</collision>"
)
PLATE = (
    '<collision><origin xyz="0 0 -0.1"/><geometry><box size="0.6 0.6 0.2"/></geometry></collision>'
)


def _swing_arm(path: Path, name: str = "tiny") -> Path:
    """base (a plate) -> hinge about y -> arm (a bar clear of the plate at q = 0) -> hand."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        f'<robot name="{name}"><link name="base">{PLATE}{INERTIAL}</link>'
        f'<link name="arm">{SWING}{INERTIAL}</link><link name="hand">{INERTIAL}</link>'
        '<joint name="hinge" type="revolute"><parent link="base"/><child link="arm"/>'
        '<axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="5" velocity="1"/></joint>'
        '<joint name="wrist" type="fixed"><parent link="arm"/><child link="hand"/></joint>'
        "</robot>"
    )
    return path


def _excluded(spec: mujoco.MjSpec) -> set[tuple[str, str]]:
    return {tuple(sorted((e.bodyname1, e.bodyname2))) for e in spec.excludes}


def _without_excludes(spec: mujoco.MjSpec) -> mujoco.MjModel:
    for exclude in list(spec.excludes):
        spec.delete(exclude)
    return spec.compile()


def _contacts_at(model: mujoco.MjModel, qpos: list[float]) -> int:
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    return data.ncon


def test_parent_and_child_links_never_collide(tmp_path: Path) -> None:
    spec = load_urdf(_swing_arm(tmp_path / "tiny.urdf"))
    assert _excluded(spec) == {("arm", "base"), ("arm", "hand")}
    assert _contacts_at(spec.compile(), [0.5]) == 0
    # MuJoCo's own parent filter skips a world-welded parent: without the exclusion the bar
    # swung into the plate touches it.
    assert _contacts_at(_without_excludes(spec), [0.5]) > 0
    assert _contacts_at(_without_excludes(spec), [0.0]) == 0  # and is clear of it at rest


def test_links_touching_at_rest_are_excluded(tmp_path: Path) -> None:
    urdf = _swing_arm(tmp_path / "tiny.urdf")
    urdf.write_text(urdf.read_text().replace('xyz="0.15 0 0.05"', 'xyz="0.15 0 -0.01"'))
    extra = f'<link name="stand">{PLATE.replace("-0.1", "-0.15")}{INERTIAL}</link>'
    joint = '<joint name="bolt" type="fixed"><parent link="arm"/><child link="stand"/></joint>'
    urdf.write_text(urdf.read_text().replace("</robot>", extra + joint + "</robot>"))
    spec = load_urdf(urdf)
    assert ("base", "stand") in _excluded(spec)  # not adjacent: they overlap at qpos0
    assert _contacts_at(spec.compile(), [0.0]) == 0
    assert _contacts_at(_without_excludes(spec), [0.0]) > 0


def _srdf(path: Path, body: str, robot: str = "tiny") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f'<?xml version="1.0"?>\n<robot name="{robot}">{body}</robot>')
    return path


DISABLE = '<disable_collisions link1="base" link2="hand" reason="Never"/>'


def test_srdf_given_explicitly(tmp_path: Path) -> None:
    urdf = _swing_arm(tmp_path / "tiny.urdf")
    srdf = _srdf(tmp_path / "elsewhere" / "mine.srdf", DISABLE)
    assert ("base", "hand") not in _excluded(load_urdf(urdf))
    assert ("base", "hand") in _excluded(load_urdf(urdf, srdf=srdf))


@pytest.mark.parametrize(
    "where", ["urdf/tiny.srdf", "urdf/srdf/tiny.srdf", "srdf/tiny.srdf", "srdf/robot.srdf"]
)
def test_srdf_found_next_to_the_urdf(tmp_path: Path, where: str) -> None:
    urdf = _swing_arm(tmp_path / "pkg" / "urdf" / "tiny.urdf", name="robot")
    _srdf(tmp_path / "pkg" / where, DISABLE, robot="robot")
    assert ("base", "hand") in _excluded(load_urdf(urdf))


def test_srdf_pairs_of_other_links_do_not_apply(tmp_path: Path) -> None:
    urdf = _swing_arm(tmp_path / "tiny.urdf")
    pairs = DISABLE + '<disable_collisions link1="head" link2="torso" reason="Adjacent"/>'
    _srdf(tmp_path / "tiny.srdf", pairs)  # written for a bigger robot
    assert _excluded(load_urdf(urdf)) == {("arm", "base"), ("arm", "hand"), ("base", "hand")}


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("<robot name='tiny'><disable_collisions", "is not valid XML"),
        ("<mujoco/>", "is not an SRDF file: its root element is <mujoco>"),
        ("<robot><disable_collisions link1='base'/></robot>", "needs link1 and link2"),
        (
            "<robot><disable_collisions link1='a' link2='b'/></robot>",
            "none of its disable_collisions links are in this robot",
        ),
    ],
)
def test_bad_srdf_names_the_file(tmp_path: Path, content: str, message: str) -> None:
    urdf = _swing_arm(tmp_path / "tiny.urdf")
    srdf = tmp_path / "bad.srdf"
    srdf.write_text(content)
    with pytest.raises(SpecError, match=message) as info:
        load_urdf(urdf, srdf=srdf)
    assert str(srdf) in str(info.value)


def test_malformed_srdf_found_next_to_the_urdf_names_it(tmp_path: Path) -> None:
    urdf = _swing_arm(tmp_path / "tiny.urdf")
    (tmp_path / "tiny.srdf").write_text("<robot")
    with pytest.raises(SpecError, match=f"{tmp_path / 'tiny.srdf'} is not valid XML"):
        load_urdf(urdf)


def test_missing_srdf_names_the_path(tmp_path: Path) -> None:
    urdf = _swing_arm(tmp_path / "tiny.urdf")
    robot = mjk.RobotSpec(path=urdf, srdf=tmp_path / "gone.srdf")
    with pytest.raises(ModelFileError, match=f"SRDF file not found: {tmp_path / 'gone.srdf'}"):
        mjk.Scene.build(_spec(robot))


def _spec(*robots: mjk.RobotSpec, floor: bool = False) -> mjk.SceneSpec:
    return mjk.SceneSpec(timestep=0.002, add_floor=floor, add_skybox=False, robots=list(robots))


@pytest.mark.parametrize(
    "relative", ["talos_data/robots/talos_left_arm.urdf", "z1_description/urdf/z1.urdf"]
)
def test_no_self_contact_at_rest(relative: str) -> None:
    path = example_robot_data_path(relative)
    # Without the exclusions these robots touch themselves at qpos0 (the reference).
    bare = _without_excludes(load_urdf(path))
    assert _contacts_at(bare, bare.qpos0.tolist()) > 0
    with mjk.Scene.build(_spec(mjk.RobotSpec(path=path))) as scene:
        model, data = scene.model, scene.data
        robot = set(range(1, model.nbody))
        assert _self_contacts(model, data, robot) == 0
        start = data.qpos.copy()
        for _ in range(250):  # 0.5 s holding still against gravity (bias forces compensated)
            data.qfrc_applied[:] = data.qfrc_bias
            scene.step()
            assert _self_contacts(model, data, robot) == 0
        assert np.abs(data.qpos - start).max() < 1e-3


def test_kinova_meshes_are_visible() -> None:
    path = example_robot_data_path("kinova_description/robots/kinova.urdf")
    with mjk.Scene.build(_spec(mjk.RobotSpec(path=path))) as scene:
        m = scene.model
        visual = [
            g
            for g in range(m.ngeom)
            if m.geom_group[g] == 2 and m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
        ]
        assert len(visual) == sum(_expected_mesh_geoms(path, "visual").values()) == 17
        assert all(m.mesh_vertnum[m.geom_dataid[g]] > 0 for g in visual)
        assert all(m.geom_rgba[g][3] > 0 for g in visual)


GO2 = "go2_description/urdf/go2.urdf"


def test_floating_go2_falls_and_fixed_go2_stays() -> None:
    path = example_robot_data_path(GO2)
    duration = 0.5
    for floating in (True, False):
        robot = mjk.RobotSpec(path=path, pos=[0.0, 0.0, 2.0], floating=floating)
        with mjk.Scene.build(_spec(robot)) as scene:
            model, data = scene.model, scene.data
            base = model.body("base").id
            free = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "root_joint")
            assert (free >= 0 and model.jnt_type[free] == mujoco.mjtJoint.mjJNT_FREE) == floating
            assert model.nq == 12 + 7 * floating
            z0, com0 = data.xpos[base][2], data.subtree_com[base][2]
            scene.step(round(duration / scene.timestep()))
            scene.forward()
            drop, com_drop = z0 - data.xpos[base][2], com0 - data.subtree_com[base][2]
            if floating:  # nothing to stand on: free fall, 0.5 g t² = 1.226 m
                free_fall = 0.5 * 9.81 * duration**2
                assert abs(com_drop - free_fall) < 0.01 * free_fall
                assert drop > 0.95 * free_fall
            else:
                assert abs(drop) < 1e-9


def test_floating_errors_name_the_field(tmp_path: Path) -> None:
    path = example_robot_data_path(GO2)
    on_site = mjk.RobotSpec(
        path=path, floating=True, attach_to=mjk.AttachTarget(mjk.AttachKind.Site, "x")
    )
    with pytest.raises(SpecError, match=r"robots\[0\]: a floating robot stands in the world"):
        mjk.Scene.build(_spec(on_site))
    mjcf = tmp_path / "arm.xml"
    mjcf.write_text("<mujoco><worldbody><body name='b'/></worldbody></mujoco>")
    for robot in (mjk.RobotSpec(path=mjcf, floating=True), mjk.RobotSpec(path=mjcf, srdf="a")):
        with pytest.raises(SpecError, match=r"robots\[0\].path: srdf and floating apply to URDF"):
            mjk.Scene.build(_spec(robot))


@pytest.mark.parametrize(
    ("relative", "roots"),
    [(UR5, ["base_link"]), (PANDA, ["panda_link0"]), ("z1_description/urdf/z1.urdf", ["link00"])],
)
def test_root_links_are_the_compiled_roots(relative: str, roots: list[str]) -> None:
    model = _compile(relative)
    compiled = [model.body(b).name for b in range(1, model.nbody) if model.body_parentid[b] == 0]
    assert root_links(example_robot_data_path(relative)) == compiled == roots


def test_link_without_inertial_has_no_mass(tmp_path) -> None:
    """URDF: a link with geometry but no <inertial> has no mass (not one from its geoms)."""
    box = '<collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision>'
    flange = (
        f'<link name="flange">{box}</link>'
        '<joint name="mount" type="fixed"><parent link="arm"/><child link="flange"/></joint>'
    )
    model = load_urdf(_write_urdf(tmp_path / "tiny.urdf", box, flange)).compile()
    assert model.body("flange").mass[0] == 0.0
    assert model.body("arm").mass[0] == 1.0  # the authored <inertial>, the box not added
