"""PPO on many worlds with rsl-rl (the `warp-rl` extra): `BatchEnv` as rsl-rl's `VecEnv`, a
recipe per task, and `train`.

rsl-rl (ETH Zurich's PPO, the learner of Isaac Lab and legged_gym) is built for thousands of
worlds whose observations, rewards and dones are already torch tensors on the GPU: it
collects rollouts without leaving the device, which is what `BatchEnv` gives. Stable-Baselines3
(the `rl` extra) copies through NumPy at every step, and skrl's Gymnasium wrapper does too.
"""

from __future__ import annotations

import copy
import dataclasses
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from gymnasium import spaces
from rsl_rl.env import VecEnv
from rsl_rl.runners import OnPolicyRunner
from tensordict import TensorDict

from ...errors import SpecError
from ..registry import actuation
from ..spec import Actuation
from .cpu_engine import available_threads
from .env import BatchEnv, make_batch


class RslRlEnv(VecEnv):
    """A `BatchEnv` as rsl-rl's `VecEnv`: every vector observation, flattened and concatenated
    in the env's order, is the `policy` group that actor and critic read; `time_outs` are the
    truncations, `log` the success rate of the step."""

    def __init__(self, batch: BatchEnv) -> None:
        self.batch = batch
        self.num_envs = batch.num_envs
        self.num_actions = len(batch.action_labels)
        steps = batch.max_episode_steps
        if steps is None:
            raise SpecError(
                "rsl-rl needs a bounded episode: give the task a time_limit or max_episode_steps"
            )
        self.max_episode_length = int(steps)
        self.device = batch.device
        self.cfg: dict[str, Any] = {}
        single = batch.single_observation_space
        assert isinstance(single, spaces.Dict)
        for key, space in single.spaces.items():
            if space.shape is None or len(space.shape) > 1:
                raise SpecError(
                    f"observation {key!r} (shape {space.shape}) is an image; the PPO recipe "
                    "reads vector observations only"
                )
        self._obs = self._group(batch.reset(seed=0)[0])

    @property
    def episode_length_buf(self) -> torch.Tensor:
        """Control steps of each world's current episode."""
        return self.batch.episode_steps

    @episode_length_buf.setter
    def episode_length_buf(self, value: torch.Tensor) -> None:
        self.batch.episode_steps[:] = value

    def _group(self, obs: dict[str, torch.Tensor]) -> TensorDict:
        flat = torch.cat([v.reshape(self.num_envs, -1).float() for v in obs.values()], dim=1)
        return TensorDict({"policy": flat}, batch_size=[self.num_envs])

    def get_observations(self) -> TensorDict:
        return self._obs

    def step(self, actions: torch.Tensor) -> tuple[TensorDict, torch.Tensor, torch.Tensor, dict]:
        obs, reward, terminated, truncated, info = self.batch.step(actions)
        self._obs = self._group(obs)
        done = terminated | truncated
        success = info.get("final_info", info)["is_success"]
        extras = {
            "time_outs": truncated & ~terminated,
            "log": {"/success": success.float().mean()},
        }
        return self._obs, reward.float(), done.long(), extras


@dataclass
class Recipe:
    """PPO settings for one task: worlds on a GPU, rollout length, iterations, rsl-rl's
    config, the task's parameters (`make_batch`'s and `gymnasium.make`'s keywords, e.g. the
    action's `cartesian_axes`) and the worlds on the CPU engine."""

    num_envs: int
    num_steps_per_env: int
    iterations: int
    config: dict[str, Any] = field(default_factory=dict)
    task_kwargs: dict[str, Any] = field(default_factory=dict)
    cpu_num_envs: int = 64
    """Worlds on the CPU engine: thousands of worlds step at a few thousand world-steps a
    second there, so a GPU's count would make each rollout take minutes."""
    cpu: Recipe | None = None
    """The task's own settings on the CPU engine, where they differ beyond the worlds (None:
    these with `cpu_num_envs` worlds)."""

    def on(self, device: str) -> Recipe:
        """The settings for `device`: these on a GPU; on the CPU `cpu`, else these with
        `cpu_num_envs` worlds."""
        if device.startswith("cuda"):
            return self
        return self.cpu or dataclasses.replace(self, num_envs=self.cpu_num_envs)

    def worlds(self, device: str) -> int:
        """The recipe's worlds on `device` (`on(device).num_envs`)."""
        return self.on(device).num_envs

    def parameters(self, overrides: dict[str, Any]) -> dict[str, Any]:
        """The task's parameters: the recipe's, then `overrides`. A joint-space `actuation`
        among them drops the recipe's `cartesian_axes` (they choose Cartesian entries)."""
        out = dict(self.task_kwargs)
        if actuation(overrides.get("actuation", "cartesian_velocity")) is not (
            Actuation.CARTESIAN_VELOCITY
        ):
            out.pop("cartesian_axes", None)
        out.update(overrides)
        return out


def _config(
    hidden: tuple[int, ...],
    lr: float,
    entropy: float,
    gamma: float,
    lam: float = 0.95,
    init_std: float = 1.0,
) -> dict[str, Any]:
    model = {
        "class_name": "MLPModel",
        "hidden_dims": list(hidden),
        "activation": "elu",
        "obs_normalization": True,
    }
    return {
        "algorithm": {
            "class_name": "PPO",
            "num_learning_epochs": 5,
            "num_mini_batches": 4,
            "learning_rate": lr,
            "entropy_coef": entropy,
            "gamma": gamma,
            "lam": lam,
            "schedule": "adaptive",
            "desired_kl": 0.01,
        },
        "actor": {
            **model,
            "distribution_cfg": {"class_name": "GaussianDistribution", "init_std": init_std},
        },
        "critic": dict(model),
        "obs_groups": {"actor": ["policy"], "critic": ["policy"]},
        "save_interval": 10**9,
        "check_for_nan": True,
    }


# The object tasks (docs/task.md, Learning): translation and the gripper alone (4 entries: a
# 4 cm cube is grasped at any yaw, and the yaw's noise only slowed exploration), the shaped
# reward; ManiSkill's PPO settings for its pick tasks (a short discount, 0.8, on a dense
# staged reward; a narrower initial action noise), 3 x 256. On the CPU engine 128 worlds.
OBJECT_CPU = Recipe(
    128,
    24,
    1000,
    _config((256, 256, 256), 3e-4, 0.0, 0.8, lam=0.9, init_std=0.6),
    {"cartesian_axes": "vx,vy,vz", "reward_type": "shaped"},
)
# On a GPU the same settings on 4096 worlds: PickCube's held-out success was 100 % after 22
# iterations (2.2 M steps, 133 s of training on one H200), 80 % after 41; Push's and
# PickAndPlace's iteration counts are unmeasured starting points.
OBJECT_GPU = dataclasses.replace(OBJECT_CPU, num_envs=4096)
# Push ends its episodes on success, as PickCube does: the step that ends one is paid for the
# steps it cuts off (`success_bonus`), so a push that gets there is worth tens of steps of the
# shaped reward, where pushes of up to 0.4 m take more steps than a discount of 0.8 looks ahead.
PUSH_KWARGS = {**OBJECT_CPU.task_kwargs, "terminate_on_success": True}
PUSH_CPU = dataclasses.replace(OBJECT_CPU, task_kwargs=PUSH_KWARGS)
DEFAULT_RECIPE = Recipe(4096, 24, 300, _config((256, 128, 64), 1e-3, 5e-3, 0.97))
RECIPES: dict[str, Recipe] = {
    "mjkdl/PandaReach-v0": Recipe(2048, 24, 100, _config((128, 64), 1e-3, 5e-3, 0.97)),
    "mjkdl/PandaPickCube-v0": dataclasses.replace(OBJECT_GPU, iterations=25, cpu=OBJECT_CPU),
    "mjkdl/PandaPush-v0": dataclasses.replace(
        OBJECT_GPU, iterations=300, task_kwargs=PUSH_KWARGS, cpu=PUSH_CPU
    ),
    "mjkdl/PandaPickAndPlace-v0": dataclasses.replace(OBJECT_GPU, iterations=1200, cpu=OBJECT_CPU),
}


def recipe(task_id: str) -> Recipe:
    """The PPO recipe for `task_id` (a copy): its own, else `DEFAULT_RECIPE`."""
    return copy.deepcopy(RECIPES.get(task_id, DEFAULT_RECIPE))


def auto_reset_workers(device: str) -> int:
    """Reset workers for a batch on `device`: on a GPU all cores this process may run on but
    two (at most 15), which keep up with thousands of worlds; none on the CPU, whose physics
    takes every core."""
    if not device.startswith("cuda"):
        return 0
    return max(0, min(15, available_threads() - 2))


@dataclass
class TrainResult:
    """What `train` did: the runner (its `alg` holds the policy), steps and wall time."""

    runner: OnPolicyRunner
    env_steps: int
    seconds: float


@contextmanager
def env_policy(runner: OnPolicyRunner) -> Iterator[Callable[[dict[str, np.ndarray]], np.ndarray]]:
    """The runner's policy as a CPU env's policy (observation dict in, action out), evaluated
    on the CPU; on leaving, the policy goes back to the runner's device, so learning can go
    on (rsl-rl's `get_inference_policy("cpu")` alone leaves it there, and the next `learn` on
    a GPU mixes devices)."""
    net = runner.get_inference_policy("cpu")

    def act(obs: dict[str, np.ndarray]) -> np.ndarray:
        flat = np.concatenate([np.ravel(v) for v in obs.values()]).astype(np.float32)
        td = TensorDict({"policy": torch.as_tensor(flat)[None]}, batch_size=[1])
        with torch.no_grad():
            return net(td)[0].numpy()

    try:
        yield act
    finally:
        net.to(runner.device)


def train(
    task_id: str,
    *,
    device: str | None = None,
    num_envs: int | None = None,
    num_steps_per_env: int | None = None,
    iterations: int | None = None,
    log_dir: str | None = None,
    seed: int = 0,
    reset_workers: int | None = None,
    **task_kwargs: Any,
) -> TrainResult:
    """PPO (rsl-rl) on `task_id`'s recipe, any of its numbers overridden, on `device` (None:
    a GPU if torch has one, else the CPU engine; the recipe's worlds for it,
    `Recipe.worlds`); `task_kwargs` go to the task (`time_limit`, `reward_type`, ...) over
    the recipe's own; `reset_workers` as `make_batch`'s (None: `auto_reset_workers(device)`).
    The worlds start spread over the episode (rsl-rl's `init_at_random_ep_len`). Returns the
    runner with the trained policy."""
    if device is None:
        device = "cuda:0" if torch.cuda.is_available() else "cpu"
    r = recipe(task_id).on(device)
    envs = num_envs or r.num_envs
    steps = num_steps_per_env or r.num_steps_per_env
    iters = iterations or r.iterations
    torch.manual_seed(seed)
    workers = auto_reset_workers(device) if reset_workers is None else reset_workers
    kwargs = r.parameters(task_kwargs)
    batch = make_batch(task_id, envs, device=device, reset_workers=workers, **kwargs)
    env = RslRlEnv(batch)
    cfg = {**r.config, "num_steps_per_env": steps, "seed": seed}
    try:
        runner = OnPolicyRunner(env, cfg, log_dir=log_dir, device=str(batch.device))
        start = time.perf_counter()
        runner.learn(num_learning_iterations=iters, init_at_random_ep_len=True)
        seconds = time.perf_counter() - start
    finally:
        batch.close()
    return TrainResult(runner, envs * steps * iters, seconds)
