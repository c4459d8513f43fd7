"""Many episodes of a registered task over Ray actors, on this machine or a cluster.

Each actor builds the environment once and runs its share of the seeds; an episode depends on
its seed alone, so the returns are the same whichever actor ran it (`--verify` checks that
against a sequential run here). Needs `pip install 'mjkdl[ray]'`.

    python examples/ray_rollouts.py --headless --episodes 8 --actors 2
    python examples/ray_rollouts.py --headless --address ray://head:10001   # a running cluster
    python examples/ray_rollouts.py                   # then shows the best episode in the viewer
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import ray
from common import parse_args
from tqdm import tqdm

import mjkdl.task


def options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", default="mjkdl/PandaReach-v0", help="registered task id")
    parser.add_argument("--episodes", type=int, default=8, help="episodes to collect")
    parser.add_argument("--actors", type=int, default=2, help="Ray actors (one process each)")
    parser.add_argument("--address", default=None, help="Ray cluster address (default: local)")
    parser.add_argument("--verify", action="store_true", help="compare with a sequential run")


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=2.0, extra=options)
    if args.address is None:
        ray.init(num_cpus=args.actors, include_dashboard=False, log_to_driver=False)
    else:
        ray.init(address=args.address)
    max_steps = max(1, round(args.duration / 0.1))
    seeds = list(range(args.episodes))
    try:
        start = time.perf_counter()
        episodes = mjkdl.task.ray_collect(args.task, seeds, actors=args.actors, max_steps=max_steps)
        elapsed = time.perf_counter() - start
    finally:
        ray.shutdown()
    for e in episodes:
        print(f"seed {e.seed}: steps {e.steps}, return {e.total_reward:.4f}")
    steps = sum(e.steps for e in episodes)
    print(f"episodes: {len(episodes)}")
    print(f"mean return: {sum(e.total_reward for e in episodes) / len(episodes):.4f}")
    print(f"control steps per second (with Ray start-up): {steps / elapsed:.0f}")
    env = gym.make(args.task)
    if args.verify:
        sequential = tqdm(seeds, desc="sequential episodes", disable=None, delay=1.0)
        here = [mjkdl.task.run_episode(env, s, max_steps=max_steps) for s in sequential]
        print(f"matches sequential: {here == episodes}")
    if not args.headless:
        best = max(episodes, key=lambda e: e.total_reward)
        print(f"showing seed {best.seed}")
        space = env.action_space
        space.seed(best.seed)
        mjkdl.task.view(env, lambda obs: space.sample(), seed=best.seed, max_steps=max_steps)
    env.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
