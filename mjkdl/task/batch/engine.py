"""What the batched task needs of a physics engine running many worlds: `Engine`.

An engine holds `nworld` copies of one model's state and exposes MuJoCo's `MjData` fields as
torch tensors with the worlds first, sharing memory with the engine's own arrays (a write to
a row of `qpos` or `ctrl` is the world's state). The task (`env.BatchEnv`), its observations
(`sensors`), its control (`control`) and its resets (`reset`) see only this interface; each
engine is one module: `cpu_engine` (MuJoCo's `mujoco.batch`, float64, on the CPU's threads)
and `warp_engine` (MuJoCo Warp, float32, on a GPU).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from ...errors import MjkdlError

if TYPE_CHECKING:
    import mujoco

    from ..env import ArmEffector


class UnsupportedFeatureError(MjkdlError, NotImplementedError):
    """The task or scene uses a feature that the chosen engine does not implement."""


@dataclass(frozen=True)
class Tcp:
    """Where an arm's TCP is: its reference frame (site or body), the body that carries it,
    and the tool's offset from that frame (as `ArmReader` computes it)."""

    site: int
    """The reference site, or -1 for the tip body."""
    body: int
    """The body carrying the frame (the tip body, or the site's body)."""
    offset: torch.Tensor
    """(3,) TCP position in the reference frame."""
    rotation: torch.Tensor
    """(3, 3) TCP orientation in the reference frame."""


class Engine(ABC):
    """`nworld` worlds of one model: MjData's fields as (nworld, ...) torch tensors on
    `device` in the engine's `dtype`, and the calls that advance them.

    State fields (`time`, `qpos`, `qvel`, `ctrl`, `act`, `qacc_warmstart`, `mocap_pos`,
    `mocap_quat`) are written by resets and control; the derived ones (`xpos`, `xquat`,
    `xmat`, `xipos`, `xanchor`, `xaxis`, `site_xpos`, `site_xmat`, `cvel`, `subtree_com`,
    `actuator_length`, `qfrc_actuator`) describe the state after `step` or `forward`."""

    device: str
    nworld: int
    dtype: torch.dtype
    name: str
    """The engine, as `make_batch(engine=...)` names it."""
    time: torch.Tensor
    qpos: torch.Tensor
    qvel: torch.Tensor
    ctrl: torch.Tensor
    act: torch.Tensor
    qacc_warmstart: torch.Tensor
    mocap_pos: torch.Tensor
    mocap_quat: torch.Tensor
    xpos: torch.Tensor
    xquat: torch.Tensor
    xmat: torch.Tensor
    xipos: torch.Tensor
    xanchor: torch.Tensor
    xaxis: torch.Tensor
    site_xpos: torch.Tensor
    site_xmat: torch.Tensor
    cvel: torch.Tensor
    subtree_com: torch.Tensor
    actuator_length: torch.Tensor
    qfrc_actuator: torch.Tensor
    root: torch.Tensor
    """(nbody,) each body's root body (`body_rootid`)."""
    tcps: dict[str, Tcp]
    """The arms' TCPs, by arm name (registered by the observer)."""

    @abstractmethod
    def forward(self, rows: torch.Tensor) -> None:
        """`mj_forward` of the worlds `rows` (a bool mask) after their state was written; the
        other worlds step on as if this had not run."""

    @abstractmethod
    def step(self, substeps: int, meanwhile: Callable[[], None] | None = None) -> None:
        """`substeps` physics steps of every world, then the derived fields of the new state
        (as the CPU env's `mj_forward` after `mj_step`); `meanwhile` (host work that touches
        no engine field: the next episodes' starts) runs while the physics does."""

    @abstractmethod
    def failed(self) -> torch.Tensor:
        """(nworld,) bool: the worlds whose physics went wrong since their last `clear`
        (MuJoCo's warnings or errors, or an engine's buffer overflow)."""

    @abstractmethod
    def failure_message(self, rows: torch.Tensor) -> str:
        """What went wrong in the worlds `rows` (a bool mask), and the fix if there is one."""

    @abstractmethod
    def clear(self, rows: torch.Tensor) -> None:
        """Forget the failures of the worlds `rows` (they start a new episode)."""

    @abstractmethod
    def contacts(
        self, body: int | None = None, others: Sequence[int] = ()
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(world, geom1, geom2) of the current contacts at zero or negative distance; with
        `body`, every one between a geom of `body` and one of `others` is among them (others
        may be left out)."""

    def gravity(
        self, eff: ArmEffector, model: mujoco.MjModel, jids: list[int]
    ) -> Callable[[], torch.Tensor] | None:
        """A function giving the (nworld, n) joint torques that hold arm `eff` (joints
        `jids`) against gravity at the current state, or None (the default) for the chain's
        bodies summed on the device (`control.ChainGravity`)."""
        return None

    def set_model(self, ids: np.ndarray, values: Mapping[str, np.ndarray]) -> None:
        """Worlds `ids` take their own values of MjModel fields (`values`: field -> one row
        per world, 'opt.<name>' for MjOption's; with masses, centres of mass or armature,
        also the constants `mj_setConst` computed from them, `randomization.CONST_OUTPUTS`);
        the other worlds keep theirs. By default refused: the engine shares one model."""
        raise UnsupportedFeatureError(
            f"engine {self.name!r} holds one model for all worlds; it cannot give worlds their "
            f"own {', '.join(values)}"
        )

    def close(self) -> None:  # noqa: B027  (engines without resources keep it)
        """Release what the engine holds beyond its arrays."""

    def host_work(self) -> AbstractContextManager[None]:
        """A context for the torch work of a step (control, observations, rules): nothing by
        default."""
        return nullcontext()

    # ------------------------------------------------------------------ TCP quantities

    def tcp_of(self, arm: str) -> Tcp:
        """The TCP of arm `arm` (registered by the observer)."""
        return self.tcps[arm]

    def frame_pos(self, tcp: Tcp) -> tuple[torch.Tensor, torch.Tensor]:
        """(N, 3) position and (N, 3, 3) rotation of the TCP's reference frame."""
        if tcp.site >= 0:
            return self.site_xpos[:, tcp.site], self.site_xmat[:, tcp.site]
        return self.xpos[:, tcp.body], self.xmat[:, tcp.body]

    def tcp_pos(self, tcp: Tcp) -> torch.Tensor:
        """(N, 3) TCP position: reference frame * offset."""
        pos, rot = self.frame_pos(tcp)
        return pos + (rot @ tcp.offset)

    def tcp_rot(self, tcp: Tcp) -> torch.Tensor:
        _, rot = self.frame_pos(tcp)
        return rot @ tcp.rotation

    def tcp_vel(self, tcp: Tcp, pos: torch.Tensor | None = None) -> torch.Tensor:
        """(N, 6) [v, w] of the TCP point, world axes: MuJoCo's `cvel` (at the root's
        subtree centre of mass) moved to the TCP (at `pos`, its `tcp_pos`, if given)."""
        cvel = self.cvel[:, tcp.body]
        w, v = cvel[:, :3], cvel[:, 3:]
        com = self.subtree_com[:, self.root[tcp.body]]
        lever = (self.tcp_pos(tcp) if pos is None else pos) - com
        lin = v + torch.linalg.cross(w, lever, dim=-1)
        return torch.cat([lin, w], dim=1)


def mat_to_quat(mat: torch.Tensor) -> torch.Tensor:
    """(N, 3, 3) rotations to (N, 4) quaternions [w, x, y, z] with MuJoCo's `mju_mat2Quat`
    branches, so the sign matches the CPU env's. Each branch's quaternion is a multiple
    (by 1 / (4 q_k), q_k its largest entry) of a vector of sums of entries, so the chosen
    vector, normalised, is it."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = mat.reshape(-1, 9).unbind(1)
    tr = m00 + m11 + m22
    a, b, c = m21 - m12, m02 - m20, m10 - m01
    d, e, f = m01 + m10, m02 + m20, m12 + m21
    # Row k: the branch where entry k is largest (w, x, y, z), scaled by 4 q_k.
    rows = torch.stack(
        [
            1.0 + tr, a, b, c,
            a, 1.0 + m00 - m11 - m22, d, e,
            b, d, 1.0 - m00 + m11 - m22, f,
            c, e, f, 1.0 - m00 - m11 + m22,
        ],
        1,
    ).reshape(-1, 4, 4)  # fmt: skip
    branch = torch.where(
        tr > 0, 0, torch.where((m00 > m11) & (m00 > m22), 1, torch.where(m11 > m22, 2, 3))
    )
    out = rows[torch.arange(len(branch), device=mat.device), branch]
    return out / torch.linalg.norm(out, dim=1, keepdim=True)


def as_numpy(value: Any) -> np.ndarray:
    """A host NumPy copy of a tensor (float64 for floats), for the task's host callables."""
    arr = value.detach().cpu().numpy()
    return arr.astype(np.float64) if arr.dtype.kind == "f" else arr
