"""URDF loading: meshes, actuators, limits, kinematics against Pinocchio, errors, attaching."""

from __future__ import annotations

import importlib.metadata
import struct
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from mjkdl.errors import BuildError, ModelFileError, SpecError
from mjkdl.urdf import UnreadableMeshWarning, example_robot_data_path, load_urdf

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


def _load_quietly(path: Path) -> mujoco.MjSpec:
    with pytest.warns(UnreadableMeshWarning):
        return load_urdf(path)


def _compile(relative: str) -> mujoco.MjModel:
    return _load_quietly(example_robot_data_path(relative)).compile()


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


def _expected_mesh_geoms(urdf: Path) -> dict[str, int]:
    """Per link: readable collision meshes, one per readable visual mesh, and the collision
    meshes once more (as visuals) when the link has an unreadable visual mesh."""

    def readable(element: ET.Element) -> bool:
        mesh = element.find("geometry/mesh")
        return mesh is not None and Path(mesh.get("filename", "")).suffix.lower() == ".stl"

    def unreadable(element: ET.Element) -> bool:
        return element.find("geometry/mesh") is not None and not readable(element)

    counts = {}
    for link in ET.parse(urdf).getroot().findall("link"):
        collisions = sum(readable(c) for c in link.findall("collision"))
        visuals = link.findall("visual")
        total = collisions + sum(readable(v) for v in visuals)
        total += collisions * any(unreadable(v) for v in visuals)
        if total:
            counts[link.get("name")] = total
    return counts


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
    assert model.nmesh == 7  # each visual reuses its link's collision mesh asset


def test_ur5_warning_lists_the_replaced_dae_files() -> None:
    with pytest.warns(UnreadableMeshWarning) as record:
        load_urdf(example_robot_data_path(UR5))
    assert len(record) == 1
    message = str(record[0].message)
    assert "replaced by collision meshes: base.dae, shoulder.dae" in message
    assert "dropped" not in message


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
    assert "panda_leftfinger" not in _mesh_geoms_per_body(model)
    assert model.body("panda_hand_tcp").id > 0
    assert model.body(model.body_parentid[model.body("panda_link0").id]).name == "world"


def test_panda_warning_reports_the_dropped_finger_visual() -> None:
    with pytest.warns(UnreadableMeshWarning) as record:
        load_urdf(example_robot_data_path(PANDA))
    assert len(record) == 1
    assert str(record[0].message).endswith("dropped: finger.dae")


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


def test_dae_visual_replaced_by_collision_mesh(tmp_path: Path) -> None:
    _write_stl(tmp_path / "meshes" / "arm.stl")
    for dae in ("arm.dae", "decal.dae"):
        (tmp_path / "meshes" / dae).write_text("<COLLADA/>")
    decal = _mesh("visual", "meshes/decal.dae")  # dropped: the collision mesh is drawn once
    visual = (
        '<visual><geometry><mesh filename="meshes/arm.dae"/></geometry>'
        '<material name="red"><color rgba="1 0 0 1"/></material></visual>'
    )
    collision = (
        '<collision><origin xyz="0 0 0.5"/>'
        '<geometry><mesh filename="meshes/arm.stl"/></geometry></collision>'
    )
    urdf = _write_urdf(tmp_path / "tiny.urdf", visual + collision + decal)
    expected = r"replaced by collision meshes: arm\.dae; dropped: decal\.dae$"
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


def test_dae_without_collision_mesh_is_dropped(tmp_path: Path) -> None:
    (tmp_path / "arm.dae").write_text("<COLLADA/>")
    (tmp_path / "tool.ply").write_text("ply")
    body = _mesh("visual", "arm.dae") + _mesh("collision", "tool.ply")
    urdf = _write_urdf(tmp_path / "tiny.urdf", body)
    with pytest.warns(UnreadableMeshWarning) as record:
        model = load_urdf(urdf).compile()
    assert len(record) == 1
    assert str(record[0].message).endswith("dropped: tool.ply, arm.dae")
    assert model.ngeom == 0


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
    parent.attach(_load_quietly(example_robot_data_path(UR5)), prefix="r_", frame=frame)
    model = parent.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert data.xpos[model.body("r_base_link").id].tolist() == [1, 0, 0]
    assert [model.actuator(a).name for a in range(model.nu)] == [f"r_{j}" for j in UR5_JOINTS]
    assert _joint_range(model, "r_elbow_joint") == [-3.14159265359, 3.14159265359]
    assert model.nmesh == 7


def test_attach_two_pandas_to_sites() -> None:
    parent = mujoco.MjSpec.from_string("<mujoco/>")  # MJCF default: angles in degrees
    for prefix, y in (("left_", 0.5), ("right_", -0.5)):
        site = parent.worldbody.add_site(name=f"{prefix}mount", pos=[0, y, 0])
        parent.attach(_load_quietly(example_robot_data_path(PANDA)), prefix=prefix, site=site)
    model = parent.compile()
    assert model.nu == 16 and model.neq == 2
    assert model.equality(1).name == "right_panda_finger_joint2"
    assert _joint_range(model, "right_panda_joint4") == [-3.0718, -0.0698]
    assert model.body_pos[model.body("left_panda_link0").id].tolist() == [0, 0.5, 0]


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
