"""The same PickCube actions in the plain simulation and in the loop: how far the arms differ.

For each seed the scripted expert runs a whole `mjkdl/PandaPickCube-v0` episode in the plain
simulation (the task env's Panda, Menagerie's position servos); its actions are then replayed,
unchanged, in the loop (`robot_ip`) against `python -m mjkdl.hw.franka_sim --lockstep --scene
empty` (started here), whose arm runs the robot's joint-impedance controller at 1 kHz with its
rate limits. Reported per seed: the TCP distance between the two runs after each control step
(median, max, over the steps both ran), the lowest TCP height in each, and success in each
(`info["is_success"]` at the end). With `--closed-loop` the expert also runs in the loop on its
own observations (success only), as a Franka user would run it. `--arm-drive
franka_impedance` simulates the Panda with the arm's own joint impedance
(`mjkdl.hw.joint_impedance`) instead. `--cost` times, in one process, the task env's step
with each drive on the same actions, against raw `mj_step` of the same scene for a control
period (no loop, no server). `--experts` runs every registered task's expert (or those of
`--tasks`) on its own observations, whole episodes, in the simulation with `--arm-drive` and
in the loop, and prints each one's success at the end of the episode in both.

    python benchmarks/sim_to_loop.py [--seeds 5] [--closed-loop] [--arm-drive DRIVE]
    python benchmarks/sim_to_loop.py --cost
    python benchmarks/sim_to_loop.py --experts [--tasks Stack,Push] --seeds 30
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import threading
import time

import gymnasium as gym
import mujoco
import numpy as np
import scenes  # noqa: F401  (points MENAGERIE_ROOT at the shared Menagerie when unset)

from mjkdl.demos.episodes import run_episode
from mjkdl.demos.policy import make_policy
from mjkdl.task.experts import expert_for
from mjkdl.task.registry import TASKS

TASK = "mjkdl/PandaPickCube-v0"
# the env's process may stall for seconds on a loaded machine: the arm waits (lockstep=True)
SERVER = ("--lockstep", "--scene", "empty", "--command-timeout", "10")


def expert_episode(env: gym.Env, seed: int) -> tuple[list[np.ndarray], np.ndarray, bool]:
    """(actions, TCP position after each step, success at the end) of the expert's episode."""
    expert = expert_for(env)
    obs, _ = env.reset(seed=seed)
    expert.reset()
    actions, tcp, done, info = [], [], False, {}
    while not done:
        action = expert(obs)
        obs, _, terminated, truncated, info = env.step(action)
        actions.append(np.array(action))
        tcp.append(obs["panda_tcp_pos"].copy())
        done = terminated or truncated
    return actions, np.array(tcp), bool(info["is_success"])


def replay(env: gym.Env, seed: int, actions: list[np.ndarray]) -> tuple[np.ndarray, bool]:
    """(TCP position after each step, success at the end) of `actions` from `seed`."""
    env.reset(seed=seed)
    tcp, info = [], {}
    for action in actions:
        obs, _, terminated, truncated, info = env.step(action)
        tcp.append(obs["panda_tcp_pos"].copy())
        if terminated or truncated:
            break
    return np.array(tcp), bool(info["is_success"])


def cost(seeds: int) -> None:
    """ms per step of each drive on the servo expert's actions, and of raw mj_step, in CPU
    time of this process, the drives interleaved step by step (a loaded machine slows
    both alike); then the impedance drive's step against the servos'."""
    servo = gym.make(TASK)
    episodes = [(seed, expert_episode(servo, seed)[0]) for seed in range(seeds)]
    drives = ("servo", "franka_impedance")
    envs = [gym.make(TASK, arm_drive=drive) for drive in drives]
    raw = [(e.unwrapped.scene.model, mujoco.MjData(e.unwrapped.scene.model)) for e in envs]
    spent, bare, steps = [0.0, 0.0], [0.0, 0.0], 0
    clock = time.process_time
    for seed, actions in episodes:
        for env in envs:
            env.reset(seed=seed)
        for action in actions:
            for i, env in enumerate(envs):
                t = clock()
                env.step(action)
                spent[i] += clock() - t
                m, d = raw[i]
                t = clock()
                mujoco.mj_step(m, d, env.unwrapped.control_substeps)
                bare[i] += clock() - t
            steps += 1
    print("| drive | ms per step | raw mj_step, same period (ms) | ratio to raw |")
    print("|---|---|---|---|")
    for i, drive in enumerate(drives):
        per, mj = spent[i] / steps, bare[i] / steps
        print(f"| {drive} | {1e3 * per:.2f} | {1e3 * mj:.2f} | {per / mj:.2f} |")
    print(f"franka_impedance's step / the servos': {spent[1] / spent[0]:.2f} ({steps} steps)")
    for env in (*envs, servo):
        env.close()


def success(env: gym.Env, seed: int) -> bool:
    """Whether the expert's whole episode from `seed` ends in success."""
    return run_episode(env, make_policy("expert", env), seed).success


def experts(host: str, seeds: int, drive: str, only: str) -> None:
    """Each task's expert in the simulation, then in the loop, `seeds` episodes each."""
    ids = [i for i in TASKS if not only or any(t in i for t in only.split(","))]
    print(f"the experts, {seeds} seeds each: simulation (arm_drive={drive!r}) and the loop")
    print("| task | simulation | loop | failed seeds sim / loop |")
    print("|---|---|---|---|")
    for env_id in ids:
        sim = gym.make(env_id, arm_drive=drive)
        in_sim = [success(sim, s) for s in range(seeds)]
        sim.close()
        loop = gym.make(env_id, robot_ip=host, lockstep=True)
        in_loop = [success(loop, s) for s in range(seeds)]
        loop.close()
        failed = [[s for s, ok in enumerate(run) if not ok] or "-" for run in (in_sim, in_loop)]
        print(
            f"| `{env_id}` | {sum(in_sim)}/{seeds} | {sum(in_loop)}/{seeds} | "
            f"{failed[0]} / {failed[1]} |",
            flush=True,
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--closed-loop", action="store_true", help="also the expert in the loop")
    parser.add_argument("--arm-drive", default="servo", help="the simulated arm's drive")
    parser.add_argument("--cost", action="store_true", help="time each drive's step instead")
    parser.add_argument("--experts", action="store_true", help="every task's expert instead")
    parser.add_argument("--tasks", default="", help="with --experts: ids containing these")
    args = parser.parse_args()
    if args.cost:
        cost(args.seeds)
        return
    host = f"127.{os.getpid() % 250 + 1}.253.1"
    server = subprocess.Popen(
        [sys.executable, "-m", "mjkdl.hw.franka_sim", "--host", host, *SERVER],
        stderr=subprocess.PIPE,
        text=True,
    )
    assert server.stderr is not None
    server.stderr.readline()  # it listens
    # what it logs from now on, read so that a long run never fills the pipe
    threading.Thread(target=server.stderr.read, daemon=True).start()
    if args.experts:
        try:
            experts(host, args.seeds, args.arm_drive, args.tasks)
        finally:
            stop(server)
        return
    sim = gym.make(TASK, arm_drive=args.arm_drive)
    loop = None
    try:
        loop = gym.make(TASK, robot_ip=host, lockstep=True)
        print(f"{TASK}, arm_drive={args.arm_drive!r}: the expert's actions replayed in the loop")
        print(
            "| seed | steps sim/loop | TCP difference median (mm) | max (mm) "
            "| lowest TCP z sim/loop (m) | success sim | success loop (replay) |"
            + (" success loop (expert) |" if args.closed_loop else "")
        )
        print("|---|---|---|---|---|---|---|" + ("---|" if args.closed_loop else ""))
        # the simulation's episodes first: the arm's watchdog stops a motion left without
        # commands for 0.2 s, which a simulated episode in between would take
        plain = [expert_episode(sim, seed) for seed in range(args.seeds)]
        every = []
        for seed, (actions, tcp_sim, ok_sim) in enumerate(plain):
            tcp_loop, ok_loop = replay(loop, seed, actions)
            n = min(len(tcp_sim), len(tcp_loop))
            diff = 1000.0 * np.linalg.norm(tcp_sim[:n] - tcp_loop[:n], axis=1)
            every.append(diff)
            row = (
                f"| {seed} | {len(tcp_sim)}/{len(tcp_loop)} | {np.median(diff):.1f} | "
                f"{diff.max():.1f} | {tcp_sim[:, 2].min():.3f}/{tcp_loop[:, 2].min():.3f} | "
                f"{ok_sim} | {ok_loop} |"
            )
            if args.closed_loop:
                row += f" {expert_episode(loop, seed)[2]} |"
            print(row, flush=True)
        pooled = np.concatenate(every)
        print(
            f"all steps of {args.seeds} seeds: TCP difference median {np.median(pooled):.1f} mm, "
            f"max {pooled.max():.1f} mm"
        )
    finally:
        sim.close()
        if loop is not None:
            loop.close()
        stop(server)


def stop(server: subprocess.Popen) -> None:
    """End the server, killed if a loaded machine keeps it from ending within 30 s."""
    server.terminate()
    try:
        server.wait(30)
    except subprocess.TimeoutExpired:
        server.kill()
        server.wait()


if __name__ == "__main__":
    main()
