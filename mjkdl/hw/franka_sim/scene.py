"""The simulated arm's world: an ordinary mjkdl scene (Menagerie's Panda with its hand; a floor, a
table and a cube on it, or the arm alone for hardware in the loop), and what the robot itself
tells a client about it: the arm's URDF (from which libfranka >= 0.18 builds its dynamics model)
and the hand's mass properties."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from mjkdl import menagerie
from mjkdl.errors import SpecError
from mjkdl.spec import Condim, RobotSpec, SceneObject, SceneSpec, Shape

from .limits import ArmLimits

ARM_JOINTS = tuple(f"joint{i}" for i in range(1, 8))
FLANGE_OFFSET = 0.107  # link7 origin to the flange along link7's z (Panda, FR3)
HAND_TCP = 0.1034  # flange to the Franka Hand's TCP, between the fingertips
CUBE_HALF = 0.02
TABLE_TOP = 0.15  # m
CUBE_AT = np.array([0.45, 0.45, TABLE_TOP + CUBE_HALF])  # beside the examples' x-z plane


# What the simulated arm shares its world with: "pick" a floor, a table and a cube to pick
# through the protocol; "empty" nothing, for hardware in the loop, where the client's own scene
# simulates everything but the arm (a second floor or cube here would push the arm where the
# client's scene has nothing).
SCENES = ("pick", "empty")


def franka_scene(kind: str = "pick") -> SceneSpec:
    """Panda (1 kHz, the robot's control rate) at the origin and, for `kind` "pick", a floor,
    a table in front of it and a 4 cm cube on the table (`CUBE_AT`); "empty": the arm alone."""
    if kind not in SCENES:
        raise SpecError(f"scene {kind!r}: the simulator has the scenes {list(SCENES)}")
    pick = kind == "pick"
    return SceneSpec(
        timestep=0.001,
        add_floor=pick,
        add_skybox=False,
        robots=[RobotSpec(path=menagerie.model_path("franka_emika_panda"))],
        objects=[]
        if not pick
        else [
            SceneObject(
                name="table",
                shape=Shape.BOX,
                size=[0.15, 0.15, TABLE_TOP / 2],
                pos=[CUBE_AT[0], CUBE_AT[1] + 0.05, TABLE_TOP / 2],
                rgba=[0.6, 0.45, 0.3, 1.0],
                fixed=True,
            ),
            SceneObject(
                name="cube",
                shape=Shape.BOX,
                size=[CUBE_HALF] * 3,
                pos=list(CUBE_AT),
                rgba=[0.1, 0.4, 1.0, 1.0],
                mass=0.05,
                condim=Condim.Torsional,
                friction=[1.0, 0.02, 0.001],
            ),
        ],
    )


@dataclass(frozen=True)
class HandInertia:
    """The hand with its fingers as the robot reports it: mass, centre of mass in the flange
    frame, inertia about it (flange axes, column-major 3×3)."""

    m_ee: float
    F_x_Cee: np.ndarray
    I_ee: np.ndarray


def _rpy(mat: np.ndarray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw (fixed x, y, z) of a rotation matrix."""
    pitch = float(np.arcsin(-np.clip(mat[2, 0], -1.0, 1.0)))
    roll = float(np.arctan2(mat[2, 1], mat[2, 2]))
    yaw = float(np.arctan2(mat[1, 0], mat[0, 0]))
    return roll, pitch, yaw


def _mat(quat: np.ndarray) -> np.ndarray:
    out = np.zeros(9)
    mujoco.mju_quat2Mat(out, quat)
    return out.reshape(3, 3)


def _body_inertia(m: mujoco.MjModel, b: int) -> np.ndarray:
    r = _mat(m.body_iquat[b])
    return r @ np.diag(m.body_inertia[b]) @ r.T


def arm_urdf(m: mujoco.MjModel, limits: ArmLimits) -> str:
    """The arm from `link0` to the flange (`link8`) as URDF, read from the compiled model: link
    placements and inertias as MuJoCo simulates them, joint limits the published ones, the flange
    named `link8` as libfranka expects. The hand
    is not in it: the robot reports it in the state (`m_ee`, `F_x_Cee`, `I_ee`), as the real
    robot does, and libfranka adds it to the last link."""
    lines = ['<?xml version="1.0"?>', '<robot name="panda">']
    names = ["link0", *[f"link{i}" for i in range(1, 8)]]
    for name in names:
        b = m.body(name).id
        inertia = _body_inertia(m, b)
        c = m.body_ipos[b]
        lines += [
            f'  <link name="{name}">',
            "    <inertial>",
            f'      <origin xyz="{c[0]:.17g} {c[1]:.17g} {c[2]:.17g}" rpy="0 0 0"/>',
            f'      <mass value="{m.body_mass[b]:.17g}"/>',
            f'      <inertia ixx="{inertia[0, 0]:.17g}" ixy="{inertia[0, 1]:.17g}" '
            f'ixz="{inertia[0, 2]:.17g}" iyy="{inertia[1, 1]:.17g}" iyz="{inertia[1, 2]:.17g}" '
            f'izz="{inertia[2, 2]:.17g}"/>',
            "    </inertial>",
            "  </link>",
        ]
    for i in range(1, 8):
        b = m.body(f"link{i}").id
        p = m.body_pos[b]
        roll, pitch, yaw = _rpy(_mat(m.body_quat[b]))
        lines += [
            f'  <joint name="joint{i}" type="revolute">',
            f'    <parent link="link{i - 1}"/>',
            f'    <child link="link{i}"/>',
            f'    <origin xyz="{p[0]:.17g} {p[1]:.17g} {p[2]:.17g}" '
            f'rpy="{roll:.17g} {pitch:.17g} {yaw:.17g}"/>',
            '    <axis xyz="0 0 1"/>',
            f'    <limit lower="{limits.q_min[i - 1]}" upper="{limits.q_max[i - 1]}" '
            f'effort="{limits.tau_max[i - 1]}" velocity="{limits.dq_max[i - 1]}"/>',
            # libfranka >= 0.18 reads these for its position-dependent velocity limits: the
            # speed from which the joint can still brake at its acceleration limit.
            f'    <position_based_velocity_limits velocity_offset="0" '
            f'deceleration_limit="{limits.ddq_max[i - 1]}"/>',
            "  </joint>",
        ]
    lines += [
        '  <link name="link8"/>',
        '  <joint name="joint8" type="fixed">',
        '    <parent link="link7"/>',
        '    <child link="link8"/>',
        f'    <origin xyz="0 0 {FLANGE_OFFSET}" rpy="0 0 0"/>',
        "  </joint>",
        "</robot>",
    ]
    return "\n".join(lines) + "\n"


def hand_inertia(m: mujoco.MjModel, d: mujoco.MjData) -> HandInertia:
    """The hand and its fingers (MuJoCo's `hand` subtree) lumped in the flange frame."""
    link7 = m.body("link7").id
    r_f = d.xmat[link7].reshape(3, 3)
    p_f = d.xpos[link7] + r_f[:, 2] * FLANGE_OFFSET
    root = m.body("hand").id
    bodies = [b for b in range(m.nbody) if b == root or _descends(m, b, root)]
    mass = float(sum(m.body_mass[b] for b in bodies))
    com_w = sum(m.body_mass[b] * d.xipos[b] for b in bodies) / mass
    inertia_w = np.zeros((3, 3))
    for b in bodies:
        r = d.ximat[b].reshape(3, 3)
        arm = d.xipos[b] - com_w
        inertia_w += r @ np.diag(m.body_inertia[b]) @ r.T
        inertia_w += m.body_mass[b] * (arm @ arm * np.eye(3) - np.outer(arm, arm))
    com_f = r_f.T @ (com_w - p_f)
    inertia_f = r_f.T @ inertia_w @ r_f
    return HandInertia(mass, com_f, inertia_f.flatten(order="F"))


def _descends(m: mujoco.MjModel, b: int, root: int) -> bool:
    while b > 0:
        b = int(m.body_parentid[b])
        if b == root:
            return True
    return False
