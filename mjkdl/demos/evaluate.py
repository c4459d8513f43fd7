"""Evaluation: a policy on many seeds; success rate with its 95 % Wilson interval."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tqdm import tqdm

from ..errors import SpecError
from ..task._check import integer
from .deploy import StopKey, deploy
from .episodes import EpisodeResult, Video, run_seeds
from .policy import PolicySource, at_policy_rate

Z95 = 1.959963984540054  # the standard normal's 97.5 % quantile


def wilson_interval(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of a binomial proportion (95 % for the default `z`)."""
    if n <= 0:
        raise SpecError(f"a success rate needs at least one episode, got {n}")
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


@dataclass(frozen=True)
class Evaluation:
    """Per-episode results (seed order) and the success rate with its 95 % interval."""

    episodes: list[EpisodeResult]
    videos: list[Path]

    @property
    def successes(self) -> int:
        """Successful episodes."""
        return sum(e.success for e in self.episodes)

    @property
    def success_rate(self) -> float:
        """Fraction of successful episodes."""
        return self.successes / len(self.episodes)

    @property
    def interval(self) -> tuple[float, float]:
        """95 % Wilson interval of the success rate."""
        return wilson_interval(self.successes, len(self.episodes))

    @property
    def mean_return(self) -> float:
        """Mean summed reward per episode."""
        return sum(e.total_reward for e in self.episodes) / len(self.episodes)

    @property
    def mean_length(self) -> float:
        """Mean steps per episode."""
        return sum(e.length for e in self.episodes) / len(self.episodes)

    def summary(self) -> str:
        """`success: 93.0 % (95 % CI 86.3-96.6 %, 93/100), return ..., length ...`."""
        lo, hi = self.interval
        n = len(self.episodes)
        return (
            f"success: {100 * self.success_rate:.1f} % (95 % CI {100 * lo:.1f}-{100 * hi:.1f} %, "
            f"{self.successes}/{n}); mean return {self.mean_return:.3f}, "
            f"mean length {self.mean_length:.1f} steps"
        )


def evaluate(
    env_id: str,
    policy: PolicySource,
    *,
    episodes: int,
    seed: int = 0,
    env_kwargs: Mapping[str, Any] | None = None,
    video_dir: str | os.PathLike[str] | None = None,
    videos: int = 3,
    video_size: tuple[int, int] = (640, 480),
    workers: int = 1,
    progress: bool = True,
    robot_ip: str | None = None,
    stop_key: StopKey | None = None,
) -> Evaluation:
    """Run `policy` for `episodes` episodes on seeds `seed`, `seed + 1`, ...; with
    `video_dir`, MP4s of the first `videos` episodes (`episode_<seed>.mp4`, `video_size`).
    A policy with a rate of its own (a LeRobot policy's dataset fps) acts at it: the env's
    `control_timestep` is its period.

    With `robot_ip` the policy is deployed on the arm at that address, in the loop, in this
    process (`mjkdl.demos.deploy`): Enter on the terminal (`stop_key`, stdin's by default) or
    Ctrl+C raise `DeploymentStopped`, a fault `DeploymentFault`, each with the arm at rest."""
    episodes = integer(episodes, "--episodes")
    seed = integer(seed, "--seed", least=0)
    kwargs = at_policy_rate(policy, env_kwargs or {})
    if robot_ip is not None:
        if workers != 1:
            raise SpecError(
                f"--robot-ip: the arm takes one client, run --workers 1 (got {workers})"
            )
        if "robot_ip" in kwargs:
            raise SpecError("--robot-ip and --env-kwargs' robot_ip: give the address once")
        kwargs["robot_ip"] = robot_ip
    seeds = list(range(seed, seed + episodes))
    paths: dict[int, Video] = {}
    if video_dir is not None:
        folder = Path(video_dir)
        folder.mkdir(parents=True, exist_ok=True)
        paths = {
            s: Video(folder / f"episode_{s}.mp4", *video_size) for s in seeds[: max(0, videos)]
        }
    results: list[EpisodeResult] = []
    with tqdm(total=episodes, desc=f"evaluate {env_id}", unit="ep", disable=not progress) as bar:

        def done(result: EpisodeResult) -> None:
            results.append(result)
            bar.update()
            bar.set_postfix(success=sum(r.success for r in results))

        if robot_ip is not None:
            deploy(env_id, kwargs, policy, seeds, videos=paths, on_episode=done, stop_key=stop_key)
        else:
            for result in run_seeds(env_id, kwargs, policy, seeds, videos=paths, workers=workers):
                done(result)
    return Evaluation(results, [v.path for v in paths.values()])
