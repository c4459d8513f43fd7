"""Check a whole `SceneSpec` before MuJoCo sees it: types, finiteness, ranges and names.

No silent coercion: flags must be `bool`, numbers real numbers (not `bool`, not text), names
and paths text without NUL bytes. Every failure is a `SpecError` (a `ValueError`; a wrong
type is a `SpecTypeError`, also a `TypeError`) naming the field path, e.g.
``robots[0].attachments[1].pos`` or ``objects[2] ('cube').size``. Files are checked later,
when `compile.py` opens them.
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Sequence

import numpy as np

from .errors import SpecError, SpecTypeError
from .spec import (
    AttachKind,
    AttachmentSpec,
    AttachTarget,
    CameraSpec,
    Condim,
    ForceTorqueSensorSpec,
    GripperDrive,
    JointImpedanceDrive,
    PhysicsOptions,
    RobotSpec,
    SceneObject,
    SceneSpec,
    Shape,
    ToolFrameSpec,
    _Required,
)

# Sane ranges: beyond them MuJoCo either fails deep inside or simulates nonsense.
TIMESTEP_RANGE = (1e-6, 1.0)  # s
MAX_GRAVITY = 1e3  # m/s^2, magnitude
MAX_USERDATA = 1_000_000  # SceneSpec.userdata entries
MAX_LENGTH = 1e4  # m: positions and offsets
SIZE_RANGE = (1e-4, 1e4)  # m: primitive half-sizes and radii
MAX_ANGLE = 1e4  # degrees, magnitude of each Euler angle
MASS_RANGE = (1e-6, 1e6)  # kg, a primitive's explicit mass
MAX_FRICTION = 1e3

# Names mjkdl gives its own elements (the floor geom; light, textures and material "mjkdl_*").
RESERVED_PREFIX = "mjkdl_"
FLOOR_GEOM = "floor"

SIZE_COUNT = {
    Shape.BOX: 3,
    Shape.SPHERE: 1,
    Shape.CYLINDER: 2,
    Shape.CAPSULE: 2,
    Shape.ELLIPSOID: 3,
}


def validate_scene_spec(spec: SceneSpec) -> None:
    """Raise `SpecError` naming the first field of `spec` that cannot be built."""
    if not isinstance(spec, SceneSpec):
        raise SpecTypeError(f"expected a SceneSpec, got {type(spec).__name__}")
    for name in ("timestep", "add_floor", "add_skybox"):
        if _unset(getattr(spec, name)):
            raise SpecError(f"SceneSpec.{name} is required and has no default: set it")
    _in_range(real(spec.timestep, "SceneSpec.timestep"), TIMESTEP_RANGE, "SceneSpec.timestep")
    floor = flag(spec.add_floor, "SceneSpec.add_floor")
    flag(spec.add_skybox, "SceneSpec.add_skybox")
    gravity = real(spec.gravity_z, "SceneSpec.gravity_z")
    _in_range(abs(gravity), (0.0, MAX_GRAVITY), "SceneSpec.gravity_z (magnitude)")
    _entries(spec.objects, SceneObject, "SceneSpec.objects")
    _entries(spec.robots, RobotSpec, "SceneSpec.robots")
    _entries(spec.cameras, CameraSpec, "SceneSpec.cameras")
    _unique_names(spec.objects, "objects", "object", floor)
    _unique_names(spec.cameras, "cameras", "camera", floor)
    for i, obj in enumerate(spec.objects):
        _check_object(obj, f"objects[{i}] ({obj.name!r})")
    for i, robot in enumerate(spec.robots):
        _check_robot(robot, f"robots[{i}]")
    for i, cam in enumerate(spec.cameras):
        _check_camera(cam, f"cameras[{i}] ({cam.name!r})")
    _check_physics(spec.physics)
    _check_userdata(spec.userdata)


def _check_userdata(n: object) -> None:
    field = "SceneSpec.userdata"
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise SpecTypeError(f"{field} must be a whole number of entries, got {n!r}")
    if not 0 <= n <= MAX_USERDATA:
        raise SpecError(f"{field} must be from 0 to {MAX_USERDATA}, got {n}")


CONES = ("pyramidal", "elliptic")


def _check_physics(physics: object) -> None:
    """`SceneSpec.physics`: a `PhysicsOptions` whose set fields MuJoCo accepts."""
    where = "SceneSpec.physics"
    if not isinstance(physics, PhysicsOptions):
        raise SpecTypeError(f"{where} must be a PhysicsOptions, got {type(physics).__name__}")
    if physics.cone is not None and physics.cone not in CONES:
        raise SpecError(f"{where}.cone must be None or one of {list(CONES)}, got {physics.cone!r}")
    if physics.impratio is not None and real(physics.impratio, f"{where}.impratio") < 1.0:
        raise SpecError(f"{where}.impratio must be at least 1 (or None), got {physics.impratio!r}")
    for name in ("noslip_iterations", "iterations"):
        value = getattr(physics, name)
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise SpecError(f"{where}.{name} must be None or a non-negative integer, got {value!r}")
        if name == "iterations" and value < 1:
            raise SpecError(f"{where}.iterations must be at least 1 (or None), got {value!r}")


# ----------------------------------------------------------------------------- scalars


def _unset(value: object) -> bool:
    """A required field left at its default (`spec.REQUIRED`) or set to None."""
    return value is None or isinstance(value, _Required)


def real(value: object, field: str) -> float:
    """`value` as a finite float; it must be a real number (an int or float, not a bool)."""
    if not is_real(value):
        raise SpecTypeError(f"{field} must be a number, got {value!r}")
    out = float(value)  # type: ignore[arg-type]
    if not math.isfinite(out):
        raise SpecError(f"{field} must be finite, got {value!r}")
    return out


def flag(value: object, field: str) -> bool:
    """`value` as a bool; only `True`/`False` (or NumPy's) are accepted, never truthiness."""
    if not isinstance(value, (bool, np.bool_)):
        raise SpecTypeError(f"{field} must be True or False, got {value!r}")
    return bool(value)


def text(value: object, field: str) -> str:
    """`value` as a string without NUL bytes (MuJoCo would cut the name there)."""
    if not isinstance(value, str):
        raise SpecTypeError(f"{field} must be a string, got {value!r}")
    if "\x00" in value:
        raise SpecError(f"{field} contains a NUL byte: {value!r}")
    return value


def path_text(value: object, field: str) -> str:
    """A file path given as `str` or `os.PathLike`, as text without NUL bytes."""
    if not isinstance(value, (str, os.PathLike)):
        raise SpecTypeError(f"{field} must be a path (str or Path), got {value!r}")
    return text(os.fspath(value), field)


def vector(value: object, n: int | Sequence[int], field: str, positive: bool = False) -> np.ndarray:
    """`value` as a finite float vector of length `n` (or one of the lengths in `n`).

    Accepts a flat list, tuple or NumPy array of real numbers; text and bools are refused.
    """
    lengths = (n,) if isinstance(n, int) else tuple(n)
    want = " or ".join(str(k) for k in lengths)
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "iuf":
            raise SpecTypeError(f"{field} must hold real numbers, got dtype {value.dtype}")
        if value.ndim != 1:
            raise SpecTypeError(f"{field} must be a flat list of {want} numbers, got {value!r}")
        arr = value.astype(float)
    elif isinstance(value, (list, tuple)):
        if any(isinstance(v, (list, tuple, np.ndarray)) for v in value):
            raise SpecTypeError(f"{field} must be a flat list of {want} numbers, got {value!r}")
        if not all(is_real(v) for v in value):
            raise SpecTypeError(f"{field} must be a list of numbers, got {value!r}")
        arr = np.array(value, dtype=float)
    else:
        raise SpecTypeError(f"{field} must be a list of numbers, got {value!r}")
    if arr.size not in lengths:
        raise SpecError(f"{field} must have {want} values, got {arr.size}: {value!r}")
    if not np.all(np.isfinite(arr)):
        raise SpecError(f"{field} must be finite, got {value!r}")
    if positive and np.any(arr <= 0):
        raise SpecError(f"{field} must be positive, got {value!r}")
    return arr


def real_array(value: object, field: str) -> np.ndarray:
    """`value` as a new float64 array, of any shape, when it holds only real numbers: NumPy
    would turn text and bools into numbers (``[True, 0.5]`` is even a float64 array) and
    drop imaginary parts."""
    arr: np.ndarray | None
    if isinstance(value, (list, tuple)) and any(isinstance(v, (bool, np.bool_)) for v in value):
        arr = None
    else:
        try:
            arr = np.asarray(value)
        except (TypeError, ValueError):  # ragged nesting
            arr = None
    if arr is None or arr.dtype.kind not in "iuf":
        raise SpecTypeError(f"{field} must hold real numbers, got {value!r}")
    return arr.astype(np.float64)


def is_real(value: object) -> bool:
    """Whether `value` is a real number: an int or float, Python's or NumPy's, not a bool."""
    kind = type(value)
    if kind is float or kind is int:  # the common case, without the slower ABC check
        return True
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _in_range(value: float, bounds: tuple[float, float], field: str) -> None:
    lo, hi = bounds
    if not lo <= value <= hi:
        raise SpecError(f"{field} must lie in [{lo:g}, {hi:g}], got {value!r}")


def _bounded(arr: np.ndarray, limit: float, field: str, unit: str) -> None:
    if np.any(np.abs(arr) > limit):
        raise SpecError(f"{field} values must lie within ±{limit:g} {unit}, got {arr.tolist()}")


def _pose(pos: object, euler: object, field: str) -> None:
    _bounded(vector(pos, 3, f"{field}.pos"), MAX_LENGTH, f"{field}.pos", "m")
    _bounded(vector(euler, 3, f"{field}.euler"), MAX_ANGLE, f"{field}.euler", "degrees")


# ----------------------------------------------------------------------------- names


def _entries(items: object, cls: type, field: str) -> None:
    if not isinstance(items, list):
        raise SpecTypeError(f"{field} must be a list of {cls.__name__}, got {items!r}")
    for i, item in enumerate(items):
        if not isinstance(item, cls):
            raise SpecTypeError(f"{field}[{i}] must be a {cls.__name__}, got {item!r}")


def _unique_names(items: list, field: str, kind: str, floor: bool) -> None:
    """Every object or camera has a distinct, non-reserved name."""
    first: dict[str, int] = {}
    for i, item in enumerate(items):
        where = f"{field}[{i}].name"
        name = text(item.name, where)
        if not name:
            raise SpecError(f"{where} is empty: every {kind} needs a name")
        reserved_prefix(name, where)
        if kind == "object" and floor and name == FLOOR_GEOM:
            raise SpecError(
                f"{where}: {name!r} is the floor's geom name (add_floor=True); rename the {kind}"
            )
        if name in first:
            raise SpecError(
                f"{where}: duplicate {kind} name {name!r} ({field}[{first[name]}] has it too)"
            )
        first[name] = i


def reserved_prefix(name: str, field: str) -> None:
    """Names and prefixes starting with `RESERVED_PREFIX` belong to mjkdl's own elements."""
    if name.startswith(RESERVED_PREFIX):
        raise SpecError(f"{field}: names starting with {RESERVED_PREFIX!r} are reserved for mjkdl")


def _target(target: object, field: str, kinds: tuple[AttachKind, ...]) -> None:
    if (
        not isinstance(target, AttachTarget)
        or not isinstance(target.kind, AttachKind)
        or (target.kind not in kinds)
    ):
        allowed = ", ".join(k.name for k in kinds)
        raise SpecTypeError(
            f"{field} must be an AttachTarget(AttachKind, name) of kind {allowed}, got {target!r}"
        )
    if not text(target.name, f"{field}.name"):
        raise SpecError(f"{field}.name is empty: name the {target.kind.value} to mount on")


# ----------------------------------------------------------------------------- entries


def _check_object(obj: SceneObject, field: str) -> None:
    _pose(obj.pos, obj.euler, field)
    flag(obj.fixed, f"{field}.fixed")
    path = path_text(obj.mjcf_path, f"{field}.mjcf_path")
    if flag(obj.marker, f"{field}.marker") and (path or obj.fixed or obj.mass != 0):
        raise SpecError(
            f"{field}: a marker is a massless primitive placed by set_body_pose; give it "
            "no mjcf_path, fixed or mass"
        )
    if path:
        primitive = not isinstance(obj.size, list) or obj.size or not is_real(obj.mass)
        if obj.shape is not None or primitive or obj.mass != 0:
            raise SpecError(
                f"{field}: give either mjcf_path or a primitive (shape, size, mass), not both"
            )
        for name in _PRIMITIVE_ONLY:
            if _set(obj, name):
                raise SpecError(
                    f"{field}.{name} applies to primitive objects only; an MJCF object keeps "
                    f"what its file gives (edit the file, or model.geom_{name} after building)"
                )
        return
    if obj.shape is None:
        raise SpecError(f"{field}.shape is unset: a primitive object needs a Shape")
    if not isinstance(obj.shape, Shape):
        raise SpecTypeError(f"{field}.shape must be a Shape, got {obj.shape!r}")
    where = f"{field}.size ({obj.shape.name})"
    size = vector(obj.size, SIZE_COUNT[obj.shape], where, positive=True)
    if np.any(size < SIZE_RANGE[0]) or np.any(size > SIZE_RANGE[1]):
        raise SpecError(
            f"{where} values must lie in [{SIZE_RANGE[0]:g}, {SIZE_RANGE[1]:g}] m, got {obj.size!r}"
        )
    rgba = vector(obj.rgba, 4, f"{field}.rgba")
    if np.any(rgba < 0) or np.any(rgba > 1):
        raise SpecError(f"{field}.rgba values must lie in [0, 1], got {obj.rgba!r}")
    friction = vector(obj.friction, (1, 2, 3), f"{field}.friction")
    if np.any(friction < 0) or np.any(friction > MAX_FRICTION):
        raise SpecError(
            f"{field}.friction values must lie in [0, {MAX_FRICTION:g}], got {obj.friction!r}"
        )
    mass = real(obj.mass, f"{field}.mass")
    if mass < 0 or (mass == 0 and not (obj.fixed or obj.marker)):
        raise SpecError(f"{field}.mass must be positive for a free object, got {obj.mass!r}")
    if mass:
        _in_range(mass, MASS_RANGE, f"{field}.mass")
    if not (isinstance(obj.condim, (int, np.integer)) and not isinstance(obj.condim, bool)) or (
        int(obj.condim) not in {int(c) for c in Condim}
    ):
        raise SpecError(f"{field}.condim must be 1, 3, 4 or 6, got {obj.condim!r}")


# SceneObject fields that describe a primitive's geom; an MJCF object's come from its file.
_PRIMITIVE_ONLY = ("rgba", "friction", "condim")
_DEFAULTS = SceneObject()


def _set(obj: SceneObject, name: str) -> bool:
    """Whether field `name` of `obj` differs from its default."""
    value, default = getattr(obj, name), getattr(_DEFAULTS, name)
    try:
        return not np.array_equal(np.asarray(value, dtype=float), np.asarray(default, dtype=float))
    except (TypeError, ValueError):
        return True


def _check_robot(robot: RobotSpec, field: str) -> None:
    if not path_text(robot.path, f"{field}.path"):
        raise SpecError(f"{field}.path is empty: give an MJCF or URDF file")
    reserved_prefix(text(robot.prefix, f"{field}.prefix"), f"{field}.prefix")
    if robot.attach_to is not None:
        _target(robot.attach_to, f"{field}.attach_to", tuple(AttachKind))
    _pose(robot.pos, robot.euler, field)
    path_text(robot.srdf, f"{field}.srdf")
    flag(robot.floating, f"{field}.floating")
    _entries(robot.attachments, AttachmentSpec, f"{field}.attachments")
    for j, att in enumerate(robot.attachments):
        where = f"{field}.attachments[{j}]"
        if not path_text(att.mjcf_path, f"{where}.mjcf_path"):
            raise SpecError(f"{where}.mjcf_path is empty: give an MJCF file")
        if att.attach_to is None:
            raise SpecError(f"{where}.attach_to is unset: name the site, body or frame to mount on")
        _target(att.attach_to, f"{where}.attach_to", tuple(AttachKind))
        prefix = text(att.prefix, f"{where}.prefix")
        reserved_prefix(robot.prefix + prefix, f"{where}.prefix")
        _pose(att.pos, att.euler, where)
    _entries(robot.grippers, GripperDrive, f"{field}.grippers")
    for j, drive in enumerate(robot.grippers):
        where = f"{field}.grippers[{j}]"
        if not text(drive.actuator, f"{where}.actuator"):
            raise SpecError(f"{where}.actuator is empty: name the gripper's actuator")
        text(drive.pads, f"{where}.pads")
        for name, unit in (("force", "N"), ("speed", "m/s")):
            if real(getattr(drive, name), f"{where}.{name}") <= 0.0:
                raise SpecError(
                    f"{where}.{name} must be positive ({unit}), got {getattr(drive, name)!r}"
                )
    if robot.impedance is not None:
        _check_impedance(robot.impedance, f"{field}.impedance")


def _check_impedance(drive: object, field: str) -> None:
    """A `JointImpedanceDrive`: named actuators, once each, and a value of each per actuator."""
    if not isinstance(drive, JointImpedanceDrive):
        raise SpecTypeError(f"{field} must be a JointImpedanceDrive, got {drive!r}")
    if not isinstance(drive.actuators, list):
        raise SpecTypeError(f"{field}.actuators must be a list of names, got {drive.actuators!r}")
    if not drive.actuators:
        raise SpecError(f"{field}.actuators is empty: name the arm's actuators")
    names = [text(a, f"{field}.actuators[{i}]") for i, a in enumerate(drive.actuators)]
    for i, name in enumerate(names):
        if name in names[:i]:
            raise SpecError(f"{field}.actuators[{i}]: {name!r} is named twice")
    n = len(names)
    vector(drive.stiffness, n, f"{field}.stiffness", positive=True)
    vector(drive.torque_limit, n, f"{field}.torque_limit", positive=True)
    vector(drive.damping_pose, n, f"{field}.damping_pose")


def check_tool(tool: object, field: str = "tool") -> None:
    """A `ToolFrameSpec` as `create_robot` takes it: names are text, each F/T pair is named
    once and names both of its MuJoCo sensors (the TCP offset is checked where it is read)."""
    if not isinstance(tool, ToolFrameSpec):
        raise SpecTypeError(f"{field} must be a ToolFrameSpec, got {type(tool).__name__}")
    text(tool.tool_body, f"{field}.tool_body")
    text(tool.tcp_site, f"{field}.tcp_site")
    _entries(tool.ft_sensors, ForceTorqueSensorSpec, f"{field}.ft_sensors")
    first: dict[str, int] = {}
    for i, sensor in enumerate(tool.ft_sensors):
        where = f"{field}.ft_sensors[{i}]"
        name = text(sensor.name, f"{where}.name")
        if not name:
            raise SpecError(f"{where}.name is empty: ft_sensor(name) reads the pair by it")
        if name in first:
            raise SpecError(
                f"{where}.name: duplicate {name!r} ({field}.ft_sensors[{first[name]}] has it too)"
            )
        first[name] = i
        for part in ("force", "torque"):
            if not text(getattr(sensor, f"{part}_sensor"), f"{where}.{part}_sensor"):
                raise SpecError(f"{where}.{part}_sensor is empty: name the MuJoCo {part} sensor")


def _check_camera(cam: CameraSpec, field: str) -> None:
    if _unset(cam.pos):
        raise SpecError(f"{field}.pos is required")
    if _unset(cam.fovy):
        raise SpecError(f"{field}.fovy is required (vertical field of view, degrees)")
    _pose(cam.pos, cam.euler, field)
    fovy = real(cam.fovy, f"{field}.fovy")
    if not 0 < fovy < 180:
        raise SpecError(f"{field}.fovy must lie in (0, 180) degrees, got {cam.fovy!r}")
    if cam.attach_to is not None:
        _target(cam.attach_to, f"{field}.attach_to", (AttachKind.Body, AttachKind.Site))
