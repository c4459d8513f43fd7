"""Extract a Pinocchio model of a serial chain from a *compiled* MuJoCo model.

The chain runs from a base body to a tip body. Each MuJoCo hinge or slide joint becomes a
Pinocchio revolute/prismatic joint about z, with the axis alignment, the joint anchor and the
joint reference (`qpos0`) folded into the joint placement, so a Pinocchio q equals MuJoCo's
qpos. Bodies hanging off the chain (the tool below the tip, side branches) join the inertia
of the link they hang from: rigid ones once, jointed ones (gripper fingers) at their current
configuration on every `refresh_inertias`.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from .errors import SpecError, unknown_name

_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
_SLIDE = int(mujoco.mjtJoint.mjJNT_SLIDE)
# Jointed subtrees (fingers) are re-lumped once their joints moved this far (rad or m) since
# the last time: far below any effect on gravity or inertia that a test could resolve.
RELUMP_TOL = 1e-9
# Pinocchio's dynamic parameters are [m, mc, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]; MuJoCo's
# cinert/crb rows are [Ixx, Iyy, Izz, Ixy, Ixz, Iyz, mc, m], both about the same origin.
_CRB_TO_PIN = np.array([9, 6, 7, 8, 0, 3, 1, 4, 5, 2])


@dataclass
class _JointedSubtree:
    """A subtree with joints of its own (gripper fingers) hanging off one chain body."""

    root: int  # MuJoCo body id of the subtree's root
    body: int  # MuJoCo chain body it hangs from
    joint: int  # Pinocchio joint that carries that body
    joint_in_body: pin.SE3  # placement of the Pinocchio joint frame in `body`


class Chain:
    """A Pinocchio model of the chain `base_body` → `tip_body` of a compiled `MjModel`."""

    def __init__(
        self,
        mj_model: mujoco.MjModel,
        mj_data: mujoco.MjData,
        base_body: str,
        tip_body: str,
        tcp_site: str = "",
        tcp_offset: pin.SE3 | None = None,
    ) -> None:
        self.base = _body_id(mj_model, base_body)
        self.tip = _body_id(mj_model, tip_body)
        path = _path(mj_model, self.base, self.tip, base_body, tip_body)
        self.model = pin.Model()
        self.model.name = f"{base_body}->{tip_body}"
        self.model.gravity = pin.Motion(np.asarray(mj_model.opt.gravity, float), np.zeros(3))
        self.joint_ids: list[int] = []
        self._subtrees: list[_JointedSubtree] = []
        self._build(mj_model, mj_data, path)
        if not self.joint_ids:
            raise SpecError(f"the chain {base_body!r} -> {tip_body!r} has no joints")
        self.qpos_adr = np.array([mj_model.jnt_qposadr[j] for j in self.joint_ids])
        self.dof_adr = np.array([mj_model.jnt_dofadr[j] for j in self.joint_ids])
        self.joint_names = [mj_model.joint(j).name for j in self.joint_ids]
        self.tip_frame = self._body_frames[self.tip]
        self.tcp_frame = self.tip_frame
        if tcp_site:
            self.tcp_frame = self._add_site_frame(mj_model, tcp_site)
        if tcp_offset is not None:
            host = self.model.frames[self.tcp_frame]
            self.tcp_frame = self.model.addFrame(
                pin.Frame(
                    f"{host.name}_tcp", host.parentJoint, host.placement * tcp_offset, pin.OP_FRAME
                )
            )
        self._static_inertias = [pin.Inertia(y) for y in self.model.inertias]
        joints = sorted({sub.joint for sub in self._subtrees})
        self._subtrees_by_joint = [
            (j, [sub for sub in self._subtrees if sub.joint == j]) for j in joints
        ]
        self._origin = pin.SE3.Identity()
        self._subtree_qpos = _qpos_span(mj_model, [sub.root for sub in self._subtrees])
        # A view kept from construction: MjData's array properties build a new wrapper on
        # every access, which the per-step check below would pay each time.
        self._data = mj_data
        span = self._subtree_qpos
        self._subtree_q = mj_data.qpos[span] if isinstance(span, slice) else None
        nsub = len(mj_data.qpos[span])
        self._lumped_q = np.full(nsub, np.nan)  # NaN: nothing lumped yet
        self._dq = np.zeros(nsub)
        # A base carried by joints of its own (a mobile base, another robot) moves: keep the
        # root placements relative to it and re-place them on every refresh.
        self.base_moves = bool(mj_model.body_weldid[self.base] != 0)
        base_inv = _body_pose(mj_data, self.base).inverse()
        self._root_joints = [
            (j, base_inv * self.model.jointPlacements[j])
            for j in range(1, self.model.njoints)
            if self.model.parents[j] == 0
        ]
        self._root_frames = [
            (f, base_inv * frame.placement)
            for f, frame in enumerate(self.model.frames)
            if frame.parentJoint == 0 and f > 0
        ]
        self.refresh(mj_model, mj_data)

    # ------------------------------------------------------------------ building

    def _build(self, m: mujoco.MjModel, d: mujoco.MjData, path: list[int]) -> None:
        on_path = set(path) | {self.base}
        # Placement of the current MuJoCo body frame in the current Pinocchio joint frame;
        # the universe frame is MuJoCo's world, so the base pose comes first.
        parent = 0
        frame = self.model.addFrame(
            pin.Frame(_frame_name(m, self.base), 0, 0, _body_pose(d, self.base), pin.BODY)
        )
        self._body_frames = {self.base: frame}  # MuJoCo body id -> Pinocchio frame id
        acc = _body_pose(d, self.base)
        for b in path:
            acc = acc * pin.SE3(_quat_matrix(m.body_quat[b]), m.body_pos[b].copy())
            for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]):
                parent, acc = self._add_joint(m, j, parent, acc)
            self.model.appendBodyToJoint(parent, _body_inertia(m, b), acc)
            frame = self.model.addBodyFrame(_frame_name(m, b), parent, acc, frame)
            self._body_frames[b] = frame
            self._lump_branches(m, b, parent, acc, on_path)

    def _add_joint(
        self, m: mujoco.MjModel, j: int, parent: int, acc: pin.SE3
    ) -> tuple[int, pin.SE3]:
        jtype = int(m.jnt_type[j])
        name = m.joint(j).name or f"joint{j}"
        if jtype not in (_HINGE, _SLIDE):
            kind = mujoco.mjtJoint(jtype).name
            raise SpecError(
                f"joint {name!r} is a {kind} joint: a chain takes only hinge and slide joints"
            )
        align = _align_z(m.jnt_axis[j])
        q0 = float(m.qpos0[m.jnt_qposadr[j]])
        if jtype == _HINGE:
            # MuJoCo rotates about the axis through the anchor by (qpos - qpos0).
            to_joint = pin.SE3(align, m.jnt_pos[j].copy())
            ref = pin.SE3(_rot_z(-q0), np.zeros(3))
            model = pin.JointModelRZ()
        else:
            to_joint = pin.SE3(align, np.zeros(3))
            ref = pin.SE3(np.eye(3), np.array([0.0, 0.0, -q0]))
            model = pin.JointModelPZ()
        lo, hi = (m.jnt_range[j] if m.jnt_limited[j] else (-np.inf, np.inf))
        big = np.array([np.inf])
        jid = self.model.addJoint(
            parent, model, acc * to_joint * ref, name, big, big, np.array([lo]), np.array([hi])
        )
        self.model.armature[self.model.idx_vs[jid]] = m.dof_armature[m.jnt_dofadr[j]]
        self.joint_ids.append(j)
        return jid, to_joint.inverse()

    def _lump_branches(
        self, m: mujoco.MjModel, b: int, joint: int, body_in_joint: pin.SE3, on_path: set[int]
    ) -> None:
        """Add the inertia of every child subtree of chain body `b` that is off the path."""
        for child in np.flatnonzero(m.body_parentid == b):
            if child in on_path or child == b:
                continue
            members = _subtree(m, int(child))
            if any(m.body_jntnum[k] for k in members):
                sub = _JointedSubtree(int(child), b, joint, body_in_joint.inverse())
                self._subtrees.append(sub)
            else:
                for k in members:
                    rel = _relative_pose(m, b, k)
                    self.model.appendBodyToJoint(joint, _body_inertia(m, k), body_in_joint * rel)

    def _add_site_frame(self, m: mujoco.MjModel, site: str) -> int:
        s = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, site)
        if s < 0:
            known = [m.site(k).name for k in range(m.nsite)]
            raise unknown_name("site", site, known, where="the model (tool.tcp_site)")
        body = int(m.site_bodyid[s])
        between = [body]  # bodies from the site's up to the first chain body
        while between[-1] not in self._body_frames:
            if between[-1] == 0:
                raise SpecError(
                    f"TCP site {site!r} (body {m.body(body).name!r}) is not on the chain or "
                    f"below its tip {m.body(self.tip).name!r}"
                )
            between.append(int(m.body_parentid[between[-1]]))
        anchor = between.pop()
        if any(m.body_jntnum[b] for b in between):
            raise SpecError(
                f"TCP site {site!r} is on body {m.body(body).name!r}, which moves relative "
                "to the chain through joints outside it (fingers, links beyond the tip): "
                "choose a site rigidly fixed to the chain or its tool"
            )
        host = self.model.frames[self._body_frames[anchor]]
        site_in_body = pin.SE3(_quat_matrix(m.site_quat[s]), m.site_pos[s].copy())
        placement = host.placement * _relative_pose(m, anchor, body) * site_in_body
        return self.model.addFrame(pin.Frame(site, host.parentJoint, placement, pin.OP_FRAME))

    # ------------------------------------------------------------------ runtime

    def invalidate(self) -> None:
        """Forget the lumped subtree inertia: MuJoCo's data changed behind our back."""
        if self._subtrees:
            self._lumped_q.fill(np.nan)

    def refresh(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        """Follow MuJoCo's last computed state: jointed subtrees' inertia and a moving base.

        A subtree's inertia is MuJoCo's composite rigid-body inertia `crb` of its root (about
        the kinematic tree's `subtree_com`, world axes), which `mj_forward`/`mj_step` already
        computed, so no kinematics is repeated here.
        """
        if self.base_moves:
            base = _body_pose(d, self.base)
            for j, rel in self._root_joints:
                self.model.jointPlacements[j] = base * rel
            for f, rel in self._root_frames:
                frame = self.model.frames[f]
                frame.placement = base * rel
                self.model.frames[f] = frame
        if not self._subtrees:
            return
        # The lumped inertia, in the frame of the joint carrying it, depends only on the
        # subtree's own joints: re-lump when they moved by more than RELUMP_TOL since.
        q = self._subtree_q
        if q is None or d is not self._data:
            q = d.qpos[self._subtree_qpos]
        dq = self._dq
        np.subtract(q, self._lumped_q, out=dq)
        if dq.dot(dq) <= RELUMP_TOL * RELUMP_TOL:
            return
        if d.crb[self._subtrees[0].root, 9] <= 0.0:
            return  # not computed yet (reset data, no mj_forward since): nothing to lump from
        np.copyto(self._lumped_q, q)
        inertias = self.model.inertias
        origin = self._origin
        for joint, subtrees in self._subtrees_by_joint:
            total = self._static_inertias[joint]
            for sub in subtrees:
                about_origin = pin.Inertia.FromDynamicParameters(d.crb[sub.root][_CRB_TO_PIN])
                origin.translation = d.subtree_com[m.body_rootid[sub.root]]
                joint_in_world = _body_pose(d, sub.body) * sub.joint_in_body
                total = total + joint_in_world.actInv(origin).act(about_origin)
            inertias[joint] = total


# ---------------------------------------------------------------------------- helpers


def _frame_name(m: mujoco.MjModel, b: int) -> str:
    """Pinocchio frame name of MuJoCo body `b` (its name, or `body<id>` when unnamed)."""
    return m.body(b).name or f"body{b}"


def _body_id(m: mujoco.MjModel, name: str) -> int:
    i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
    if i < 0:
        known = [m.body(k).name for k in range(m.nbody)]
        raise unknown_name("body", name, known, where="the model")
    return i


def _path(m: mujoco.MjModel, base: int, tip: int, base_name: str, tip_name: str) -> list[int]:
    """Bodies from just below `base` down to `tip`, or a clear error if not an ancestor."""
    path = []
    b = tip
    while b != base:
        if b == 0:
            raise SpecError(
                f"base body {base_name!r} is not an ancestor of tip body {tip_name!r}: "
                "a chain runs from a base down to a tip in one kinematic tree"
            )
        path.append(b)
        b = int(m.body_parentid[b])
    return path[::-1]


def _qpos_span(m: mujoco.MjModel, roots: list[int]) -> slice | np.ndarray:
    """qpos addresses of every joint in the subtrees under `roots` (a slice when contiguous)."""
    adr = sorted(
        a
        for root in roots
        for b in _subtree(m, root)
        for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])
        for a in range(m.jnt_qposadr[j], m.jnt_qposadr[j] + joint_sizes(int(m.jnt_type[j]))[0])
    )
    if adr and adr == list(range(adr[0], adr[-1] + 1)):
        return slice(adr[0], adr[-1] + 1)
    return np.array(adr, dtype=int)


def joint_sizes(jtype: int) -> tuple[int, int]:
    """(nq, nv) of a MuJoCo joint type."""
    return {
        int(mujoco.mjtJoint.mjJNT_FREE): (7, 6),
        int(mujoco.mjtJoint.mjJNT_BALL): (4, 3),
    }.get(jtype, (1, 1))


def _subtree(m: mujoco.MjModel, root: int) -> list[int]:
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


def _body_pose(d: mujoco.MjData, b: int) -> pin.SE3:
    return pin.SE3(d.xmat[b].reshape(3, 3), d.xpos[b])


def _relative_pose(m: mujoco.MjModel, ancestor: int, body: int) -> pin.SE3:
    """Pose of `body` in `ancestor` through jointless bodies (their model offsets)."""
    pose = pin.SE3.Identity()
    while body != ancestor:
        pose = pin.SE3(_quat_matrix(m.body_quat[body]), m.body_pos[body].copy()) * pose
        body = int(m.body_parentid[body])
    return pose


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
