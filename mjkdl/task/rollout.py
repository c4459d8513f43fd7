"""Whole episodes, reproducible from a seed: what a rollout worker (a process, a Ray actor) runs."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from ..errors import SpecError, SpecTypeError
from ..validate import text
from ._check import integer, is_int

Policy = Callable[[Mapping[str, np.ndarray]], Any]


@dataclass(frozen=True)
class Episode:
    """What one episode gave: its seed, length, summed reward, how it ended, and whether its
    last step reported success (`info["is_success"]`; False for envs without one)."""

    seed: int
    steps: int
    total_reward: float
    terminated: bool
    truncated: bool
    success: bool = False


def run_episode(
    env: gym.Env, seed: int, policy: Policy | None = None, max_steps: int | None = None
) -> Episode:
    """Reset `env` with `seed` and act until the episode ends (or `max_steps` steps).

    `policy(obs) -> action`; None samples the action space, seeded with `seed` too, so the
    episode depends on the seed alone — in any process, on any machine with the same versions.
    """
    if not isinstance(env, gym.Env):
        raise SpecTypeError(f"env must be a gymnasium.Env, got {env!r}")
    seed = integer(seed, "seed", least=0)
    _check_run(policy, max_steps)
    obs, _ = env.reset(seed=seed)
    if policy is None:
        env.action_space.seed(seed)
    total, steps = 0.0, 0
    terminated = truncated = False
    info: dict[str, Any] = {}
    while not (terminated or truncated) and (max_steps is None or steps < max_steps):
        action = env.action_space.sample() if policy is None else policy(obs)
        obs, reward, terminated, truncated, info = env.step(action)
        total += float(reward)
        steps += 1
    success = bool(info.get("is_success", False))
    return Episode(seed, steps, total, bool(terminated), bool(truncated), success)


def _check_run(policy: object, max_steps: object) -> None:
    if policy is not None and not callable(policy):
        raise SpecTypeError(f"policy must be callable (obs -> action) or None, got {policy!r}")
    if max_steps is not None:
        message = f"max_steps must be a positive integer or None, got {max_steps!r}"
        if not is_int(max_steps):
            raise SpecTypeError(message)
        if max_steps < 1:  # type: ignore[operator]
            raise SpecError(message)


def ray_collect(
    env_id: str,
    seeds: Sequence[int],
    *,
    actors: int = 2,
    policy: Policy | None = None,
    max_steps: int | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
) -> list[Episode]:
    """One `run_episode` per seed, spread over `actors` Ray actors; results in seed order.

    Each actor builds `gymnasium.make(env_id, **env_kwargs)` once and runs its share of the
    seeds, so the results equal a sequential run with the same seeds. Connect first with
    `ray.init()` (this machine) or `ray.init(address=...)` (a cluster whose nodes have mjkdl
    and the models installed); without it Ray starts a local instance. Needs `mjkdl[ray]`.
    """
    text(env_id, "env_id")
    if isinstance(seeds, str) or not isinstance(seeds, (Sequence, np.ndarray)):
        raise SpecTypeError(f"seeds must be a list of non-negative integers, got {seeds!r}")
    seeds = [integer(s, f"seeds[{i}]", least=0) for i, s in enumerate(seeds)]
    actors = integer(actors, "actors")
    _check_run(policy, max_steps)
    if env_kwargs is not None and not (
        isinstance(env_kwargs, Mapping) and all(isinstance(k, str) for k in env_kwargs)
    ):
        raise SpecTypeError(
            f"env_kwargs must be a mapping of argument names or None, got {env_kwargs!r}"
        )
    kwargs = dict(env_kwargs or {})
    try:
        import ray
    except ImportError:
        raise ImportError("ray_collect needs Ray: pip install 'mjkdl[ray]'") from None

    class Worker:
        def __init__(self) -> None:
            import mjkdl.task  # noqa: F401  (registers the tasks in the actor's process)

            self.env = gym.make(env_id, **kwargs)

        def run(self, share: list[int]) -> list[Episode]:
            return [run_episode(self.env, s, policy, max_steps) for s in share]

    count = min(actors, max(1, len(seeds)))
    actor: Any = ray.remote(Worker)
    workers = [actor.remote() for _ in range(count)]
    shares = [seeds[k::count] for k in range(count)]
    results = ray.get([w.run.remote(share) for w, share in zip(workers, shares, strict=True)])
    for w in workers:
        ray.kill(w)
    ordered: list[Episode] = [None] * len(seeds)  # type: ignore[list-item]
    for k, part in enumerate(results):
        ordered[k::count] = part
    return ordered
