"""Each world's next episode start, computed ahead on the host by the CPU env's own reset.

A world's episodes draw only on its own generator, so the start of its next episode is known
as soon as the current one has begun. `EpisodeStarts` computes it while the device runs the
physics (`prefetch`), and a finished world restarts from one batched upload of every
finished world's row (`start`): the episodes stay exactly the CPU env's
`TaskEnv.reset(seed=...)` sequence, and the host's reset cost leaves the critical path on a GPU.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import torch
from gymnasium.utils.seeding import np_random

if TYPE_CHECKING:
    from .batch_control import BatchArm
    from .batch_state import DeviceState
    from .env import TaskEnv

# The state a reset sets, by DeviceState attribute and MjData field.
FIELDS = ("qpos", "qvel", "ctrl", "act", "qacc_warmstart", "mocap_pos", "mocap_quat", "time")


class EpisodeStarts:
    """One host row per world holding the state its next episode starts from."""

    def __init__(
        self, host: TaskEnv, state: DeviceState, arms: Sequence[BatchArm], num_envs: int
    ) -> None:
        self._host, self._state, self._arms = host, state, list(arms)
        data = host.scene.data
        self._rows = {f: np.zeros((num_envs, np.size(getattr(data, f)))) for f in FIELDS}
        self._q_cmd = [np.zeros((num_envs, arm.n)) for arm in self._arms]
        self._qd = [np.zeros((num_envs, arm.n)) for arm in self._arms]
        self._ready = np.zeros(num_envs, dtype=bool)
        self._rngs: list[np.random.Generator] = [np_random(i)[0] for i in range(num_envs)]

    def seed(self, seeds: Sequence[int]) -> None:
        """World `i`'s episodes from now on are those of a CPU env reset with `seeds[i]`."""
        self._rngs = [np_random(int(s))[0] for s in seeds]
        self._ready[:] = False

    def prefetch(self) -> None:
        """Compute the next start of every world that has none ready."""
        self._compute(np.flatnonzero(~self._ready))

    def start(self, rows: torch.Tensor) -> None:
        """Worlds `rows` (a bool mask) take their next start: one upload per state field."""
        ids = torch.nonzero(rows).flatten().cpu().numpy()
        self._compute(ids[~self._ready[ids]])
        s, dev = self._state, self._state.device
        idx = torch.as_tensor(ids, device=dev, dtype=torch.long)
        for f in FIELDS:
            view = getattr(s, f)
            if view.numel():
                value = torch.as_tensor(self._rows[f][ids], device=dev, dtype=view.dtype)
                view[idx] = value.reshape((len(ids), *view.shape[1:]))
        for j, arm in enumerate(self._arms):
            arm.reset_rows(idx, self._q_cmd[j][ids], self._qd[j][ids])
        self._ready[ids] = False

    def _compute(self, ids: np.ndarray) -> None:
        host = self._host
        data = host.scene.data
        for i in ids.tolist():
            host.np_random = self._rngs[i]
            host.reset()
            for f in FIELDS:
                self._rows[f][i] = np.ravel(getattr(data, f))
            for j, eff in enumerate(host.effectors):
                self._q_cmd[j][i] = eff.robot.jnt_pos_cmd
                self._qd[j][i] = eff.robot.jnt_vel_msr
            self._ready[i] = True
