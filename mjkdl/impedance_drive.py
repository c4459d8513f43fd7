"""`JointImpedanceDrive`: an arm's actuators rewritten in the scene's `MjSpec` into a joint
impedance, and the robot's weight cancelled by MuJoCo, so that MuJoCo itself runs the law
a Franka robot runs on its joints (docs/hardware.md)."""

from __future__ import annotations

import mujoco
import numpy as np

from .errors import SpecError, unknown_name
from .spec import JointImpedanceDrive

_MOVING = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


def critical_damping(
    stiffness: np.ndarray, inertia: np.ndarray, out: np.ndarray | None = None
) -> np.ndarray:
    """D = 2 sqrt(K m): each joint critically damped on its own inertia m (into `out`, a
    float64 array of the same length, when given: a control loop's, allocating nothing)."""
    if out is None:
        out = np.zeros(len(stiffness))
    np.multiply(stiffness, inertia, out=out)
    np.sqrt(out, out=out)
    out *= 2.0
    return out


def apply_impedance_drives(
    s: mujoco.MjSpec,
    model: mujoco.MjModel,
    drives: list[tuple[str, JointImpedanceDrive, str, list[str]]],
) -> None:
    """Rewrite `s` for each (robot prefix, drive, field, the robot's root bodies); `model` is
    `s` compiled as it was, for the transmissions and the mass matrix."""
    for prefix, drive, field, roots in drives:
        _apply(s, model, prefix, drive, field, roots)


def _apply(
    s: mujoco.MjSpec,
    model: mujoco.MjModel,
    prefix: str,
    drive: JointImpedanceDrive,
    field: str,
    roots: list[str],
) -> None:
    actuators = [
        _actuator(s, model, prefix, name, f"{field}.actuators[{i}]")
        for i, name in enumerate(drive.actuators)
    ]
    joints = [int(model.actuator_trnid[a, 0]) for a in actuators]
    inertia = _inertia(model, joints, np.asarray(drive.damping_pose, dtype=float))
    stiffness = np.asarray(drive.stiffness, dtype=float)
    damping = critical_damping(stiffness, inertia)
    for a, k, d, limit in zip(actuators, stiffness, damping, drive.torque_limit, strict=True):
        act = s.actuator(model.actuator(a).name)
        # As MuJoCo's <position> writes a servo: force = kp ctrl - kp l - kv dl on the actuator
        # length l = gear q, so the joint gets K = gear² kp and D = gear² kv.
        gear = float(model.actuator_gear[a, 0])
        act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        act.gainprm = [k / gear**2] + [0.0] * 9
        act.biasprm = [0.0, -k / gear**2, -d / gear**2] + [0.0] * 7
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.forcerange = [-float(limit) / abs(gear), float(limit) / abs(gear)]
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE  # a setpoint may lead the range
    for root in roots:
        body = s.body(root)
        for b in [body, *body.find_all(mujoco.mjtObj.mjOBJ_BODY)]:
            b.gravcomp = 1.0
        for joint in body.find_all(mujoco.mjtObj.mjOBJ_JOINT):
            # through the actuators: the joint torques a robot measures include its weight
            if int(joint.type) in _MOVING:
                joint.actgravcomp = True


def _actuator(s: mujoco.MjSpec, model: mujoco.MjModel, prefix: str, name: str, field: str) -> int:
    """The id of the robot's actuator `name`, checked to drive one moving joint directly."""
    if s.actuator(prefix + name) is None:
        known = [a.name[len(prefix) :] for a in s.actuators if a.name.startswith(prefix)]
        raise unknown_name("actuator", name, known, where=field)
    a = model.actuator(prefix + name).id
    if int(model.actuator_trntype[a]) != int(mujoco.mjtTrn.mjTRN_JOINT):
        raise SpecError(
            f"{field}: actuator {name!r} does not drive a joint directly (its transmission is "
            f"{mujoco.mjtTrn(int(model.actuator_trntype[a])).name}); a JointImpedanceDrive "
            "needs one joint per actuator"
        )
    if int(model.jnt_type[model.actuator_trnid[a, 0]]) not in _MOVING:
        raise SpecError(
            f"{field}: actuator {name!r} drives a ball or free joint, not a hinge or slide joint"
        )
    if int(model.actuator_dyntype[a]) != int(mujoco.mjtDyn.mjDYN_NONE):
        raise SpecError(
            f"{field}: actuator {name!r} has activation dynamics "
            f"({mujoco.mjtDyn(int(model.actuator_dyntype[a])).name}); a joint impedance acts "
            "at once"
        )
    return a


def _inertia(model: mujoco.MjModel, joints: list[int], pose: np.ndarray) -> np.ndarray:
    """Each joint's own inertia (the mass matrix's diagonal, armature included) with the
    joints at `pose` and the rest of the model at `qpos0`."""
    data = mujoco.MjData(model)
    for j, q in zip(joints, pose, strict=True):
        data.qpos[model.jnt_qposadr[j]] = q
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    return np.array([full[d, d] for d in model.jnt_dofadr[joints]])
