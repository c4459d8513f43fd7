"""Extract a Pinocchio model of what moves an arm from a *compiled* MuJoCo model.

The model holds the joints from the world down to the base body (a turning torso, a free or
mocap base), the chain from the base to the tip (the arm), and everything below the base that
hangs off the chain (the tool with its fingers, side branches) with its joints. Bodies beside
the base's ancestors (another arm on the same torso) are left out: they do not enter the arm's
rows and columns of any quantity, only the base joints' own rows.

Each MuJoCo hinge or slide joint becomes a Pinocchio revolute/prismatic joint about z, with the
axis alignment, the joint anchor and the joint reference (`qpos0`) folded into the joint
placement, so a Pinocchio q equals MuJoCo's qpos. Ball and free joints become spherical and
free-flyer joints (their quaternions reordered, a free joint's linear velocity rotated into the
body frame); a mocap ancestor is a free-flyer whose q comes from `mocap_pos`/`mocap_quat`, at
rest as MuJoCo treats it. Jointless bodies join the inertia of the joint carrying them.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from .errors import SpecError
from .names import model_id

_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
_SLIDE = int(mujoco.mjtJoint.mjJNT_SLIDE)
_BALL = int(mujoco.mjtJoint.mjJNT_BALL)
_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
# Pinocchio stores quaternions [x, y, z, w], MuJoCo [w, x, y, z].
_TO_PIN_QUAT = [1, 2, 3, 0]


@dataclass(frozen=True)
class _Member:
    """One MuJoCo body's share of a Pinocchio joint's inertia."""

    joint: int  # Pinocchio joint carrying the body
    body: int  # MuJoCo body id
    placement: pin.SE3  # body frame in the joint frame


class Chain:
    """A Pinocchio model of the arm `base_body` → `tip_body` of a compiled `MjModel`.

    `model` is the whole model (base joints, arm, passive tool and branch joints); the arm's
    entries are `arm_q`/`arm_v` of its q and v (slices when contiguous, the usual case).
    """

    def __init__(
        self,
        m: mujoco.MjModel,
        base_body: str,
        tip_body: str,
        tcp_site: str = "",
        tcp_offset: pin.SE3 | None = None,
    ) -> None:
        self.base = model_id(m, mujoco.mjtObj.mjOBJ_BODY, "body", base_body, "the model")
        self.tip = model_id(m, mujoco.mjtObj.mjOBJ_BODY, "body", tip_body, "the model")
        path = _path(m, self.base, self.tip, base_body, tip_body)
        self.model = pin.Model()
        self.model.name = f"{base_body}->{tip_body}"
        self.joint_ids: list[int] = []  # MuJoCo ids of the arm's joints, base to tip
        self.arm_joints: list[int] = []  # their Pinocchio joint ids
        self._members: list[_Member] = []
        self._dofs: list[tuple[int, int]] = []  # (Pinocchio joint, MuJoCo dof address)
        self._frames: dict[int, int] = {}  # MuJoCo body id -> Pinocchio body frame id
        self._carrier: dict[int, tuple[int, pin.SE3]] = {0: (0, pin.SE3.Identity())}
        q_src: list[int] = []  # qpos address of each Pinocchio q entry (-1: mocap)
        v_src: list[int] = []
        self.free: list[tuple[int, int]] = []  # (Pinocchio idx_q, idx_v) of free joints
        self.mocap: list[tuple[int, int, int]] = []  # (idx_q, idx_v, mocap id)
        ancestors = _ancestors(m, self.base)
        self._check_equality_mounts(m, ancestors)
        arm = set(path)
        # Below the world only the tree that holds the arm matters (not every free object).
        below = _subtree(m, self.base) if self.base else [0, *_subtree(m, path[0])]
        for b in ancestors[:-1] + below:
            self._add_body(m, b, arm, q_src, v_src)
        if not self.joint_ids:
            raise SpecError(f"the chain {base_body!r} -> {tip_body!r} has no joints")
        self.qpos_adr = np.array([m.jnt_qposadr[j] for j in self.joint_ids])
        self.dof_adr = np.array([m.jnt_dofadr[j] for j in self.joint_ids])
        self.joint_names = [m.joint(j).name for j in self.joint_ids]
        self.arm_q = _span([self.model.idx_qs[j] for j in self.arm_joints])
        self.arm_v = _span([self.model.idx_vs[j] for j in self.arm_joints])
        self.q_index = np.array(q_src, dtype=int)
        self.v_index = np.array(v_src, dtype=int)
        # A plain copy does when Pinocchio's q and v are contiguous runs of qpos and qvel.
        self.quats = [  # where each quaternion starts in q (after a free joint's position)
            self.model.idx_qs[j] + self.model.nqs[j] - 4
            for j in range(1, self.model.njoints)
            if self.model.nqs[j] != self.model.nvs[j]
        ]
        q_span, v_span = _span(q_src), _span(v_src)
        plain = isinstance(q_span, slice) and isinstance(v_span, slice) and not self.free
        self.q_span = q_span if plain else None
        self.v_span = v_span if plain else None
        self.tip_frame = self._frames[self.tip]
        self.tcp_frame = self.tip_frame
        if tcp_site:
            self.tcp_frame = self._add_site_frame(m, tcp_site)
        if tcp_offset is not None:
            host = self.model.frames[self.tcp_frame]
            self.tcp_frame = self.model.addFrame(
                pin.Frame(
                    f"{host.name}_tcp", host.parentJoint, host.placement * tcp_offset, pin.OP_FRAME
                )
            )
        self.gravcomp_model: pin.Model | None = None
        self.load_parameters(m)

    # ------------------------------------------------------------------ building

    def _check_equality_mounts(self, m: mujoco.MjModel, ancestors: list[int]) -> None:
        """Refuse a base that floats in the tree but is held by an equality constraint."""
        floating = [b for b in ancestors if m.body_jntnum[b] or m.body_mocapid[b] >= 0]
        if not floating:
            return
        held = set(ancestors[ancestors.index(floating[0]) :])
        for e in range(m.neq):
            if int(m.eq_type[e]) not in (
                int(mujoco.mjtEq.mjEQ_WELD),
                int(mujoco.mjtEq.mjEQ_CONNECT),
            ):
                continue
            if int(m.eq_objtype[e]) != int(mujoco.mjtObj.mjOBJ_BODY):
                continue
            bodies = {int(m.eq_obj1id[e]), int(m.eq_obj2id[e])}
            if bodies & held and m.eq_active0[e]:
                name = m.equality(e).name or f"#{e}"
                raise SpecError(
                    f"base body {m.body(self.base).name!r} is held by equality constraint "
                    f"{name!r}, which the Pinocchio model cannot represent (it follows the "
                    "kinematic tree only); mount the robot in the tree instead (RobotSpec."
                    "attach_to) or choose a base_body below the constraint"
                )

    def _add_body(
        self, m: mujoco.MjModel, b: int, arm: set[int], q_src: list[int], v_src: list[int]
    ) -> None:
        parent = int(m.body_parentid[b])
        joint, acc = self._carrier[parent]
        mocap = int(m.body_mocapid[b])
        if mocap >= 0:
            # MuJoCo places a mocap body at mocap_pos/mocap_quat in the world.
            joint = self._add_pin_joint(
                pin.JointModelFreeFlyer(), 0, pin.SE3.Identity(), _frame_name(m, b)
            )
            iq, iv = self.model.idx_qs[joint], self.model.idx_vs[joint]
            self.mocap.append((iq, iv, mocap))
            q_src.extend([-1] * 7)
            v_src.extend([-1] * 6)
            acc = pin.SE3.Identity()
        else:
            acc = acc * pin.SE3(_quat_matrix(m.body_quat[b]), m.body_pos[b].copy())
        for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]):
            joint, acc = self._add_joint(m, j, joint, acc, b in arm, q_src, v_src)
            if b in arm:
                self.arm_joints.append(joint)
                self.joint_ids.append(j)
        self._members.append(_Member(joint, b, acc))
        parent_frame = self._frames.get(parent, 0)
        self._frames[b] = self.model.addBodyFrame(_frame_name(m, b), joint, acc, parent_frame)
        self._carrier[b] = (joint, acc)

    def _add_joint(
        self,
        m: mujoco.MjModel,
        j: int,
        parent: int,
        acc: pin.SE3,
        on_arm: bool,
        q_src: list[int],
        v_src: list[int],
    ) -> tuple[int, pin.SE3]:
        """Add MuJoCo joint `j` below Pinocchio joint `parent`; return it and the body in it."""
        jtype = int(m.jnt_type[j])
        body = int(m.jnt_bodyid[j])
        name = m.joint(j).name or f"joint{j}"
        qa, va = int(m.jnt_qposadr[j]), int(m.jnt_dofadr[j])
        if on_arm and jtype not in (_HINGE, _SLIDE):
            kind = mujoco.mjtJoint(jtype).name
            raise SpecError(
                f"joint {name!r} is a {kind} joint: the chain from base to tip takes only "
                "hinge and slide joints"
            )
        if jtype == _FREE:
            if int(m.body_parentid[body]) != 0 or parent != 0:
                raise SpecError(f"free joint {name!r} is not on a top-level body")
            # MuJoCo's free joint sets the body pose in the world from qpos directly.
            jid = self._add_pin_joint(pin.JointModelFreeFlyer(), 0, pin.SE3.Identity(), name)
            self.free.append((self.model.idx_qs[jid], self.model.idx_vs[jid]))
            q_src.extend([qa, qa + 1, qa + 2] + [qa + 3 + k for k in _TO_PIN_QUAT])
            v_src.extend(range(va, va + 6))
            self._dofs.append((jid, va))
            return jid, pin.SE3.Identity()
        if jtype == _BALL:
            # MuJoCo turns the body about the anchor by the quaternion qpos (not relative to
            # qpos0), expressed in the body frame.
            to_joint = pin.SE3(np.eye(3), m.jnt_pos[j].copy())
            jid = self._add_pin_joint(pin.JointModelSpherical(), parent, acc * to_joint, name)
            q_src.extend(qa + k for k in _TO_PIN_QUAT)
            v_src.extend(range(va, va + 3))
            self._dofs.append((jid, va))
            return jid, to_joint.inverse()
        if jtype not in (_HINGE, _SLIDE):
            raise SpecError(
                f"joint {name!r} (body {m.body(body).name!r}) has type {jtype}, which the "
                "Pinocchio model cannot represent"
            )
        align = _align_z(m.jnt_axis[j])
        q0 = float(m.qpos0[qa])
        if jtype == _HINGE:
            # MuJoCo rotates about the axis through the anchor by (qpos - qpos0).
            to_joint = pin.SE3(align, m.jnt_pos[j].copy())
            ref = pin.SE3(_rot_z(-q0), np.zeros(3))
            model = pin.JointModelRZ()
        else:
            to_joint = pin.SE3(align, np.zeros(3))
            ref = pin.SE3(np.eye(3), np.array([0.0, 0.0, -q0]))
            model = pin.JointModelPZ()
        jid = self._add_pin_joint(model, parent, acc * to_joint * ref, name)
        if m.jnt_limited[j]:
            iq = self.model.idx_qs[jid]
            self.model.lowerPositionLimit[iq] = m.jnt_range[j, 0]
            self.model.upperPositionLimit[iq] = m.jnt_range[j, 1]
        q_src.append(qa)
        v_src.append(va)
        self._dofs.append((jid, va))
        return jid, to_joint.inverse()

    def _on_path(self, m: mujoco.MjModel, body: int) -> bool:
        """Whether `body` is on the chain below the base (its joints are the arm's)."""
        b = self.tip
        while b != self.base:
            if b == body:
                return True
            b = int(m.body_parentid[b])
        return False

    def _add_pin_joint(self, jmodel: object, parent: int, placement: pin.SE3, name: str) -> int:
        jid = self.model.addJoint(parent, jmodel, placement, name)
        lo, hi = self.model.lowerPositionLimit, self.model.upperPositionLimit
        iq, nq = self.model.idx_qs[jid], self.model.nqs[jid]
        lo[iq : iq + nq] = -np.inf
        hi[iq : iq + nq] = np.inf
        self.model.lowerPositionLimit, self.model.upperPositionLimit = lo, hi
        return jid

    def _add_site_frame(self, m: mujoco.MjModel, site: str) -> int:
        s = model_id(m, mujoco.mjtObj.mjOBJ_SITE, "site", site, "the model (tool.tcp_site)")
        body = int(m.site_bodyid[s])
        if body not in self._frames or not self._rigid_to_arm(m, body):
            if body in self._frames and body not in _ancestors(m, self.base):
                raise SpecError(
                    f"TCP site {site!r} is on body {m.body(body).name!r}, which moves relative "
                    "to the chain through joints outside it (fingers, links beyond the tip): "
                    "choose a site rigidly fixed to the chain or its tool"
                )
            raise SpecError(
                f"TCP site {site!r} (body {m.body(body).name!r}) is not on the chain or "
                f"below its tip {m.body(self.tip).name!r}"
            )
        host = self.model.frames[self._frames[body]]
        site_in_body = pin.SE3(_quat_matrix(m.site_quat[s]), m.site_pos[s].copy())
        return self.model.addFrame(
            pin.Frame(site, host.parentJoint, host.placement * site_in_body, pin.OP_FRAME)
        )

    def _rigid_to_arm(self, m: mujoco.MjModel, body: int) -> bool:
        """Whether `body` is below the base and carried by no joints but the arm's."""
        b = body
        while b != self.base:
            if b == 0:
                return False
            if m.body_jntnum[b] and not self._on_path(m, b):
                return False
            b = int(m.body_parentid[b])
        return True

    # ------------------------------------------------------------------ state

    def read_state(self, d: mujoco.MjData, q: np.ndarray, v: np.ndarray) -> None:
        """Pinocchio's q and v from MuJoCo's state (the general path: quaternions, mocap)."""
        np.take(d.qpos, self.q_index, out=q)
        np.take(d.qvel, self.v_index, out=v)
        for iq, iv, mocap in self.mocap:
            q[iq : iq + 3] = d.mocap_pos[mocap]
            q[iq + 3 : iq + 7] = d.mocap_quat[mocap][_TO_PIN_QUAT]
            v[iv : iv + 6] = 0.0
        for iq in self.quats:  # MuJoCo normalises a copy of each quaternion it reads
            quat = q[iq : iq + 4]
            quat /= np.linalg.norm(quat)
        for iq, iv in self.free:
            # MuJoCo's free-joint velocity is linear in the world, angular in the body frame;
            # Pinocchio's is all in the body frame.
            rot = pin.Quaternion(q[iq + 3 : iq + 7]).matrix()
            v[iv : iv + 3] = rot.T @ v[iv : iv + 3]

    # ------------------------------------------------------------------ parameters

    def _load_effort_limits(self, m: mujoco.MjModel) -> None:
        """Joint effort limits from the actuators' forcerange (times gear) and actfrcrange."""
        model = self.model
        limit = np.full(model.nv, np.inf)
        for jid, dof in self._dofs:
            if model.nvs[jid] != 1:
                continue
            j = int(m.dof_jntid[dof])
            iv = model.idx_vs[jid]
            if m.jnt_actfrclimited[j]:
                limit[iv] = np.abs(m.jnt_actfrcrange[j]).max()
            for a in np.flatnonzero(
                (m.actuator_trntype == int(mujoco.mjtTrn.mjTRN_JOINT))
                & (m.actuator_trnid[:, 0] == j)
            ):
                if m.actuator_forcelimited[a]:
                    force = np.abs(m.actuator_forcerange[a]).max() * abs(m.actuator_gear[a, 0])
                    limit[iv] = min(limit[iv], force)
        model.effortLimit = limit  # the same memory as upperEffortLimit
        model.lowerEffortLimit = -limit

    def set_velocity_limits(self, limits: dict[str, float]) -> None:
        """Joint velocity limits by MuJoCo joint name (MJCF has none; URDF files do)."""
        model = self.model
        limit = np.full(model.nv, np.inf)
        for jid in range(1, model.njoints):
            if model.nvs[jid] == 1 and model.names[jid] in limits:
                limit[model.idx_vs[jid]] = limits[model.names[jid]]
        model.velocityLimit = limit  # the same memory as upperVelocityLimit
        model.lowerVelocityLimit = -limit

    def load_parameters(self, m: mujoco.MjModel) -> None:
        """(Re)load inertias, gravcomp, armature and gravity from `m` (run-time edits too).

        Bodies with MuJoCo `gravcomp` get that share of their weight cancelled by MuJoCo
        (`qfrc_gravcomp`); `gravcomp_model` holds just that share, to be subtracted from
        gravity so it is not compensated twice (None when no body has gravcomp).
        """
        model = self.model
        model.gravity = pin.Motion(np.asarray(m.opt.gravity, float).copy(), np.zeros(3))
        inertias = [pin.Inertia.Zero() for _ in range(model.njoints)]
        shares = [pin.Inertia.Zero() for _ in range(model.njoints)]
        for member in self._members:
            body_inertia = member.placement.act(_body_inertia(m, member.body))
            inertias[member.joint] = inertias[member.joint] + body_inertia
            gc = float(m.body_gravcomp[member.body])
            if gc:
                shares[member.joint] = shares[member.joint] + _scaled(body_inertia, gc)
        for jid in range(model.njoints):
            model.inertias[jid] = inertias[jid]
        for jid, dof in self._dofs:
            iv, nv = model.idx_vs[jid], model.nvs[jid]
            model.armature[iv : iv + nv] = m.dof_armature[dof : dof + nv]
        self._load_effort_limits(m)
        if any(y.mass != 0.0 for y in shares):
            gc_model = model.copy()
            for jid in range(model.njoints):
                gc_model.inertias[jid] = shares[jid]
            self.gravcomp_model = gc_model
        else:
            self.gravcomp_model = None


# ---------------------------------------------------------------------------- helpers


def _scaled(y: pin.Inertia, k: float) -> pin.Inertia:
    return pin.Inertia(y.mass * k, y.lever.copy(), y.inertia * k)


def _span(idx: list[int]) -> slice | np.ndarray:
    """`idx` as a slice when it is a contiguous ascending run, else as an index array."""
    if idx and list(idx) == list(range(idx[0], idx[0] + len(idx))):
        return slice(int(idx[0]), int(idx[0]) + len(idx))
    return np.array(idx, dtype=int)


def _frame_name(m: mujoco.MjModel, b: int) -> str:
    """Pinocchio frame name of MuJoCo body `b` (its name, or `body<id>` when unnamed)."""
    return m.body(b).name or f"body{b}"


def _ancestors(m: mujoco.MjModel, body: int) -> list[int]:
    """Bodies from the top-level one down to `body` (inclusive), without the world."""
    out = []
    while body != 0:
        out.append(body)
        body = int(m.body_parentid[body])
    return out[::-1]


def _path(m: mujoco.MjModel, base: int, tip: int, base_name: str, tip_name: str) -> list[int]:
    """Bodies from just below `base` down to `tip`, or a clear error if not an ancestor."""
    path = []
    b = tip
    while b != base:
        if b == 0:
            raise SpecError(
                f"base body {base_name!r} is not an ancestor of tip body {tip_name!r}: "
                "a chain runs from a base down to a tip in one kinematic tree"
                + _equality_hint(m, base, tip)
            )
        path.append(b)
        b = int(m.body_parentid[b])
    return path[::-1]


def _equality_hint(m: mujoco.MjModel, base: int, tip: int) -> str:
    """Name the equality constraint that ties the tip's tree to the base, if one does."""
    tip_tree = set(_subtree(m, int(m.body_rootid[tip])))
    base_side = set(_ancestors(m, base)) | set(_subtree(m, base))
    for e in range(m.neq):
        if int(m.eq_objtype[e]) != int(mujoco.mjtObj.mjOBJ_BODY):
            continue
        pair = {int(m.eq_obj1id[e]), int(m.eq_obj2id[e])}
        if pair & tip_tree and pair & base_side:
            name = m.equality(e).name or f"#{e}"
            return (
                f" (they are joined only by equality constraint {name!r}, which the Pinocchio "
                "model cannot represent)"
            )
    return ""


def _subtree(m: mujoco.MjModel, root: int) -> list[int]:
    """`root` and its descendants, in MuJoCo's body order (parents before children)."""
    members = [root]
    inside = {root}
    for k in range(root + 1, m.nbody):
        if int(m.body_parentid[k]) in inside:
            members.append(k)
            inside.add(k)
    return members


def _quat_matrix(quat: np.ndarray) -> np.ndarray:
    mat = np.empty(9)
    mujoco.mju_quat2Mat(mat, np.asarray(quat, float))
    return mat.reshape(3, 3)


def _body_inertia(m: mujoco.MjModel, b: int) -> pin.Inertia:
    """Body inertia in the body frame (MuJoCo stores it diagonal in the inertial frame)."""
    rot = _quat_matrix(m.body_iquat[b])
    inertia = rot @ np.diag(m.body_inertia[b]) @ rot.T
    return pin.Inertia(float(m.body_mass[b]), m.body_ipos[b].copy(), inertia)


def _align_z(axis: np.ndarray) -> np.ndarray:
    """A rotation whose z column is `axis` (unit), so a z-joint turns about it."""
    z = np.asarray(axis, float) / np.linalg.norm(axis)
    quat = np.empty(4)
    mujoco.mju_quatZ2Vec(quat, z)
    return _quat_matrix(quat)


def _rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
