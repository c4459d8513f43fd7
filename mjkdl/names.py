"""Name lookups in a compiled `MjModel` whose errors list the close names."""

from __future__ import annotations

import mujoco

from .errors import SpecTypeError, unknown_name

# The MjModel field that counts each kind of element.
COUNT_FIELD = {
    mujoco.mjtObj.mjOBJ_BODY: "nbody",
    mujoco.mjtObj.mjOBJ_JOINT: "njnt",
    mujoco.mjtObj.mjOBJ_GEOM: "ngeom",
    mujoco.mjtObj.mjOBJ_SITE: "nsite",
    mujoco.mjtObj.mjOBJ_CAMERA: "ncam",
    mujoco.mjtObj.mjOBJ_LIGHT: "nlight",
    mujoco.mjtObj.mjOBJ_EQUALITY: "neq",
    mujoco.mjtObj.mjOBJ_ACTUATOR: "nu",
    mujoco.mjtObj.mjOBJ_TENDON: "ntendon",
    mujoco.mjtObj.mjOBJ_FLEX: "nflex",
    mujoco.mjtObj.mjOBJ_SENSOR: "nsensor",
    mujoco.mjtObj.mjOBJ_KEY: "nkey",
}


def find_id(model: mujoco.MjModel, obj: mujoco.mjtObj, name: object) -> int:
    """MuJoCo id of the element `name`, -1 when there is none or `name` is not a non-empty
    string. Every lookup goes through here: MuJoCo's `mj_name2id` crashes on None and would
    find "hand" for "hand\\0junk" (C strings end at a NUL byte)."""
    if not isinstance(name, str) or not name or "\x00" in name:
        return -1
    return mujoco.mj_name2id(model, obj, name)


def model_id(model: mujoco.MjModel, obj: mujoco.mjtObj, kind: str, name: object, where: str) -> int:
    """MuJoCo id of the `kind` element `name`, or an `UnknownNameError` naming `where`
    (`SpecTypeError` when `name` is not text at all)."""
    if not isinstance(name, str):
        raise SpecTypeError(f"{kind} name in {where} must be a string, got {name!r}")
    i = find_id(model, obj, name)
    if i < 0:
        count = getattr(model, COUNT_FIELD[obj])
        known = [mujoco.mj_id2name(model, obj, k) or "" for k in range(count)]
        raise unknown_name(kind, str(name), known, where=where)
    return i
