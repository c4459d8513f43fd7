"""Many worlds: `mjkdl.task.make_batch` against one CPU env and a Gymnasium vector env.

`mjkdl/PandaPickCube-v0` (0.1 s control steps of 50 physics steps of 2 ms), random actions,
episodes restarting as they end. Baseline: one CPU env (`TaskEnv.step`). Compared, in the
same process and interleaved (each runner measured for `--seconds` in turn, `--rounds`
times; the figures are each runner's median, the ratios medians over its rounds against the
CPU env's in the same round): a Gymnasium `AsyncVectorEnv` of `--async-envs` CPU envs (one
process each), and the batch's CPU engine (MuJoCo's own `mujoco.batch`) at each of
`--worlds` on the cores available, with the physics alone (`Batch.step` of the same worlds,
no task) beside it, and at `--scaling` worlds on 1 ... all cores. Control steps/s are summed
over worlds. The first step's time is measured in a fresh process: from `make_batch` to the
end of its first `step`. `--warp` adds MuJoCo Warp (on a GPU where one is lent, else on
Warp's CPU device): its rows, its cameras against MuJoCo's OpenGL renderer, and its first
call with an empty and with a filled kernel cache.

    python benchmarks/batch.py                          # CPU engine, 64 and 256 worlds
    python benchmarks/batch.py --warp --device cuda --warp-worlds 1024 8192
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable

import gymnasium as gym
import numpy as np
import scenes  # noqa: F401  (points MENAGERIE_ROOT at the shared Menagerie when unset)

import mjkdl.task  # noqa: F401  (registers the tasks)

TASK = "mjkdl/PandaPickCube-v0"
SUBSTEPS = 50

Runner = Callable[[float], int]  # seconds to run -> control steps taken (summed over worlds)


def cpu_env() -> Runner:
    """One CPU env, reset as its episodes end: on success, or at the registered time limit
    (`gym.make`'s `TimeLimit`, counted here without the wrapper's cost), as the batch's and
    the vector env's worlds are."""
    env = gym.make(TASK).unwrapped
    horizon = gym.spec(TASK).max_episode_steps or np.inf
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    taken = 0

    def run(seconds: float) -> int:
        nonlocal taken
        steps, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            _, _, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 7).astype(np.float32))
            taken += 1
            if terminated or truncated or taken >= horizon:
                env.reset()
                taken = 0
            steps += 1
        return steps

    return run


def async_vector(n: int) -> tuple[Runner, Callable[[], None]]:
    """A Gymnasium `AsyncVectorEnv` of `n` CPU envs (each in its own process); its close."""
    envs = gym.make_vec(TASK, num_envs=n, vectorization_mode="async")
    envs.reset(seed=0)
    rng = np.random.default_rng(0)

    def run(seconds: float) -> int:
        steps, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            envs.step(rng.uniform(-1, 1, (n, 7)).astype(np.float32))
            steps += n
        return steps

    return run, envs.close


def batch(n: int, device: str, **kwargs: object) -> tuple[Runner, Runner, object]:
    """The batch on `n` worlds: (its runner, the physics alone on the same worlds, the
    batch). The worlds' episodes are spread over the time limit first, as a learner spreads
    them, so about n/100 worlds restart in each step (their starts computed ahead)."""
    import mujoco
    import torch

    from mjkdl.task import make_batch

    envs = make_batch(TASK, n, device=device, **kwargs)
    envs.reset(seed=0)
    gen = torch.Generator(device=device).manual_seed(0)

    def actions() -> torch.Tensor:
        return torch.rand(n, 7, generator=gen, device=device) * 2 - 1

    for _ in range(2):  # warm (MuJoCo Warp: the kernels load, then the physics is captured)
        envs.step(actions())
    horizon = envs.max_episode_steps or 100
    envs.episode_steps[:] = torch.randint(0, horizon, (n,), generator=gen, device=device)

    def run(seconds: float) -> int:
        steps, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            envs.step(actions())
            steps += n
        if device.startswith("cuda"):
            torch.cuda.synchronize()
        return steps

    def physics(seconds: float) -> int:
        raw = envs.state.batch
        steps, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            raw.step(nstep=SUBSTEPS, stage=mujoco.mjtStage.mjSTAGE_ACC)
            steps += n
        return steps

    return run, physics, envs


# The parts of a batch step, by the method that does each (exclusive CPU time: a part's
# time leaves out the parts it calls).
PARTS = (
    ("physics (Batch.step: 50 substeps, then mj_forward)", "cpu_engine.CpuEngine", "_step"),
    ("next episodes' starts (the CPU env's reset, per world)", "reset.EpisodeStarts", "prefetch"),
    ("restarts: the rows written", "reset.EpisodeStarts", "start"),
    ("restarts: mj_forward of them", "cpu_engine.CpuEngine", "forward"),
    ("Cartesian QP (eigh, active set)", "control.BatchArm", "_solve"),
    ("chain kinematics at the command", "control.ChainKinematics", "__call__"),
    ("gravity feed-forward (Pinocchio)", "cpu_engine.PinocchioGravity", "__call__"),
    ("control: the rest (ctrl written, gripper)", "control.BatchArm", "apply"),
    ("observations", "sensors.BatchObserver", "read"),
    ("contacts (worlds near the fingers recomputed)", "cpu_engine.CpuEngine", "contacts"),
    ("reward, success, termination", "env.BatchEnv", "_evaluate"),
    ("action checks and scaling", "env.BatchEnv", "_checked"),
    ("the step's own (ends, autoreset, info)", "env.BatchEnv", "_step"),
)


def breakdown(n: int, steps: int) -> None:
    """Where a batch step's CPU time goes, on one thread (so that the physics' CPU time is
    its own) with the starts computed after the physics instead of beside it: each part's
    CPU microseconds per world and control step, and its share of the physics; then the
    physics alone (`Batch.step` of the same worlds, the controls held: another workload, the
    arms pressing on at the last command) and one CPU env's step, restarts included."""
    import importlib

    import mujoco
    import torch

    from mjkdl.task.batch import cpu_engine

    spent = dict.fromkeys([name for name, _, _ in PARTS], 0.0)
    inner: list[float] = []

    def timed(name: str, fn: Callable[..., object]) -> Callable[..., object]:
        def wrapper(*args: object, **kwargs: object) -> object:
            start = time.process_time()
            inner.append(0.0)
            try:
                return fn(*args, **kwargs)
            finally:
                took = time.process_time() - start
                spent[name] += took - inner.pop()
                if inner:
                    inner[-1] += took

        return wrapper

    saved = []
    for name, owner, method in PARTS:
        module, cls = owner.split(".")
        klass = getattr(importlib.import_module(f"mjkdl.task.batch.{module}"), cls)
        saved.append((klass, method, getattr(klass, method)))
        setattr(klass, method, timed(name, getattr(klass, method)))

    def serial(self: cpu_engine.CpuEngine, substeps: int, meanwhile=None) -> None:  # type: ignore[no-untyped-def]
        self._step(substeps)
        if meanwhile is not None:
            meanwhile()

    saved.append((cpu_engine.CpuEngine, "step", cpu_engine.CpuEngine.step))
    cpu_engine.CpuEngine.step = serial  # type: ignore[method-assign]
    try:
        _, _, envs = batch(n, "cpu", threads=1)
        spent.update((k, 0.0) for k in spent)
        start = time.process_time()
        gen = torch.Generator().manual_seed(1)
        for _ in range(steps):
            envs.step(torch.rand(n, 7, generator=gen) * 2 - 1)  # type: ignore[attr-defined]
        total = time.process_time() - start
        raw = envs.state.batch  # type: ignore[attr-defined]
        start = time.process_time()
        for _ in range(steps):
            raw.step(nstep=SUBSTEPS, stage=mujoco.mjtStage.mjSTAGE_ACC)
        floor = time.process_time() - start
        envs.close()  # type: ignore[attr-defined]
    finally:
        for klass, method, fn in saved:
            setattr(klass, method, fn)
    physics = spent[PARTS[0][0]]
    per = 1e6 / (n * steps)
    print(f"\nbreakdown, {n} worlds, 1 thread, {steps} steps: CPU us per world and control step")
    print(f"{'part':56s} {'CPU us':>8s} {'of physics':>10s}")
    for name, value in spent.items():
        print(f"{name:56s} {value * per:8.1f} {100 * value / physics:9.1f}%")
    rest = total - physics
    print(f"{'everything besides the physics':56s} {rest * per:8.1f} {100 * rest / physics:9.1f}%")
    print(f"{'the whole step':56s} {total * per:8.1f}")
    print(f"{'physics alone (Batch.step, controls held)':56s} {floor * per:8.1f}")
    one = cpu_env()
    start, steps = time.process_time(), one(3.0)
    env_us = 1e6 * (time.process_time() - start) / steps
    print(f"{'one CPU env (TaskEnv.step, restarts included)':56s} {env_us:8.1f}")


_FIRST_STEP = """
import time, scenes, mjkdl.task, torch
from mjkdl.task import make_batch
start = time.perf_counter()
envs = make_batch({task!r}, {worlds}, device={device!r}, engine={engine!r})
envs.reset(seed=0)
envs.step(torch.zeros({worlds}, 7))
first = time.perf_counter() - start
envs.step(torch.zeros({worlds}, 7))  # MuJoCo Warp: the physics is captured here
print(first, time.perf_counter() - start)
"""


def first_step(worlds: int, device: str, engine: str, cache: str | None) -> tuple[float, float]:
    """Seconds from `make_batch` to the end of its first and of its second step, in a fresh
    process (imports not counted); `cache`: Warp's kernel cache folder."""
    env = dict(os.environ)
    if cache is not None:
        env["WARP_CACHE_PATH"] = cache
    code = _FIRST_STEP.format(task=TASK, worlds=worlds, device=device, engine=engine)
    out = subprocess.run(
        [sys.executable, "-c", code],
        env=env,
        capture_output=True,
        text=True,
        check=True,
        cwd=os.path.dirname(os.path.abspath(__file__)),
    )
    first, second = out.stdout.strip().splitlines()[-1].split()
    return float(first), float(second)


def cameras(n: int, size: int, reps: int, device: str) -> tuple[float, float]:
    """Frames/s of PickCube's `front` camera (RGB and depth, `size` x `size`): MuJoCo Warp's
    renderer drawing all `n` worlds at once, and the baseline, MuJoCo's OpenGL renderer (the
    CPU env's) drawing one world's state at a time, as the CPU env's camera reader does."""
    import mujoco

    from mjkdl.task import CameraSensor, TaskEnv, make_batch, registry

    spec = registry.panda_pick_cube_spec()
    spec.sensors = [*spec.sensors, CameraSensor("front", size, size, depth=True)]
    envs = make_batch(spec, n, device=device, engine="warp")
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, nargs="+", default=[64, 256])
    parser.add_argument("--scaling", type=int, default=256, help="worlds of the thread scaling")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds")
    parser.add_argument("--seconds", type=float, default=2.0, help="per runner and round")
    parser.add_argument("--async-envs", type=int, default=2, help="AsyncVectorEnv size")
    parser.add_argument("--no-first-step", action="store_true", help="skip the fresh processes")
    parser.add_argument("--warp", action="store_true", help="add MuJoCo Warp's rows")
    parser.add_argument("--device", default="", help="--warp: cuda or cpu (default: cuda if any)")
    parser.add_argument(
        "--warp-worlds", type=int, nargs="+", default=None, help="--warp: worlds (--worlds')"
    )
    parser.add_argument("--camera-size", type=int, default=64, help="--warp: image side, px")
    parser.add_argument(
        "--breakdown",
        type=int,
        nargs="*",
        default=None,
        help="only the CPU time by part, at these worlds (default 64 256)",
    )
    parser.add_argument("--breakdown-steps", type=int, default=60, help="--breakdown: steps")
    args = parser.parse_args()
    if args.breakdown is not None:
        for n in args.breakdown or [64, 256]:
            breakdown(n, args.breakdown_steps)
        return
    import torch

    from mjkdl.task.batch.cpu_engine import available_threads

    cores = available_threads()
    print(f"{os.cpu_count()} cores, {cores} available; {args.rounds} interleaved rounds")
    runners: dict[str, Runner] = {"CPU env (TaskEnv.step)": cpu_env()}
    k = args.async_envs
    run, close_async = async_vector(k)
    runners[f"AsyncVectorEnv of {k}"] = run
    batches = []
    for n in args.worlds:
        run, physics, envs = batch(n, "cpu")
        runners[f"batch (mujoco), {n} worlds, {cores} threads"] = run
        runners[f"  physics alone, {n} worlds"] = physics
        batches.append(envs)
    for t in range(1, cores):  # the batch on all cores is among the rows above, or here
        run, _, envs = batch(args.scaling, "cpu", threads=t)
        runners[f"batch (mujoco), {args.scaling} worlds, {t} threads"] = run
        batches.append(envs)
    if args.scaling not in args.worlds:
        run, _, envs = batch(args.scaling, "cpu")
        runners[f"batch (mujoco), {args.scaling} worlds, {cores} threads"] = run
        batches.append(envs)
    device = args.device or ("cuda:0" if torch.cuda.is_available() else "cpu")
    if args.warp:
        for n in args.warp_worlds or args.worlds:
            run, _, envs = batch(n, device, engine="warp")
            runners[f"batch (warp, {device}), {n} worlds"] = run
            batches.append(envs)
    rates: dict[str, list[float]] = {name: [] for name in runners}
    cpu_us: dict[str, list[float]] = {name: [] for name in runners}
    for _ in range(args.rounds):
        for name, run in runners.items():
            wall, cpu = time.perf_counter(), time.process_time()
            steps = run(args.seconds)
            wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
            rates[name].append(steps / wall)
            cpu_us[name].append(1e6 * cpu / steps)
    base = rates["CPU env (TaskEnv.step)"]
    vec = rates[f"AsyncVectorEnv of {k}"]
    # CPU time: this process's threads (the vector env's workers are other processes).
    print(
        f"{'runner':44s} {'control steps/s':>15s} {'vs CPU env':>10s} {'vs async':>9s}"
        f" {'CPU us/step':>11s}  (range of control steps/s)"
    )
    for name, values in rates.items():
        ratio = statistics.median(v / b for v, b in zip(values, base, strict=True))
        versus = statistics.median(v / a for v, a in zip(values, vec, strict=True))
        used = "n/a" if name.startswith("Async") else f"{statistics.median(cpu_us[name]):.0f}"
        spread = f"({min(values):.0f}-{max(values):.0f})"
        print(
            f"{name:44s} {statistics.median(values):15.1f} {ratio:9.2f}x {versus:8.2f}x"
            f" {used:>11s}  {spread}"
        )
    close_async()
    for envs in batches:
        envs.close()  # type: ignore[attr-defined]
    if not args.no_first_step:
        n = args.worlds[0]
        first, _ = first_step(n, "cpu", "mujoco", None)
        print(f"first step (mujoco, {n} worlds, from make_batch, fresh process): {first:.2f} s")
    if args.warp:
        size = args.camera_size
        for n in (16, 64):
            warp_rate, gl_rate = cameras(n, size, 3, device)
            print(
                f"camera {size}x{size} RGB+depth, {n} worlds: {warp_rate:.1f} frames/s (MuJoCo "
                f"Warp) against {gl_rate:.1f} frames/s (MuJoCo's OpenGL, one world at a time,"
                f" baseline): {warp_rate / gl_rate:.2f}x"
            )
        if not args.no_first_step:
            with tempfile.TemporaryDirectory() as cache:
                cold = first_step(4, device, "warp", cache)[1]
                warm = first_step(4, device, "warp", cache)[1]
            print(
                f"first call (warp, 4 worlds, build+reset+2 steps): {cold:.1f} s empty kernel "
                f"cache, {warm:.1f} s cached ({cold / warm:.1f}x)"
            )


if __name__ == "__main__":
    main()
