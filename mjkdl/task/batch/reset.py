"""Each world's next episode start, computed ahead on the host by the CPU env's own reset.

A world's episodes draw only on its own generator, so the start of its next episode is known
as soon as the current one has begun. `EpisodeStarts` computes it while the device runs the
physics (`prefetch`), and a finished world restarts from one batched upload of every
finished world's row (`start`): the episodes stay exactly the CPU env's
`TaskEnv.reset(seed=...)` sequence, and the host's reset cost leaves the critical path: on a
GPU, and on the CPU beside MuJoCo's batch, which steps on its own threads without the GIL.

With `workers`, separate processes (each with its own copy of the env, owning every
`workers`-th world's generator) compute the starts in parallel and in the background: a GPU
steps thousands of worlds faster than one core resets the ones that finish.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import subprocess
import sys
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection, wait
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from gymnasium.utils.seeding import np_random

from ...errors import MjkdlError, SpecError
from ..randomization import CONST_INPUTS, CONST_OUTPUTS, fields_in_use, model_fields

if TYPE_CHECKING:
    from ..env import TaskEnv
    from .control import BatchArm
    from .engine import Engine

# The state a reset sets, by Engine attribute and MjData field.
FIELDS = ("qpos", "qvel", "ctrl", "act", "qacc_warmstart", "mocap_pos", "mocap_quat", "time")

LATENCY = "action_latency"  # a start's row holding its episode's drawn action latency

# The worker is a fresh interpreter (multiprocessing's spawn would re-run an unguarded script).
_CHILD = "import sys; from mjkdl.task.batch.reset import _worker; _worker(sys.argv[1:])"

Start = tuple[dict[str, np.ndarray], list[np.ndarray], list[np.ndarray]]


def start_of(env: TaskEnv) -> Start:
    """The state `env`'s reset just set: MuJoCo's fields (and the model fields its
    randomization drew, `randomization.model_fields`), then each arm's synced position
    command and joint velocities."""
    data, model = env.scene.data, env.scene.model
    fields = {f: np.ravel(getattr(data, f)).copy() for f in FIELDS}
    for name in randomized(env):
        value = model.opt.gravity if name == "opt.gravity" else getattr(model, name)
        fields[name] = np.ravel(value).astype(np.float64)
    description, draw = env.task_spec.randomization, env.randomization_draw
    if description is not None and draw is not None and LATENCY in fields_in_use(description):
        fields[LATENCY] = np.array([draw.action_latency], dtype=np.float64)
    q_cmd = [np.array(eff.robot.jnt_pos_cmd) for eff in env.effectors]
    qd = [np.array(eff.robot.jnt_vel_msr) for eff in env.effectors]
    return fields, q_cmd, qd


def randomized(env: TaskEnv) -> list[str]:
    """The model fields a reset of `env` draws per episode (none without randomization), and
    MuJoCo's constants that follow them (`CONST_OUTPUTS`, as `mj_setConst` computed them)."""
    description = env.task_spec.randomization
    names = [] if description is None else model_fields(description)
    if any(name in CONST_INPUTS for name in names):
        names += CONST_OUTPUTS
    return names


class EpisodeStarts:
    """One host row per world holding the state its next episode starts from.

    `maker` builds a copy of the host env in a worker process (a picklable callable); it is
    needed only with `workers` > 0."""

    def __init__(
        self,
        host: TaskEnv,
        state: Engine,
        arms: Sequence[BatchArm],
        num_envs: int,
        workers: int = 0,
        maker: Callable[[], TaskEnv] | None = None,
    ) -> None:
        self._host, self._state, self._arms = host, state, list(arms)
        data = host.scene.data
        self._rows = {f: np.zeros((num_envs, np.size(getattr(data, f)))) for f in FIELDS}
        self._params = randomized(host)
        start = start_of(host)[0]
        self._rows.update((f, np.zeros((num_envs, np.size(start[f])))) for f in self._params)
        self.latency: torch.Tensor | None = None
        """(num_envs,) long: each world's drawn action latency this episode (None: none)."""
        if LATENCY in start:
            self._rows[LATENCY] = np.zeros((num_envs, 1))
            self.latency = torch.zeros(num_envs, dtype=torch.long, device=state.device)
        self._q_cmd = [np.zeros((num_envs, arm.n)) for arm in self._arms]
        self._qd = [np.zeros((num_envs, arm.n)) for arm in self._arms]
        self._ready = np.zeros(num_envs, dtype=bool)
        self._asked = np.zeros(num_envs, dtype=bool)  # requested from a worker, not back yet
        self._rngs: list[np.random.Generator] = []
        self._generation = 0  # seeds given so far: rows computed under older ones are dropped
        self._workers: list[_Worker] = []
        if workers and maker is None:
            raise SpecError("reset workers need `maker`, a picklable callable building the task")
        try:
            for k in range(workers):
                assert maker is not None
                self._workers.append(_Worker(maker, k))
            for w in self._workers:
                w.ready()
        except BaseException:
            self.close()
            raise
        self.seed(range(num_envs))

    def seed(self, seeds: Sequence[int]) -> None:
        """World `i`'s episodes from now on are those of a CPU env reset with `seeds[i]`."""
        while self._asked.any():  # take in the replies first: a worker blocked sending one
            self._collect(block=True)  # would not read what comes next
        self._generation += 1
        self._ready[:] = False
        self._asked[:] = False
        n = len(self._workers)
        if not n:
            self._rngs = [np_random(int(s))[0] for s in seeds]
            return
        for k, w in enumerate(self._workers):
            mine = {i: int(s) for i, s in enumerate(seeds) if i % n == k}
            w.send(("seed", self._generation, mine))

    def prefetch(self) -> None:
        """Compute (in-process) or ask for (workers) the next start of every world that has
        none ready."""
        if self._workers:
            self._collect(block=False)
            self._ask(np.flatnonzero(~self._ready & ~self._asked))
        else:
            self._compute(np.flatnonzero(~self._ready))

    def start(self, rows: torch.Tensor) -> None:
        """Worlds `rows` (a bool mask) take their next start: one upload per state field."""
        ids = torch.nonzero(rows).flatten().cpu().numpy()
        if self._workers:
            self._ask(ids[~self._ready[ids] & ~self._asked[ids]])
            while not self._ready[ids].all():
                self._collect(block=True)
        else:
            self._compute(ids[~self._ready[ids]])
        s, dev = self._state, self._state.device
        idx = torch.as_tensor(ids, device=dev, dtype=torch.long)
        for f in FIELDS:
            view = getattr(s, f)
            if view.numel():
                value = torch.as_tensor(self._rows[f][ids], device=dev, dtype=view.dtype)
                view[idx] = value.reshape((len(ids), *view.shape[1:]))
        if self._params:  # the worlds' models take their episodes' draws
            s.set_model(ids, {f: self._rows[f][ids] for f in self._params})
        if self.latency is not None:
            latency = self._rows[LATENCY][ids, 0]
            self.latency[idx] = torch.as_tensor(latency, device=dev, dtype=torch.long)
        for j, arm in enumerate(self._arms):
            arm.reset_rows(idx, self._q_cmd[j][ids], self._qd[j][ids])
        self._ready[ids] = False
        if self._workers:
            self._ask(ids)  # the workers compute these worlds' next starts meanwhile

    def close(self) -> None:
        """Stop the workers: their pipes closed, each ends; then wait for them all."""
        for w in self._workers:
            w.hang_up()
        for w in self._workers:
            w.join()
        self._workers = []

    # ------------------------------------------------------------------ rows

    def _store(self, ids: Sequence[int], start: Start) -> None:
        fields, q_cmd, qd = start
        for f, rows in self._rows.items():
            rows[ids] = fields[f]
        for j in range(len(self._arms)):
            self._q_cmd[j][ids] = q_cmd[j]
            self._qd[j][ids] = qd[j]
        self._ready[ids] = True

    def _compute(self, ids: np.ndarray) -> None:
        host = self._host
        for i in ids.tolist():
            host.np_random = self._rngs[i]
            host.reset()
            self._store([i], start_of(host))

    def _ask(self, ids: np.ndarray) -> None:
        n = len(self._workers)
        for k, w in enumerate(self._workers):
            mine = [int(i) for i in ids if i % n == k]
            if mine:
                w.send(("compute", self._generation, mine))
        self._asked[ids] = True

    def _collect(self, block: bool) -> None:
        """Take in the rows the workers have sent (waiting for one message if `block`)."""
        conns = [w.inbox for w in self._workers]
        ready = wait(conns, timeout=None if block else 0)
        for conn in ready:
            w = self._workers[conns.index(conn)]  # type: ignore[arg-type]
            generation, ids, fields, q_cmd, qd = w.receive()
            if generation == self._generation:
                self._asked[ids] = False
                self._store(ids, (fields, q_cmd, qd))


class _Worker:
    """A process with a copy of the env computing starts for the worlds it owns."""

    def __init__(self, maker: Callable[[], TaskEnv], index: int) -> None:
        self.index = index
        down_r, down_w = os.pipe()
        up_r, up_w = os.pipe()
        self._proc = subprocess.Popen(
            [sys.executable, "-c", _CHILD, str(down_r), str(up_w)], pass_fds=(down_r, up_w)
        )
        os.close(down_r)
        os.close(up_w)
        self.outbox = Connection(down_w, readable=False)
        self.inbox = Connection(up_r, writable=False)
        try:
            # The task unpickles in the worker after it takes this process's import path.
            self.send(("make", list(sys.path), pickle.dumps(maker)))
        except BaseException:
            self.hang_up()
            self.join()
            raise

    def ready(self) -> None:
        """Wait until the worker has built its env."""
        self.receive()

    def send(self, message: tuple[Any, ...]) -> None:
        try:
            self.outbox.send(message)
        except OSError:
            raise self._died() from None

    def receive(self) -> Any:
        try:
            kind, payload = self.inbox.recv()
        except (EOFError, OSError):
            raise self._died() from None
        if kind == "error":
            raise MjkdlError(f"reset worker {self.index} failed: {payload}")
        return payload

    def _died(self) -> MjkdlError:
        code = self._proc.wait(timeout=5)
        return MjkdlError(
            f"reset worker {self.index} ended (exit code {code}); its worlds cannot start "
            "new episodes. Its error, if any, is above; make_batch(reset_workers=0) resets "
            "in this process"
        )

    def hang_up(self) -> None:
        """Close the pipes: the worker ends at its next read or write."""
        for conn in (self.outbox, self.inbox):
            conn.close()

    def join(self) -> None:
        try:
            self._proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()


def check_picklable(maker: Callable[[], TaskEnv]) -> None:
    """Refuse a task the reset workers cannot rebuild: a lambda or local function in it, or
    anything of the running script (`__main__`, which a worker does not run)."""
    try:
        data = pickle.dumps(maker)
    except (pickle.PicklingError, AttributeError, TypeError) as err:
        why = f"it cannot be pickled ({err})"
    else:
        if b"__main__" not in data:
            return
        why = "it uses something defined in the running script (__main__)"
    raise SpecError(
        f"reset_workers rebuild the task in other processes, and {why}; define the task's "
        "functions (and register its id) in an importable module, or use reset_workers=0"
    )


def _worker(argv: list[str]) -> None:
    """The worker's loop: build the env, then compute the starts asked for, in order."""
    inbox = Connection(int(argv[0]), writable=False)
    outbox = Connection(int(argv[1]), readable=False)
    try:
        _, path, maker = inbox.recv()
        sys.path[:] = path
        env = pickle.loads(maker)()
        env.reset(seed=0)
        outbox.send(("ready", None))
        rngs: dict[int, np.random.Generator] = {}
        generation = 0
        while True:
            kind, gen, payload = inbox.recv()
            if kind == "seed":
                generation, rngs = gen, {i: np_random(s)[0] for i, s in payload.items()}
                continue
            if gen != generation:
                continue
            starts = []
            for i in payload:
                env.np_random = rngs[i]
                env.reset()
                starts.append(start_of(env))
            fields = {f: np.stack([s[0][f] for s in starts]) for f in starts[0][0]}
            q_cmd = [np.stack([s[1][j] for s in starts]) for j in range(len(env.effectors))]
            qd = [np.stack([s[2][j] for s in starts]) for j in range(len(env.effectors))]
            outbox.send(("rows", (gen, payload, fields, q_cmd, qd)))
    except (EOFError, BrokenPipeError):  # the batch closed
        return
    except Exception as err:  # reported to the parent, which raises it
        with contextlib.suppress(OSError):
            outbox.send(("error", f"{type(err).__name__}: {err}"))
