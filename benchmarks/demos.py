"""Demonstration collection: the scripted expert on `mjkdl/PandaPickCube-v0`, recorded to HDF5,
against the same episodes without recording; file size per episode; LeRobot export time.

Compared in one process, interleaved round by round on the same seeds (the overhead is given
as best round against best round, and as the median of the rounds' own ratios):
(a) the env alone: a hand-written loop `obs = env.reset(seed); expert.reset();
    env.step(expert(obs))` to the episode's end;
(b) recording: `mjkdl.demos.run_episode(..., record=True)` (the action checked, the MuJoCo
    state and every observation kept before each step) and `EpisodeWriter.write` (HDF5,
    flushed per episode) into a temporary file;
(c) both with a 128x128 `front` camera observation (`camera_names=["front"]`), fewer seeds.
Then the LeRobot v3.0 export of the camera file (parquet + H.264).

    python benchmarks/demos.py
    python benchmarks/demos.py --episodes 20 --camera-episodes 4 --rounds 5   # steadier
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("MUJOCO_GL", "egl")  # before MuJoCo is imported

import scenes  # noqa: F401  (points MENAGERIE_ROOT at the shared Menagerie when unset)

from mjkdl.demos import EpisodeWriter, export_lerobot, make_env, make_policy, run_episode

ENV = "mjkdl/PandaPickCube-v0"
CAMERA = {"camera_names": ["front"], "camera_size": [128, 128]}


def env_alone(env: Any, expert: Any, seeds: list[int]) -> int:
    """The baseline: the expert drives the env; control steps taken."""
    steps = 0
    for seed in seeds:
        obs, _ = env.reset(seed=seed)
        expert.reset()
        done = False
        while not done:
            obs, _, terminated, truncated, _ = env.step(expert(obs))
            done = terminated or truncated
            steps += 1
    return steps


def recorded(env: Any, expert: Any, seeds: list[int], path: Path, kwargs: dict) -> int:
    """The same episodes recorded and written; control steps taken."""
    steps = 0
    with EpisodeWriter(path, ENV, kwargs, overwrite=True) as writer:
        for seed in seeds:
            ep = run_episode(env, expert, seed, record=True, source="expert")
            assert ep.data is not None
            writer.write(ep.data)
            steps += ep.length
    return steps


def timed(fn: Callable[[], int]) -> tuple[float, int]:
    start = time.perf_counter()
    steps = fn()
    return time.perf_counter() - start, steps


def compare(label: str, kwargs: dict, seeds: list[int], rounds: int, folder: Path) -> Path:
    env = make_env(ENV, kwargs)
    expert = make_policy("expert", env)
    env_alone(env, expert, seeds[:1])  # warm-up: renderer, QP solver, caches
    base: list[float] = []
    rec: list[float] = []
    path = folder / f"{label}.hdf5"
    steps = 0
    for _ in range(rounds):  # interleaved, so load swings hit both alike
        t, steps = timed(lambda: env_alone(env, expert, seeds))
        base.append(t)
        t, _ = timed(lambda: recorded(env, expert, seeds, path, kwargs))
        rec.append(t)
    env.close()
    b, r = min(base), min(rec)
    ratios = sorted(x / y for x, y in zip(rec, base, strict=True))
    n = len(seeds)
    size = path.stat().st_size / n
    print(f"{label}: {n} expert episodes, {steps} control steps, best of {rounds} rounds")
    print(f"  env alone:  {60 * n / b:8.1f} episodes/min  {steps / b:8.1f} steps/s")
    print(f"  recording:  {60 * n / r:8.1f} episodes/min  {steps / r:8.1f} steps/s")
    print(
        f"  recording overhead: {100 * (r / b - 1):.1f} % (best against best; median of the "
        f"rounds' ratios {100 * (ratios[len(ratios) // 2] - 1):.1f} %)"
    )
    print(
        f"  file size per episode: {size / 1024:.1f} KiB ({size / steps * n / 1024:.2f} KiB/step)"
    )
    return path


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--episodes", type=int, default=10, help="seeds without a camera")
    p.add_argument("--camera-episodes", type=int, default=2, help="seeds with the camera")
    p.add_argument("--rounds", type=int, default=3)
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        compare("no camera", {}, list(range(a.episodes)), a.rounds, folder)
        cam = compare("128x128 camera", CAMERA, list(range(a.camera_episodes)), a.rounds, folder)
        start = time.perf_counter()
        out = export_lerobot(cam, folder / "lerobot")
        t = time.perf_counter() - start
        print(f"LeRobot export of the camera file: {out.frames} frames in {t:.2f} s")
        print(f"  export: {out.frames / t:.1f} frames/s")


if __name__ == "__main__":
    main()
