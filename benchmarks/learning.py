"""Proof by learning: standard learners on the registered tasks, with measured curves.

On demand, not in CI (minutes to an hour on 2 cores). Needs the `rl` extra:
`pip install -e ".[rl]"` (Stable-Baselines3, sb3-contrib; PyTorch, CPU is enough).

    python benchmarks/learning.py ppo-reach            # PPO defaults, MultiInputPolicy, 150k steps
    python benchmarks/learning.py her-reach            # SAC + HER on PandaReachGoal-v0, 30k steps
    python benchmarks/learning.py bc-pick              # behaviour cloning of the expert, PickCube
    python benchmarks/learning.py rslrl-pick --device cuda   # rsl-rl PPO on many worlds
    python benchmarks/learning.py rslrl-pick --device cuda --minutes 10 --chunks 10  # by time
    python benchmarks/learning.py rslrl-place --device cuda --minutes 30 --chunks 15
    python benchmarks/learning.py rslrl-reach --device cpu --envs 8 --iterations 2  # tiny
    python benchmarks/learning.py rslrl-pick --device cpu --minutes 30 --chunks 6 --threads 2
    python benchmarks/learning.py rslrl-push --device cpu --minutes 30 --chunks 6 --threads 2
    python benchmarks/learning.py rslrl-place --device cpu --minutes 60 --chunks 6 --threads 2
    python benchmarks/learning.py plot                 # docs/learning.png from the saved curves

The `rslrl-*` runs need the `warp-rl` extra: PPO (rsl-rl) on `mjkdl.task.make_batch`'s
worlds with the task's recipe (`mjkdl.task.batch.ppo`), evaluated on the CPU env. Their goal on
one H100: PickCube >= 90 % success within 10 minutes of wall time, PickAndPlace >= 80 % within
30 (`--minutes`: training wall time, the evaluations on the CPU env not counted; not measured
here: no GPU was lent). On a CPU (`--device cpu`) a task's recipe may have its own settings
(`Recipe.on`): PickCube's runs 128 worlds of MuJoCo's batch with the shaped reward, aiming at
>= 90 % within 30 minutes on 2 cores (docs/task.md gives what was measured).

Each run evaluates the deterministic policy on 20 held-out seeds (10000..10019) at checkpoints
and writes its curve, with wall time and steps/s of training and of the env alone, to
`benchmarks/results/<run>.json`; `plot` draws them. Success is `info["is_success"]` at the last
step of an episode (what SB3's `success_rate` reads).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import scenes  # noqa: F401  (points MENAGERIE_ROOT at the shared Menagerie when unset)

import mjkdl.task  # noqa: F401  (registers the tasks)
from mjkdl.task.experts import expert_for

RESULTS = [Path(__file__).resolve().parent / "results"]  # --results changes it
EVAL_SEEDS = range(10_000, 10_020)
Policy = Callable[[dict[str, np.ndarray]], np.ndarray]


def evaluate(env_id: str, policy: Policy, seeds: range = EVAL_SEEDS, **task_kwargs: Any) -> float:
    """Fraction of `seeds` whose episode ends in success under `policy` (the env made with
    `task_kwargs`)."""
    env = gym.make(env_id, **task_kwargs)
    wins = 0
    for seed in seeds:
        obs, info = env.reset(seed=seed)
        done = False
        while not done:
            obs, _, terminated, truncated, info = env.step(policy(obs))
            done = terminated or truncated
        wins += bool(info["is_success"])
    env.close()
    return wins / len(seeds)


def env_steps_per_second(env_id: str, steps: int = 2000, **task_kwargs: Any) -> float:
    """Control steps/s of the env alone under random actions (the learner's ceiling)."""
    env = gym.make(env_id, **task_kwargs)
    env.reset(seed=0)
    env.action_space.seed(0)
    start = time.perf_counter()
    for _ in range(steps):
        *_, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            env.reset()
    rate = steps / (time.perf_counter() - start)
    env.close()
    return rate


def write(run: str, record: dict[str, Any]) -> None:
    """`record` to `<results>/<run>.json`."""
    RESULTS[0].mkdir(parents=True, exist_ok=True)
    (RESULTS[0] / f"{run}.json").write_text(json.dumps(record, indent=1))


def result_name(record: dict[str, Any]) -> str:
    """A run's file name: its name, with "-cuda" for a run on a GPU (a CPU run keeps its own)."""
    return record["run"] + ("-cuda" if record.get("device", "cpu").startswith("cuda") else "")


def save(run: str, record: dict[str, Any]) -> None:
    write(run, record)
    last = record["curve"][-1]
    print(
        f"{run}: {last['success']:.0%} success after {last['steps']} steps, "
        f"{record['wall_seconds']:.0f} s wall, training {record['train_steps_per_s']:.0f} "
        f"steps/s, env alone {record['env_steps_per_s']:.0f} steps/s"
    )


def sb3_run(run: str, env_id: str, make_model: Callable[[gym.Env], Any], steps: int, every: int):
    """Train an SB3 model with evaluation checkpoints; returns the record it saves."""
    from stable_baselines3.common.callbacks import BaseCallback

    curve: list[dict[str, float]] = []
    train_time = [0.0]

    class Checkpoints(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.last = time.perf_counter()

        def _on_step(self) -> bool:
            if self.num_timesteps % every == 0:
                self.checkpoint()
            return True

        def checkpoint(self) -> None:
            """Evaluate the deterministic policy now; the time spent is not training."""
            now = time.perf_counter()
            train_time[0] += now - self.last

            def policy(obs: dict[str, np.ndarray]) -> np.ndarray:
                return self.model.predict(obs, deterministic=True)[0]

            rate = evaluate(env_id, policy)
            curve.append({"steps": self.num_timesteps, "success": rate})
            print(f"  {self.num_timesteps:>7} steps: {rate:.0%} ({train_time[0]:.0f} s)")
            self.last = time.perf_counter()

    env = gym.make(env_id)
    model = make_model(env)
    start = time.perf_counter()
    callback = Checkpoints()
    model.learn(total_timesteps=steps, callback=callback)
    if not curve or curve[-1]["steps"] < callback.num_timesteps:  # the result is the last
        callback.checkpoint()
    wall = time.perf_counter() - start
    record = {
        "run": run,
        "env_id": env_id,
        "curve": curve,
        "wall_seconds": wall,
        "train_seconds": train_time[0],
        "train_steps_per_s": callback.num_timesteps / train_time[0],
        "env_steps_per_s": env_steps_per_second(env_id),
        "torch_threads": __import__("torch").get_num_threads(),
    }
    env.close()
    return record


def ppo_reach(steps: int) -> None:
    """SB3 PPO with its default hyperparameters, MultiInputPolicy, one env, no wrappers."""
    from stable_baselines3 import PPO

    record = sb3_run(
        "ppo-reach",
        "mjkdl/PandaReach-v0",
        lambda env: PPO("MultiInputPolicy", env, seed=0, verbose=0),
        steps,
        every=10_000,
    )
    record["recipe"] = "PPO('MultiInputPolicy', env) with SB3's defaults, seed 0"
    save("ppo-reach", record)


# rl-zoo's settings for goal-conditioned reaching (a shorter horizon, faster targets): with
# SB3's defaults (gamma 0.99, learning rate 3e-4, tau 0.005) SAC + HER was still at 0 % after
# 16k steps here.
HER_REACH = {"gamma": 0.95, "learning_rate": 1e-3, "tau": 0.05}


def her_reach(steps: int) -> None:
    """SAC + HER (SB3's HerReplayBuffer, 4 future goals) on the goal-conditioned Reach."""
    from stable_baselines3 import SAC, HerReplayBuffer

    record = sb3_run(
        "her-reach",
        "mjkdl/PandaReachGoal-v0",
        lambda env: SAC(
            "MultiInputPolicy",
            env,
            replay_buffer_class=HerReplayBuffer,
            replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
            learning_starts=1000,
            **HER_REACH,
            seed=0,
            verbose=0,
        ),
        steps,
        every=2_000,
    )
    record["recipe"] = (
        "SAC('MultiInputPolicy', env, replay_buffer_class=HerReplayBuffer, "
        "replay_buffer_kwargs={'n_sampled_goal': 4, 'goal_selection_strategy': 'future'}, "
        f"learning_starts=1000, {HER_REACH}), otherwise SB3's defaults, seed 0"
    )
    save("her-reach", record)


def bc_pick(demos: int, epochs: int, noise: float) -> None:
    """Behaviour cloning of the scripted expert on PickCube: an MLP (256, 256) regressing
    the expert's action from the observation vector, trained with Adam on `demos` episodes.
    The demonstrations execute the expert's action plus Gaussian noise of std `noise` while
    recording the expert's own action (DART): the clone sees, and learns to leave, the states
    its own small errors lead to."""
    import torch

    env_id = "mjkdl/PandaPickCube-v0"
    env = gym.make(env_id)
    keys = [k for k, b in env.observation_space.spaces.items() if k != "time"]
    expert = expert_for(env)

    def flat(obs: dict[str, np.ndarray]) -> np.ndarray:
        return np.concatenate([np.ravel(obs[k]) for k in keys]).astype(np.float32)

    start = time.perf_counter()
    xs, ys = [], []
    rng = np.random.default_rng(0)
    for seed in range(demos):
        obs, _ = env.reset(seed=seed)
        expert.reset()
        done = False
        while not done:
            action = expert(obs)
            xs.append(flat(obs))
            ys.append(action)
            noisy = np.clip(action + rng.normal(0.0, noise, action.shape), -1, 1)
            obs, _, terminated, truncated, _ = env.step(noisy.astype(np.float32))
            done = terminated or truncated
    collect = time.perf_counter() - start
    x, y = torch.tensor(np.array(xs)), torch.tensor(np.array(ys))
    mean, std = x.mean(0), x.std(0) + 1e-6
    torch.manual_seed(0)
    net = torch.nn.Sequential(
        torch.nn.Linear(x.shape[1], 256),
        torch.nn.ReLU(),
        torch.nn.Linear(256, 256),
        torch.nn.ReLU(),
        torch.nn.Linear(256, y.shape[1]),
        torch.nn.Tanh(),
    )
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)

    def policy(obs: dict[str, np.ndarray]) -> np.ndarray:
        with torch.no_grad():
            out = net((torch.tensor(flat(obs)) - mean) / std).numpy()
        return out

    curve = []
    train = 0.0
    every = max(1, epochs // 10)
    for epoch in range(1, epochs + 1):
        t0 = time.perf_counter()
        order = torch.randperm(len(x))
        for i in range(0, len(x), 256):
            idx = order[i : i + 256]
            loss = torch.nn.functional.mse_loss(net((x[idx] - mean) / std), y[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
        train += time.perf_counter() - t0
        if epoch % every == 0:
            rate = evaluate(env_id, policy)
            curve.append({"steps": epoch, "success": rate, "loss": loss.item()})
            print(f"  epoch {epoch}: loss {loss.item():.4f}, {rate:.0%}")
    env.close()
    save(
        "bc-pick",
        {
            "run": "bc-pick",
            "env_id": env_id,
            "recipe": f"behaviour cloning (DART noise {noise}): {demos} expert episodes "
            f"({len(x)} steps), MLP 256x256 + tanh, Adam 1e-3, batch 256, MSE, {epochs} "
            "epochs, seed 0",
            "curve": curve,
            "x_label": "epochs",
            "wall_seconds": time.perf_counter() - start,
            "collect_seconds": collect,
            "train_seconds": train,
            "train_steps_per_s": len(x) * epochs / train,
            "env_steps_per_s": env_steps_per_second(env_id),
            "torch_threads": torch.get_num_threads(),
        },
    )


def rslrl_run(
    run: str,
    env_id: str,
    device: str,
    envs: int,
    iterations: int,
    chunks: int,
    minutes: float,
    seed: int = 0,
):
    """rsl-rl PPO on `envs` worlds of `env_id` (the task's recipe), evaluated on the CPU env
    after each of `chunks` equal parts of `iterations`; with `minutes`, instead for that much
    training wall time, evaluated about every `minutes / chunks`. PyTorch is seeded with
    `seed`, as `train` seeds it (the worlds start from seeds 0, 1, ...). The curve is saved
    after every evaluation, so a run stopped from outside keeps what it measured."""
    import torch
    from rsl_rl.runners import OnPolicyRunner

    from mjkdl.task.batch import make_batch
    from mjkdl.task.batch.ppo import RslRlEnv, auto_reset_workers, env_policy, recipe

    if not device:
        device = "cuda:0" if torch.cuda.is_available() else "cpu"
    elif device.startswith("cuda") and not torch.cuda.is_available():
        print(f"--device {device}: no CUDA GPU here; the CPU engine runs the recipe's CPU worlds")
        device = "cpu"
    r = recipe(env_id).on(device)
    envs = envs or r.num_envs
    iterations = iterations or r.iterations
    torch.manual_seed(seed)
    batch = make_batch(
        env_id,
        envs,
        device=device,
        reset_workers=auto_reset_workers(device),
        **r.task_kwargs,
    )
    env = RslRlEnv(batch)
    runner = OnPolicyRunner(
        env, {**r.config, "num_steps_per_env": r.num_steps_per_env}, None, str(batch.device)
    )
    curve: list[dict[str, float]] = []
    train_seconds, done = 0.0, 0
    start = time.perf_counter()
    record = {
        "run": run,
        "env_id": env_id,
        "task_kwargs": r.task_kwargs,
        "device": str(batch.device),
        "num_envs": envs,
        "num_steps_per_env": r.num_steps_per_env,
        "config": r.config,
        "torch_threads": torch.get_num_threads(),
        "seed": seed,
    }
    budget = 60.0 * minutes
    for k in range(10**9 if budget else chunks):
        if budget:
            if train_seconds >= budget:
                break
            t = time.perf_counter()
            while time.perf_counter() - t < budget / chunks and train_seconds < budget:
                step = time.perf_counter()
                runner.learn(num_learning_iterations=1, init_at_random_ep_len=done == 0)
                train_seconds += time.perf_counter() - step
                done += 1
        else:
            part = iterations * (k + 1) // chunks - done
            t = time.perf_counter()
            runner.learn(num_learning_iterations=part, init_at_random_ep_len=done == 0)
            train_seconds += time.perf_counter() - t
            done += part
        steps = envs * r.num_steps_per_env * done
        with env_policy(runner) as policy:  # on the CPU, then back on the runner's device
            rate = evaluate(env_id, policy, **r.task_kwargs)
        curve.append({"steps": steps, "success": rate, "seconds": train_seconds})
        print(f"  {steps:>9} steps: {rate:.0%} ({train_seconds:.0f} s)", flush=True)
        write(result_name(record), {**record, "curve": curve, "train_seconds": train_seconds})
    batch.close()
    return {
        **record,
        "curve": curve,
        "wall_seconds": time.perf_counter() - start,
        "train_seconds": train_seconds,
        "train_steps_per_s": curve[-1]["steps"] / train_seconds,
        "env_steps_per_s": env_steps_per_second(env_id, **r.task_kwargs),
    }


# Each run's goal in percent of the held-out seeds (the dashed line; others 90).
GOALS = {"bc-pick": 50, "rslrl-place": 80}


def plot() -> None:
    """docs/learning.png: the saved curves side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = [json.loads(p.read_text()) for p in sorted(RESULTS[0].glob("*.json"))]
    fig, axes = plt.subplots(1, len(runs), figsize=(4 * len(runs), 3.2), squeeze=False)
    for ax, run in zip(axes[0], runs, strict=True):
        steps = [c["steps"] for c in run["curve"]]
        ax.plot(steps, [100 * c["success"] for c in run["curve"]], marker="o")
        where = ", GPU" if run.get("device", "cpu").startswith("cuda") else ""
        ax.set_title(f"{run['run']} ({run['env_id'].split('/')[1]}{where})", fontsize=9)
        ax.set_xlabel(run.get("x_label", "environment steps"))
        ax.set_ylabel("success, 20 held-out seeds (%)")
        ax.set_ylim(-5, 105)
        ax.axhline(GOALS.get(run["run"], 90), color="grey", lw=0.8, ls="--")
        ax.grid(alpha=0.3)
    fig.tight_layout()
    out = Path(__file__).resolve().parents[1] / "docs" / "learning.png"
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "run",
        choices=[
            "ppo-reach",
            "her-reach",
            "bc-pick",
            "rslrl-reach",
            "rslrl-pick",
            "rslrl-push",
            "rslrl-place",
            "plot",
        ],
    )
    parser.add_argument(
        "--device", default="", help="rslrl-*: cuda (MuJoCo Warp) or cpu (default: cuda if any)"
    )
    parser.add_argument("--envs", type=int, default=0, help="rslrl-*: worlds (0: recipe's)")
    parser.add_argument(
        "--iterations", type=int, default=0, help="rslrl-*: PPO iterations (0: recipe's)"
    )
    parser.add_argument("--chunks", type=int, default=1, help="rslrl-*: evaluations")
    parser.add_argument(
        "--minutes", type=float, default=0.0, help="rslrl-*: train this long (not --iterations)"
    )
    parser.add_argument("--steps", type=int, default=0, help="training steps (0: the run's own)")
    parser.add_argument("--seed", type=int, default=0, help="rslrl-*: PyTorch's seed")
    parser.add_argument("--demos", type=int, default=300, help="bc-pick: expert episodes")
    parser.add_argument("--epochs", type=int, default=50, help="bc-pick: training epochs")
    parser.add_argument(
        "--noise", type=float, default=0.3, help="bc-pick: action noise while demonstrating"
    )
    parser.add_argument(
        "--threads", type=int, default=1, help="PyTorch threads (small networks: 1 is fastest)"
    )
    parser.add_argument("--results", type=Path, default=RESULTS[0], help="where curves go")
    args = parser.parse_args()
    RESULTS[0] = args.results
    os.environ.setdefault("MUJOCO_GL", "egl")
    if args.run != "plot":
        import torch

        torch.set_num_threads(args.threads)
    if args.run == "ppo-reach":
        ppo_reach(args.steps or 150_000)
    elif args.run == "her-reach":
        her_reach(args.steps or 30_000)
    elif args.run.startswith("rslrl-"):
        task = {
            "rslrl-reach": "mjkdl/PandaReach-v0",
            "rslrl-pick": "mjkdl/PandaPickCube-v0",
            "rslrl-push": "mjkdl/PandaPush-v0",
            "rslrl-place": "mjkdl/PandaPickAndPlace-v0",
        }
        record = rslrl_run(
            args.run,
            task[args.run],
            args.device,
            args.envs,
            args.iterations,
            args.chunks,
            args.minutes,
            args.seed,
        )
        save(result_name(record), record)
    elif args.run == "bc-pick":
        bc_pick(args.demos, args.epochs, args.noise)
    else:
        plot()


if __name__ == "__main__":
    main()
