"""Joint velocity and acceleration limits of an arm: the user's, a MoveIt `joint_limits.yaml`,
the model's, or the maker's published figures for an arm recognised beyond doubt.

MJCF files (Menagerie's included) carry no joint velocity or acceleration limits, and URDF's
velocity limits are lost on compiling to MuJoCo; the planner needs both. Per joint and
quantity the first of these that has one is used: the planner's arguments, a `RobotLimits`
(read from a MoveIt `joint_limits.yaml` with `RobotLimits.load`), the model (a URDF's
`<limit velocity>`), then the table `DATASHEETS`. A table entry is used only when the arm
matches it *unambiguously*: the bodies its joints turn end with the entry's names (any prefix,
e.g. `wx250s/` or `fr3_`) and its kinematics are the entry's, compared through quantities
every description of the same arm shares (`kinematic_signature`: the distance and angle
between consecutive joint axes and the offsets along them). Names alone are not enough: an
arm named like the iiwa with other kinematics (a Flexiv Rizon) gets a warning, not the
iiwa's limits. Whatever is still missing is listed in one error.

Where a maker publishes no joint acceleration limit (`acceleration=None`), the planner uses
each joint's velocity limit reached in `RAMP` seconds and says so in its `limits_source`.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from ..errors import ModelFileError, SpecError, SpecTypeError

# Seconds to full speed when a datasheet gives no acceleration limit (UR's, KUKA's, UFACTORY's
# and Trossen's do not): a deliberate, conservative rule, not a published figure.
RAMP = 0.5
# Two descriptions of one arm (an MJCF and a URDF, a model and the maker's DH table) agree to
# well under a millimetre; a different arm of the same family differs by centimetres (UR5 and
# UR5e: 5 mm in the wrist, 24 mm at the elbow). Lengths match within this (m) plus
# `KINEMATIC_REL` of the length, angles within `KINEMATIC_ANGLE` (rad).
KINEMATIC_TOLERANCE = 0.003
KINEMATIC_REL = 0.01
KINEMATIC_ANGLE = 0.02
_DEG = math.pi / 180.0
_QUANTITIES = ("velocity", "acceleration")


@dataclass(frozen=True)
class Datasheet:
    """One arm's published limits: `velocity` (rad/s), `acceleration` (rad/s², None where
    unpublished), the document each comes from, and how the arm is recognised: `links`,
    suffixes of the bodies each joint turns, and `kinematics`, one row per joint in the
    `convention` "dh" (standard Denavit-Hartenberg d, a, alpha), "mdh" (Craig's modified
    d, a, alpha: a and alpha of the link before the joint) or "offsets" (x, y, z of the
    joint's origin from the previous one's and its axis x, y, z, all frames aligned at zero).
    """

    arm: str
    links: tuple[str, ...]
    kinematics: tuple[tuple[float, ...], ...]
    convention: str
    velocity: tuple[float, ...]
    acceleration: tuple[float, ...] | None
    velocity_source: str
    acceleration_source: str
    kinematics_source: str
    verified: str = ""  # how the figures were re-checked, against which published copy


@dataclass(frozen=True)
class ArmLimits:
    """The limits a planner uses and where they come from (`source`: one line per quantity)."""

    velocity: np.ndarray
    acceleration: np.ndarray
    source: str
    torque: np.ndarray | None = None  # N·m or N per joint (inf: none); None: no joint has one


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
_HALF = math.pi / 2
# Franka's DH table (FCI documentation, "Robot and interface specifications"): the same for
# the Panda and the FR3.
_FRANKA = (
    (0.333, 0.0, 0.0),
    (0.0, 0.0, -_HALF),
    (0.316, 0.0, _HALF),
    (0.0, 0.0825, _HALF),
    (0.384, -0.0825, -_HALF),
    (0.0, 0.0, _HALF),
    (0.0, 0.088, _HALF),
)
_FRANKA_KIN = "Franka FCI documentation, DH parameters (the Panda's and the FR3's are the same)"


def _iiwa(d1: float, d3: float) -> tuple[tuple[float, ...], ...]:
    """A KUKA LBR iiwa's DH rows: its shoulder height, upper-arm length, 0.4 m forearm."""
    return (
        (d1, 0.0, -_HALF),
        (0.0, 0.0, _HALF),
        (d3, 0.0, _HALF),
        (0.0, 0.0, -_HALF),
        (0.4, 0.0, -_HALF),
        (0.0, 0.0, _HALF),
        (0.126, 0.0, 0.0),
    )


def _ur(d1: float, a2: float, a3: float, d4: float, d5: float, d6: float) -> tuple:
    """A Universal Robots arm's DH rows (Universal Robots' published DH parameters)."""
    return (
        (d1, 0.0, _HALF),
        (0.0, a2, 0.0),
        (0.0, a3, 0.0),
        (d4, 0.0, _HALF),
        (d5, 0.0, -_HALF),
        (d6, 0.0, 0.0),
    )


def _trossen(
    shoulder: float, elbow: tuple[float, float], forearm: float, wrist: float, hand: float
) -> tuple:
    """An Interbotix arm's joint origins (xsarm_descriptions URDF): waist, shoulder, elbow,
    forearm roll, wrist angle, wrist rotate."""
    return (
        (0.0, 0.0, 0.0, 0.0, 0.0, 1.0),
        (0.0, 0.0, shoulder, 0.0, 1.0, 0.0),
        (elbow[0], 0.0, elbow[1], 0.0, 1.0, 0.0),
        (forearm, 0.0, 0.0, 1.0, 0.0, 0.0),
        (wrist, 0.0, 0.0, 0.0, 1.0, 0.0),
        (hand, 0.0, 0.0, 1.0, 0.0, 0.0),
    )


_UR_KIN = "Universal Robots' published DH parameters for the arm"
_KUKA_KIN = "KUKA LBR iiwa specification, dimensions (the DH rows Drake and lbr-stack use)"
_UFACTORY_KIN = "UFACTORY's published DH parameters (xArm user manual / xarm_ros)"
_TROSSEN_KIN = "Interbotix xsarm_descriptions URDF joint origins"


def _deg(*values: float) -> tuple[float, ...]:
    return tuple(round(v * _DEG, 4) for v in values)


# Among the entries an arm matches, the one with the longest names wins (fr3_link1 before
# link1); entries that match equally are ambiguous and none is used. Each row's `verified`
# cites the published copy its figures were checked against; on 2026-11-28 the FR3, iiwa 7,
# xArm 6, UR3e, UR5e, UR10e, UR10 and vx300s rows were checked against published models
# (tests/test_plan_limits.py builds their joint origins): all matched, none changed.
DATASHEETS: tuple[Datasheet, ...] = (
    Datasheet(
        "Franka Research 3",
        tuple(f"fr3_link{i}" for i in range(1, 8)),
        _FRANKA,
        "mdh",
        (2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26),
        (10.0,) * 7,
        "Franka FCI documentation, 'Limits for Franka Research 3' (dq_max)",
        "Franka FCI documentation, 'Limits for Franka Research 3' (ddq_max)",
        _FRANKA_KIN,
        "2026-11-28: frankaemika/franka_description robots/fr3/joint_limits.yaml gives the "
        "same velocities; Menagerie's franka_fr3/fr3.xml joint origins match the kinematics "
        "(2026-11-26: the FCI documentation's limit tables)",
    ),
    Datasheet(
        "Franka Emika Panda",
        _LINK7,
        _FRANKA,
        "mdh",
        (2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61),
        (15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0),
        "Franka FCI documentation, 'Limits for Panda' (dq_max)",
        "Franka FCI documentation, 'Limits for Panda' (ddq_max)",
        _FRANKA_KIN,
        "2026-11-26: against the FCI documentation's limit tables",
    ),
    Datasheet(
        "KUKA LBR iiwa 14 R820",
        _LINK7,
        _iiwa(0.36, 0.42),
        "dh",
        _deg(85, 85, 100, 75, 130, 135, 135),
        None,
        "KUKA 'LBR iiwa 7 R800, LBR iiwa 14 R820' specification, §4.3.2 axis data "
        "(spez_lbr_iiwa_en.pdf)",
        _NO_ACCEL,
        _KUKA_KIN,
        "2026-11-26: the same seven figures in Drake's iiwa_constants.cc, which cites §4.3.2",
    ),
    Datasheet(
        "KUKA LBR iiwa 7 R800",
        _LINK7,
        _iiwa(0.34, 0.40),
        "dh",
        _deg(98, 98, 100, 130, 140, 180, 180),
        None,
        "KUKA 'LBR iiwa 7 R800, LBR iiwa 14 R820' specification, axis data of the R800 "
        "(spez_lbr_iiwa_en.pdf)",
        _NO_ACCEL,
        _KUKA_KIN,
        "2026-11-28: lbr-stack/lbr_fri_ros2_stack lbr_description/urdf/iiwa7: "
        "joint_limits.yaml gives the same seven velocities, iiwa7_description.xacro's joint "
        "origins match the kinematics (0.34 m shoulder, 0.40 m upper arm and forearm, "
        "0.126 m to the flange)",
    ),
    Datasheet(
        "UFACTORY xArm 7",
        _LINK7,
        (
            (0.267, 0.0, -_HALF),
            (0.0, 0.0, _HALF),
            (0.293, 0.0525, _HALF),
            (0.0, 0.0775, _HALF),
            (0.3425, 0.0, _HALF),
            (0.0, 0.076, -_HALF),
            (0.097, 0.0, 0.0),
        ),
        "dh",
        _deg(*([180] * 7)),
        None,
        "UFACTORY xArm user manual §8.1, xArm5/6/7 common specifications: maximum joint "
        "speed 180°/s",
        _NO_ACCEL,
        _UFACTORY_KIN,
        "2026-11-26: UFACTORY's own manual source (xArm-Developer/ufactory_doc_usermanual)",
    ),
    Datasheet(
        "UFACTORY xArm 6",
        tuple(f"link{i}" for i in range(1, 7)),
        (
            (0.267, 0.0, -_HALF),
            (0.0, 0.28948, 0.0),
            (0.0, 0.0775, -_HALF),
            (0.3425, 0.0, _HALF),
            (0.0, 0.076, -_HALF),
            (0.097, 0.0, 0.0),
        ),
        "dh",
        _deg(*([180] * 6)),
        None,
        "UFACTORY xArm user manual §8.1, xArm5/6/7 common specifications: maximum joint "
        "speed 180°/s",
        _NO_ACCEL,
        _UFACTORY_KIN,
        "2026-11-28: xArm-Developer/xarm_ros2 xarm_description/urdf/xarm6/xarm6.urdf.xacro's "
        "joint origins match the kinematics (its URDF velocity limits are 3.14 rad/s and its "
        "MoveIt joint_limits.yaml 2.14 rad/s, not the manual's figure, which is kept); "
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
        (
            (0.2848, 0.0, _HALF),
            (0.0118, 0.0, _HALF),
            (0.4208, 0.0, _HALF),
            (0.0128, 0.0, _HALF),
            (0.3143, 0.0, _HALF),
            (0.0, 0.0, _HALF),
            (0.1674, 0.0, 0.0),
        ),
        "dh",
        (1.3963,) * 4 + (1.2218,) * 3,
        (8.6,) * 7,
        "Kinova Gen3 user guide, actuator speeds (large 80°/s, small 70°/s)",
        "not in the user guide: ros2_kortex's MoveIt configuration (8.6 rad/s²)",
        "Kinova Gen3 user guide, classic DH parameters (7 DoF)",
        "2026-11-26: Kinova's ros2_kortex kinova_gen3_7dof_robotiq_2f_85_moveit_config "
        "joint_limits.yaml gives 1.3963 / 1.2218 rad/s and 8.6 rad/s²",
    ),
    Datasheet(
        "Universal Robots UR3e",
        _UR_LINKS,
        _ur(0.15185, -0.24355, -0.2132, 0.13105, 0.08535, 0.0921),
        "dh",
        _deg(180, 180, 180, 360, 360, 360),
        None,
        "Universal Robots UR3e user manual (e-Series, 5.8), joint speeds",
        _NO_ACCEL,
        _UR_KIN,
        "2026-11-28: Universal_Robots_ROS2_Description config/ur3e/joint_limits.yaml "
        "(which cites that manual) gives the same speeds; ros-industrial/universal_robot "
        "ur_description/config/ur3e/default_kinematics.yaml the same DH parameters",
    ),
    Datasheet(
        "Universal Robots UR5e",
        _UR_LINKS,
        _ur(0.1625, -0.425, -0.3922, 0.1333, 0.0997, 0.0996),
        "dh",
        _deg(180, 180, 180, 180, 180, 180),
        None,
        "Universal Robots UR5e user manual (e-Series, 5.8), joint speeds",
        _NO_ACCEL,
        _UR_KIN,
        "2026-11-28: Universal_Robots_ROS2_Description config/ur5e/joint_limits.yaml "
        "(which cites that manual) gives the same speeds; ros-industrial/universal_robot "
        "ur_description/config/ur5e/default_kinematics.yaml the same DH parameters, "
        "Menagerie's universal_robots_ur5e/ur5e.xml the same to the millimetre",
    ),
    Datasheet(
        "Universal Robots UR5 (CB3)",
        _UR_LINKS,
        _ur(0.089159, -0.425, -0.39225, 0.10915, 0.09465, 0.0823),
        "dh",
        _deg(180, 180, 180, 180, 180, 180),
        None,
        "Universal Robots UR5/CB3 user manual (3.13), joint speeds",
        _NO_ACCEL,
        _UR_KIN,
        "2026-11-26: Universal Robots' Universal_Robots_ROS2_Description ur5 "
        "joint_limits.yaml, which cites that manual",
    ),
    Datasheet(
        "Universal Robots UR10e",
        _UR_LINKS,
        _ur(0.1807, -0.6127, -0.57155, 0.17415, 0.11985, 0.11655),
        "dh",
        _deg(120, 120, 180, 180, 180, 180),
        None,
        "Universal Robots UR10e user manual (e-Series, 5.8), joint speeds",
        _NO_ACCEL,
        _UR_KIN,
        "2026-11-28: Universal_Robots_ROS2_Description config/ur10e/joint_limits.yaml "
        "(which cites that manual) gives the same speeds, its physical_parameters.yaml the "
        "same DH parameters to the millimetre, as does Menagerie's "
        "universal_robots_ur10e/ur10e.xml",
    ),
    Datasheet(
        "Universal Robots UR10 (CB3)",
        _UR_LINKS,
        _ur(0.1273, -0.612, -0.5723, 0.163941, 0.1157, 0.0922),
        "dh",
        _deg(120, 120, 180, 180, 180, 180),
        None,
        "Universal Robots UR10/CB3 user manual (3.x), joint speeds (base and shoulder "
        "120°/s, the others 180°/s)",
        _NO_ACCEL,
        _UR_KIN,
        "2026-11-28: Universal_Robots_ROS2_Description config/ur10/joint_limits.yaml "
        "(which cites the UR10/CB3 manual 3.13) gives the same speeds; "
        "ros-industrial/universal_robot ur_description/config/ur10/default_kinematics.yaml "
        "the same DH parameters",
    ),
    Datasheet(
        "Trossen WidowX 250 6DOF (wx250s)",
        _TROSSEN,
        _trossen(0.03865, (0.04975, 0.25), 0.175, 0.075, 0.065),
        "offsets",
        (math.pi,) * 6,
        None,
        "no datasheet figure: Interbotix xsarm_descriptions URDF joint velocity limits (π rad/s)",
        _NO_ACCEL,
        _TROSSEN_KIN,
        "2026-11-26: Interbotix's wx250s and vx300s .urdf.xacro: every arm joint's "
        "velocity limit is π",
    ),
    Datasheet(
        "Trossen ViperX 300 6DOF (vx300s)",
        _TROSSEN,
        _trossen(0.04805, (0.05955, 0.3), 0.2, 0.1, 0.069744),
        "offsets",
        (math.pi,) * 6,
        None,
        "no datasheet figure: Interbotix xsarm_descriptions URDF joint velocity limits (π rad/s)",
        _NO_ACCEL,
        _TROSSEN_KIN,
        "2026-11-28: Interbotix/interbotix_ros_manipulators interbotix_xsarm_descriptions/"
        "urdf/vx300s.urdf.xacro: the same joint origins and every arm joint's velocity limit π",
    ),
)


def chain_bodies(model: mujoco.MjModel, joints: Sequence[str]) -> list[str]:
    """The names of the bodies `joints` turn."""
    return [model.body(int(model.joint(j).bodyid[0])).name for j in joints]


def axis_lines(model: mujoco.MjModel, joints: Sequence[str]) -> np.ndarray:
    """The joints' axes as lines (n×6: a point, the unit direction) in the world at `qpos0`."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    ids = [int(model.joint(j).id) for j in joints]
    return np.hstack([data.xanchor[ids], data.xaxis[ids]])


def datasheet_lines(sheet: Datasheet) -> np.ndarray:
    """The joint axes (n×6, as `axis_lines`) of a table entry's kinematics at zero."""
    frame = np.eye(4)
    out = []
    for row in sheet.kinematics:
        if sheet.convention == "offsets":
            frame = frame @ _move(0.0, row[0], 0.0, row[1], row[2])
            out.append(np.concatenate([frame[:3, 3], np.asarray(row[3:], dtype=float)]))
            continue
        d, a, alpha = row
        if sheet.convention == "mdh":  # the link before the joint, then the joint's offset
            frame = frame @ _move(alpha, a, d)
            out.append(np.concatenate([frame[:3, 3], frame[:3, 2]]))
        else:  # standard: the joint turns about the previous frame's z
            out.append(np.concatenate([frame[:3, 3], frame[:3, 2]]))
            frame = frame @ _move(0.0, 0.0, d) @ _move(alpha, a, 0.0)
    return np.array(out)


def _move(alpha: float, a: float, d: float, y: float = 0.0, z: float | None = None) -> np.ndarray:
    """Rot_x(alpha) Trans_x(a) Trans_z(d) (or Trans(a, y, z) with `z` given)."""
    c, s = math.cos(alpha), math.sin(alpha)
    out = np.array([[1.0, 0, 0, a], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]])
    if z is None:
        out[:3, 3] += out[:3, 2] * d
    else:
        out[1, 3], out[2, 3] = y, z
    return out


def kinematic_signature(lines: np.ndarray) -> np.ndarray:
    """What every description of an arm's kinematics shares, from its joint axes (n×6): for
    each pair of consecutive axes their distance and angle (0..π/2), and for each inner joint
    the distance along its axis between where the previous and the next axes' common
    perpendiculars meet it (through a run of parallel axes: from the run's first to its
    last). NaN where undefined (inside a run of parallel axes, the first and last joints)."""
    n = len(lines)
    points, axes = lines[:, :3], lines[:, 3:] / np.linalg.norm(lines[:, 3:], axis=1)[:, None]
    dist, angle = np.zeros(n - 1), np.zeros(n - 1)
    enter = np.full(n, np.nan)  # where the previous axis's perpendicular meets axis i
    leave = np.full(n, np.nan)  # where the next axis's perpendicular meets axis i
    for i in range(n - 1):
        p, u, q, v = points[i], axes[i], points[i + 1], axes[i + 1]
        w = p - q
        cosine = float(u @ v)
        angle[i] = math.acos(min(1.0, abs(cosine)))
        cross = np.cross(u, v)
        norm = float(np.linalg.norm(cross))
        if norm < 1e-6:  # parallel: the next axis carries on where this one was entered
            dist[i] = float(np.linalg.norm(w - (w @ u) * u))
            enter[i + 1] = (enter[i] + float(u @ (p - q))) * math.copysign(1.0, cosine)
            continue
        dist[i] = abs(float((q - p) @ cross)) / norm
        e, f, den = float(u @ w), float(v @ w), 1.0 - cosine * cosine
        leave[i] = (cosine * f - e) / den  # along u from p
        enter[i + 1] = (f - cosine * e) / den  # along v from q
    inner = np.abs(leave[1:-1] - enter[1:-1])
    return np.concatenate([dist, angle, inner])


def _differs(mine: np.ndarray, theirs: np.ndarray) -> str | None:
    """The largest difference between two signatures beyond the tolerances, worded; None
    when they match."""
    if len(mine) != len(theirs):
        return "another number of joints"
    n = (len(mine) + 2) // 3 + 1
    worst, where = 0.0, ""
    for k, (x, y) in enumerate(zip(mine.tolist(), theirs.tolist(), strict=True)):
        if math.isnan(x) != math.isnan(y):
            return "axes parallel in one and not the other"
        if math.isnan(x):
            continue
        is_angle = n - 1 <= k < 2 * (n - 1)
        allowed = (
            KINEMATIC_ANGLE
            if is_angle
            else KINEMATIC_TOLERANCE + KINEMATIC_REL * max(abs(x), abs(y))
        )
        excess = abs(x - y) / allowed
        if excess > 1.0 and excess > worst:
            if k < n - 1:
                what = f"joint axes {k + 1} and {k + 2} are {x:.4f} m apart, theirs {y:.4f} m"
            elif is_angle:
                j = k - (n - 1)
                what = (
                    f"joint axes {j + 1} and {j + 2} meet at {math.degrees(x):.1f}°, "
                    f"theirs at {math.degrees(y):.1f}°"
                )
            else:
                j = k - 2 * (n - 1) + 2
                what = f"along joint axis {j} the offset is {x:.4f} m, theirs {y:.4f} m"
            worst, where = excess, what
    return where or None


@dataclass(frozen=True)
class DatasheetMatch:
    """Which table entry an arm is (`sheet`, None when none is beyond doubt) and why not
    (`note`: entries whose names it has but not their kinematics, or several that fit)."""

    sheet: Datasheet | None
    note: str


def match_datasheet(model: mujoco.MjModel, joints: Sequence[str]) -> DatasheetMatch:
    """The table's entry for the arm whose joints are `joints`: its body names and its
    kinematics must both match, and one entry must fit best (see the module's docstring)."""
    links = chain_bodies(model, joints)
    named = [
        sheet
        for sheet in DATASHEETS
        if len(sheet.links) == len(links)
        and all(name.endswith(suffix) for name, suffix in zip(links, sheet.links, strict=True))
    ]
    if not named:
        return DatasheetMatch(None, "")
    mine = kinematic_signature(axis_lines(model, joints))
    fits, misses = [], []
    for sheet in named:
        why = _differs(mine, kinematic_signature(datasheet_lines(sheet)))
        if why is None:
            fits.append(sheet)
        else:
            misses.append(f"{sheet.arm} ({why})")
    if fits:
        best = max(len("".join(s.links)) for s in fits)
        fits = [s for s in fits if len("".join(s.links)) == best]
    if len(fits) == 1:
        return DatasheetMatch(fits[0], "")
    if fits:
        arms = ", ".join(s.arm for s in fits)
        return DatasheetMatch(None, f"the arm fits several entries of the table equally ({arms})")
    return DatasheetMatch(
        None,
        "its bodies are named like those of "
        + "; ".join(misses)
        + ", but its kinematics differ, so their limits are not used",
    )


def read_file(path: str | Path, what: str) -> tuple[Path, str]:
    """The path and text of a configuration file; ModelFileError naming it (`what`)."""
    file = Path(path)
    try:
        return file, file.read_text()
    except OSError as error:
        raise ModelFileError(f"{what} {str(file)!r}: {error.strerror}") from None


@dataclass(frozen=True)
class RobotLimits:
    """Per-joint limits by joint name, as MoveIt's `joint_limits.yaml` holds them: `velocity`
    (rad/s or m/s), `acceleration` (rad/s², m/s²), `effort` (N·m or N); a joint may have any
    of them. `source` says where they come from (`load` puts the file's path there). A
    name matches a robot's joint of that name or one ending in it after a prefix (`/`, `_`)."""

    velocity: Mapping[str, float] = field(default_factory=dict)
    acceleration: Mapping[str, float] = field(default_factory=dict)
    effort: Mapping[str, float] = field(default_factory=dict)
    source: str = "RobotLimits"

    def __post_init__(self) -> None:
        for quantity in ("velocity", "acceleration", "effort"):
            given = getattr(self, quantity)
            if not isinstance(given, Mapping):
                raise SpecTypeError(
                    f"{self.source}: RobotLimits.{quantity} must map joint names to numbers, "
                    f"got {given!r}"
                )
            checked = {}
            for name, value in given.items():
                where = f"{self.source}: {quantity} of joint {name!r}"
                if not isinstance(name, str):
                    raise SpecTypeError(f"{where}: joint names must be strings")
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise SpecTypeError(f"{where} must be a number, got {value!r}")
                if not (math.isfinite(value) and value > 0):
                    raise SpecError(f"{where} must be a finite number > 0, got {value!r}")
                checked[name] = float(value)
            object.__setattr__(self, quantity, checked)

    @classmethod
    def load(cls, path: str | Path) -> RobotLimits:
        """The limits in a MoveIt `joint_limits.yaml` (`joint_limits: {joint: {has_velocity_
        limits: true, max_velocity: ...}}`; `max_acceleration`, `max_effort` likewise)."""
        import yaml

        file, text = read_file(path, "joint limits file")
        try:
            data = yaml.safe_load(text)
        except yaml.YAMLError as error:
            raise SpecError(f"joint limits file {str(file)!r} is not YAML: {error}") from None
        joints = data.get("joint_limits") if isinstance(data, dict) else None
        if not isinstance(joints, dict):
            raise SpecError(
                f"joint limits file {str(file)!r} has no 'joint_limits' mapping (MoveIt's "
                "joint_limits.yaml: joint_limits: {joint: {max_velocity: ...}})"
            )
        found: dict[str, dict[str, float]] = {q: {} for q in ("velocity", "acceleration", "effort")}
        for joint, entry in joints.items():
            if not isinstance(entry, dict):
                raise SpecError(f"{file}: joint_limits.{joint} must be a mapping, got {entry!r}")
            for quantity in found:
                if entry.get(f"has_{quantity}_limits", True) is False:
                    continue
                if f"max_{quantity}" in entry:
                    found[quantity][str(joint)] = entry[f"max_{quantity}"]
                elif entry.get(f"has_{quantity}_limits") is True:
                    raise SpecError(
                        f"{file}: joint_limits.{joint} has has_{quantity}_limits: true but no "
                        f"max_{quantity}"
                    )
        return cls(found["velocity"], found["acceleration"], found["effort"], str(file))

    def save(self, path: str | Path) -> None:
        """Write the limits as a MoveIt `joint_limits.yaml` (what `load` reads)."""
        import yaml

        joints: dict[str, dict[str, object]] = {}
        for quantity in ("velocity", "acceleration", "effort"):
            for name, value in getattr(self, quantity).items():
                entry = joints.setdefault(name, {})
                entry[f"has_{quantity}_limits"] = True
                entry[f"max_{quantity}"] = value
        Path(path).write_text(yaml.safe_dump({"joint_limits": joints}, sort_keys=False))

    def lookup(self, quantity: str, joint: str) -> float | None:
        """The `quantity` limit of the robot's joint `joint` (exact name, or a name it ends
        with after a prefix), or None."""
        table: Mapping[str, float] = getattr(self, quantity)
        if joint in table:
            return table[joint]
        for name, value in table.items():
            if joint.endswith(name) and joint[-len(name) - 1] in "/_:":
                return value
        return None


def resolve_limits(
    model: mujoco.MjModel,
    joints: Sequence[str],
    given: Mapping[str, np.ndarray | None],
    limits: RobotLimits | None,
    own_velocity: np.ndarray,
    own_effort: np.ndarray | None = None,
) -> ArmLimits:
    """Each joint's velocity and acceleration limit from the first source that has one:
    `given` (the planner's arguments), `limits`, the model's velocity (`own_velocity`, 0 or
    inf where none), the table on an unambiguous match. SpecError listing every missing
    limit at once; a warning when the names match a table entry but the kinematics do not.
    Torque limits (optional) from `limits.effort`, else the model's (`own_effort`)."""
    n = len(joints)
    match = match_datasheet(model, joints)
    sheet = match.sheet
    values = {q: np.full(n, np.nan) for q in _QUANTITIES}
    sources: dict[str, list[str]] = {q: [""] * n for q in _QUANTITIES}
    for quantity in _QUANTITIES:
        arg = given.get(quantity)
        for i, joint in enumerate(joints):
            if arg is not None:
                values[quantity][i], sources[quantity][i] = arg[i], "given"
                continue
            value = None if limits is None else limits.lookup(quantity, joint)
            if value is not None:
                values[quantity][i], sources[quantity][i] = value, str(limits and limits.source)
            elif quantity == "velocity" and 0 < own_velocity[i] < 1e6:
                values[quantity][i] = own_velocity[i]
                sources[quantity][i] = "the model's (a URDF's <limit velocity>)"
    if sheet is not None:
        a_source = f"{sheet.arm}: {sheet.acceleration_source}"
        if sheet.acceleration is None:
            a_source += f"; the velocity limit reached in {RAMP:g} s"
        for i in range(n):
            if math.isnan(values["velocity"][i]):
                values["velocity"][i] = sheet.velocity[i]
                sources["velocity"][i] = f"{sheet.arm}: {sheet.velocity_source}"
            if math.isnan(values["acceleration"][i]):
                values["acceleration"][i] = (
                    values["velocity"][i] / RAMP  # the velocity in use, reached in RAMP s
                    if sheet.acceleration is None
                    else sheet.acceleration[i]
                )
                sources["acceleration"][i] = a_source
    missing = [
        f"no {quantity} limit for joint{'s' if len(gap) > 1 else ''} {', '.join(gap)}"
        for quantity in _QUANTITIES
        if (gap := [joints[i] for i in np.flatnonzero(np.isnan(values[quantity])).tolist()])
    ]
    links = chain_bodies(model, joints)
    if match.note and any(s != "given" for q in _QUANTITIES for s in sources[q]):
        warnings.warn(
            f"planning limits: the arm (bodies {', '.join(links)}): {match.note}", stacklevel=4
        )
    if missing:
        known = ", ".join(d.arm for d in DATASHEETS)
        note = (
            f"; {match.note}" if match.note else f"; it is none of the arms mjkdl knows ({known})"
        )
        raise SpecError(
            f"{'; '.join(missing)} (the arm's bodies: {', '.join(links)}{note}). Give them "
            "with velocity_limits=/acceleration_limits= (one value per joint), or "
            "limits=RobotLimits(...) or limits='joint_limits.yaml' (MoveIt's file)"
        )
    lines = []
    for quantity in _QUANTITIES:
        groups: dict[str, list[str]] = {}
        for joint, source in zip(joints, sources[quantity], strict=True):
            groups.setdefault(source, []).append(joint)
        if len(groups) == 1:
            lines.append(f"{quantity}: {next(iter(groups))}")
        else:
            parts = [f"{source} ({', '.join(names)})" for source, names in groups.items()]
            lines.append(f"{quantity}: " + "; ".join(parts))
    torque = np.full(n, np.inf)
    where = []
    for i, joint in enumerate(joints):
        value = None if limits is None else limits.lookup("effort", joint)
        if value is not None:
            torque[i] = value
            where.append(limits.source if limits is not None else "")
        elif own_effort is not None and 0 < own_effort[i] < 1e6:
            torque[i] = own_effort[i]
            where.append("the model's (a URDF's <limit effort>, an actuator's force range)")
        else:
            where.append("none")
    if np.isinf(torque).all():
        return ArmLimits(values["velocity"], values["acceleration"], "\n".join(lines))
    groups = {}
    for joint, source in zip(joints, where, strict=True):
        groups.setdefault(source, []).append(joint)
    lines.append(
        "torque: "
        + (
            next(iter(groups))
            if len(groups) == 1
            else "; ".join(f"{source} ({', '.join(names)})" for source, names in groups.items())
        )
    )
    return ArmLimits(values["velocity"], values["acceleration"], "\n".join(lines), torque)
