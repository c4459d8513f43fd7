"""`make_batch`: a task run as many worlds at once, with batched torch tensors.

The CPU env (`TaskEnv`) stays the one definition of a task: the batch builds one from the
same `TaskSpec` (or registered id and parameters) and takes from it the compiled model, the
action layout, the observation readers, the arms' controllers and the task's own reward,
success and termination callables. The physics runs on an engine (`engine.Engine`): MuJoCo's
own batch on the CPU's threads (`cpu_engine`), or MuJoCo Warp on a GPU (`warp_engine`).
Resets run the CPU env's reset on the host, world by world with the world's own generator,
and write the state, so world `i` after `reset(seed=s)` starts the episode
`TaskEnv.reset(seed=s + i)` starts; each world's next start is computed ahead, while the
engine steps (`reset.EpisodeStarts`).
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable, Iterator, Mapping
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from gymnasium.vector import AutoresetMode, VectorEnv

from ...errors import MjkdlError, SpecError, SpecTypeError
from ..env import TaskEnv
from ..goal import GoalTaskEnv
from ..initializers import PhysicsRandomizer
from ..randomization import MODEL_FIELDS, Randomization, fields_in_use
from ..rewards import batchable
from ..spec import TaskSpec
from . import cpu_engine, warp_engine
from .cameras import image_bytes
from .control import ActionLatency, BatchArm
from .engine import Engine, UnsupportedFeatureError, as_numpy
from .reset import EpisodeStarts, check_picklable, randomized
from .sensors import BatchObserver

__all__ = [
    "ENGINES",
    "RANDOMIZED",
    "BatchEnv",
    "DeviceUnavailableError",
    "UnsupportedFeatureError",
    "make_batch",
]

ENGINES = ("mujoco", "warp")
"""`make_batch`'s engines: MuJoCo's own batch on the CPU, MuJoCo Warp (GPU, or its CPU
device for testing kernels)."""

# The fields of `TaskSpec.randomization` each engine draws per world; the others are refused.
# MuJoCo Warp holds `body_simple` (which a centre of mass moved off the body frame changes)
# once for all worlds.
RANDOMIZED: dict[str, tuple[str, ...]] = {
    "mujoco": (*MODEL_FIELDS, "action_latency"),
    "warp": (*(f for f in MODEL_FIELDS if f != "body_com"), "action_latency"),
}

MEMORY_SHARE = 0.8  # of the device's available memory a batch may plan to take
# MuJoCo Warp's buffers: constraint rows per world, and contacts per world pooled over all
# worlds (nconmax x num_envs). Its own defaults (64 rows for a Panda scene) overflow in a
# grasp: measured peaks over the experts' episodes, PickCube 129 rows and 32 contacts, Stack
# 161 rows and 39 contacts. Overflowing worlds end as diverged (the pool: every world).
DEFAULT_NJMAX = 256
DEFAULT_NCONMAX = 64


class DeviceUnavailableError(MjkdlError, RuntimeError):
    """The device asked for does not exist here (no CUDA GPU for `device="cuda"`)."""


def make_batch(
    task: str | TaskSpec,
    num_envs: int,
    device: str | None = None,
    *,
    engine: str | None = None,
    threads: int | None = None,
    allow_cpu: bool = False,
    nconmax: int | None = None,
    njmax: int | None = None,
    max_episode_steps: int | None = None,
    reset_workers: int = 0,
    **kwargs: Any,
) -> BatchEnv:
    """`num_envs` worlds of `task` (a registered id with its parameters as `kwargs`, or a
    `TaskSpec`) on `device` ("cpu", "cuda" or "cuda:N"; None: a CUDA GPU when torch has
    one, else the CPU; a GPU that MuJoCo Warp cannot use, or MuJoCo Warp not installed, falls
    back to the CPU with a warning).

    The engine follows the device: on the CPU MuJoCo's own batch (`engine="mujoco"`,
    `mujoco.batch`, float64, bit for bit the CPU env's physics) on `threads` threads (None:
    the cores this process may use), on a GPU MuJoCo Warp (`engine="warp"`, float32);
    `engine="warp"` with `device="cpu"` runs MuJoCo Warp's CPU device, slow, for testing its
    kernels. Without a GPU, `device="cuda..."` raises unless `allow_cpu`, which runs the CPU
    engine with a warning. MuJoCo Warp only: `njmax` is its constraint rows per world,
    `nconmax` its contacts per world, pooled over all worlds (None: `DEFAULT_NJMAX`,
    `DEFAULT_NCONMAX`, room for the registered tasks' grasps); a world that overflows its
    rows ends its episode as diverged, an overflow of the contact pool ends every world's.
    `max_episode_steps` overrides the registered time limit. `reset_workers` processes
    compute the worlds' episode starts in parallel (each builds a copy of the task; 0: this
    process): on a GPU, where one core resets the finished worlds slower than the device
    steps them all. The task's randomization (`TaskSpec.randomization`) is drawn per world
    and episode, as the CPU env draws it for the world's seed; a field the engine cannot
    draw per world is refused by name (`RANDOMIZED`).
    """
    _check_engine(engine, device)
    device = _device(device, allow_cpu)
    if engine is None:
        engine = "warp" if device.startswith("cuda") else "mujoco"
    if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)):
        raise SpecTypeError(f"num_envs must be a positive integer, got {num_envs!r}")
    if num_envs <= 0:
        raise SpecError(f"num_envs must be a positive integer, got {num_envs}")
    if engine == "warp":
        if threads is not None:
            raise SpecError(f"threads={threads!r} is the CPU engine's (engine='mujoco')")
        nconmax = DEFAULT_NCONMAX if nconmax is None else _room(nconmax, "nconmax")
        njmax = DEFAULT_NJMAX if njmax is None else _room(njmax, "njmax")
    else:
        for field, value in (("nconmax", nconmax), ("njmax", njmax)):
            if value is not None:
                raise SpecError(
                    f"{field}={value!r} sizes MuJoCo Warp's buffers (engine='warp'); MuJoCo's "
                    "own batch sizes its arena from the model"
                )
        if threads is None:
            threads = cpu_engine.available_threads()
        elif isinstance(threads, bool) or not isinstance(threads, (int, np.integer)):
            raise SpecTypeError(f"threads must be a positive integer, got {threads!r}")
        elif threads <= 0:
            raise SpecError(f"threads must be a positive integer, got {threads}")
    if isinstance(reset_workers, bool) or not isinstance(reset_workers, (int, np.integer)):
        raise SpecTypeError(f"reset_workers must be a whole number, got {reset_workers!r}")
    if reset_workers < 0:
        raise SpecError(f"reset_workers must be 0 or more, got {reset_workers}")
    horizon = max_episode_steps
    maker: Callable[[], TaskEnv]
    if isinstance(task, TaskSpec):
        if kwargs:
            raise SpecError(
                f"make_batch: parameters {sorted(kwargs)} go with a registered task id, not a "
                "TaskSpec (set them on the spec)"
            )
        maker = functools.partial(TaskEnv, task)
        host = TaskEnv(task)
    elif isinstance(task, str):
        if task not in gym.registry:
            raise SpecError(f"make_batch: no registered task {task!r}; import mjkdl.task first")
        registered = gym.registry[task]
        made = gym.make(task, disable_env_checker=True, **kwargs).unwrapped
        if not isinstance(made, TaskEnv):
            made.close()
            raise SpecError(f"make_batch: {task!r} is not an mjkdl task (TaskEnv)")
        host = made
        # By its spec: an id registered outside mjkdl is rebuilt without re-registering it.
        maker = functools.partial(_registered, registered, kwargs)
        if horizon is None:
            horizon = registered.max_episode_steps
    else:
        raise SpecTypeError(f"make_batch takes a task id or a TaskSpec, got {task!r}")
    if host.drive is not None:
        host.close()
        raise SpecError(
            "make_batch: arm_drive='franka_impedance' runs on one env (its ramp and rate "
            "limiter step in Python at each 1 ms tick); the batched engines drive the model's "
            "actuators: leave arm_drive at 'servo'"
        )
    description = host.task_spec.randomization
    drawn = description is not None and "body_mass" in fields_in_use(description)
    if drawn and (host.scene.model.body_gravcomp > 0).any():
        host.close()
        raise UnsupportedFeatureError(
            "TaskSpec.randomization.body_mass: the scene has bodies whose weight MuJoCo's "
            "gravcomp cancels (RobotSpec.impedance); only the CPU env (TaskEnv) keeps it "
            "nominal per draw"
        )
    try:
        if reset_workers:
            check_picklable(maker)
        return BatchEnv(
            host,
            num_envs,
            device,
            engine=engine,
            threads=int(threads or 1),
            nconmax=nconmax,
            njmax=njmax,
            horizon=horizon,
            reset_workers=int(reset_workers),
            maker=maker,
        )
    except BaseException:
        host.close()
        raise


def _registered(spec: gym.envs.registration.EnvSpec, kwargs: dict[str, Any]) -> TaskEnv:
    """A registered task's env, as `make_batch` builds its host (in a reset worker)."""
    env = gym.make(spec, disable_env_checker=True, **kwargs).unwrapped
    assert isinstance(env, TaskEnv)
    return env


def _room(value: object, field: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value <= 0:
        raise SpecError(f"{field} must be a positive integer (per world), got {value!r}")
    return int(value)


def _check_engine(engine: object, device: object) -> None:
    if engine is not None and engine not in ENGINES:
        raise SpecError(f"engine must be one of {list(ENGINES)} or None, got {engine!r}")
    if engine == "mujoco" and isinstance(device, str) and device.startswith("cuda"):
        raise SpecError(f"engine='mujoco' (MuJoCo's own batch) runs on the CPU, not {device!r}")


def _check_randomization(description: Randomization, engine: str) -> None:
    """Refuse, by field, a randomization that `engine` cannot draw per world."""
    for name in fields_in_use(description):
        if name not in RANDOMIZED[engine]:
            able = [e for e, names in RANDOMIZED.items() if name in names]
            where = (
                f"engine={able[0]!r} draws it per world"
                if able
                else "only the CPU env (TaskEnv) draws it"
            )
            raise UnsupportedFeatureError(
                f"TaskSpec.randomization.{name}: engine={engine!r} does not draw it per world; "
                f"{where}"
            )


def _device(device: object, allow_cpu: bool) -> str:
    if device is None:  # a GPU that torch and MuJoCo Warp can use, else (with a warning) the CPU
        return _device("cuda:0", allow_cpu=True) if torch.cuda.is_available() else "cpu"
    if not isinstance(device, str):
        raise SpecTypeError(f"device must be 'cuda', 'cuda:N' or 'cpu', got {device!r}")
    if device == "cpu":
        return device
    if device != "cuda" and not (device.startswith("cuda:") and device[5:].isdigit()):
        raise SpecError(f"device must be 'cuda', 'cuda:N' or 'cpu', got {device!r}")
    index = 0 if device == "cuda" else int(device[5:])
    if not torch.cuda.is_available():
        why = "torch sees no CUDA GPU here (no GPU, or a CPU build of torch)"
    else:
        try:
            wp, _ = warp_engine.warp_modules()
        except ImportError:
            wp = None
        count = 0 if wp is None else wp.get_cuda_device_count()
        if index < count:
            return f"cuda:{index}"
        why = (
            "MuJoCo Warp is not installed (pip install 'mjkdl[warp]')"
            if wp is None
            else f"Warp sees {count} CUDA device(s)"
        )
    if allow_cpu:
        warnings.warn(
            f"device={device!r}: {why}; running on the CPU (MuJoCo's own batch)", stacklevel=3
        )
        return "cpu"
    raise DeviceUnavailableError(
        f"device={device!r}: {why}. Pass device='cpu' (MuJoCo's own batch on the CPU's "
        "threads), or allow_cpu=True to fall back with a warning, or run on a machine with an "
        "NVIDIA GPU (and a CUDA build of torch)"
    )


class BatchEnv(VectorEnv):
    """`num_envs` worlds of one task on an engine; Gymnasium's `VectorEnv` interface.

    `reset(seed=s)` and `step(actions)` return torch tensors on `device` (observations and
    rewards in the engine's `dtype`: float64 on the CPU engine, float32 on MuJoCo Warp; bool
    for terminated/truncated): observations a dict of
    `(num_envs, ...)` tensors, as the CPU env's observation space (goal-conditioned tasks:
    `observation`, `achieved_goal`, `desired_goal`). `actions` is a `(num_envs, n)` tensor
    (or array) in the CPU env's action space. Finished worlds start their next episode in
    the same step (Gymnasium's SAME_STEP autoreset): their returned observation is the new
    episode's, `info["final_obs"]` holds the last one for every world (rows of finished
    worlds are meaningful) and `info["_final"]` marks them. `info["is_success"]` and
    `info["diverged"]` are bool tensors; a world diverges when its state stops being finite,
    when MuJoCo raises an error in it (CPU engine) or when MuJoCo Warp drops its constraints
    or contacts for lack of room (its rows, or the contact pool all worlds share: then every
    world): its episode ends (`terminated`, reward 0); MuJoCo's errors and MuJoCo Warp's
    overflows come with a warning that says what happened.

    The task's reward, success and termination rules (`mjkdl.task.rewards`, the same objects
    the CPU env calls) evaluate every world at once as torch operations on the device, in
    float64; a callable of the user's own without `evaluate` runs on the host, world by world
    (docs/task.md, "Many worlds").
    """

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.SAME_STEP}  # noqa: RUF012

    def __init__(
        self,
        host: TaskEnv,
        num_envs: int,
        device: str,
        *,
        engine: str = "warp",
        threads: int = 1,
        nconmax: int | None = DEFAULT_NCONMAX,
        njmax: int | None = DEFAULT_NJMAX,
        horizon: int | None = None,
        reset_workers: int = 0,
        maker: Callable[[], TaskEnv] | None = None,
    ) -> None:
        self.host = host
        self.num_envs = num_envs
        self.device = torch.device(device)
        spec = host.task_spec
        for i, init in enumerate(spec.initializers):
            if isinstance(init, PhysicsRandomizer):
                raise UnsupportedFeatureError(
                    f"TaskSpec.initializers[{i}] (PhysicsRandomizer) edits the model per "
                    "episode; the batched worlds share one model, so it runs only in the CPU env"
                )
        if spec.randomization is not None:
            _check_randomization(spec.randomization, engine)
        host.reset(seed=0)  # configures the arms' actuators (Robot control modes) in the model
        model, data = host.scene.model, host.scene.data
        if host._randomizer is not None:  # the engine starts from the nominal model
            host._randomizer.restore(model)
        self.state: Engine
        if engine == "warp":
            per_world, shared = warp_engine.world_bytes(model, data, device, nconmax, njmax)
            per_world += image_bytes(host.readers, model)
            _check_memory(per_world, shared, num_envs, device, "(or smaller nconmax/njmax)")
            self.state = warp_engine.WarpEngine(
                model, data, num_envs, device, nconmax, njmax, randomized(host)
            )
        else:
            per_world, shared = cpu_engine.world_bytes(model, threads)
            _check_memory(per_world, shared, num_envs, device, "(or fewer threads)")
            self.state = cpu_engine.CpuEngine(model, data, num_envs, threads)
        self.dtype = self.state.dtype
        self.observer = BatchObserver(host, self.state)
        self.state.tcps.update(self.observer.tcps)  # the arms' TCPs, shared with control
        self.arms = [BatchArm(eff, model, self.state) for eff in host.effectors]
        self._substeps, self._period = host.control_substeps, host.control_timestep
        limit = host.time_limit_steps
        if limit is None and horizon is not None:
            limit = horizon
        elif limit is not None and horizon is not None:
            limit = min(limit, horizon)
        self.max_episode_steps = limit
        self._hold_steps = host.success_hold_steps
        dev, dtype = self.device, self.dtype
        low, high = host.action_bounds
        self._low = torch.as_tensor(low, device=dev, dtype=dtype)
        self._high = torch.as_tensor(high, device=dev, dtype=dtype)
        self._normalized = spec.normalize_actions
        if self._normalized:  # as the CPU env scales [-1, 1] onto the bounds
            self._mid = torch.as_tensor(0.5 * (high + low), device=dev, dtype=dtype)
            self._half = torch.as_tensor(0.5 * (high - low), device=dev, dtype=dtype)
        self._steps = torch.zeros(num_envs, dtype=torch.long, device=dev)
        self._held = torch.zeros(num_envs, dtype=torch.long, device=dev)
        self.starts = EpisodeStarts(host, self.state, self.arms, num_envs, reset_workers, maker)
        self._delay: ActionLatency | None = None
        if self.starts.latency is not None:
            assert spec.randomization is not None and spec.randomization.action_latency
            most = spec.randomization.action_latency[1]
            self._delay = ActionLatency(self.starts.latency, len(low), most, dtype)
        self.single_observation_space = host.observation_space
        self.single_action_space = host.action_space
        self.observation_space = gym.vector.utils.batch_space(
            self.single_observation_space, num_envs
        )
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, num_envs)
        self.action_labels = host.action_labels
        self._needs_reset = True
        self.closed = False

    @property
    def episode_steps(self) -> torch.Tensor:
        """Control steps of each world's current episode: the batch's own (num_envs,) long
        tensor on the device, which a learner may write in place (rsl-rl spreads the worlds
        over their episodes at the start); the time limit counts from it."""
        return self._steps

    # ------------------------------------------------------------------ episodes

    def reset(
        self, *, seed: int | list[int] | None = None, options: Mapping[str, Any] | None = None
    ) -> tuple[dict[str, torch.Tensor], dict[str, Any]]:
        """Every world starts an episode; world `i` with seed `seed + i` (or `seed[i]`)."""
        self._check_open()
        if options:
            raise SpecError(f"BatchEnv.reset(options=...) takes no options, got {options!r}")
        if seed is not None:
            seeds = list(seed) if isinstance(seed, (list, tuple)) else None
            if seeds is None:
                if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
                    raise SpecTypeError(
                        f"reset(seed=...) must be an integer or a list, got {seed!r}"
                    )
                seeds = [int(seed) + i for i in range(self.num_envs)]
            if len(seeds) != self.num_envs:
                raise SpecError(f"reset(seed=[...]) needs {self.num_envs} seeds, got {len(seeds)}")
            self.starts.seed(seeds)
        rows = torch.ones(self.num_envs, dtype=torch.bool, device=self.device)
        with torch.no_grad(), self.state.host_work():
            self._reset_rows(rows)
            self._needs_reset = False
            obs = self.observer.read()
            success = self._evaluate(obs, rows)[1]
        return self._shown(obs), {"is_success": success, "diverged": ~rows}

    def step(
        self, actions: Any
    ) -> tuple[dict[str, torch.Tensor], torch.Tensor, torch.Tensor, torch.Tensor, dict[str, Any]]:
        """Hold `actions` for one control period in every world; finished worlds reset."""
        self._check_open()
        if self._needs_reset:
            raise RuntimeError("BatchEnv.step() before reset(): call reset() first")
        # The physics is not differentiable: an action that requires grad is taken as data,
        # and no op of the step pays autograd's bookkeeping.
        with torch.no_grad(), self.state.host_work():
            return self._step(actions)

    def _step(
        self, actions: Any
    ) -> tuple[dict[str, torch.Tensor], torch.Tensor, torch.Tensor, torch.Tensor, dict[str, Any]]:
        a = self._checked(actions)
        if self._delay is not None:
            a = self._delay(a)
        for arm in self.arms:
            arm.apply(a, self._period)
        self.state.step(self._substeps, meanwhile=self.starts.prefetch)
        s = self.state
        failed = s.failed()
        diverged = ~(torch.isfinite(s.qpos).all(1) & torch.isfinite(s.qvel).all(1)) | failed
        if bool(failed.any()):
            warnings.warn(s.failure_message(failed), stacklevel=4)
        obs = self.observer.read()
        self._steps += 1
        reward, success, terminated = self._evaluate(obs, ~diverged)
        self._held.copy_(torch.where(success, self._held + 1, torch.zeros_like(self._held)))
        spec = self.host.task_spec
        if spec.terminate_on_success:
            ends = (self._held > self._hold_steps) & ~terminated
            if self.max_episode_steps is not None:
                # The steps this end cuts off would each have paid about this step's reward.
                left = torch.clamp(self.max_episode_steps - self._steps, min=0)
                reward = torch.where(ends, reward * (1 + left), reward)
            terminated = terminated | ends
        terminated = terminated | diverged
        reward = torch.where(diverged, torch.zeros_like(reward), reward)
        success = success & ~diverged
        if self.max_episode_steps is not None:
            truncated = self._steps >= self.max_episode_steps
        else:
            truncated = torch.zeros_like(terminated)
        done = terminated | truncated
        info: dict[str, Any] = {"is_success": success, "diverged": diverged}
        shown = self._shown(obs)
        if bool(done.any()):
            info["final_obs"] = {k: v.clone() for k, v in shown.items()}
            info["final_info"] = {"is_success": success.clone(), "diverged": diverged.clone()}
            info["_final"] = done
            self._reset_rows(done)
            fresh = self.observer.read()
            restart = self._evaluate(fresh, done)[1]
            started = self._shown(fresh)
            shown = {k: torch.where(_rows(done, v), started[k], v) for k, v in shown.items()}
            info["is_success"] = torch.where(done, restart, success)
        return shown, reward, terminated, truncated, info

    def _reset_rows(self, rows: torch.Tensor) -> None:
        """Worlds `rows` start their next episode (the CPU env's reset with the world's
        generator, `EpisodeStarts`); then one `mj_forward` of every world."""
        self.starts.start(rows)
        if self._delay is not None:
            self._delay.restart(rows)
        self.state.clear(rows)
        self.state.forward(rows)
        self._steps.masked_fill_(rows, 0)
        self._held.masked_fill_(rows, 0)

    def _evaluate(
        self, obs: dict[str, torch.Tensor], live: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Reward, success and termination of each world in `live` by the task's own rules
        (the others: 0, False, False). The rules of `mjkdl.task.rewards` (`ArrayRule`s)
        evaluate all worlds at once on the device, in float64; any other callable runs on the
        host, world by world, on the world's float64 NumPy observation."""
        spec = self.host.task_spec
        wide = Float64View(obs)
        host_obs: dict[str, np.ndarray] | None = None
        out = []
        for fn, dtype in (
            (spec.reward, self.dtype),
            (spec.success, torch.bool),
            (spec.terminated, torch.bool),
        ):
            if fn is None:
                value = torch.zeros(self.num_envs, dtype=dtype, device=self.device)
            elif batchable(fn):
                value = torch.as_tensor(fn.evaluate(wide), device=self.device)
                value = torch.where(live, value, torch.zeros_like(value)).to(dtype)
            else:
                if host_obs is None:
                    host_obs = {k: as_numpy(v) for k, v in obs.items()}
                kind = bool if dtype is torch.bool else float
                rows = np.zeros(self.num_envs, dtype=kind)
                for i in torch.nonzero(live).flatten().tolist():
                    rows[i] = kind(fn({k: v[i] for k, v in host_obs.items()}))
                value = torch.as_tensor(rows, device=self.device, dtype=dtype)
            out.append(value)
        return out[0], out[1], out[2]

    def _shown(self, obs: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """The agent's part of the observation, as the CPU env gives it."""
        host = self.host
        shown = host.observation_space.spaces
        if isinstance(host, GoalTaskEnv):
            g = host.goal_reward
            out = {
                "observation": torch.cat([obs[k] for k, _ in host.observation_layout], dim=1),
                "achieved_goal": obs[g.achieved][:, :3],
                "desired_goal": obs[g.desired][:, :3],
            }
            out.update((k, obs[k]) for k in shown if k not in out)  # the cameras
            return out
        return {k: obs[k] for k in shown}

    def _checked(self, actions: Any) -> torch.Tensor:
        a = torch.as_tensor(actions, device=self.device, dtype=self.dtype)
        shape = (self.num_envs, len(self.action_labels))
        if tuple(a.shape) != shape:
            raise SpecError(
                f"actions must have shape {shape} ({', '.join(self.action_labels)}), got "
                f"{tuple(a.shape)}"
            )
        bad = ~torch.isfinite(a)
        if bool(bad.any()):
            world, entry = (int(x) for x in torch.nonzero(bad)[0])
            raise SpecError(
                f"actions must be finite: world {world}, {self.action_labels[entry]}="
                f"{float(a[world, entry])}"
            )
        if self._normalized:
            return torch.clamp(a, -1.0, 1.0) * self._half + self._mid
        return torch.maximum(torch.minimum(a, self._high), self._low)

    # ------------------------------------------------------------------ lifecycle

    def _check_open(self) -> None:
        if self.closed:
            raise RuntimeError("this BatchEnv is closed")

    def close(self, **kwargs: Any) -> None:
        """Release the host env; later calls raise RuntimeError."""
        if not self.closed:
            self.starts.close()
            self.state.close()
            self.host.close()
        self.closed = True


class Float64View(Mapping[str, torch.Tensor]):
    """The batch's observations, each floating one cast to float64 (on its device) when first
    read: the task's rules evaluate in the CPU env's precision."""

    def __init__(self, obs: Mapping[str, torch.Tensor]) -> None:
        self._obs = obs
        self._wide: dict[str, torch.Tensor] = {}

    def __getitem__(self, key: str) -> torch.Tensor:
        if key not in self._wide:
            value = self._obs[key]
            self._wide[key] = value.double() if value.is_floating_point() else value
        return self._wide[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._obs)

    def __len__(self) -> int:
        return len(self._obs)


def _rows(mask: torch.Tensor, like: torch.Tensor) -> torch.Tensor:
    return mask.reshape((-1,) + (1,) * (like.dim() - 1))


def _free_bytes(device: str) -> int:
    """Memory a batch may take on `device`: a GPU's free memory; on the CPU the kernel's
    estimate of what is available without swapping (`MemAvailable`: free memory and the
    page cache it can reclaim), else the free pages."""
    if device.startswith("cuda"):
        free, _ = torch.cuda.mem_get_info(torch.device(device))
        return int(free)
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    import os

    return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))


def _check_memory(per_world: int, shared: int, num_envs: int, device: str, fix: str) -> None:
    """Refuse, before allocating, a batch of `num_envs` worlds of `per_world` bytes each
    (and `shared` bytes) that would not fit the memory available on `device`."""
    need = shared + per_world * num_envs
    free = _free_bytes(device)
    if need > MEMORY_SHARE * free:
        fits = max(0, int((MEMORY_SHARE * free - shared) // max(per_world, 1)))
        raise SpecError(
            f"num_envs={num_envs} needs about {need / 2**30:.2f} GiB on {device} "
            f"({per_world / 2**10:.0f} KiB per world), more than {MEMORY_SHARE:.0%} of the "
            f"{free / 2**30:.2f} GiB available; use at most about {fits} worlds {fix}"
        )
