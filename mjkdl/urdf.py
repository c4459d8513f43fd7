"""Load a URDF robot as an editable `mujoco.MjSpec` that compiles alone or attaches elsewhere."""

from __future__ import annotations

import copy
import difflib
import hashlib
import importlib.metadata
import math
import os
import site
import sysconfig
import tempfile
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote

import mujoco
import trimesh

from mjkdl.errors import BuildError, ModelFileError, SpecError

# The only mesh decoders built into MuJoCo 4.0; any other file (.dae, .ply, .glb, ...) fails to
# compile with "no decoder found for mesh file".
READABLE_MESH_SUFFIXES = frozenset({".stl", ".obj", ".msh"})
# What trimesh (with pycollada for .dae) reads; such meshes are converted to OBJ in the cache.
CONVERTIBLE_MESH_SUFFIXES = frozenset({".dae", ".ply", ".glb", ".gltf", ".off"})
# Bump when the conversion changes, so stale cache entries are not reused.
_CONVERTER_VERSION = "1"

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
    """URDF meshes neither MuJoCo nor trimesh can decode were replaced by collision meshes or
    dropped."""


@dataclass
class _MeshReport:
    """File names of the unreadable meshes one load replaced or dropped."""

    replaced: list[str] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class _UrdfJoint:
    """What the actuator and collision passes need from one URDF `<joint>`."""

    kind: str
    effort: float
    mimic: bool
    parent: str
    child: str


def load_urdf(path: str | Path, srdf: str | Path = "", floating: bool = False) -> mujoco.MjSpec:
    """Read a URDF file into a `MjSpec` with resolved meshes, Menagerie geom groups and motors.

    Every mesh path becomes absolute (`package://`, `file://`, absolute or URDF-relative), so the
    spec compiles on its own and can be attached into another spec. Meshes MuJoCo cannot decode
    (`.dae`, `.ply`, `.glb`, `.gltf`, `.off`) are converted through trimesh into OBJ files in
    `mesh_cache_dir()`, keyed by the file's content. Links on fixed joints stay bodies. Visual
    geoms get `contype=conaffinity=0, group=2`; collision geoms `group=3`. Each revolute,
    continuous or prismatic joint gets a `motor` named like the joint (`gear=1`, control and
    force limited to ±effort when effort > 0; a NaN, infinite or negative effort is an error).
    A `<mimic>` joint gets no motor: MuJoCo ties it to its leader with a `joint` equality
    (polycoef `[offset, multiplier, 0, 0, 0]`), named like the mimic joint. Inertias are kept
    as authored (`balanceinertia` stays off).

    The root link is welded to the world, or free (a free joint named `root_joint`) when
    `floating`. Contacts are excluded between the two links of every joint, between the link
    pairs of the SRDF's `<disable_collisions>` (`srdf`, else `<urdf stem>.srdf` or
    `<robot name>.srdf` next to the URDF or in a `srdf` folder beside or above it) and between
    links that touch at the reference pose (qpos0), as MoveIt's setup assistant does.
    """
    urdf = _existing_file(path)
    root = _read_robot_xml(urdf)
    report = _MeshReport()
    for link in root.findall("link"):
        _rewrite_link_meshes(link, urdf, report)
    _override_compiler(root)
    joints = _urdf_joints(root, urdf)
    srdf_file = _srdf_file(urdf, root, srdf)
    # MuJoCo's URDF reader (mjXURDF::AddToTree) creates no body for a link named "world": its
    # children hang straight off the worldbody, so UR5's `world` link and fixed `world_joint`
    # leave nothing behind and its root body is `base_link`. It adds no free joint either.
    spec = _spec_from_xml(root, urdf)
    spec.strippath = False
    spec.meshdir = ""  # every mesh file is absolute, whatever spec it ends up attached to
    _set_geom_groups(spec)
    _add_motors(spec, joints)
    _name_mimic_equalities(spec, joints)
    if floating:
        _add_free_joint(spec, urdf)
    pairs = {(j.parent, j.child) for j in joints.values()}
    if srdf_file is not None:
        pairs |= _srdf_pairs(srdf_file, spec, explicit=bool(str(srdf)))
    _exclude(spec, pairs)
    _exclude(spec, _touching_at_rest(spec, urdf))
    _warn_unreadable(urdf, report)
    return spec


def mesh_cache_dir() -> Path:
    """Where converted meshes are kept: `$MJKDL_CACHE_DIR/meshes`, else
    `$XDG_CACHE_HOME/mjkdl/meshes`, else `~/.cache/mjkdl/meshes`. Safe to delete."""
    base = os.environ.get("MJKDL_CACHE_DIR")
    if base:
        return Path(base).expanduser() / "meshes"
    cache = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(cache).expanduser() / "mjkdl" / "meshes"


def root_links(path: str | Path) -> list[str]:
    """Names of the URDF's root links as MuJoCo compiles them (a `world` link's children)."""
    root = _read_robot_xml(_existing_file(path))
    children = {_child(j) for j in root.findall("joint")}
    roots = [link.get("name", "") for link in root.findall("link")]
    roots = [name for name in roots if name not in children]
    if roots == ["world"]:
        return [_child(j) for j in root.findall("joint") if _parent(j) == "world"]
    return roots


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
    robots = Path(str(distribution.locate_file(_ERD_ROBOTS)))
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


def _read_robot_xml(file: Path, kind: str = "a URDF") -> ET.Element:
    """The `<robot>` root of a URDF or SRDF (`kind`) file."""
    try:
        root = ET.parse(file).getroot()
    except ET.ParseError as err:
        raise SpecError(f"{file} is not valid XML: {err}") from None
    if root.tag != "robot":
        raise SpecError(f"{file} is not {kind} file: its root element is <{root.tag}>, not <robot>")
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
    """The absolute mesh file of a `<visual>`/`<collision>`, written back; None if no mesh.

    A mesh trimesh can convert is replaced by its converted OBJ file.
    """
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
    if mesh_file.suffix.lower() in CONVERTIBLE_MESH_SUFFIXES:
        mesh_file = _converted_mesh(mesh_file, urdf, link_name)
    mesh.set("filename", str(mesh_file))
    return mesh_file


def _converted_mesh(source: Path, urdf: Path, link_name: str) -> Path:
    """`source` as an OBJ file in metres in the mesh cache (converted once per content)."""
    data = source.read_bytes()
    digest = hashlib.sha256(data + _CONVERTER_VERSION.encode()).hexdigest()[:20]
    target = mesh_cache_dir() / f"{source.stem}-{digest}.obj"
    if target.is_file():
        return target
    where = f"{urdf}: mesh {source} of link {link_name!r}"
    try:
        scene = trimesh.load_scene(source)
        if scene.units not in (None, "meters"):  # COLLADA <unit meter="0.001"/> and the like
            scene = scene.convert_units("meters")
        mesh = scene.to_mesh()
    except Exception as err:  # trimesh and pycollada raise many unrelated types
        raise ModelFileError(f"{where} cannot be read: {type(err).__name__}: {err}") from None
    if len(mesh.faces) == 0:
        raise ModelFileError(f"{where} has no triangles")
    text = trimesh.exchange.obj.export_obj(mesh, include_texture=False, include_color=False)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        # Written under a temporary name and renamed: parallel processes never read half a file.
        with tempfile.NamedTemporaryFile(
            "w", dir=target.parent, suffix=".tmp", delete=False
        ) as out:
            out.write(text)
        os.replace(out.name, target)
    except OSError as err:
        raise ModelFileError(
            f"{where}: cannot write its converted copy to {target.parent} ({err}); "
            "set MJKDL_CACHE_DIR to a writable folder"
        ) from None
    return target


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
        name = joint.get("name", "")
        limit = joint.find("limit")
        text = limit.get("effort", "0") if limit is not None else "0"
        try:
            effort = float(text)
        except ValueError:
            effort = math.nan
        if not math.isfinite(effort) or effort < 0:
            raise SpecError(
                f"{path}: joint {name!r} has effort {text!r}; the force limit must be a finite "
                "number >= 0 (0 or no <limit>: unlimited)"
            )
        joints[name] = _UrdfJoint(
            kind=joint.get("type", ""),
            effort=effort,
            mimic=joint.find("mimic") is not None,
            parent=_parent(joint),
            child=_child(joint),
        )
    return joints


def _parent(joint: ET.Element) -> str:
    element = joint.find("parent")
    return element.get("link", "") if element is not None else ""


def _child(joint: ET.Element) -> str:
    element = joint.find("child")
    return element.get("link", "") if element is not None else ""


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
    if effort == 0:
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


def _add_free_joint(spec: mujoco.MjSpec, urdf: Path) -> None:
    roots = list(spec.worldbody.bodies)
    if len(roots) != 1:
        names = ", ".join(b.name for b in roots) or "none"
        raise SpecError(f"{urdf}: floating=True needs one root link, found {names}")
    if not any(j.type == mujoco.mjtJoint.mjJNT_FREE for j in roots[0].joints):
        roots[0].add_freejoint(name="root_joint")


def _srdf_file(urdf: Path, root: ET.Element, given: str | Path) -> Path | None:
    """The SRDF to read: `given`, else one named like the URDF or its robot, else None."""
    if str(given):
        file = Path(given).expanduser()
        if not file.is_file():
            raise ModelFileError(f"SRDF file not found: {file} (given for {urdf})")
        return file.resolve()
    folders = (urdf.parent, urdf.parent / "srdf", urdf.parent.parent / "srdf")
    for name in dict.fromkeys(n for n in (urdf.stem, root.get("name", "")) if n):
        for folder in folders:
            if (folder / f"{name}.srdf").is_file():
                return (folder / f"{name}.srdf").resolve()
    return None


def _srdf_pairs(srdf: Path, spec: mujoco.MjSpec, explicit: bool) -> set[tuple[str, str]]:
    """The SRDF's `<disable_collisions>` link pairs that name two links of this robot.

    An SRDF written for a whole robot may name links a partial URDF lacks (talos.srdf for
    `talos_left_arm.urdf`); those pairs do not apply. An SRDF given explicitly must match.
    """
    root = _read_robot_xml(srdf, "an SRDF")
    pairs = set()
    for element in root.iter("disable_collisions"):
        link1, link2 = element.get("link1"), element.get("link2")
        if not link1 or not link2:
            raise SpecError(
                f"{srdf}: <disable_collisions> needs link1 and link2, got {element.attrib}"
            )
        pairs.add((link1, link2))
    known = {(a, b) for a, b in pairs if spec.body(a) is not None and spec.body(b) is not None}
    if explicit and pairs and not known:
        raise SpecError(f"SRDF {srdf}: none of its disable_collisions links are in this robot")
    return known


def _exclude(spec: mujoco.MjSpec, pairs: set[tuple[str, str]]) -> None:
    for a, b in sorted(pairs):
        if a != b and spec.body(a) is not None and spec.body(b) is not None:
            spec.add_exclude(bodyname1=a, bodyname2=b)


def _touching_at_rest(spec: mujoco.MjSpec, urdf: Path) -> set[tuple[str, str]]:
    """Body pairs whose geoms touch at qpos0 despite the exclusions so far."""
    try:
        model = spec.compile()
    except ValueError as err:
        raise BuildError(f"MuJoCo cannot compile URDF {urdf}: {err}") from None
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    pairs = set()
    for contact in data.contact[: data.ncon]:
        pair = (model.geom_bodyid[contact.geom1], model.geom_bodyid[contact.geom2])
        pairs.add((model.body(pair[0]).name, model.body(pair[1]).name))
    return pairs


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
