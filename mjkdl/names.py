"""Name lookups in a compiled `MjModel` whose errors list the close names."""

from __future__ import annotations

import mujoco

from .errors import unknown_name

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


def model_id(model: mujoco.MjModel, obj: mujoco.mjtObj, kind: str, name: object, where: str) -> int:
    """MuJoCo id of the `kind` element `name`, or an `UnknownNameError` naming `where`."""
    i = mujoco.mj_name2id(model, obj, name) if isinstance(name, str) and name else -1
    if i < 0:
        count = getattr(model, COUNT_FIELD[obj])
        known = [mujoco.mj_id2name(model, obj, k) or "" for k in range(count)]
        raise unknown_name(kind, str(name), known, where=where)
    return i
