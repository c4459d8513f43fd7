"""A random agent on a registered task, through nothing but Gymnasium's API.

`gymnasium.make("mjkdl/PandaReach-v0")` after `import mjkdl.task`; actions are drawn from the
action space, seeded per episode, so every run prints the same returns.

    python examples/random_agent.py                              # viewer with live plots
    python examples/random_agent.py --headless --episodes 3      # prints each episode's return
    python examples/random_agent.py --headless --task mjkdl/PandaPickCube-v0
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
from common import parse_args
from tqdm import tqdm

import mjkdl.task


def options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", default="mjkdl/PandaReach-v0", help="registered task id")
    parser.add_argument("--episodes", type=int, default=2, help="episodes to run headless")
    parser.add_argument("--seed", type=int, default=0, help="seed of the first episode")


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=10.0, extra=options)
    env = gym.make(args.task)
    print(f"task: {args.task}")
    print(f"action space: {env.action_space}")
    if not args.headless:
        space = env.action_space
        space.seed(args.seed)
        mjkdl.task.view(env, lambda obs: space.sample(), plots=["panda_tcp_pos"], seed=args.seed)
        env.close()
        return 0
    max_steps = max(1, round(args.duration / env.unwrapped.control_timestep))
    total_steps, start = 0, time.perf_counter()
    returns = []
    for k in tqdm(range(args.episodes), desc="episodes", disable=None, delay=1.0):
        episode = mjkdl.task.run_episode(env, args.seed + k, max_steps=max_steps)
        returns.append(episode.total_reward)
        total_steps += episode.steps
        tqdm.write(
            f"episode {k}: seed {episode.seed}, steps {episode.steps}, "
            f"return {episode.total_reward:.4f}"
        )
    elapsed = time.perf_counter() - start
    print(f"episodes: {len(returns)}")
    print(f"mean return: {sum(returns) / len(returns):.4f}")
    print(f"control steps per second: {total_steps / elapsed:.0f}")
    env.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
