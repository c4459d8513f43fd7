"""Task environment throughput: `mjkdl/PandaReach-v0` control steps against raw MuJoCo.

One control step is 0.1 s of simulation: 50 physics steps of 2 ms. Compared in one process,
interleaved in blocks of `STEPS` control steps (each block starts from a fresh reset, untimed):
(a) raw MuJoCo: `mj_step(m, d, 50)` on the same compiled model from the state the env's
    episode starts in (arm pose, ball), the arm held there by its authored servos;
(b) `env.step(action)`: the action checked and clipped, the Cartesian QP solved, 50 physics
    steps, a forward pass, every observation read and copied, the reward;
(c) the same with a 128x128 RGB camera observation (and with depth as well), shadows and
    reflections off (`CameraSensor`'s default), in their own shorter blocks.
Then `render()` ("rgb_array", shadows off) against a `CameraSensor` of the same size, and an
async vector env (`gymnasium.make_vec(..., vectorization_mode="async")`) with 1 ... N
sub-environments, N the machine's cores, without and with a 128x128 camera each.
dm_robotics_panda's own figure for its Panda environment, for scale: 209 control steps/s.

    python benchmarks/task_env.py
    python benchmarks/task_env.py --blocks 40 --vector-seconds 10     # longer, steadier
"""

from __future__ import annotations

import argparse
import os
import time
import tracemalloc
from collections.abc import Callable

import gymnasium as gym
import mujoco
import numpy as np
import scenes  # noqa: F401  (points MENAGERIE_ROOT at the shared Menagerie when unset)
from tqdm import tqdm

import mjkdl as mjk
from mjkdl.task import CameraSensor, TaskEnv  # importing mjkdl.task registers the tasks
from mjkdl.task.registry import panda_reach_spec

STEPS = 20  # control steps per block (2 s of simulation)
CAMERA_STEPS = 5
DM_ROBOTICS_PANDA = 209.0  # control steps/s, from the issue


def raw_loop(
    template: TaskEnv, seed: int = 0
) -> tuple[Callable[[], None], Callable[[int], None], mjk.Scene]:
    """The scene of PandaReach-v0 stepped by MuJoCo alone, from the state `template` starts
    its episode of `seed` in (the arm's pose, the ball's place), the authored servos holding
    the arm there and the hand opening: the physics `env.step` runs, without the env."""
    scene = mjk.Scene.build(panda_reach_spec().scene)
    m, d = scene.model, scene.data
    substeps = round(0.1 / m.opt.timestep)

    def reset() -> None:
        template.reset(seed=seed)
        mujoco.mj_resetData(m, d)
        d.qpos[:] = template.scene.data.qpos
        d.ctrl[:7] = d.qpos[:7]
        d.ctrl[7] = 255.0
        mujoco.mj_forward(m, d)

    def run(n: int) -> None:
        for _ in range(n):
            mujoco.mj_step(m, d, substeps)

    return reset, run, scene


def env_loop(env: TaskEnv, seed: int = 0) -> tuple[Callable[[], None], Callable[[int], None]]:
    """`env.step` with a still twist and the hand open (what the raw loop simulates)."""
    action = np.zeros(env.action_space.shape, np.float32)
    action[-1] = env.action_space.low[-1]  # the gripper's "open" end

    def reset() -> None:
        env.reset(seed=seed)

    def run(n: int) -> None:
        for _ in range(n):
            env.step(action)

    return reset, run


def camera_env(depth: bool) -> TaskEnv:
    spec = panda_reach_spec()
    spec.sensors = [*spec.sensors, CameraSensor("front", 128, 128, depth=depth)]
    return TaskEnv(spec)


def interleaved(
    loops: dict[str, tuple], blocks: int, steps: int
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Wall-clock and CPU seconds (all threads of this process) per control step of each
    loop, per block of `steps`, run in turn. On a busy machine the CPU figure is the steadier:
    it leaves out the time spent waiting for a core."""
    times: dict[str, list[float]] = {name: [] for name in loops}
    cpu: dict[str, list[float]] = {name: [] for name in loops}
    for reset, run in loops.values():  # warm up: caches, renderer, QP solver
        reset()
        run(3)
    for _ in tqdm(range(blocks), desc="blocks", disable=None, leave=False):
        for name, (reset, run) in loops.items():
            reset()
            t0, c0 = time.perf_counter(), time.process_time()
            run(steps)
            times[name].append((time.perf_counter() - t0) / steps)
            cpu[name].append((time.process_time() - c0) / steps)
    return {k: np.array(t) for k, t in times.items()}, {k: np.array(t) for k, t in cpu.items()}


def retained_bytes(reset: Callable[[], None], run: Callable[[int], None]) -> int:
    """Bytes still allocated after 60 control steps (the returned observations dropped)."""
    reset()
    run(5)
    tracemalloc.start()
    before = tracemalloc.take_snapshot()
    run(60)
    after = tracemalloc.take_snapshot()
    tracemalloc.stop()
    return sum(s.size_diff for s in after.compare_to(before, "filename"))


def render_costs(size: tuple[int, int], frames: int) -> tuple[float, float]:
    """Seconds per `env.render()` frame ("rgb_array") and per camera observation of the same
    camera and size (a step with a `CameraSensor` minus one without), interleaved."""
    w, h = size
    spec = panda_reach_spec()
    spec.sensors = [*spec.sensors, CameraSensor("front", w, h)]
    with_camera = TaskEnv(spec)
    renders = TaskEnv(
        panda_reach_spec(), "rgb_array", render_camera="front", render_width=w, render_height=h
    )
    loops = {"sensor": env_loop(with_camera), "plain": env_loop(renders)}

    def render_loop(n: int) -> None:
        for _ in range(n):
            renders.render()

    loops["render"] = (loops["plain"][0], render_loop)
    times, _ = interleaved(loops, frames, 3)
    with_camera.close()
    renders.close()
    sensor = float(np.median(times["sensor"] - times["plain"]))
    return float(np.median(times["render"])), sensor


def vector_rate(num_envs: int, seconds: float, **kwargs: object) -> float:
    """Control steps per second summed over `num_envs` async sub-environments (Linux's default
    start method, fork), with `gym.make` keyword arguments `kwargs` (e.g. cameras)."""
    vec = gym.make_vec(
        "mjkdl/PandaReach-v0", num_envs=num_envs, vectorization_mode="async", **kwargs
    )
    try:
        vec.reset(seed=0)
        action = np.zeros(vec.action_space.shape, np.float32)
        action[:, -1] = -1.0  # hands open
        vec.step(action)
        steps, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            vec.step(action)
            steps += num_envs
        return steps / (time.perf_counter() - t0)
    finally:
        vec.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=15, help="interleaved blocks")
    parser.add_argument("--camera-blocks", type=int, default=4, help="blocks with cameras")
    parser.add_argument(
        "--vector-seconds", type=float, default=4.0, help="wall seconds per vector-env size"
    )
    args = parser.parse_args()

    # Vector envs first, before this process renders: their workers are forked (Linux's
    # default start method), and OpenGL does not survive a fork once the parent rendered.
    cores = os.cpu_count() or 1
    vector_lines = []
    for label, kwargs in (("no camera", {}), ("128x128 camera", {"camera_names": ["wrist"]})):
        single = None
        for n in sorted({1, *range(2, cores + 1)}):
            rate = vector_rate(n, args.vector_seconds, **kwargs)
            single = rate if single is None else single
            vector_lines.append(
                f"async vector env, {label}, {n} sub-env(s): {rate:7.0f} control steps/s  "
                f"(x{rate / single:.2f} of 1 sub-env; {cores} cores)"
            )

    plain = TaskEnv(panda_reach_spec())
    raw_reset, raw_run, raw_scene = raw_loop(TaskEnv(panda_reach_spec()))
    raw = (raw_reset, raw_run)
    times, cpu = interleaved({"raw MuJoCo": raw, "env.step": env_loop(plain)}, args.blocks, STEPS)
    # Software OpenGL takes tens of ms per image: fewer, shorter blocks for the cameras.
    rgb, rgbd = camera_env(False), camera_env(True)
    cams = {
        "raw MuJoCo": raw,
        "camera 128x128 RGB": env_loop(rgb),
        "camera RGB + depth": env_loop(rgbd),
    }
    cam_times, cam_cpu = interleaved(cams, args.camera_blocks, CAMERA_STEPS)
    print(
        f"MuJoCo {mjk.mujoco_version()}, PandaReach-v0, 0.1 s control period over 2 ms "
        f"physics, interleaved blocks"
    )
    for label, results in (("wall", times), ("CPU", cpu), ("wall", cam_times), ("CPU", cam_cpu)):
        base = results["raw MuJoCo"]
        for name, t in results.items():
            ratio = t / base
            print(
                f"{name:20} {label:4} {1 / np.median(t):7.1f} control steps/s "
                f"({np.median(t) * 1e3:7.2f} ms/step)  ratio to raw: median "
                f"{np.median(ratio):.3f} (p10 {np.percentile(ratio, 10):.3f}, "
                f"p90 {np.percentile(ratio, 90):.3f})"
            )
    env_rate = 1 / np.median(times["env.step"])
    print(
        f"env.step vs dm_robotics_panda's {DM_ROBOTICS_PANDA:.0f} steps/s: "
        f"{env_rate / DM_ROBOTICS_PANDA:.1f}x"
    )
    overhead = np.median(cpu["env.step"] - cpu["raw MuJoCo"]) * 1e6
    print(f"env.step overhead over raw physics (CPU): {overhead:.0f} us per control step")
    print(f"memory retained over 60 env steps: {retained_bytes(*env_loop(plain))} bytes")
    for env in (plain, rgb, rgbd):
        env.close()
    raw_scene.close()

    for size in ((128, 128), (640, 480)):
        render, sensor = render_costs(size, args.camera_blocks)
        print(
            f"render() rgb_array {size[0]}x{size[1]}: {render * 1e3:6.2f} ms/frame; a "
            f"CameraSensor of that size: {sensor * 1e3:6.2f} ms/step (ratio {render / sensor:.2f})"
        )
    print("\n".join(vector_lines))


if __name__ == "__main__":
    main()
