"""Limit-respecting inverse kinematics on a Pinocchio serial chain.

:class:`IKSolver` runs Levenberg–Marquardt on the SE(3) pose error with Sugihara's adaptive
damping λ = c·|e|² + w.  Each step is the minimiser of the damped Gauss–Newton model subject
to the joint limits: a small box-constrained QP solved by MuJoCo's ``mju_boxQP``, so a joint
that reaches a limit stays there while the others keep converging (clipping the free step
instead left ~4% of first attempts stalled on the Kinova Gen3).  An attempt whose error stops
improving is restarted from deterministic random seeds inside the limits; the best attempt is
returned.

The hot loop is a dozen C calls per iteration: the world-frame joint Jacobian is read from
``data.J`` without a copy, the error is the world twist ``log6(oMf · target⁻¹)`` that this
Jacobian maps joint velocities to, and the QP is posed in absolute joint positions so its box
is the joint limits themselves and its solution is written straight into q.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from mjkdl.errors import SpecError

__all__ = ["IKResult", "IKSolver"]


@dataclass(frozen=True)
class IKResult:
    """Outcome of one :meth:`IKSolver.solve` call."""

    q: np.ndarray  # solution (best found, even when not successful)
    success: bool
    iterations: int  # total over all attempts
    restarts: int  # number of extra seeds tried
    position_error: float  # metres, final
    rotation_error: float  # radians, final


def _clip(q: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
    """Clip `q` into [lo, hi] in place (ufuncs: np.clip is several times slower on 7 values)."""
    np.maximum(q, lo, out=q)
    np.minimum(q, hi, out=q)


def _limit_vector(name: str, value: np.ndarray, nq: int) -> np.ndarray:
    arr = np.array(value, dtype=float).reshape(-1)
    if arr.shape != (nq,):
        raise SpecError(f"{name} must have length {nq}, got shape {np.shape(value)}")
    if np.isnan(arr).any():
        raise SpecError(f"{name} must not contain NaN")
    return arr


class IKSolver:
    """Damped, box-constrained Gauss–Newton IK for one frame of a Pinocchio model.

    The solved joints are the model's (all 1-DoF) or the 1-DoF `joints` (an arm inside a
    larger model); the others stay at the configuration `solve` is given. An instance owns its
    work buffers: share it between threads only with a lock.
    """

    #: λ = DAMP_ERROR·|e|² + DAMP_FLOOR (Sugihara 2011), tuned on the Kinova Gen3.
    DAMP_ERROR = 3e-3
    DAMP_FLOOR = 1e-9
    #: Iterations without a new best error after which an attempt is abandoned.
    STALL_ITERS = 6

    def __init__(
        self,
        model: pin.Model,
        frame_id: int,
        lower: np.ndarray,
        upper: np.ndarray,
        *,
        tol_pos: float = 1e-6,
        tol_rot: float = 1e-5,
        max_iters: int = 50,
        max_restarts: int = 20,
        seed: int = 0,
        joints: list[int] | None = None,
    ) -> None:
        """Prepare buffers for frame `frame_id` of `model` with joint limits `lower`/`upper`.

        Unlimited joints take -inf/+inf.  `max_iters` bounds each attempt; `max_restarts` is
        the number of extra seeds (drawn from `seed`) tried after the caller's seed fails.
        `joints`: the Pinocchio joint ids (1-DoF, in model order) to solve for; default all.
        """
        if not isinstance(model, pin.Model):
            raise SpecError(f"model must be a pinocchio.Model, got {type(model).__name__}")
        ids = list(range(1, model.njoints)) if joints is None else [int(j) for j in joints]
        if (
            not ids
            or any(not 0 < j < model.njoints for j in ids)
            or any(model.nqs[j] != 1 or model.nvs[j] != 1 for j in ids)
        ):
            raise SpecError("joints must be 1-DoF joints of the model (nq == nv == 1 each)")
        if len(set(ids)) != len(ids) or ids != sorted(ids):
            raise SpecError("joints must be distinct and in the model's order")
        nq = len(ids)
        # Where the solved joints sit in q and v: slices when consecutive (no copies).
        qs = [model.idx_qs[j] for j in ids]
        vs = [model.idx_vs[j] for j in ids]
        run = qs == list(range(qs[0], qs[0] + nq)) and vs == list(range(vs[0], vs[0] + nq))
        self._q_at: slice | np.ndarray = slice(qs[0], qs[0] + nq) if run else np.array(qs)
        self._v_at: slice | np.ndarray = slice(vs[0], vs[0] + nq) if run else np.array(vs)
        self._partial = nq != model.nq
        if not 0 <= frame_id < model.nframes:
            raise SpecError(f"frame_id {frame_id} out of range [0, {model.nframes})")
        lo = _limit_vector("lower", lower, nq)
        hi = _limit_vector("upper", upper, nq)
        if (lo > hi).any() or (lo == np.inf).any() or (hi == -np.inf).any():
            raise SpecError("lower must be <= upper for every joint, with lower < +inf")
        if not (tol_pos > 0 and tol_rot > 0):
            raise SpecError("tol_pos and tol_rot must be positive")
        if max_iters < 1 or max_restarts < 0:
            raise SpecError("max_iters must be >= 1 and max_restarts >= 0")

        self.model = model
        self.frame_id = int(frame_id)
        self.lower, self.upper = lo, hi
        self.tol_pos, self.tol_rot = float(tol_pos), float(tol_rot)
        self.max_iters, self.max_restarts, self.seed = int(max_iters), int(max_restarts), seed

        data = model.createData()
        # A model with a single degree of freedom gets its (6, 1) Jacobian as a vector.
        jac_all = data.J if data.J.ndim == 2 else data.J[:, None]
        # data.J, the world-frame joint Jacobian that computeJointJacobians refreshes, is the
        # frame's Jacobian once the columns of joints not carrying the frame are zeroed.  It is
        # a view on pinocchio's buffer, so it is fetched once.
        support = model.supports[model.frames[self.frame_id].parentJoint][1:]
        mask = np.zeros((1, nq))
        mask[0, [ids.index(j) for j in support if j in ids]] = 1.0
        # The damped Hessian J'J + λI is computed as A'A with A = [J; √λ·I].
        aug = np.zeros((6 + nq, nq))
        # mju_boxQP needs lower < upper strictly: a locked joint is opened by one ulp.
        self._locked = bool((lo == hi).any())
        self._qfull = pin.neutral(model)
        self._loop = (
            model,
            data,
            self.frame_id,
            jac_all[:, self._v_at] if run else None,  # None: gathered every iteration
            None if mask.all() else mask,
            aug,
            aug[:6],
            aug[6:].reshape(-1)[:: nq + 1],  # diagonal of the √λ·I block
            lo,
            np.where(lo < hi, hi, np.nextafter(hi, np.inf)),
            np.zeros((nq, nq + 7)),  # mju_boxQP scratch
        )
        seed_lo = np.where(np.isfinite(lo), lo, -np.pi)
        seed_hi = np.where(np.isfinite(hi), hi, np.pi)
        self._seeds = np.random.default_rng(seed).uniform(seed_lo, seed_hi, (max_restarts, nq))

    def solve(self, target: pin.SE3, q0: np.ndarray, q_rest: np.ndarray | None = None) -> IKResult:
        """Joint positions within the limits that put the frame at `target`, seeded at `q0`.

        A `q0` outside the limits is first clipped into them. `q_rest`: the whole model's
        configuration the joints not solved for keep (needed when `joints` was given).
        """
        if not isinstance(target, pin.SE3):
            raise SpecError(f"target must be a pinocchio.SE3, got {type(target).__name__}")
        if not (np.isfinite(target.translation).all() and np.isfinite(target.rotation).all()):
            raise SpecError(f"target must be finite, got {target}")
        if self._partial:
            if q_rest is None or np.shape(q_rest) != (self.model.nq,):
                raise SpecError(
                    f"q_rest must be the whole model's configuration ({self.model.nq} values)"
                )
            self._qfull[...] = q_rest
        try:
            q = np.array(q0, dtype=float)
        except (TypeError, ValueError) as error:
            raise SpecError(f"q0 must be a vector of numbers: {error}") from None
        nq = len(self.lower)
        if q.shape != (nq,):
            raise SpecError(f"q0 must be a vector of length {nq}, got shape {q.shape}")
        if not math.isfinite(q.dot(q)) and not np.isfinite(q).all():
            raise SpecError(f"q0 must be finite, got {q0!r}")
        lo, hi = self.lower, self.upper
        _clip(q, lo, hi)

        target_inv = target.inverse()
        p_target = target.translation
        tp, tr = self.tol_pos, self.tol_rot
        # |log6(oMf · target⁻¹)|² of any pose within tolerance is below this bound.
        gate = 4.0 * (tp + tr * (1.0 + math.sqrt(p_target.dot(p_target)))) ** 2 + tr * tr
        total = restarts = 0
        best_q, best_err = q, math.inf
        while True:
            q, err, its, done = self._attempt(q, target_inv, p_target, gate)
            total += its
            if done is not None:
                if self._locked:
                    _clip(q, lo, hi)
                return IKResult(q, True, total, restarts, *done)
            if err < best_err:
                best_q, best_err = q, err
            if restarts == self.max_restarts:
                break
            q = self._seeds[restarts].copy()
            restarts += 1
        if self._locked:
            _clip(best_q, lo, hi)
        return IKResult(best_q, False, total, restarts, *self._errors(best_q, target))

    def _attempt(
        self, q: np.ndarray, target_inv: pin.SE3, p_target: np.ndarray, gate: float
    ) -> tuple[np.ndarray, float, int, tuple[float, float] | None]:
        """One LM run from `q`, updated in place.

        Returns q, its squared twist error, the iterations taken and, on convergence, the
        (position, rotation) error.
        """
        model, data, fid, jac, mask, aug, aug_jac, aug_diag, qp_lo, qp_hi, scratch = self._loop
        ce, cw, stall = self.DAMP_ERROR, self.DAMP_FLOOR, self.STALL_ITERS
        tp2, tr2 = self.tol_pos**2, self.tol_rot**2
        aug_t, aug_jac_t = aug.T, aug_jac.T
        cjj, ufp, log6 = pin.computeJointJacobians, pin.updateFramePlacement, pin.log6
        boxqp, mul, sub, sqrt = mujoco.mju_boxQP, np.multiply, np.subtract, math.sqrt
        best, since = math.inf, 0
        qfull, q_at, v_at = self._qfull, self._q_at, self._v_at
        for it in range(self.max_iters + 1):
            qfull[q_at] = q
            cjj(model, data, qfull)
            oMf = ufp(model, data, fid)
            e = log6(oMf * target_inv).vector
            err = e.dot(e)
            if err < gate:
                w = e[3:]
                dp = oMf.translation - p_target
                rot2, pos2 = w.dot(w), dp.dot(dp)
                if rot2 <= tr2 and pos2 <= tp2:
                    return q, err, it, (sqrt(pos2), sqrt(rot2))
            if it == self.max_iters:
                break
            if err < best:
                best, since = err, 0
            else:
                since += 1
                if since >= stall:
                    break
            # q+ = argmin |J(q+ - q) + e|² + λ|q+ - q|²  s.t.  lower <= q+ <= upper, that is
            # min ½x'Hx + x'(J'e - Hq) over the box; mju_boxQP warm-starts at and writes to q.
            if jac is None:
                aug_jac[...] = data.J[:, v_at]
            else:
                aug_jac[...] = jac
            if mask is not None:
                mul(aug_jac, mask, out=aug_jac)
            aug_diag[...] = sqrt(ce * err + cw)
            h = aug_t.dot(aug)
            g = aug_jac_t.dot(e)
            sub(g, h.dot(q), out=g)
            if boxqp(q, scratch, None, h, g, qp_lo, qp_hi) < 0:
                break
        return q, err, it, None

    def _errors(self, q: np.ndarray, target: pin.SE3) -> tuple[float, float]:
        """Position (m) and rotation (rad) error of the frame at `q` from `target`."""
        data = self._loop[1]
        self._qfull[self._q_at] = q
        pin.framesForwardKinematics(self.model, data, self._qfull)
        oMf = data.oMf[self.frame_id]
        pos = float(np.linalg.norm(oMf.translation - target.translation))
        rot = float(np.linalg.norm(pin.log3(oMf.rotation.T @ target.rotation)))
        return pos, rot
