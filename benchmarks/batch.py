"""Many worlds: `mjkdl.task.make_batch` on MuJoCo Warp against the CPU env, in one process.

`mjkdl/PandaPickCube-v0` (0.1 s control steps of 50 physics steps of 2 ms), random actions.
Baseline: one CPU env (`TaskEnv.step`), then a synchronous CPU vector env of 4, then the
batch on MuJoCo Warp's device with 1 ... 256 worlds (the CPU device where no GPU is lent):
control steps/s summed over worlds, world-steps/s (physics steps of one world per second),
the reset cost per world (the CPU env's reset on the host, uploaded), MuJoCo Warp's data
per world, and the cost per world of the task's reward and success: evaluated for all worlds
on the device (as `step` does) against each world's rules called on the host (as `step` did
before). Cameras: frames/s of MuJoCo Warp's renderer for all worlds against MuJoCo's OpenGL
renderer (the CPU env's) one world at a time. First-call time (kernel compile) is measured in
fresh subprocesses: with an empty kernel cache and with the one the first filled. The timed
steps run after two warm ones (kernels loaded, physics captured as a graph) with the worlds'
episodes spread over the time limit, so about 1 % of the worlds restart in each.

    python benchmarks/batch.py                       # CPU device, 1..256 worlds
    python benchmarks/batch.py --device cuda --worlds 1 64 1024 8192
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import gymnasium as gym
import numpy as np
import scenes  # noqa: F401  (points MENAGERIE_ROOT at the shared Menagerie when unset)

import mjkdl.task  # noqa: F401  (registers the tasks)

TASK = "mjkdl/PandaPickCube-v0"
SUBSTEPS = 50


def cpu_env(steps: int) -> float:
    """Control steps/s of one CPU env."""
    env = gym.make(TASK).unwrapped
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    start = time.perf_counter()
    for _ in range(steps):
        env.step(rng.uniform(-1, 1, 7).astype(np.float32))
    rate = steps / (time.perf_counter() - start)
    env.close()
    return rate


def cpu_vector(n: int, steps: int) -> float:
    """Control steps/s (all sub-envs) of a synchronous vector env of `n` CPU envs."""
    envs = gym.make_vec(TASK, num_envs=n, vectorization_mode="sync")
    envs.reset(seed=0)
    rng = np.random.default_rng(0)
    start = time.perf_counter()
    for _ in range(steps):
        envs.step(rng.uniform(-1, 1, (n, 7)).astype(np.float32))
    rate = n * steps / (time.perf_counter() - start)
    envs.close()
    return rate


def rules(envs: object, reps: int) -> tuple[float, float]:
    """Microseconds per world of evaluating the task's reward and success for every world:
    (the rules on the device, as `step` does; the baseline, each world's rules called on
    the host with its NumPy observation, as `step` did before)."""
    from mjkdl.task.batch import Float64View
    from mjkdl.task.batch_state import as_numpy

    spec = envs.host.task_spec  # type: ignore[attr-defined]
    fns = [f for f in (spec.reward, spec.success, spec.terminated) if f is not None]
    obs = envs.observer.read()  # type: ignore[attr-defined]
    n = envs.num_envs  # type: ignore[attr-defined]
    start = time.perf_counter()
    for _ in range(reps):
        wide = Float64View(obs)
        for f in fns:
            f.evaluate(wide)
    device = (time.perf_counter() - start) / reps / n
    start = time.perf_counter()
    for _ in range(reps):
        host = {k: as_numpy(v) for k, v in obs.items()}
        for i in range(n):
            o = {k: v[i] for k, v in host.items()}
            for f in fns:
                f(o)
    baseline = (time.perf_counter() - start) / reps / n
    return device * 1e6, baseline * 1e6


def batch(n: int, steps: int, device: str) -> tuple[float, float, float, int, tuple[float, float]]:
    """(control steps/s over all worlds, reset s per world, data bytes per world, episodes
    restarted in the timed steps, `rules`). The worlds' episodes are spread over the time
    limit first, as a learner spreads them, so the timed steps restart about n/100 worlds
    each (their starts computed ahead, as in training)."""
    import torch

    from mjkdl.task.batch import make_batch, world_bytes

    envs = make_batch(TASK, n, device=device)
    start = time.perf_counter()
    envs.reset(seed=0)
    reset = (time.perf_counter() - start) / n
    s = envs.state
    per_world, _ = world_bytes(
        envs.host.scene.model, envs.host.scene.data, device, s.nconmax, s.njmax
    )
    gen = torch.Generator(device=device).manual_seed(0)
    for _ in range(2):  # warm: the kernels load, then the physics is captured as a graph
        envs.step(torch.rand(n, 7, generator=gen, device=device) * 2 - 1)
    horizon = envs.max_episode_steps or 100
    envs.episode_steps[:] = torch.randint(0, horizon, (n,), generator=gen, device=device)
    restarts = 0
    start = time.perf_counter()
    for _ in range(steps):
        _, _, terminated, truncated, _ = envs.step(
            torch.rand(n, 7, generator=gen, device=device) * 2 - 1
        )
        restarts += int((terminated | truncated).sum())
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    rate = n * steps / (time.perf_counter() - start)
    evaluation = rules(envs, 5)
    envs.close()
    return rate, reset, per_world, restarts, evaluation


def cameras(n: int, size: int, reps: int, device: str) -> tuple[float, float]:
    """Frames/s of PickCube's `front` camera (RGB and depth, `size` x `size`): MuJoCo Warp's
    renderer drawing all `n` worlds at once, and the baseline, MuJoCo's OpenGL renderer (the
    CPU env's) drawing one world's state at a time, as the CPU env's camera reader does."""
    import mujoco

    from mjkdl.task import CameraSensor, TaskEnv, registry
    from mjkdl.task.batch import make_batch

    spec = registry.panda_pick_cube_spec()
    spec.sensors = [*spec.sensors, CameraSensor("front", size, size, depth=True)]
    envs = make_batch(spec, n, device=device)
    envs.reset(seed=0)
    batch_cameras = envs.observer.cameras
    batch_cameras.read()  # warm
    start = time.perf_counter()
    for _ in range(reps):
        batch_cameras.read()
    warp_rate = n * reps / (time.perf_counter() - start)
    envs.close()
    env = TaskEnv(spec)
    env.reset(seed=0)
    r = mujoco.Renderer(env.scene.model, size, size)
    flags = r.scene.flags  # as the CPU env's camera reader draws: no shadows, no reflections
    flags[mujoco.mjtRndFlag.mjRND_SHADOW] = flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False

    def frame() -> None:
        r.update_scene(env.scene.data, camera="front")
        r.enable_depth_rendering()
        r.render()
        r.disable_depth_rendering()
        r.render()

    frame()  # warm: the OpenGL context and the model's upload
    start = time.perf_counter()
    for _ in range(n * reps):
        frame()
    gl_rate = n * reps / (time.perf_counter() - start)
    r.close()
    env.close()
    return warp_rate, gl_rate


_FIRST_CALL = """
import time, scenes, mjkdl.task
from mjkdl.task.batch import make_batch
import torch
start = time.perf_counter()
envs = make_batch({task!r}, 4, device={device!r})
envs.reset(seed=0)
for _ in range(2):  # the kernels load, then the physics is captured
    envs.step(torch.zeros(4, 7))
print(time.perf_counter() - start)
"""


def first_call(device: str, cache: str) -> float:
    """Seconds from `make_batch` to the end of the second step, in a fresh process with the
    Warp kernel cache at `cache`."""
    env = {**os.environ, "WARP_CACHE_PATH": cache}
    code = _FIRST_CALL.format(task=TASK, device=device)
    out = subprocess.run(
        [sys.executable, "-c", code],
        env=env,
        capture_output=True,
        text=True,
        check=True,
        cwd=os.path.dirname(os.path.abspath(__file__)),
    )
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="", help="cuda or cpu (default: cuda if present)")
    parser.add_argument("--worlds", type=int, nargs="+", default=[1, 4, 16, 64, 256])
    parser.add_argument("--steps", type=int, default=10, help="timed control steps per size")
    parser.add_argument("--cpu-steps", type=int, default=20, help="timed CPU env steps")
    parser.add_argument("--vector-envs", type=int, default=4, help="CPU vector env size")
    parser.add_argument("--no-compile", action="store_true", help="skip the first-call runs")
    parser.add_argument(
        "--camera-worlds", type=int, nargs="*", default=[16, 64], help="worlds for the cameras"
    )
    parser.add_argument("--camera-size", type=int, default=64, help="camera image side, px")
    args = parser.parse_args()
    from mjkdl.task.batch_state import warp_modules

    wp, _ = warp_modules()  # Warp logs warnings only
    gpu = wp.get_cuda_device_count() > 0
    device = args.device or ("cuda:0" if gpu else "cpu")
    if not gpu:
        print("No GPU is lent here: MuJoCo Warp runs on its CPU device; GPU figures not measured.")
    print(f"device {device}, {os.cpu_count()} cores")
    base = cpu_env(args.cpu_steps)
    print(f"CPU env (TaskEnv.step):       {base:8.1f} control steps/s  (baseline, 1.00x)")
    k = args.vector_envs
    vec = cpu_vector(k, max(1, args.cpu_steps // 2))
    print(f"CPU sync vector env of {k}:     {vec:8.1f} control steps/s  ({vec / base:.2f}x)")
    print(
        "worlds  control steps/s  world-steps/s   vs CPU env  restarts  reset s/world"
        "  KiB/world  rules us/world (device | host loop)"
    )
    for n in args.worlds:
        rate, reset, per_world, restarts, (dev_us, host_us) = batch(n, args.steps, device)
        print(
            f"{n:6d}  {rate:15.1f}  {rate * SUBSTEPS:13.0f}  {rate / base:9.2f}x"
            f"  {restarts:8d}  {reset:13.3f}  {per_world / 1024:9.0f}"
            f"  {dev_us:7.2f} | {host_us:6.1f} ({host_us / dev_us:.0f}x)"
        )
    size = args.camera_size
    for n in args.camera_worlds:
        warp_rate, gl_rate = cameras(n, size, 3, device)
        print(
            f"camera {size}x{size} RGB+depth, {n} worlds: {warp_rate:.1f} frames/s (MuJoCo Warp) "
            f"against {gl_rate:.1f} frames/s (MuJoCo's OpenGL, one world at a time, baseline):"
            f" {warp_rate / gl_rate:.2f}x"
        )
    if not args.no_compile:
        with tempfile.TemporaryDirectory() as cache:
            cold = first_call(device, cache)
            warm = first_call(device, cache)
        print(
            f"first call (4 worlds, build+reset+2 steps): {cold:.1f} s empty kernel cache, "
            f"{warm:.1f} s cached ({cold / warm:.1f}x)"
        )


if __name__ == "__main__":
    main()
