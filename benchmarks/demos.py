"""Demonstration collection: the scripted expert on `mjkdl/PandaPickCube-v0`, recorded to HDF5,
against the same episodes without recording; file size per episode; LeRobot export time.

Compared in one process on the same seeds, each seed run both ways back to back in alternating
order. The overhead is given on each episode's least time over the rounds (the run the
machine's other load disturbed least), summed over the seeds, and as the median over rounds
of the rounds' ratios; in this process's CPU time and in wall time:
(a) the env alone: a hand-written loop `obs = env.reset(seed); expert.reset();
    env.step(expert(obs))` to the episode's end;
(b) recording: `mjkdl.demos.run_episode(..., record=True)` (the action checked, the MuJoCo
    state and every observation kept before each step) and `EpisodeWriter.write` (HDF5,
    flushed per episode) into a temporary file;
(c) both with a 128x128 `front` camera observation (`camera_names=["front"]`), fewer seeds.
Then the LeRobot v3.0 export of the camera file (parquet + H.264).

    python benchmarks/demos.py
    python benchmarks/demos.py --episodes 20 --camera-episodes 4 --rounds 15   # steadier
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("MUJOCO_GL", "egl")  # before MuJoCo is imported

import numpy as np
import scenes  # noqa: F401  (points MENAGERIE_ROOT at the shared Menagerie when unset)

from mjkdl.demos import (
    EpisodeBuffer,
    EpisodeWriter,
    export_lerobot,
    make_env,
    make_policy,
    run_episode,
)

ENV = "mjkdl/PandaPickCube-v0"
CAMERA = {"camera_names": ["front"], "camera_size": [128, 128]}


def env_alone(env: Any, expert: Any, seed: int) -> int:
    """The baseline: the expert drives the env through one episode; control steps taken."""
    obs, _ = env.reset(seed=seed)
    expert.reset()
    steps, done = 0, False
    while not done:
        obs, _, terminated, truncated, _ = env.step(expert(obs))
        done = terminated or truncated
        steps += 1
    return steps


def recorded(env: Any, expert: Any, seed: int, writer: EpisodeWriter, stored: int) -> int:
    """The same episode recorded and written (flushed) under the seed `stored` (a file refuses
    a seed twice, and every round writes the seeds again); control steps taken."""
    ep = run_episode(env, expert, seed, record=True, source="expert")
    assert ep.data is not None
    writer.write(dataclasses.replace(ep.data, seed=stored))
    return ep.length


def parts(env: Any, expert: Any, path: Path, repeats: int = 30) -> tuple[float, float]:
    """The recording's own costs, each the least of `repeats` timings (CPU seconds): writing
    one episode to HDF5, and keeping one step's state and observation in the buffer."""
    obs, _ = env.reset(seed=0)
    data = run_episode(env, expert, 0, record=True, source="expert").data
    assert data is not None
    buffer = EpisodeBuffer(env.unwrapped.scene)
    action = expert(obs)

    def keep() -> int:
        buffer.before_step(obs)
        buffer.after_step(action, 0.0, False, obs)
        return 1

    copies = [dataclasses.replace(data, seed=k) for k in range(repeats)]  # one seed per write
    with EpisodeWriter(path, ENV, overwrite=True) as writer:  # a scratch file
        write = min(timed(lambda d=d: writer.write(d) and 1)[1] for d in copies)
    step = min(timed(keep)[1] for _ in range(repeats * 10))
    return write, step


def timed(fn: Callable[[], int]) -> tuple[float, float, int]:
    """Wall-clock and CPU seconds of `fn()` (CPU: this process only, so a busy neighbour on a
    shared machine does not count), and what it returned."""
    wall, cpu = time.perf_counter(), time.process_time()
    steps = fn()
    return time.perf_counter() - wall, time.process_time() - cpu, steps


def compare(label: str, kwargs: dict, seeds: list[int], rounds: int, folder: Path) -> Path:
    env = make_env(ENV, kwargs)
    expert = make_policy("expert", env)
    env_alone(env, expert, seeds[0])  # warm-up: renderer, QP solver, caches
    path = folder / f"{label}.hdf5"
    # times[kind][round, seed] = (wall, cpu) of one episode
    times = {kind: np.zeros((rounds, len(seeds), 2)) for kind in ("alone", "recorded")}
    steps = 0
    with EpisodeWriter(path, ENV, kwargs, overwrite=True) as writer:
        for r in range(rounds):
            if r == rounds - 1:  # measured between rounds, while the file is open
                write, keep = parts(env, expert, folder / "parts.hdf5")
            steps = 0
            for i, seed in enumerate(seeds):
                stored = r * len(seeds) + i
                # Each seed runs both ways back to back, in alternating order, so a swing in
                # the machine's load hits both alike.
                runs = [
                    ("alone", lambda s=seed: env_alone(env, expert, s)),
                    (
                        "recorded",
                        lambda s=seed, k=stored: recorded(env, expert, s, writer, k),
                    ),
                ]
                for kind, fn in runs if (i + r) % 2 == 0 else runs[::-1]:
                    wall, cpu, n = timed(fn)
                    times[kind][r, i] = (wall, cpu)
                steps += n
    env.close()
    # Each episode's least time over the rounds (the run least disturbed by the neighbours),
    # summed over the seeds; and the median over rounds of each round's ratio.
    least = {kind: t.min(axis=0).sum(axis=0) for kind, t in times.items()}
    wall_pct, cpu_pct = 100 * (least["recorded"] / least["alone"] - 1)
    per_round = times["recorded"].sum(axis=1) / times["alone"].sum(axis=1)
    med_wall, med_cpu = 100 * (np.median(per_round, axis=0) - 1)
    base, rec = least["alone"][0], least["recorded"][0]
    n = len(seeds)
    size = path.stat().st_size / writer.num_demos
    print(f"{label}: {n} expert episodes x {rounds} rounds, {steps} control steps per round")
    print(f"  env alone:  {60 * n / base:8.1f} episodes/min  {steps / base:8.1f} steps/s")
    print(f"  recording:  {60 * n / rec:8.1f} episodes/min  {steps / rec:8.1f} steps/s")
    print(
        f"  recording overhead: {cpu_pct:.1f} % in CPU time, {wall_pct:.1f} % in wall time "
        f"(each episode's best of {rounds} rounds); median of the rounds' ratios "
        f"{med_cpu:.1f} % CPU, {med_wall:.1f} % wall"
    )
    print(
        f"  of which: HDF5 writing {write * 1e3:.2f} ms per episode "
        f"({100 * write * n / least['alone'][1]:.1f} %), buffering {keep * 1e6:.1f} us per "
        f"step ({100 * keep * steps / least['alone'][1]:.1f} %), each the least of many timings"
    )
    print(
        f"  file size per episode: {size / 1024:.1f} KiB ({size / steps * n / 1024:.2f} KiB/step)"
    )
    return path


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--episodes", type=int, default=10, help="seeds without a camera")
    p.add_argument("--camera-episodes", type=int, default=2, help="seeds with the camera")
    p.add_argument("--rounds", type=int, default=9)
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        compare("no camera", {}, list(range(a.episodes)), a.rounds, folder)
        cam = compare("128x128 camera", CAMERA, list(range(a.camera_episodes)), a.rounds, folder)
        start = time.perf_counter()
        out = export_lerobot(cam, folder / "lerobot")
        t = time.perf_counter() - start
        print(f"LeRobot export of the camera file ({out.writer}): {out.frames} frames in {t:.2f} s")
        print(f"  export: {out.frames / t:.1f} frames/s")


if __name__ == "__main__":
    main()
