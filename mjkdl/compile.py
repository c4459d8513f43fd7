"""Compile a `SceneSpec` into a MuJoCo model with `mujoco.MjSpec`.

Order: environment (floor, skybox, lights), objects in declaration order, robots with their
attachments in order, then cameras. `validate.validate_scene_spec` checks the whole description
first and the files are checked as they are opened, so bad input fails with the field at fault
named, never inside MuJoCo without context.
"""

from __future__ import annotations

import stat
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import mujoco
import numpy as np

from . import urdf
from .errors import BuildError, ModelFileError, SpecError, unknown_name
from .gripper_drive import apply_drives
from .impedance_drive import apply_impedance_drives
from .spec import (
    AttachKind,
    AttachmentSpec,
    AttachTarget,
    CameraSpec,
    PhysicsOptions,
    RobotSpec,
    SceneObject,
    SceneSpec,
    Shape,
)
from .validate import validate_scene_spec, vector

# Offscreen framebuffer large enough for 1080p recording (MuJoCo's default is 640x480).
OFFSCREEN_WIDTH = 1920
OFFSCREEN_HEIGHT = 1080

_GEOM_TYPES = {
    Shape.BOX: (mujoco.mjtGeom.mjGEOM_BOX, 3),
    Shape.SPHERE: (mujoco.mjtGeom.mjGEOM_SPHERE, 1),
    Shape.CYLINDER: (mujoco.mjtGeom.mjGEOM_CYLINDER, 2),
    Shape.CAPSULE: (mujoco.mjtGeom.mjGEOM_CAPSULE, 2),
    Shape.ELLIPSOID: (mujoco.mjtGeom.mjGEOM_ELLIPSOID, 3),
}

# `MjSpec` list attribute of each mount kind ("bodies", not "bodys").
_PLURAL = {AttachKind.Body: "bodies", AttachKind.Site: "sites", AttachKind.Frame: "frames"}

# MuJoCo's own notices when attaching: option adoption under the merge policy, and the
# empty-prefix save caveat. Real conflicts still raise (see `_attach`).
_QUIET = ("Attach conflict when attaching", "Attaching a spec with an empty prefix")

# Element kinds whose names must be unique (MuJoCo checks them only when compiling).
_NAMESPACES = (
    "bodies",
    "joints",
    "geoms",
    "sites",
    "cameras",
    "lights",
    "actuators",
    "sensors",
    "tendons",
)


def compile_scene(spec: SceneSpec) -> mujoco.MjModel:
    """Build the `MjSpec` for `spec` and compile it; raises a clear error on bad input.
    Inside `stand_in(load)`, a scene whose model files are missing compiles to `load()`."""
    try:
        return compile_mjspec(build_mjspec(spec))
    except ModelFileError as err:
        if not _STAND_INS:
            raise
        load, why = _STAND_INS[-1]
        why.append(str(err))
        return load()


_STAND_INS: list[tuple[Callable[[], mujoco.MjModel], list[str]]] = []


def note_missing(message: str) -> bool:
    """Inside `stand_in`: keep `message` (why a model file is missing) and return True, so
    the caller goes on to the compile that the stand-in answers; outside, False."""
    if not _STAND_INS:
        return False
    _STAND_INS[-1][1].append(message)
    return True


@contextmanager
def stand_in(load: Callable[[], mujoco.MjModel]) -> Iterator[list[str]]:
    """While open, `compile_scene` returns `load()` (a fresh compiled model, e.g. the one a
    demonstration file stores) for a scene whose model or asset files are missing, instead of
    raising `ModelFileError`; the list it yields collects those errors, one per use."""
    why: list[str] = []
    _STAND_INS.append((load, why))
    try:
        yield why
    finally:
        _STAND_INS.pop()


def build_mjspec(spec: SceneSpec) -> mujoco.MjSpec:
    """The `MjSpec` that `spec` describes, not yet compiled (the spec is validated first)."""
    validate_scene_spec(spec)
    s = mujoco.MjSpec()
    s.modelname = "mjkdl_scene"
    # Under the merge policy a child's non-default <option> (the 2F-85's elliptic cone and
    # impratio, Gen3's implicitfast integrator) is adopted; two children that disagree raise.
    s.compiler.conflict = mujoco.mjtConflict.mjCONFLICT_MERGE
    s.option.timestep = float(spec.timestep)
    s.option.gravity = [0.0, 0.0, float(spec.gravity_z)]
    s.nuserdata = int(spec.userdata)
    s.visual.global_.offwidth = OFFSCREEN_WIDTH
    s.visual.global_.offheight = OFFSCREEN_HEIGHT
    _add_environment(s, floor=bool(spec.add_floor), skybox=bool(spec.add_skybox))
    for i, obj in enumerate(spec.objects):
        _add_object(s, obj, f"objects[{i}] ({obj.name!r})")
    roots = [_add_robot(s, robot, f"robots[{i}]") for i, robot in enumerate(spec.robots)]
    for i, cam in enumerate(spec.cameras):
        _add_camera(s, cam, f"cameras[{i}] ({cam.name!r})")
    _apply_physics(s, spec.physics)
    drives = [
        (robot.prefix, drive, f"robots[{i}].grippers[{j}]")
        for i, robot in enumerate(spec.robots)
        for j, drive in enumerate(robot.grippers)
    ]
    impedances = [
        (robot.prefix, robot.impedance, f"robots[{i}].impedance", roots[i])
        for i, robot in enumerate(spec.robots)
        if robot.impedance is not None
    ]
    if drives or impedances:  # transmissions (MjSpec cannot list them), masses: compiled
        model = compile_mjspec(s)
        apply_drives(s, model, drives)
        apply_impedance_drives(s, model, impedances)
    return s


def _apply_physics(s: mujoco.MjSpec, physics: PhysicsOptions) -> None:
    """The set fields of `SceneSpec.physics`, over what the robots' `<option>`s merged in."""
    if physics.cone is not None:
        s.option.cone = (
            mujoco.mjtCone.mjCONE_ELLIPTIC
            if physics.cone == "elliptic"
            else mujoco.mjtCone.mjCONE_PYRAMIDAL
        )
    if physics.impratio is not None:
        s.option.impratio = float(physics.impratio)
    if physics.noslip_iterations is not None:
        s.option.noslip_iterations = int(physics.noslip_iterations)
    if physics.iterations is not None:
        s.option.iterations = int(physics.iterations)


def compile_mjspec(s: mujoco.MjSpec) -> mujoco.MjModel:
    """Compile with MuJoCo's errors turned into ours (missing files keep their path)."""
    try:
        with _quiet_attach_notices():
            return s.compile()
    except ValueError as err:
        msg = str(err).strip()
        if "error opening" in msg.lower():  # MuJoCo's words for a file it cannot read
            raise ModelFileError(f"MuJoCo could not read a model file: {msg}") from None
        raise BuildError(f"MuJoCo could not compile the scene: {msg}") from None


# ----------------------------------------------------------------------------- files


def euler_quat(euler_deg: object, field: str) -> np.ndarray:
    """Quaternion [w, x, y, z] of intrinsic xyz Euler angles in degrees (MuJoCo's default)."""
    quat = np.empty(4)
    mujoco.mju_euler2Quat(quat, np.deg2rad(vector(euler_deg, 3, field)), "xyz")
    return quat


def _model_file(path: str | Path, field: str) -> Path:
    p = Path(path).expanduser()
    regular_file(p, field, "model file")
    return p


def regular_file(path: Path, field: str, what: str) -> None:
    """`ModelFileError` naming `field` unless `path` is an existing regular file: a FIFO,
    device or directory is refused too (MuJoCo would block reading a FIFO forever)."""
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise ModelFileError(f"{field}: {what} not found: {path}") from None
    except OSError as err:
        raise ModelFileError(f"{field}: {what} {path} cannot be read: {err.strerror}") from None
    if not stat.S_ISREG(mode):
        raise ModelFileError(f"{field}: {what} {path} is not a regular file")


def load_model_file(
    path: str | Path, field: str, srdf: str | Path = "", floating: bool = False
) -> mujoco.MjSpec:
    """Parse an MJCF or URDF file into an `MjSpec`, naming the file (and `field`) on failure.

    `srdf` and `floating` apply to URDF files only (see `urdf.load_urdf`). Included files and
    the mesh, texture, height-field and skin files the model names are checked before MuJoCo
    opens them: missing ones raise `ModelFileError`, and so do FIFOs and other non-regular
    files, which would block MuJoCo's reader forever.
    """
    p = _model_file(path, field)
    if p.suffix.lower() == ".urdf":
        child = urdf.load_urdf(p, srdf=srdf, floating=floating)
    elif str(srdf) or floating:
        raise SpecError(f"{field}: srdf and floating apply to URDF files only, not {p.name}")
    else:
        _check_includes(p, p.parent, field, seen=set())
        try:
            child = mujoco.MjSpec.from_file(str(p))
        except ValueError as err:
            raise BuildError(f"{field}: MuJoCo cannot read {p}: {err}") from None
    _check_asset_files(child, p, field)
    child.compiler.conflict = mujoco.mjtConflict.mjCONFLICT_MERGE
    return child


def _check_includes(xml: Path, root: Path, field: str, seen: set[Path]) -> None:
    """Every `<include file=...>` (relative to the top model's folder) is a regular file."""
    seen.add(xml)
    try:
        text = xml.read_bytes()
        if b"<include" not in text:  # parse only the files that can include
            return
        tree = ElementTree.fromstring(text)
    except (ElementTree.ParseError, OSError):
        return  # MuJoCo's own parser reports the syntax error with its line
    for element in tree.iter("include"):
        name = element.get("file")
        if not name:
            continue
        included = (root / name).expanduser()
        regular_file(included, field, f"file {name!r} included by {xml}")
        if included not in seen:
            _check_includes(included, root, field, seen)


def _check_asset_files(child: mujoco.MjSpec, model: Path, field: str) -> None:
    """Mesh, skin, texture and height-field files exist and are regular files."""
    base = Path(child.modelfiledir or model.parent)
    groups = (
        ("mesh", child.meshes, child.compiler.meshdir),
        ("skin", child.skins, child.compiler.meshdir),
        ("texture", child.textures, child.compiler.texturedir),
        ("height field", child.hfields, child.compiler.meshdir),
    )
    for kind, elements, folder in groups:
        for element in elements:
            names = [element.file]
            if kind == "texture":
                names += list(element.cubefiles)
            for name in names:
                if not name:
                    continue
                file = base / folder / name  # an absolute folder or name replaces the base
                what = f"{kind} file of {element.name or 'an unnamed ' + kind} in {model}"
                regular_file(file, field, what)


# ----------------------------------------------------------------------------- environment


def _add_environment(s: mujoco.MjSpec, *, floor: bool, skybox: bool) -> None:
    s.visual.headlight.ambient = [0.3, 0.3, 0.3]
    s.visual.headlight.diffuse = [0.5, 0.5, 0.5]
    s.worldbody.add_light(
        name="mjkdl_sun",
        pos=[0.0, -1.0, 3.0],
        dir=[0.0, 0.3, -1.0],
        type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
        diffuse=[0.6, 0.6, 0.6],
        castshadow=True,
    )
    if skybox:
        s.add_texture(
            name="mjkdl_sky",
            type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
            builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
            rgb1=[0.4, 0.6, 0.8],
            rgb2=[0.0, 0.0, 0.0],
            width=512,
            height=3072,
        )
    if floor:
        s.add_texture(
            name="mjkdl_grid",
            type=mujoco.mjtTexture.mjTEXTURE_2D,
            builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
            rgb1=[0.2, 0.3, 0.4],
            rgb2=[0.1, 0.2, 0.3],
            mark=mujoco.mjtMark.mjMARK_EDGE,
            markrgb=[0.8, 0.8, 0.8],
            width=300,
            height=300,
        )
        mat = s.add_material(name="mjkdl_grid", texrepeat=[5, 5], texuniform=True, reflectance=0.2)
        mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "mjkdl_grid"
        s.worldbody.add_geom(
            name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05], material="mjkdl_grid"
        )


# ----------------------------------------------------------------------------- objects


def _add_object(s: mujoco.MjSpec, obj: SceneObject, field: str) -> None:
    pos = vector(obj.pos, 3, f"{field}.pos")
    quat = euler_quat(obj.euler, f"{field}.euler")
    if str(obj.mjcf_path):
        _add_mjcf_object(s, obj, field, pos, quat)
    else:
        _add_primitive(s, obj, field, pos, quat)


def _add_primitive(
    s: mujoco.MjSpec, obj: SceneObject, field: str, pos: np.ndarray, quat: np.ndarray
) -> None:
    assert obj.shape is not None  # validate_scene_spec checked the primitive's fields
    geom_type, nsize = _GEOM_TYPES[obj.shape]
    size = np.asarray(obj.size, dtype=float)
    friction = np.asarray(obj.friction, dtype=float)
    body = s.worldbody.add_body(name=obj.name, pos=pos, quat=quat, mocap=obj.marker)
    if not (obj.fixed or obj.marker):
        body.add_freejoint(name=obj.name)
    full_friction = np.array([1.0, 0.005, 0.0001])
    full_friction[: friction.size] = friction
    geom = body.add_geom(
        name=obj.name,
        type=geom_type,
        size=np.pad(size, (0, 3 - nsize)),
        rgba=np.asarray(obj.rgba, dtype=float),
        friction=full_friction,
        condim=int(obj.condim),
    )
    if obj.mass > 0:
        geom.mass = float(obj.mass)
    if obj.marker:
        geom.contype = geom.conaffinity = 0


def _add_mjcf_object(
    s: mujoco.MjSpec, obj: SceneObject, field: str, pos: np.ndarray, quat: np.ndarray
) -> None:
    child = load_model_file(obj.mjcf_path, f"{field}.mjcf_path")
    free = [j.name or "(unnamed)" for j in child.joints if j.type == mujoco.mjtJoint.mjJNT_FREE]
    if free:
        raise SpecError(
            f"{field}: {obj.mjcf_path} has a free joint ({', '.join(free)}); remove it, mjkdl "
            "adds one to the object unless fixed=True"
        )
    body = s.worldbody.add_body(name=obj.name, pos=pos, quat=quat)
    if not obj.fixed:
        body.add_freejoint(name=obj.name)
    _attach(s, child, prefix=f"{obj.name}/", frame=body.add_frame(), what=f"{field}.mjcf_path")


# ----------------------------------------------------------------------------- robots


def _add_robot(s: mujoco.MjSpec, robot: RobotSpec, field: str) -> list[str]:
    """Add `robot` to `s`; the names of its root bodies there."""
    if robot.floating and robot.attach_to is not None:
        raise SpecError(f"{field}: a floating robot stands in the world; leave attach_to unset")
    child = load_model_file(robot.path, f"{field}.path", robot.srdf, robot.floating)
    roots = [b.name for b in child.worldbody.bodies]
    for j, att in enumerate(robot.attachments):
        _add_attachment(child, att, f"{field}.attachments[{j}]")
    _offset(child, robot.pos, robot.euler, field)
    mount = _mount(s, robot.attach_to, f"{field}.attach_to", within="the scene")
    _attach(s, child, prefix=robot.prefix, what=f"{field}.path ({robot.path})", **mount)
    roots = [robot.prefix + name for name in roots]
    for name in roots:
        root = s.body(name)
        if root is not None:
            _exclude_welded_parent_contacts(s, root)
    return [name for name in roots if s.body(name) is not None]


def _add_attachment(robot: mujoco.MjSpec, att: AttachmentSpec, field: str) -> None:
    child = load_model_file(att.mjcf_path, f"{field}.mjcf_path")
    _offset(child, att.pos, att.euler, field)
    mount = _mount(robot, att.attach_to, f"{field}.attach_to", within="the robot")
    _attach(robot, child, prefix=att.prefix, what=f"{field}.mjcf_path ({att.mjcf_path})", **mount)


def _offset(child: mujoco.MjSpec, pos: object, euler: object, field: str) -> None:
    """Move everything at the child's top level by (pos, euler) in its mount frame."""
    p = vector(pos, 3, f"{field}.pos")
    q = euler_quat(euler, f"{field}.euler")
    if not np.any(p) and np.allclose(q, [1, 0, 0, 0], rtol=0, atol=0):
        return
    wb = child.worldbody
    frame = wb.add_frame(pos=p, quat=q)
    for group in (wb.bodies, wb.geoms, wb.sites, wb.cameras, wb.lights, wb.frames):
        for element in group:
            if element.frame is None and element is not frame:
                element.set_frame(frame)


def _element(s: mujoco.MjSpec, target: AttachTarget, where: str) -> Any:
    """The body, site or frame `target` names in `s`, or an error listing close names."""
    kind = target.kind.value
    element = getattr(s, kind)(target.name)
    if element is None:
        known = [e.name for e in getattr(s, _PLURAL[target.kind])]
        raise unknown_name(kind, target.name, known, where=where)
    return element


def _mount(s: mujoco.MjSpec, target: AttachTarget | None, field: str, within: str) -> dict:
    """The `attach` keyword (site= or frame=) for a mount target; None is the world."""
    if target is None:
        return {"frame": s.worldbody.add_frame()}
    element = _element(s, target, f"{within} ({field})")
    if target.kind is AttachKind.Site:
        return {"site": element}
    if target.kind is AttachKind.Body:
        return {"frame": element.add_frame()}
    return {"frame": element}


def _attach(
    s: mujoco.MjSpec, child: mujoco.MjSpec, *, prefix: str, what: str, **mount: Any
) -> None:
    try:
        with _quiet_attach_notices():
            s.attach(child, prefix=prefix, **mount)
        # MuJoCo finds some clashes only when compiling, where it cannot say whose they are.
        msg = _repeated_name(s)
    except ValueError as err:
        msg = str(err).strip()
        if "repeated name" not in msg:
            raise BuildError(f"{what}: MuJoCo cannot attach it: {msg}") from None
    if msg:
        raise BuildError(
            f"{what}: names clash with the scene ({msg}); give it a distinct prefix "
            f"(prefix is {prefix!r})"
        )


def _repeated_name(s: mujoco.MjSpec) -> str:
    """The first name two elements of one kind share, as MuJoCo would report it, or ""."""
    for group in _NAMESPACES:
        seen: set[str] = set()
        for element in getattr(s, group):
            name = element.name
            if name and name in seen:
                return f"repeated name {name!r} in {group}"
            seen.add(name)
    return ""


def _exclude_welded_parent_contacts(s: mujoco.MjSpec, body: mujoco.MjsBody) -> None:
    """Exclude contacts between a world-welded robot body and its moving children.

    MuJoCo's parent-child contact filter skips pairs whose weld parent is the world, so a
    robot base fixed in the scene would touch its first link forever (4 contacts on Gen3).
    """
    if not _is_static(body):
        return
    for child in body.bodies:
        if len(child.joints) > 0:
            s.add_exclude(bodyname1=body.name, bodyname2=child.name)
        else:
            _exclude_welded_parent_contacts(s, child)


def _is_static(body: mujoco.MjsBody) -> bool:
    while body is not None and body.name != "world":
        if len(body.joints) > 0:
            return False
        body = body.parent
    return True


# ----------------------------------------------------------------------------- cameras


def _add_camera(s: mujoco.MjSpec, cam: CameraSpec, field: str) -> None:
    if s.camera(cam.name) is not None:
        raise BuildError(f"{field}: a camera named {cam.name!r} already exists in the scene")
    _camera_host(s, cam.attach_to, f"{field}.attach_to").add_camera(
        name=cam.name,
        pos=vector(cam.pos, 3, f"{field}.pos"),
        quat=euler_quat(cam.euler, f"{field}.euler"),
        fovy=float(cam.fovy),
    )


def _camera_host(
    s: mujoco.MjSpec, target: AttachTarget | None, field: str
) -> mujoco.MjsBody | mujoco.MjsFrame:
    """The body, or a frame at the site, that a camera rides on (the world when None)."""
    if target is None:
        return s.worldbody
    element = _element(s, target, f"the scene ({field})")
    if target.kind is AttachKind.Body:
        return element
    # A frame at the site's own placement in its body. The site's orientation may still be an
    # alternative form (euler, axis-angle) in the angle unit and Euler sequence of the file it
    # came from (its own mjsCompiler); a frame added here would be read with the scene's.
    quat = element.quat
    if element.alt.type != mujoco.mjtOrientation.mjORIENTATION_QUAT:
        own = element.compiler
        quat = mujoco.MjSpec.resolve_orientation(own.degree, own.eulerseq, element.alt)
    frame = element.parent.add_frame(pos=element.pos, quat=quat)
    if element.frame is not None:
        frame.set_frame(element.frame)
    return frame


class _quiet_attach_notices(warnings.catch_warnings):
    """Silence `_QUIET` notices, both as Python warnings and through MuJoCo's C handler.

    MuJoCo's default C handler prints every warning to stdout and appends it to
    MUJOCO_LOG.TXT in the working directory. While inside, C warnings are collected instead
    (a Python handler must never raise: MuJoCo would abort) and the others re-issued as Python
    warnings on exit.
    """

    def __enter__(self) -> None:
        super().__enter__()
        for text in _QUIET:
            warnings.filterwarnings("ignore", message=text)
        self._notices: list[str] = []
        self._handler = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(self._notices.append)

    def __exit__(self, *exc: Any) -> None:
        mujoco.set_mju_user_warning(self._handler)
        super().__exit__(*exc)
        for notice in self._notices:
            if not notice.startswith(_QUIET):
                warnings.warn(f"MuJoCo: {notice}", UserWarning, stacklevel=3)
