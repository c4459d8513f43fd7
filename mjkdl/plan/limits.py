"""Joint velocity and acceleration limits of known arms, from their makers' published figures.

MJCF files (Menagerie's included) carry no joint velocity or acceleration limits, and URDF's
velocity limits are lost on compiling to MuJoCo; the planner needs both. An arm is recognised
by the names of the bodies its joints turn (any prefix, e.g. `wx250s/` or `fr3_`) and by its
*span*, the summed lengths of the body offsets from the first joint's body to the last one's
(sizes of one family: UR3e/UR5e/UR10e), within `SPAN_TOLERANCE`.

Where a maker publishes no joint acceleration limit (`acceleration=None`), the planner uses
each joint's velocity limit reached in `RAMP` seconds and says so in `ArmLimits.source`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

# Seconds to full speed when a datasheet gives no acceleration limit (UR's, KUKA's, UFACTORY's
# and Trossen's do not): a deliberate, conservative rule, not a published figure.
RAMP = 0.5
SPAN_TOLERANCE = 0.03
_DEG = math.pi / 180.0


@dataclass(frozen=True)
class Datasheet:
    """One arm's published limits: `velocity` (rad/s), `acceleration` (rad/s², None where
    unpublished), the document each comes from, and how the arm is recognised (`links`:
    suffixes of the bodies each joint turns; `span`: nominal summed offsets, m)."""

    arm: str
    links: tuple[str, ...]
    span: float
    velocity: tuple[float, ...]
    acceleration: tuple[float, ...] | None
    velocity_source: str
    acceleration_source: str
    verified: str = ""  # how the figures were re-checked, against which published copy


@dataclass(frozen=True)
class ArmLimits:
    """The limits a planner uses and where each comes from."""

    velocity: np.ndarray
    acceleration: np.ndarray
    velocity_source: str
    acceleration_source: str


_UR = ("shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link")
_UR_LINKS = (*_UR, "wrist_3_link")
_LINK7 = tuple(f"link{i}" for i in range(1, 8))
_TROSSEN = (
    "shoulder_link",
    "upper_arm_link",
    "upper_forearm_link",
    "lower_forearm_link",
    "wrist_link",
    "gripper_link",
)
_NO_ACCEL = "not published in the datasheet"


def _deg(*values: float) -> tuple[float, ...]:
    return tuple(round(v * _DEG, 4) for v in values)


# First match wins: the more specific names (fr3_) come before the generic ones.
DATASHEETS: tuple[Datasheet, ...] = (
    Datasheet(
        "Franka Research 3",
        tuple(f"fr3_link{i}" for i in range(1, 8)),
        0.879,
        (2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26),
        (10.0,) * 7,
        "Franka FCI documentation, 'Limits for Franka Research 3' (dq_max)",
        "Franka FCI documentation, 'Limits for Franka Research 3' (ddq_max)",
        "2026-11-26: against the FCI documentation's limit tables",
    ),
    Datasheet(
        "Franka Emika Panda",
        _LINK7,
        0.879,
        (2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61),
        (15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0),
        "Franka FCI documentation, 'Limits for Panda' (dq_max)",
        "Franka FCI documentation, 'Limits for Panda' (ddq_max)",
        "2026-11-26: against the FCI documentation's limit tables",
    ),
    Datasheet(
        "KUKA LBR iiwa 14 R820",
        _LINK7,
        1.104,
        _deg(85, 85, 100, 75, 130, 135, 135),
        None,
        "KUKA 'LBR iiwa 7 R800, LBR iiwa 14 R820' specification, §4.3.2 axis data "
        "(spez_lbr_iiwa_en.pdf)",
        _NO_ACCEL,
        "2026-11-26: the same seven figures in Drake's iiwa_constants.cc, which cites §4.3.2",
    ),
    Datasheet(
        "KUKA LBR iiwa 7 R800",
        _LINK7,
        1.064,
        _deg(98, 98, 100, 130, 140, 180, 180),
        None,
        "KUKA 'LBR iiwa 7 R800, LBR iiwa 14 R820' specification, axis data of the R800 "
        "(spez_lbr_iiwa_en.pdf)",
        _NO_ACCEL,
        "2026-11-26: the same seven figures in lbr-stack's lbr_description iiwa7 "
        "joint_limits.yaml (the KUKA PDF itself was not reachable)",
    ),
    Datasheet(
        "UFACTORY xArm 7",
        _LINK7,
        0.820,
        _deg(*([180] * 7)),
        None,
        "UFACTORY xArm user manual §8.1, xArm5/6/7 common specifications: maximum joint "
        "speed 180°/s",
        _NO_ACCEL,
        "2026-11-26: UFACTORY's own manual source (xArm-Developer/ufactory_doc_usermanual)",
    ),
    Datasheet(
        "UFACTORY xArm 6",
        tuple(f"link{i}" for i in range(1, 7)),
        0.820,
        _deg(*([180] * 6)),
        None,
        "UFACTORY xArm user manual §8.1, xArm5/6/7 common specifications: maximum joint "
        "speed 180°/s",
        _NO_ACCEL,
        "2026-11-26: UFACTORY's own manual source (xArm-Developer/ufactory_doc_usermanual)",
    ),
    Datasheet(
        "Kinova Gen3 (7 DoF)",
        (
            "shoulder_link",
            "half_arm_1_link",
            "half_arm_2_link",
            "forearm_link",
            "spherical_wrist_1_link",
            "spherical_wrist_2_link",
            "bracelet_link",
        ),
        0.970,
        (1.3963,) * 4 + (1.2218,) * 3,
        (8.6,) * 7,
        "Kinova Gen3 user guide, actuator speeds (large 80°/s, small 70°/s)",
        "not in the user guide: ros2_kortex's MoveIt configuration (8.6 rad/s²)",
        "2026-11-26: Kinova's ros2_kortex kinova_gen3_7dof_robotiq_2f_85_moveit_config "
        "joint_limits.yaml gives 1.3963 / 1.2218 rad/s and 8.6 rad/s²",
    ),
    Datasheet(
        "Universal Robots UR3e",
        _UR_LINKS,
        0.70,
        _deg(180, 180, 180, 360, 360, 360),
        None,
        "Universal Robots UR3e user manual (e-Series, 5.8), joint speeds",
        _NO_ACCEL,
        "2026-11-26: Universal Robots' Universal_Robots_ROS2_Description ur3e "
        "joint_limits.yaml, which cites that manual",
    ),
    Datasheet(
        "Universal Robots UR5e / UR5",
        _UR_LINKS,
        1.18,
        _deg(180, 180, 180, 180, 180, 180),
        None,
        "Universal Robots UR5e user manual (e-Series, 5.8) and UR5/CB3 user manual (3.13), "
        "joint speeds",
        _NO_ACCEL,
        "2026-11-26: Universal Robots' Universal_Robots_ROS2_Description ur5e and ur5 "
        "joint_limits.yaml, which cite those manuals",
    ),
    Datasheet(
        "Universal Robots UR10e",
        _UR_LINKS,
        1.62,
        _deg(120, 120, 180, 180, 180, 180),
        None,
        "Universal Robots UR10e user manual (e-Series, 5.8), joint speeds",
        _NO_ACCEL,
        "2026-11-26: Universal Robots' Universal_Robots_ROS2_Description ur10e "
        "joint_limits.yaml, which cites that manual",
    ),
    Datasheet(
        "Trossen WidowX 250 6DOF (wx250s)",
        _TROSSEN,
        0.60,
        (math.pi,) * 6,
        None,
        "no datasheet figure: Interbotix xsarm_descriptions URDF joint velocity limits (π rad/s)",
        _NO_ACCEL,
        "2026-11-26: Interbotix's wx250s and vx300s .urdf.xacro: every arm joint's "
        "velocity limit is π",
    ),
    Datasheet(
        "Trossen ViperX 300 6DOF (vx300s)",
        _TROSSEN,
        0.80,
        (math.pi,) * 6,
        None,
        "no datasheet figure: Interbotix xsarm_descriptions URDF joint velocity limits (π rad/s)",
        _NO_ACCEL,
        "2026-11-26: Interbotix's wx250s and vx300s .urdf.xacro: every arm joint's "
        "velocity limit is π",
    ),
)


def chain_links(model: mujoco.MjModel, joints: list[str]) -> tuple[list[str], float]:
    """The bodies `joints` turn and the arm's span (summed body offsets between them)."""
    bodies = [int(model.joint(j).bodyid[0]) for j in joints]
    span = 0.0
    for b in range(bodies[0] + 1, bodies[-1] + 1):
        # Bodies on the path from the first joint's body to the last one's.
        a = bodies[-1]
        while a > bodies[0] and a != b:
            a = int(model.body_parentid[a])
        if a == b:
            span += float(np.linalg.norm(model.body_pos[b]))
    return [model.body(b).name for b in bodies], span


def find_datasheet(model: mujoco.MjModel, joints: list[str]) -> Datasheet | None:
    """The table's entry for the arm whose joints are `joints`, or None."""
    links, span = chain_links(model, joints)
    for sheet in DATASHEETS:
        if len(sheet.links) != len(links):
            continue
        if not all(name.endswith(suffix) for name, suffix in zip(links, sheet.links, strict=True)):
            continue
        if abs(span - sheet.span) <= SPAN_TOLERANCE * sheet.span:
            return sheet
    return None


def datasheet_limits(sheet: Datasheet) -> ArmLimits:
    """The planner's limits from a table entry (velocity / `RAMP` where no acceleration)."""
    v = np.array(sheet.velocity, dtype=float)
    if sheet.acceleration is None:
        a = v / RAMP
        how = f"{sheet.arm}: {sheet.acceleration_source}; the velocity limit reached in {RAMP:g} s"
    else:
        a = np.array(sheet.acceleration, dtype=float)
        how = f"{sheet.arm}: {sheet.acceleration_source}"
    return ArmLimits(v, a, f"{sheet.arm}: {sheet.velocity_source}", how)
