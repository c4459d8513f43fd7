"""The CPU engine: many worlds on MuJoCo's own batch (`mujoco.batch.Batch`), float64.

`mujoco.batch` steps many simulations of one model on a thread pool, each bit for bit the
`mj_step` loop of one `MjData`. Its bound fields are live NumPy arrays over its rows; the
engine's tensors are `torch.from_numpy` views of them (no copy per step), so a write to a row
of `qpos` or `ctrl` is the world's state at its next call. Each control period is one call:
the substeps, then `mj_forward` at the new state, as the CPU env's `Scene.step` and
`forward`. The arms' gravity feed-forward is Pinocchio's, as the CPU env's `Robot` computes
it, so joint-space commands are the CPU env's bit for bit.
"""

from __future__ import annotations

import os
import threading
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

import mujoco
import mujoco.batch
import numpy as np
import pinocchio as pin
import torch

from ..randomization import CONST_INPUTS, CONST_OUTPUTS
from .engine import Engine, Tcp

if TYPE_CHECKING:
    from ..env import ArmEffector

# The state a world is: MjData's fields bound as the batch's rows (writable).
STATE = ("time", "qpos", "qvel", "ctrl", "act", "qacc_warmstart", "mocap_pos", "mocap_quat")
# The derived fields the task reads, refreshed by every call (read-only).
DERIVED = (
    "xpos",
    "xquat",
    "xmat",
    "xipos",
    "xanchor",
    "xaxis",
    "site_xpos",
    "site_xmat",
    "cvel",
    "subtree_com",
    "actuator_length",
    "qfrc_actuator",
    "geom_xpos",
    "ncon",
)
_SHAPES = {"xmat": (3, 3), "site_xmat": (3, 3)}  # MjData's flat 9-vectors, as 3x3 here


def available_threads() -> int:
    """The cores this process may run on (its CPU affinity, else the machine's count)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # no affinity on this platform
        return os.cpu_count() or 1


def world_bytes(model: mujoco.MjModel, threads: int) -> tuple[int, int]:
    """(bytes per world, bytes shared) of a batch: each world's state row and bound fields;
    one MjData (buffer and arena) per thread."""
    data = mujoco.MjData(model)
    nstate = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_INTEGRATION)
    fields = sum(np.size(getattr(data, f)) for f in (*STATE, *DERIVED))
    return 8 * (nstate + fields), threads * (data.nbuffer + data.narena)


class CpuEngine(Engine):
    """`nworld` copies of the host `data` in a `mujoco.batch.Batch` on `threads` threads."""

    name = "mujoco"

    def __init__(
        self, model: mujoco.MjModel, data: mujoco.MjData, nworld: int, threads: int
    ) -> None:
        self.device, self.nworld, self.dtype = "cpu", nworld, torch.float64
        self.batch = mujoco.batch.Batch(model, nworld, nthread=threads)
        self.threads = threads
        for name in STATE:
            rows = self.batch.bind(name)
            rows[:] = np.reshape(getattr(data, name), rows.shape[1:])
        with warnings.catch_warnings():
            # torch warns on a read-only array: the derived fields are outputs, never written.
            warnings.filterwarnings("ignore", "The given NumPy array is not writable")
            for name in (*STATE, *DERIVED):
                array = self.batch.bind(name)
                shape = _SHAPES.get(name)
                if shape is not None:
                    array = array.reshape(nworld, -1, *shape)
                setattr(self, name, torch.from_numpy(array))
        self.root = torch.as_tensor(model.body_rootid)
        self.tcps: dict[str, Tcp] = {}
        self._model = self.batch.get_model(0)  # the batch's own copy, for contacts
        self._scratch = mujoco.MjData(self._model)
        self._geom_body = model.geom_bodyid
        self._rbound = model.geom_rbound.copy()
        self._pairs: dict[tuple[int, tuple[int, ...]], Any] = {}  # `_near`'s geoms, by bodies
        self._failed = np.zeros(nworld, dtype=bool)
        self._errors: dict[int, str] = {}
        self._per_world: dict[str, np.ndarray] = {}  # the expanded model fields
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="mjkdl-batch")
        self._entering = threading.Event()
        self.batch.forward()

    def forward(self, rows: torch.Tensor) -> None:
        ids = np.flatnonzero(rows.numpy())
        if len(ids):
            self._call(self.batch.forward, ids)

    def step(self, substeps: int, meanwhile: Callable[[], None] | None = None) -> None:
        """The batch's call on a thread of the engine's own while `meanwhile` runs on this
        one: the call leaves Python (MuJoCo releases the GIL), so the host work shares the
        cores with the physics instead of waiting for it. This thread starts `meanwhile` once
        the other is about to enter the call: started at once, it would keep the GIL from the
        physics for Python's switch interval (5 ms, a fifth of 64 worlds' step)."""
        if meanwhile is None:
            self._step(substeps)
            return
        self._entering.clear()
        physics = self._pool.submit(self._entered_step, substeps)
        try:
            self._entering.wait()
            meanwhile()
        finally:
            physics.result()

    def _entered_step(self, substeps: int) -> None:
        self._entering.set()
        self._step(substeps)

    def _step(self, substeps: int) -> None:
        self._call(self.batch.step, None, nstep=substeps, stage=mujoco.mjtStage.mjSTAGE_ACC)

    def _call(self, fn: Callable[..., None], ids: np.ndarray | None, **kwargs: int) -> None:
        try:
            fn(ids, **kwargs)
        except mujoco.batch.SimulationError as err:
            # The others ran to completion; these kept their state and end as diverged.
            failed = np.asarray(err.ids, dtype=int)
            self._failed[failed] = True
            for i in failed.tolist():
                self._errors[i] = self.batch.error(i)

    def failed(self) -> torch.Tensor:
        return torch.from_numpy(self._failed.copy())

    def failure_message(self, rows: torch.Tensor) -> str:
        worlds = np.flatnonzero(rows.numpy() & self._failed)
        w = int(worlds[0])
        return (
            f"MuJoCo raised an error in {len(worlds)} of {self.nworld} worlds (world {w}: "
            f"{self._errors.get(w, 'no message')}); those worlds' episodes end as diverged"
        )

    def clear(self, rows: torch.Tensor) -> None:
        mask = rows.numpy()
        self._failed[mask] = False
        for i in [i for i in self._errors if mask[i]]:
            del self._errors[i]

    def contacts(
        self, body: int | None = None, others: Sequence[int] = ()
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(world, geom1, geom2) of the touching contacts (distance <= 0). MuJoCo's batch
        binds no contact list: the worlds where a geom of `body` may touch one of `others`
        (their bounding spheres overlap) have their collisions recomputed from their state
        (`mj_kinematics`, `mj_collision`: the contacts of the step's `mj_forward`); the other
        worlds' contacts between those bodies are none. Without `body`, every world with a
        contact is recomputed."""
        ncon = self.ncon.numpy()  # type: ignore[attr-defined]
        candidates = ncon > 0
        if body is not None:
            candidates &= self._near(body, others)
        worlds, g1, g2 = [], [], []
        m, d = self._model, self._scratch
        for w in np.flatnonzero(candidates).tolist():
            self.batch.get_data(w, d)
            mujoco.mj_kinematics(m, d)
            mujoco.mj_collision(m, d)
            con = d.contact
            touching = con.dist[: d.ncon] <= 0.0
            geom = con.geom[: d.ncon][touching]
            worlds.extend([w] * len(geom))
            g1.extend(geom[:, 0].tolist())
            g2.extend(geom[:, 1].tolist())
        return (
            torch.tensor(worlds, dtype=torch.long),
            torch.tensor(g1, dtype=torch.long),
            torch.tensor(g2, dtype=torch.long),
        )

    def _near(self, body: int, others: Sequence[int]) -> np.ndarray:
        """(nworld,) bool: some geom of `body` within bounding-sphere reach of a geom of
        `others` (a plane, whose bound is 0, always reaches)."""
        key = (body, tuple(others))
        pairs = self._pairs.get(key)
        if pairs is None:
            pairs = self._pairs[key] = self._pairs_of(body, others)
        if pairs is True:
            return np.ones(self.nworld, dtype=bool)
        if pairs is False:
            return np.zeros(self.nworld, dtype=bool)
        mine, theirs, reach = pairs
        pos = self.geom_xpos.numpy()  # type: ignore[attr-defined]
        gap = pos[:, mine, None] - pos[:, None, theirs]
        return np.asarray((np.einsum("wijk,wijk->wij", gap, gap) <= reach).any(axis=(1, 2)))

    def _pairs_of(
        self, body: int, others: Sequence[int]
    ) -> bool | tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The geoms of `body` and of `others` and their squared reach; True where a plane
        is among them (always near), False where either side has no geom (never)."""
        mine = np.flatnonzero(self._geom_body == body)
        theirs = np.flatnonzero(np.isin(self._geom_body, list(others)))
        if not len(mine) or not len(theirs):
            return False
        rb = self._rbound
        if (rb[mine] == 0).any() or (rb[theirs] == 0).any():
            return True
        reach = rb[mine][:, None] + rb[theirs][None, :] + 1e-6
        return mine, theirs, reach * reach

    def gravity(
        self, eff: ArmEffector, model: mujoco.MjModel, jids: list[int]
    ) -> Callable[[], torch.Tensor] | None:
        """The arm's gravity torques by Pinocchio, as its `Robot` computes them (None, the
        chain's bodies summed on the device, where MuJoCo's `gravcomp` takes a share, the Robot
        then subtracting a second model's gravity, or where Pinocchio's model has a joint of
        more than one coordinate)."""
        chain = [int(model.jnt_bodyid[j]) for j in jids]
        pm = eff.robot.model
        if (model.body_gravcomp[chain] > 0).any() or pm.nq != pm.njoints - 1:
            return None
        return PinocchioGravity(eff, model, self)

    def set_model(self, ids: np.ndarray, values: Mapping[str, np.ndarray]) -> None:
        """Through the batch's per-simulation model fields (`expand`), then `set_const` of
        those worlds where masses, centres of mass or armature changed, as `mj_setConst`
        follows them in the CPU env (it computes the constants given, the same)."""
        for name, rows in values.items():
            if name in CONST_OUTPUTS:
                continue
            if name not in self._per_world:
                self._per_world[name] = self.batch.expand(name)
            array = self._per_world[name]
            array[ids] = rows.reshape((len(ids), *array.shape[1:]))
        if any(name in CONST_INPUTS for name in values):
            self.batch.set_const(ids)

    def close(self) -> None:
        self._pool.shutdown()
        del self.batch

    @contextmanager
    def host_work(self) -> Iterator[None]:
        """torch on one thread: the batch's threads hold the cores, and torch's (OpenMP's)
        threads waiting at a barrier for a core cost more than small tensors gain from them
        (measured, PickCube at 64 worlds on the 2-core VM: the Cartesian chain's kinematics
        156 ms a step with torch's 2 threads, 4 ms with one)."""
        threads = torch.get_num_threads()
        torch.set_num_threads(1)
        try:
            yield
        finally:
            torch.set_num_threads(threads)


class PinocchioGravity:
    """(nworld, n) gravity torques of one arm: Pinocchio's inverse dynamics at rest
    (`rneaInParallel`, zero velocity and acceleration, one C++ call for all worlds) at each
    world's joint positions, the arm's entries of it. Bit for bit the CPU env's
    `Robot.update` (`computeGeneralizedGravity`): the velocity terms it adds are exact zeros."""

    def __init__(self, eff: ArmEffector, model: mujoco.MjModel, engine: CpuEngine) -> None:
        robot = eff.robot
        pm = robot.model
        self._pool = pin.ModelPool(pm, 1)
        names = [pm.names[j] for j in range(1, pm.njoints)]
        self._qadr = np.array([model.joint(n).qposadr[0] for n in names])
        self._arm_v = np.arange(pm.nv)[robot.arm_v]
        self._qpos = engine.qpos.numpy()
        nworld = engine.nworld
        # Pinocchio takes one column per world (column-major): rows of these transposes.
        self._q = np.zeros((pm.nq, nworld), order="F")
        self._rest = np.zeros((pm.nv, nworld), order="F")
        self._tau = np.zeros((pm.nv, nworld), order="F")
        self.out = torch.zeros(nworld, robot.n_joints, dtype=torch.float64)
        self._out = self.out.numpy()

    def __call__(self) -> torch.Tensor:
        np.take(self._qpos, self._qadr, axis=1, out=self._q.T)
        pin.rneaInParallel(1, self._pool, self._q, self._rest, self._rest, self._tau)
        np.take(self._tau.T, self._arm_v, axis=1, out=self._out)
        return self.out
