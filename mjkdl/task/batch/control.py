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
        if eff.gripper is not None:
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
        lam = self._damping + torch.where(
            sigma < threshold, damp * (1.0 - ratio * ratio), torch.zeros_like(sigma)
        )
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
    side = torch.zeros_like(f)  # +1 pinned at ub, -1 at lb, 0 free
    qd = f
    for _ in range(ACTIVE_SET_PASSES):
        pinned = side != 0
        value = torch.where(side > 0, ub, torch.where(side < 0, lb, torch.zeros_like(f)))
        free = (~pinned).to(H.dtype)
        # Pinned rows become identity rows holding the bound; free rows see them as known.
        A = H * free.unsqueeze(2) * free.unsqueeze(1) + eye * (1.0 - free).unsqueeze(2)
        rhs = torch.where(pinned, value, f - (H @ (value * (1.0 - free)).unsqueeze(-1))[..., 0])
        qd = torch.linalg.solve(A, rhs)
        grad = (H @ qd.unsqueeze(-1))[..., 0] - f
        release = ((side > 0) & (grad > 0)) | ((side < 0) & (grad < 0))
        over, under = (qd > ub) & ~pinned, (qd < lb) & ~pinned
        if not bool((release | over | under).any()):
            return qd
        side = torch.where(release, torch.zeros_like(side), side)
        side = torch.where(
            over, torch.ones_like(side), torch.where(under, -torch.ones_like(side), side)
        )
    return torch.maximum(torch.minimum(qd, ub), lb)


def _rotation(quat: np.ndarray) -> np.ndarray:
    out = np.empty(9)
    mujoco.mju_quat2Mat(out, quat)
    return out.reshape(3, 3)


class ChainKinematics:
    """The chain's joint anchors, axes and TCP at given joint positions, in float64, from the
    model's body offsets (MuJoCo's `mj_kinematics` along the chain), starting from the base's
    parent as it is now: the Jacobian at the command, where the CPU QP takes it."""

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
        self._steps = []
        for b in path:
            joints = range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b])
            if any(j not in index for j in joints) or len(joints) > 1:
                raise SpecError(
                    f"batched Cartesian control of arm {arm.name!r} needs one chain joint (or "
                    f"none) per body; body {model.body(b).name!r} has other joints"
                )
            j = joints[0] if len(joints) else -1
            hinge = j >= 0 and int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE)
            self._steps.append(
                (
                    b,
                    torch.tensor(model.body_pos[b], device=dev, dtype=f64),
                    torch.tensor(_rotation(model.body_quat[b]), device=dev, dtype=f64),
                    index.get(j, -1),
                    torch.tensor(
                        model.jnt_pos[j] if j >= 0 else np.zeros(3), device=dev, dtype=f64
                    ),
                    torch.tensor(
                        model.jnt_axis[j] if j >= 0 else np.zeros(3), device=dev, dtype=f64
                    ),
                    float(model.qpos0[model.jnt_qposadr[j]]) if j >= 0 else 0.0,
                    hinge,
                    _cross_matrix(model.jnt_axis[j] if j >= 0 else np.zeros(3), dev),
                )
            )
        if tcp.site >= 0:
            self._ref_body = int(model.site_bodyid[tcp.site])
            site_pos, site_rot = model.site_pos[tcp.site], _rotation(model.site_quat[tcp.site])
        else:
            self._ref_body, site_pos, site_rot = tcp.body, np.zeros(3), np.eye(3)
        if self._ref_body not in path:
            raise SpecError(f"arm {arm.name!r}: the TCP's site is not on the chain's bodies")
        self._site_pos = torch.tensor(site_pos, device=dev, dtype=f64)
        self._site_rot = torch.tensor(site_rot, device=dev, dtype=f64)
        self._offset = tcp.offset.double()
        self._n = len(jids)

    def __call__(self, q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(anchors (N, n, 3), axes (N, n, 3), TCP (N, 3)) at joint positions `q` (N, n)."""
        s = self._state
        pos = s.xpos[:, self._parent].double()
        rot = s.xmat[:, self._parent].double()
        anchors = [torch.zeros_like(pos)] * self._n
        axes = [torch.zeros_like(pos)] * self._n
        ref_pos, ref_rot = pos, rot
        for body, bpos, brot, i, jpos, jaxis, q0, hinge, cross in self._steps:
            pos = pos + (rot @ bpos)
            rot = rot @ brot
            if i >= 0:
                anchor = pos + rot @ jpos
                axis = rot @ jaxis
                anchors[i], axes[i] = anchor, axis
                angle = q[:, i] - q0
                if hinge:
                    rot = rot @ _axis_rotation(cross, angle)
                    pos = anchor - rot @ jpos
                else:
                    pos = pos + axis * angle.unsqueeze(1)
            if body == self._ref_body:
                ref_pos = pos + rot @ self._site_pos
                ref_rot = rot @ self._site_rot
        tcp = ref_pos + ref_rot @ self._offset
        return torch.stack(anchors, 1), torch.stack(axes, 1), tcp


def _cross_matrix(axis: np.ndarray, device: str) -> torch.Tensor:
    x, y, z = (float(v) for v in axis)
    k = [[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]]
    return torch.tensor(k, dtype=torch.float64, device=device)


def _axis_rotation(cross: torch.Tensor, angle: torch.Tensor) -> torch.Tensor:
    """(N, 3, 3) rotations by `angle` (N,) about the unit axis whose cross-product matrix is
    `cross`: Rodrigues' formula."""
    c, s = torch.cos(angle)[:, None, None], torch.sin(angle)[:, None, None]
    eye = torch.eye(3, dtype=angle.dtype, device=angle.device)
    return eye + s * cross + (1.0 - c) * (cross @ cross)


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
