"""Scripted experts' success rates on the registered tasks, whole episodes.

Each episode runs to its end (100 control steps, or PickCube's termination) from seeds
0, 1, ...; success is `info["is_success"]` at the last step, so a cube pushed past its goal or
dropped after a success counts as a failure. Also the median number of steps to the first
success.

    python benchmarks/experts.py                     # Push, PickAndPlace, Stack (+Goal), 50 seeds
    python benchmarks/experts.py --seeds 100 --all   # every registered task
    python benchmarks/experts.py --all --arm-drive franka_impedance   # the Franka arm's drive
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np
import scenes  # noqa: F401  (points MENAGERIE_ROOT at the shared Menagerie when unset)

from mjkdl.task.experts import expert_for
from mjkdl.task.registry import TASKS

NEW = [i for i in TASKS if any(n in i for n in ("Push", "PickAndPlace", "Stack"))]


def episode(env: gym.Env, expert, seed: int) -> tuple[bool, int | None]:
    """(success at the end, steps to the first success or None)."""
    obs, _ = env.reset(seed=seed)
    expert.reset()
    first, steps, done = None, 0, False
    while not done:
        obs, _, terminated, truncated, info = env.step(expert(obs))
        steps += 1
        if first is None and info["is_success"]:
            first = steps
        done = terminated or truncated
    return bool(info["is_success"]), first


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=50)
    parser.add_argument("--all", action="store_true", help="every registered task")
    parser.add_argument("--arm-drive", default="servo", help="the simulated arm's drive")
    args = parser.parse_args()
    print(f"{args.seeds} seeds per task, whole episodes, arm_drive={args.arm_drive!r}")
    print("| task | success at the end | failed seeds | median steps to success |")
    print("|---|---|---|---|")
    for env_id in TASKS if args.all else NEW:
        env = gym.make(env_id, arm_drive=args.arm_drive)
        expert = expert_for(env)
        rows = [episode(env, expert, s) for s in range(args.seeds)]
        env.close()
        wins = sum(r[0] for r in rows)
        failed = [s for s, r in enumerate(rows) if not r[0]]
        firsts = [r[1] for r in rows if r[1] is not None]
        median = f"{np.median(firsts):.0f}" if firsts else "-"
        print(f"| `{env_id}` | {wins}/{args.seeds} | {failed or '-'} | {median} |", flush=True)


if __name__ == "__main__":
    main()
