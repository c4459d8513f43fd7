"""`GripperDrive`: a parallel gripper's servo, finger damping and pad contacts rewritten in the
scene's `MjSpec` so that it grasps with a set force at a set finger speed (docs/physics.md)."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from .errors import SpecError, unknown_name
from .spec import GripperDrive

# The servo presses with the full force from this far (per finger, m) short of its target on:
# stiff enough that objects of any width but the thinnest get the set force.
SATURATION = 0.005
# Pad contacts as stiff and hard as Menagerie's Robotiq 2F-85 pads (0.004 s, 0.95-0.99), not
# MuJoCo's defaults (0.02 s, 0.9-0.95), into which a squeezed object sinks and creeps out of
# the grip; overdamped (damping ratio 2, lossy like rubber), or a cube shaken in the grip sets
# the damped fingers breathing and the squeeze swings between 6 and 26 N (measured).
# They win over the object's by `solmix` (MuJoCo mixes solref/solimp by the two geoms' solmix
# weights), not by `priority`, which would also impose the pads' condim and friction and take
# away, say, a cube's torsional friction.
PAD_SOLREF = (0.004, 2.0)
PAD_SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)
PAD_SOLMIX = 1000.0  # against MuJoCo's default 1: the pads' parameters weigh 0.999


def apply_drives(
    s: mujoco.MjSpec, model: mujoco.MjModel, drives: list[tuple[str, GripperDrive, str]]
) -> None:
    """Rewrite `s` for each (robot prefix, drive, field); `model` is `s` compiled as it was,
    for the transmission (which joints, with what coefficients) the spec API cannot read."""
    for prefix, drive, field in drives:
        _apply(s, model, prefix, drive, field)


def _apply(
    s: mujoco.MjSpec, model: mujoco.MjModel, prefix: str, drive: GripperDrive, field: str
) -> None:
    name = prefix + drive.actuator
    act = s.actuator(name)
    if act is None:
        known = [a.name[len(prefix) :] for a in s.actuators if a.name.startswith(prefix)]
        raise unknown_name("actuator", drive.actuator, known, where=f"{field}.actuator")
    a = model.actuator(name).id
    servo = (
        int(model.actuator_gaintype[a]) == int(mujoco.mjtGain.mjGAIN_FIXED)
        and int(model.actuator_biastype[a]) == int(mujoco.mjtBias.mjBIAS_AFFINE)
        and model.actuator_biasprm[a, 1] < 0
    )
    if not servo:
        raise SpecError(
            f"{field}: actuator {drive.actuator!r} is not a position servo (fixed gain, affine "
            "bias with a negative position term); a GripperDrive stiffens such a servo"
        )
    joints, coefs = _fingers(model, a, drive, field)
    c = float(coefs[0])
    # Actuator force F gives each finger c * F; n fingers each `SATURATION` short of the
    # target are n * c * SATURATION short in actuator length.
    limit = float(drive.force) / c
    kp = limit / (len(joints) * c * SATURATION)
    act.gainprm[0] = model.actuator_gainprm[a, 0] * kp / -model.actuator_biasprm[a, 1]
    act.biasprm[1] = -kp
    act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    act.forcerange = [-limit, limit]
    for j in joints:
        joint = s.joint(model.joint(j).name)
        joint.damping[0] = float(drive.force) / float(drive.speed)
        body = model.body(model.jnt_bodyid[j]).name
        pads = [g for g in s.body(body).geoms if _is_pad(g, prefix, drive.pads)]
        if not pads:
            classes = sorted({g.classname.name[len(prefix) :] for g in s.body(body).geoms})
            raise SpecError(
                f"{field}.pads: no geom of finger body {body!r} has a name or class starting "
                f"with {drive.pads!r}; its classes: {classes}"
            )
        for geom in pads:
            geom.solref = list(PAD_SOLREF)
            geom.solimp = list(PAD_SOLIMP)
            geom.solmix = PAD_SOLMIX


def _is_pad(geom: Any, prefix: str, pads: str) -> bool:
    names = (geom.name, geom.classname.name)
    return any(n.startswith(prefix) and n[len(prefix) :].startswith(pads) for n in names)


def _fingers(
    model: mujoco.MjModel, a: int, drive: GripperDrive, field: str
) -> tuple[list[int], np.ndarray]:
    """The finger joints the actuator drives and its force's coefficient on each."""
    trn, target = int(model.actuator_trntype[a]), int(model.actuator_trnid[a, 0])
    if trn == int(mujoco.mjtTrn.mjTRN_JOINT):
        joints, coefs = [target], np.abs(model.actuator_gear[a, :1])
    elif trn == int(mujoco.mjtTrn.mjTRN_TENDON) and int(model.tendon_num[target]) > 0:
        adr, num = int(model.tendon_adr[target]), int(model.tendon_num[target])
        if np.any(model.wrap_type[adr : adr + num] != int(mujoco.mjtWrap.mjWRAP_JOINT)):
            raise SpecError(
                f"{field}: actuator {drive.actuator!r} pulls a spatial tendon; a GripperDrive "
                "needs slide finger joints, directly or through a fixed tendon"
            )
        joints = [int(j) for j in model.wrap_objid[adr : adr + num]]
        coefs = np.abs(model.wrap_prm[adr : adr + num] * model.actuator_gear[a, 0])
    else:
        raise SpecError(
            f"{field}: actuator {drive.actuator!r} does not drive joints; a GripperDrive needs "
            "slide finger joints, directly or through a fixed tendon"
        )
    slides = [int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_SLIDE) for j in joints]
    if not all(slides) or not np.allclose(coefs, coefs[0]) or coefs[0] <= 0:
        raise SpecError(
            f"{field}: actuator {drive.actuator!r} must drive slide finger joints with equal "
            f"coefficients, got joints {[model.joint(j).name for j in joints]} "
            f"(slide: {slides}) with coefficients {coefs.tolist()}"
        )
    return joints, coefs
