"""Load a URDF robot as an editable `mujoco.MjSpec` that compiles alone or attaches elsewhere."""

from __future__ import annotations

import copy
import difflib
import importlib.metadata
import os
import site
import sysconfig
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote

import mujoco

from mjkdl.errors import BuildError, ModelFileError, SpecError

# The only mesh decoders built into MuJoCo 4.0; any other file (.dae, .ply, .glb, ...) fails to
# compile with "no decoder found for mesh file".
READABLE_MESH_SUFFIXES = frozenset({".stl", ".obj", ".msh"})

# MuJoCo's URDF reader defaults to strippath, fusestatic and discardvisual all true: that strips
# the folders off mesh files, merges every fixed-joint link (tool0, ee_link, ...) into its parent
# and deletes every visual geom. Override all three.
# URDF gives a link without <inertial> no mass; MuJoCo would derive one from its geoms.
_COMPILER_OVERRIDES = {
    "strippath": "false",
    "fusestatic": "false",
    "discardvisual": "false",
    "inertiafromgeom": "false",
}

_ACTUATED_TYPES = frozenset({"revolute", "continuous", "prismatic"})
_ERD_DISTRIBUTION = "example-robot-data"
_ERD_ROBOTS = "cmeel.prefix/share/example-robot-data/robots"


class UnreadableMeshWarning(UserWarning):
    """URDF meshes MuJoCo cannot decode were replaced by collision meshes or dropped."""


@dataclass
class _MeshReport:
    """File names of the unreadable meshes one load replaced or dropped."""

    replaced: list[str] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class _UrdfJoint:
    """What the actuator pass needs from one URDF `<joint>`."""

    kind: str
    effort: float
    mimic: bool


def load_urdf(path: str | Path) -> mujoco.MjSpec:
    """Read a URDF file into a `MjSpec` with resolved meshes, Menagerie geom groups and motors.

    Every mesh path becomes absolute (`package://`, `file://`, absolute or URDF-relative), so the
    spec compiles on its own and can be attached into another spec. Links on fixed joints stay
    bodies. Visual geoms get `contype=conaffinity=0, group=2`; collision geoms `group=3`.
    A visual mesh MuJoCo cannot read (e.g. `.dae`) is replaced by the link's readable collision
    meshes, else dropped; an unreadable collision mesh is dropped; one `UnreadableMeshWarning`
    lists them. Each revolute, continuous or prismatic joint gets a `motor` named like the joint
    (`gear=1`, control and force limited to ±effort when effort > 0). A `<mimic>` joint gets no
    motor: MuJoCo ties it to its leader with a `joint` equality (polycoef
    `[offset, multiplier, 0, 0, 0]`), named like the mimic joint. The root link is welded to
    the world. Inertias are kept as authored (`balanceinertia` stays off).
    """
    urdf = _existing_file(path)
    root = _read_robot_xml(urdf)
    report = _MeshReport()
    for link in root.findall("link"):
        _rewrite_link_meshes(link, urdf, report)
    _override_compiler(root)
    # MuJoCo's URDF reader (mjXURDF::AddToTree) creates no body for a link named "world": its
    # children hang straight off the worldbody, so UR5's `world` link and fixed `world_joint`
    # leave nothing behind and its root body is `base_link`. It adds no free joint either.
    spec = _spec_from_xml(root, urdf)
    spec.strippath = False
    spec.meshdir = ""  # every mesh file is absolute, whatever spec it ends up attached to
    _set_geom_groups(spec)
    joints = _urdf_joints(root, urdf)
    _add_motors(spec, joints)
    _name_mimic_equalities(spec, joints)
    _warn_unreadable(urdf, report)
    return spec


def example_robot_data_path(relative: str) -> Path:
    """The absolute path of `relative` inside example-robot-data's `robots` folder."""
    robots = _example_robot_data_robots()
    path = robots / relative
    if path.is_file():
        return path
    known = sorted(p.relative_to(robots).as_posix() for p in robots.rglob("*.urdf"))
    close = difflib.get_close_matches(relative, known, n=5, cutoff=0.6)
    hint = f"; close matches: {', '.join(close)}" if close else ""
    raise ModelFileError(f"no file {relative!r} in example-robot-data's {robots}{hint}")


def _example_robot_data_robots() -> Path:
    try:
        distribution = importlib.metadata.distribution(_ERD_DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError as err:
        raise ModelFileError(
            "example-robot-data is not installed: pip install example-robot-data"
        ) from err
    robots = Path(distribution.locate_file(_ERD_ROBOTS))
    if not robots.is_dir():
        raise ModelFileError(
            f"example-robot-data has no robots folder at {robots}: "
            "pip install --force-reinstall example-robot-data"
        )
    return robots


def _existing_file(path: str | Path) -> Path:
    file = Path(path).expanduser()
    if not file.is_file():
        raise ModelFileError(f"URDF file not found: {file}")
    return file.resolve()


def _read_robot_xml(urdf: Path) -> ET.Element:
    try:
        root = ET.parse(urdf).getroot()
    except ET.ParseError as err:
        raise SpecError(f"{urdf} is not valid XML: {err}") from err
    if root.tag != "robot":
        raise SpecError(f"{urdf} is not a URDF file: its root element is <{root.tag}>, not <robot>")
    return root


def _rewrite_link_meshes(link: ET.Element, urdf: Path, report: _MeshReport) -> None:
    """Make the link's mesh paths absolute and swap out the meshes MuJoCo cannot read."""
    link_name = link.get("name", "")
    readable_collisions = []
    for collision in link.findall("collision"):
        mesh_file = _resolve_mesh_element(collision, urdf, link_name)
        if mesh_file is None:
            continue
        if _readable(mesh_file):
            readable_collisions.append(collision)
        else:
            link.remove(collision)
            report.dropped.append(mesh_file.name)
    for visual in link.findall("visual"):
        mesh_file = _resolve_mesh_element(visual, urdf, link_name)
        if mesh_file is None or _readable(mesh_file):
            continue
        index = list(link).index(visual)
        link.remove(visual)
        for offset, collision in enumerate(readable_collisions):
            link.insert(index + offset, _visual_from_collision(visual, collision, offset == 0))
        target = report.replaced if readable_collisions else report.dropped
        target.append(mesh_file.name)
        readable_collisions = []  # a second unreadable visual would only draw them twice


def _resolve_mesh_element(element: ET.Element, urdf: Path, link_name: str) -> Path | None:
    """The absolute mesh file of a `<visual>`/`<collision>`, written back; None if no mesh."""
    mesh = element.find("geometry/mesh")
    if mesh is None:
        return None
    uri = mesh.get("filename", "")
    mesh_file = _resolve_uri(uri, urdf)
    if mesh_file is None:
        raise ModelFileError(
            f"{urdf}: mesh {uri!r} of link {link_name!r} not found (package:// searches "
            "ROS_PACKAGE_PATH, cmeel share folders and the URDF's parent folders)"
        )
    mesh.set("filename", str(mesh_file))
    return mesh_file


def _resolve_uri(uri: str, urdf: Path) -> Path | None:
    if uri.startswith("package://"):
        package, _, rest = uri.removeprefix("package://").partition("/")
        candidates = [folder / rest for folder in _package_folders(package, urdf)]
    elif uri.startswith("file://"):
        local = unquote(uri.removeprefix("file://")).removeprefix("localhost")
        candidates = [urdf.parent / local]
    else:
        candidates = [urdf.parent / Path(uri).expanduser()]
    return next((c.resolve() for c in candidates if c.is_file()), None)


def _package_folders(package: str, urdf: Path) -> Iterator[Path]:
    """Where `package://package/...` may live, in search order."""
    for entry in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep):
        if entry:
            folder = Path(entry).expanduser()
            if folder.name == package:
                yield folder
            yield folder / package
    for site_dir in _site_packages():
        yield site_dir / "cmeel.prefix" / "share" / package
    yield from (parent for parent in urdf.parents if parent.name == package)


def _site_packages() -> list[Path]:
    paths = sysconfig.get_paths()
    dirs = [paths["purelib"], paths["platlib"], *site.getsitepackages()]
    dirs.append(site.getusersitepackages())
    return list(dict.fromkeys(Path(d) for d in dirs))


def _readable(mesh_file: Path) -> bool:
    return mesh_file.suffix.lower() in READABLE_MESH_SUFFIXES


def _visual_from_collision(
    visual: ET.Element, collision: ET.Element, keep_name: bool
) -> ET.Element:
    """A `<visual>` showing the collision's mesh, with the visual's material (and name)."""
    replacement = ET.Element("visual")
    if keep_name and visual.get("name"):
        replacement.set("name", visual.get("name", ""))
    for tag, source in (("origin", collision), ("geometry", collision), ("material", visual)):
        child = source.find(tag)
        if child is not None:
            replacement.append(copy.deepcopy(child))
    return replacement


def _override_compiler(root: ET.Element) -> None:
    """Set the compiler overrides in the `<mujoco><compiler/>` extension MuJoCo reads."""
    extension = root.find("mujoco")
    if extension is None:
        extension = ET.Element("mujoco")
        root.insert(0, extension)
    compiler = extension.find("compiler")
    if compiler is None:
        compiler = ET.SubElement(extension, "compiler")
    compiler.attrib.update(_COMPILER_OVERRIDES)


def _spec_from_xml(root: ET.Element, urdf: Path) -> mujoco.MjSpec:
    try:
        return mujoco.MjSpec.from_string(ET.tostring(root, encoding="unicode"))
    except ValueError as err:
        raise BuildError(f"MuJoCo rejected URDF {urdf}: {err}") from err


def _set_geom_groups(spec: mujoco.MjSpec) -> None:
    # MuJoCo's URDF reader marks visual geoms by contype = conaffinity = 0.
    for geom in spec.geoms:
        geom.group = 2 if geom.contype == 0 and geom.conaffinity == 0 else 3


def _urdf_joints(root: ET.Element, path: Path) -> dict[str, _UrdfJoint]:
    joints = {}
    for joint in root.findall("joint"):
        limit = joint.find("limit")
        text = limit.get("effort", "0") if limit is not None else "0"
        try:
            effort = abs(float(text))
        except ValueError:
            raise SpecError(
                f"{path}: joint {joint.get('name', '')!r} has a non-numeric effort {text!r}"
            ) from None
        joints[joint.get("name", "")] = _UrdfJoint(
            kind=joint.get("type", ""), effort=effort, mimic=joint.find("mimic") is not None
        )
    return joints


def _add_motors(spec: mujoco.MjSpec, joints: dict[str, _UrdfJoint]) -> None:
    """One motor per actuated, non-mimic joint, in the compiled joint order."""
    for joint in spec.joints:
        info = joints.get(joint.name)
        if info is None or info.kind not in _ACTUATED_TYPES or info.mimic:
            continue
        spec.add_actuator(
            name=joint.name,
            target=joint.name,
            trntype=mujoco.mjtTrn.mjTRN_JOINT,
            gear=[1, 0, 0, 0, 0, 0],
            **_effort_limits(info.effort),
        )


def _effort_limits(effort: float) -> dict[str, object]:
    """Actuator control and force limits of ±effort; unlimited when URDF gives no effort."""
    if effort <= 0:
        unlimited = mujoco.mjtLimited.mjLIMITED_FALSE
        return {"ctrllimited": unlimited, "forcelimited": unlimited}
    bounds = [-effort, effort]
    limited = mujoco.mjtLimited.mjLIMITED_TRUE
    return {
        "ctrllimited": limited,
        "ctrlrange": bounds,
        "forcelimited": limited,
        "forcerange": bounds,
    }


def _name_mimic_equalities(spec: mujoco.MjSpec, joints: dict[str, _UrdfJoint]) -> None:
    # MuJoCo 4.0 turns each <mimic> into an unnamed joint equality (name1 = the mimic joint).
    for equality in spec.equalities:
        mimic = joints.get(equality.name1)
        if equality.type == mujoco.mjtEq.mjEQ_JOINT and not equality.name and mimic and mimic.mimic:
            equality.name = equality.name1


def _warn_unreadable(urdf: Path, report: _MeshReport) -> None:
    if not report.replaced and not report.dropped:
        return
    parts = []
    if report.replaced:
        parts.append("replaced by collision meshes: " + ", ".join(dict.fromkeys(report.replaced)))
    if report.dropped:
        parts.append("dropped: " + ", ".join(dict.fromkeys(report.dropped)))
    readable = ", ".join(sorted(READABLE_MESH_SUFFIXES))
    warnings.warn(
        f"{urdf.name}: MuJoCo reads only {readable} meshes; " + "; ".join(parts),
        UnreadableMeshWarning,
        stacklevel=3,
    )
