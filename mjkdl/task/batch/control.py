"""Batched arm control on the device: one task arm's slice of the action, for every world.

The Cartesian-velocity action is the CPU env's QP (`CartesianVelocityController`, its
parameters read from the CPU env's controller): minimise
|J qd - v|² + λ(σ)|qd|² + |N (qd - k (q_ref - q))|² at the position command (the Jacobian by the
chain's kinematics there, as the CPU QP takes it in POSITION mode), in float64, the cost from
the eigendecomposition of JᵀJ (batched `torch.linalg.eigh`), the bounds (position limits,
velocity limits, acceleration window) by a batched primal-dual active-set method instead of
DAQP; it returns DAQP's solution within rounding once the active set settles (docs/task.md,
"Many worlds", gives the measured gap). The `avoid` collision rows are left out (task arms
have none). Joint modes write the command as the CPU env's `Robot` does: setpoint plus the
gravity feed-forward the servo needs.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import mujoco
import numpy as np
import torch

from ...errors import SpecError
from ...spec import CtrlMode
from ..env import _descends
from ..spec import Actuation, ArmSpec
from .engine import Engine, Tcp

if TYPE_CHECKING:
    from ..env import ArmEffector


def _frame(model: mujoco.MjModel, name: str) -> tuple[str, int]:
    """("site" or "body", id) of a control frame name, as the CPU controller resolves it."""
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if site >= 0:
        return "site", site
    return "body", mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)


class BatchArm:
    """One arm of a task over all worlds: its action slice into joint commands (`ctrl`).

    Built from the CPU env's effector, so the gains, limits, posture and actuators are those
    the CPU env uses; `reset_rows` takes the commands the CPU env synced at reset.
    """

    def __init__(self, eff: ArmEffector, model: mujoco.MjModel, state: Engine) -> None:
        robot, arm = eff.robot, eff.arm
        self.arm, self.slice, self.grip_index = arm, eff.slice, eff.grip_index
        self._state = state
        dev = state.device
        n = robot.n_joints
        self.n = n
        jids = [model.joint(name).id for name in robot.joint_names]
        types = {int(model.jnt_type[j]) for j in jids}
        hinge, slide = int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)
        if not types <= {hinge, slide}:
            raise SpecError(
                f"batched control of arm {arm.name!r} needs hinge or slide joints; its chain "
                "has ball or free joints"
            )
        self._jid = torch.tensor(jids, device=dev)
        self._qadr = torch.tensor(model.jnt_qposadr[jids], device=dev)
        self._dadr = torch.tensor(model.jnt_dofadr[jids], device=dev)
        self._hinge = torch.tensor(
            [int(model.jnt_type[j]) == hinge for j in jids], device=dev
        ).reshape(1, n, 1)
        self._all_hinge = bool(self._hinge.all())
        self._act = torch.tensor(robot.actuator_ids, device=dev)
        self._mode = robot.ctrl_mode
        # Feed-forward of the gravity torques into the servo setpoint, as the Robot adds it.
        self._ff = bool(robot.gravity_feedforward) and self._mode is not CtrlMode.TORQUE
        scale = robot.gravity_feedforward_scale
        self._ff_scale = torch.tensor(scale, device=dev, dtype=state.dtype)
        # () -> (nworld, n) torques holding the arm against gravity now, as the engine has them
        self.gravity_torques = state.gravity(eff, model, jids) or ChainGravity(model, jids, state)
        # The TCP: reference frame (tool site or tip body) and offset, as ArmReader has it.
        self._tcp = state.tcp_of(arm.name)
        self._chain = ChainKinematics(model, arm, jids, self._tcp, state)
        self._gripper = None
        if self.grip_index >= 0:  # a held gripper keeps the ctrl its reset state holds
            g = arm.gripper
            assert g is not None
            gid = model.actuator(arm.prefix + g.actuator).id
            self._gripper = (gid, float(g.open), float(g.closed), bool(g.binary))
        self._ctrl_frame = _frame(model, arm.control_frame) if arm.control_frame else None
        self.cartesian = eff.controller is not None
        nworld = state.nworld
        # The Cartesian solve runs in float64, as the CPU QP: JᵀJ's small eigenvalues count.
        f64 = torch.float64
        self.q_cmd = torch.zeros(nworld, n, device=dev, dtype=f64)
        if self.cartesian:
            assert eff.controller is not None
            c = eff.controller.settings
            self._lower = torch.tensor(c.joint_lower, device=dev, dtype=f64)
            self._upper = torch.tensor(c.joint_upper, device=dev, dtype=f64)
            self._vmax = torch.tensor(c.max_joint_velocity, device=dev, dtype=f64)
            self._posture = torch.tensor(c.posture, device=dev, dtype=f64)
            self._posture_gain = c.posture_gain
            self._limit_gain, self._horizon = c.limit_gain, c.limit_horizon
            self._amax = c.max_joint_acceleration
            self._damping = c.damping
            self._sing = (c.singular_damping, c.singular_threshold)
            self._last = torch.zeros(nworld, n, device=dev, dtype=f64)
            self._eye = torch.eye(n, device=dev, dtype=f64)
            # The action's entries in the twist; the axes it omits stay zero.
            self._axes = torch.tensor(eff.axes, device=dev, dtype=torch.long)
            self._full = torch.zeros(nworld, 6, device=dev, dtype=f64)

    def reset_rows(self, rows: torch.Tensor, q_cmd: np.ndarray, qd: np.ndarray) -> None:
        """Worlds `rows` start an episode at command `q_cmd` with joint velocities `qd`
        (arrays of one row per world: what the CPU env synced at reset)."""
        dev = self._state.device
        self.q_cmd[rows] = torch.as_tensor(q_cmd, device=dev, dtype=self.q_cmd.dtype)
        if self.cartesian:
            self._last[rows] = torch.as_tensor(qd, device=dev, dtype=self._last.dtype)

    def jacobian(self, q: torch.Tensor | None = None) -> torch.Tensor:
        """(nworld, 6, n) world-aligned Jacobian of the TCP point (linear rows first): at
        the current state, or at joint positions `q` (float64) by the chain's kinematics."""
        s = self._state
        if q is None:
            tcp = s.tcp_pos(self._tcp)  # (N, 3)
            anchor = s.xanchor[:, self._jid]
            axis = s.xaxis[:, self._jid]
        else:
            anchor, axis, tcp = self._chain(q)
        lin_h = torch.linalg.cross(axis, tcp.unsqueeze(1) - anchor, dim=-1)
        if self._all_hinge:
            return torch.cat([lin_h, axis], dim=-1).transpose(1, 2)
        lin = torch.where(self._hinge, lin_h, axis)
        ang = torch.where(self._hinge, axis, torch.zeros_like(axis))
        return torch.cat([lin, ang], dim=-1).transpose(1, 2)

    def apply(self, action: torch.Tensor, period: float) -> None:
        """Write this arm's slice of the physical (clipped) action into `ctrl`."""
        s = self._state
        a = action[:, self.slice]
        if self.cartesian:
            # In POSITION mode the CPU QP works at the command (what the integration
            # advances and keeps inside the limits), the Jacobian too.
            self._full[:, self._axes] = a.double()
            qd = self._solve(self._full, self.q_cmd, period)
            # In place: a learner may step inside torch.inference_mode, and a tensor made
            # there could not be written by a reset outside it.
            self.q_cmd.copy_(torch.clamp(self.q_cmd + qd * period, self._lower, self._upper))
            cmd = self.q_cmd.to(s.dtype)
        elif self.arm.actuation is Actuation.JOINT_TORQUE:
            cmd = a + self.gravity_torques()
        else:
            cmd = a
        if self._ff:
            cmd = cmd + self.gravity_torques() * self._ff_scale
        s.ctrl[:, self._act] = cmd
        if self._gripper is not None:
            gid, open_, closed, binary = self._gripper
            g = action[:, self.grip_index]
            if binary:
                g = (g >= 0.5).to(g.dtype)
            s.ctrl[:, gid] = open_ + g * (closed - open_)

    def _twist(self, a: torch.Tensor) -> torch.Tensor:
        if self._ctrl_frame is None:
            return a
        kind, i = self._ctrl_frame
        rot = (self._state.site_xmat if kind == "site" else self._state.xmat)[:, i].double()
        return torch.cat([(rot @ a[:, :3, None])[..., 0], (rot @ a[:, 3:, None])[..., 0]], 1)

    def _solve(self, twist: torch.Tensor, q: torch.Tensor, dt: float) -> torch.Tensor:
        """The CPU QP: its cost in closed form, its bounds by `_box_qp`."""
        v = self._twist(twist)
        J = self.jacobian(q)
        eig, vec = torch.linalg.eigh(J.transpose(1, 2) @ J)  # ascending, as LAPACK's dsyev
        n_null = max(0, self.n - 6)
        sigma = torch.sqrt(torch.clamp(eig[:, n_null], min=0.0))
        damp, threshold = self._sing
        ratio = sigma / threshold
        # Damping grows as the smallest singular value falls below the threshold.
        lam = self._damping + damp * torch.clamp(1.0 - ratio * ratio, min=0.0)
        d = eig + lam.unsqueeze(1)
        f = (J.transpose(1, 2) @ v.unsqueeze(-1))[..., 0]
        if n_null:
            d[:, :n_null] += 1.0
            null = vec[:, :, :n_null]
            post = (self._posture - q) * self._posture_gain
            f = f + (null @ (null.transpose(1, 2) @ post.unsqueeze(-1)))[..., 0]
        H = (vec * d.unsqueeze(1)) @ vec.transpose(1, 2)  # V diag(d) Vᵀ
        # Bounds: position limits within one period (limit_gain of the gap), velocity limits,
        # then the acceleration window around the last solution (the limits win a clash).
        reach = self._limit_gain / max(dt, self._horizon)
        ub = torch.minimum((self._upper - q) * reach, self._vmax)
        lb = torch.maximum((self._lower - q) * reach, -self._vmax)
        if math.isfinite(self._amax):
            step = self._amax * dt
            wub = torch.minimum(ub, self._last + step)
            wlb = torch.maximum(lb, self._last - step)
            clash = wlb > wub
            pinned = torch.where(wlb > self._last, wlb, wub)  # the bound the window missed
            ub = torch.where(clash, pinned, wub)
            lb = torch.where(clash, pinned, wlb)
        qd = _box_qp(H, f, lb, ub, self._eye)
        self._last.copy_(qd)
        return qd


class ChainGravity:
    """(nworld, n) gravity torques of one arm from the engine's poses: each chain joint
    carries the bodies of its subtree (weights: mass less MuJoCo's gravcomp share), the
    torque is axis · Σ m (com - anchor) × (-g), in the engine's dtype."""

    def __init__(self, model: mujoco.MjModel, jids: list[int], state: Engine) -> None:
        dev, dtype = state.device, state.dtype
        self._state = state
        n = len(jids)
        weights = np.zeros((n, model.nbody))
        for i, j in enumerate(jids):
            top = int(model.jnt_bodyid[j])
            for b in range(model.nbody):
                if _descends(model, b, top):
                    weights[i, b] = model.body_mass[b] * (1.0 - model.body_gravcomp[b])
        self._jid = torch.tensor(jids, device=dev)
        hinge = int(mujoco.mjtJoint.mjJNT_HINGE)
        self._hinge = torch.tensor([int(model.jnt_type[j]) == hinge for j in jids], device=dev)
        self._mass = torch.tensor(weights, device=dev, dtype=dtype)
        self._gravity = torch.tensor(model.opt.gravity, device=dev, dtype=dtype)

    def __call__(self) -> torch.Tensor:
        s = self._state
        com = s.xipos  # (N, nbody, 3)
        anchor = s.xanchor[:, self._jid]  # (N, n, 3)
        axis = s.xaxis[:, self._jid]
        moment = torch.einsum("jb,wbk->wjk", self._mass, com)  # Σ m com, per joint
        total = self._mass.sum(dim=1).reshape(1, -1, 1)
        lever = moment - total * anchor  # Σ m (com - anchor)
        force = -self._gravity.reshape(1, 1, 3).expand_as(lever)
        hinge = (axis * torch.linalg.cross(lever, force, dim=-1)).sum(-1)
        slide = (axis * force).sum(-1) * total.squeeze(-1)
        return torch.where(self._hinge, hinge, slide)


ACTIVE_SET_PASSES = 10


def _box_qp(
    H: torch.Tensor, f: torch.Tensor, lb: torch.Tensor, ub: torch.Tensor, eye: torch.Tensor
) -> torch.Tensor:
    """min ½ qdᵀH qd - fᵀqd within [lb, ub], batched: a primal-dual active-set method (joints
    past a bound are pinned there, pinned joints whose multiplier has the wrong sign are
    freed, the rest re-solved) for up to `ACTIVE_SET_PASSES` passes, then a final clip. Exact
    once the active set settles (the KKT conditions then hold in every world)."""
    qd = torch.linalg.solve(H, f)  # the first pass: nothing pinned
    over, under = qd > ub, qd < lb
    if not bool((over | under).any()):
        return qd
    side = torch.where(over, 1.0, torch.where(under, -1.0, torch.zeros_like(f)))  # +1 at ub
    for _ in range(ACTIVE_SET_PASSES - 1):
        free = side == 0
        pinned = torch.where(free, 0.0, torch.where(side > 0, ub, lb))
        # Pinned rows become identity rows holding the bound; free rows see them as known.
        A = torch.where(free.unsqueeze(2) & free.unsqueeze(1), H, eye)
        rhs = torch.where(free, f - (H @ pinned.unsqueeze(-1)).squeeze(-1), pinned)
        qd = torch.linalg.solve(A, rhs)
        grad = (H @ qd.unsqueeze(-1)).squeeze(-1) - f
        release = side * grad > 0  # a pinned joint whose multiplier has the wrong sign
        over, under = (qd > ub) & free, (qd < lb) & free
        if not bool((release | over | under).any()):
            return qd
        side = torch.where(over, 1.0, torch.where(under, -1.0, torch.where(release, 0.0, side)))
    return torch.maximum(torch.minimum(qd, ub), lb)


def _rotation(quat: np.ndarray) -> np.ndarray:
    out = np.empty(9)
    mujoco.mju_quat2Mat(out, quat)
    return out.reshape(3, 3)


class ChainKinematics:
    """The chain's joint anchors, axes and TCP at given joint positions, in float64, from the
    model's body offsets (MuJoCo's `mj_kinematics` along the chain), starting from the base's
    parent as it is now: the Jacobian at the command, where the CPU QP takes it.

    Each body's fixed rotation and its joint's rotation are one matrix, `brot R(angle)` =
    `brot + sin brot K + (1 - cos) brot K²` (Rodrigues, K the axis' cross-product matrix),
    made for every joint at once; the walk down the chain is then one product per body."""

    def __init__(
        self, model: mujoco.MjModel, arm: ArmSpec, jids: list[int], tcp: Tcp, state: Engine
    ) -> None:
        dev, f64 = state.device, torch.float64
        self._state = state
        base = model.body(arm.prefix + arm.base_body).id
        path, b = [], model.body(arm.prefix + arm.tip_body).id
        while True:
            path.append(b)
            if b == base or b == 0:
                break
            b = int(model.body_parentid[b])
        path.reverse()
        self._parent = int(model.body_parentid[base])
        index = {j: i for i, j in enumerate(jids)}
        n = len(jids)
        fixed, k, k2 = np.zeros((n, 3, 3)), np.zeros((n, 3, 3)), np.zeros((n, 3, 3))
        q0, self._slides = np.zeros(n), []
        self._pivots: dict[int, torch.Tensor] = {}  # hinges off their body's origin: jnt_pos
        along, at = np.zeros((n, 3)), np.zeros((n, 3))  # axis and anchor in the parent frame
        self._steps: list[tuple[torch.Tensor | None, int, torch.Tensor | None]] = []
        if tcp.site >= 0:
            ref_body = int(model.site_bodyid[tcp.site])
            site_pos, site_rot = model.site_pos[tcp.site], _rotation(model.site_quat[tcp.site])
        else:
            ref_body, site_pos, site_rot = tcp.body, np.zeros(3), np.eye(3)
        if ref_body not in path:
            raise SpecError(f"arm {arm.name!r}: the TCP's site is not on the chain's bodies")
        for b in path:
            joints = range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b])
            if any(j not in index for j in joints) or len(joints) > 1:
                raise SpecError(
                    f"batched Cartesian control of arm {arm.name!r} needs one chain joint (or "
                    f"none) per body; body {model.body(b).name!r} has other joints"
                )
            brot = _rotation(model.body_quat[b])
            bpos = model.body_pos[b]
            shift = None if not bpos.any() else torch.tensor(bpos, device=dev, dtype=f64)
            if not len(joints):
                self._steps.append((shift, -1, torch.tensor(brot, device=dev, dtype=f64)))
            else:
                j = joints[0]
                i = index[j]
                axis, jpos = model.jnt_axis[j], model.jnt_pos[j]
                fixed[i], along[i], at[i] = brot, brot @ axis, brot @ jpos
                q0[i] = model.qpos0[model.jnt_qposadr[j]]
                if int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE):
                    cross = _cross_matrix(axis)
                    k[i], k2[i] = brot @ cross, brot @ cross @ cross
                    if jpos.any():  # the body turns about its anchor, off its frame's origin
                        self._pivots[i] = torch.tensor(jpos, device=dev, dtype=f64)
                else:
                    self._slides.append(i)
                self._steps.append((shift, i, None))
            if b == ref_body:
                # The TCP in this body's frame: the site's pose, then the tool's offset.
                tip = site_pos + site_rot @ tcp.offset.double().cpu().numpy()
                self._tip = torch.tensor(tip, device=dev, dtype=f64)
                self._tip_index = len(self._steps)
        self._fixed, self._k, self._k2 = (
            torch.tensor(x, device=dev, dtype=f64) for x in (fixed, k, k2)
        )
        self._q0 = torch.tensor(q0, device=dev, dtype=f64)
        self._along = torch.tensor(along, device=dev, dtype=f64).unsqueeze(-1)
        self._at = torch.tensor(at, device=dev, dtype=f64).unsqueeze(-1) if at.any() else None
        self._n = n

    def __call__(self, q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(anchors (N, n, 3), axes (N, n, 3), TCP (N, 3)) at joint positions `q` (N, n)."""
        s = self._state
        pos = s.xpos[:, self._parent].double()
        rot = s.xmat[:, self._parent].double()
        angle = q - self._q0
        sin = torch.sin(angle)[..., None, None]
        turned = self._fixed + sin * self._k + (1.0 - torch.cos(angle))[..., None, None] * self._k2
        frames: list[torch.Tensor] = [rot] * self._n  # each joint's parent frame
        origins: list[torch.Tensor] = [pos] * self._n
        tcp = pos
        for k, (shift, i, brot) in enumerate(self._steps):
            if shift is not None:
                pos = pos + rot @ shift
            if i < 0:
                rot = rot @ brot  # type: ignore[operator]
            else:
                frames[i], origins[i] = rot, pos
                rot = rot @ turned[:, i]
                if i in self._slides:
                    pos = pos + (frames[i] @ self._along[i])[..., 0] * angle[:, i : i + 1]
                elif i in self._pivots:  # the anchor stays where it is
                    pos = pos + frames[i] @ self._at[i, :, 0] - rot @ self._pivots[i]  # type: ignore[index]
            if k + 1 == self._tip_index:
                tcp = pos + rot @ self._tip
        parents = torch.stack(frames, 1)
        axes = (parents @ self._along)[..., 0]
        anchors = torch.stack(origins, 1)
        if self._at is not None:
            anchors = anchors + (parents @ self._at)[..., 0]
        return anchors, axes, tcp


def _cross_matrix(axis: np.ndarray) -> np.ndarray:
    x, y, z = (float(v) for v in axis)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


class ActionLatency:
    """Each world's actions applied its episode's `action_latency` control steps late, all
    worlds at once (the CPU env's `Randomizer.action`): a ring of the last `most` + 1 actions
    per world, the episode's first action filling it, so until `latency` steps have passed
    the first action is applied."""

    def __init__(self, latency: torch.Tensor, n: int, most: int, dtype: torch.dtype) -> None:
        self.latency = latency
        """(nworld,) long: each world's latency this episode (its reset's draw)."""
        nworld, dev = len(latency), latency.device
        self._ring = torch.zeros(nworld, most + 1, n, dtype=dtype, device=dev)
        self._age = torch.zeros(nworld, dtype=torch.long, device=dev)  # steps this episode
        self._worlds = torch.arange(nworld, device=dev)

    def restart(self, rows: torch.Tensor) -> None:
        """Worlds `rows` (a bool mask) start an episode: their next action fills the ring."""
        self._age[rows] = 0

    def __call__(self, action: torch.Tensor) -> torch.Tensor:
        """The actions applied this step, given this step's `action` of every world."""
        ring, age, size = self._ring, self._age, self._ring.shape[1]
        first = age == 0
        ring[first] = action[first].unsqueeze(1)
        ring[self._worlds, age % size] = action
        out = ring[self._worlds, (age - self.latency) % size]  # written `latency` steps ago
        age += 1
        return out
