"""Benchmark VideoRecorder at 720p on the tutorial scene: render only vs render + encode.

    python benchmarks/record.py [--frames 60] [--rounds 3]

The scene is the tutorial's (Gen3 + 2F-85 on the table, a cube, the `task` camera). The arm
servos from its zero pose to HOME while `--frames` states, 1/30 s of simulated time apart, are
stored; each variant then renders the same states through the `task` camera at 1280x720, with
shadows and reflections on and off. The first state of each run warms the renderer up (shader
compilation, texture upload) and is not timed.

* render only: `mujoco.Renderer` update + render (the frame is read back to memory);
* render + encode: `VideoRecorder.record_frame()` for every state, then `close()`, which waits
  for the encoder to finish the MP4 (H.264, yuv420p, imageio-ffmpeg).

Rounds alternate the variants; the best round of each is reported (wall clock, perf_counter).
Overhead = render+encode time / render-only time - 1; the recorder's budget is 15 %.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")  # before MuJoCo is imported

import mujoco
import numpy as np
from scenes import HOME, TOOL, tabletop_spec
from tqdm import tqdm

import mjkdl as mjk
from mjkdl.record import offscreen_renderer

WIDTH, HEIGHT, FPS = 1280, 720, 30


def tutorial_env() -> tuple[mjk.Env, mjk.Robot]:
    """The tabletop scene with a cube on the table in front of the arm."""
    spec = tabletop_spec()
    spec.objects.append(
        mjk.SceneObject(
            name="cube",
            shape=mjk.Shape.BOX,
            size=[0.025, 0.025, 0.025],
            pos=[0.35, 0.10, 0.725],
            rgba=[0.1, 0.25, 1.0, 1.0],
            mass=0.1,
        )
    )
    env = mjk.Env.build(spec)
    return env, env.create_robot("base_link", "bracelet_link", tool=TOOL)


def record_states(env: mjk.Env, robot: mjk.Robot, frames: int) -> list[np.ndarray]:
    """Full physics states 1/FPS simulated seconds apart while the arm moves to HOME."""
    robot.jnt_pos_cmd = np.array(HOME)
    steps = round(1.0 / (FPS * env.timestep()))
    size = mujoco.mj_stateSize(env.model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    states = []
    for _ in range(frames):
        for _ in range(steps):
            robot.update()
            robot.step()
        state = np.empty(size)
        mujoco.mj_getState(env.model, env.data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        states.append(state)
    return states


def load(env: mjk.Env, state: np.ndarray, t: float) -> None:
    mujoco.mj_setState(env.model, env.data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    env.data.time = t
    mujoco.mj_forward(env.model, env.data)


def render_only(env: mjk.Env, states: list[np.ndarray], quality: bool) -> float:
    """Seconds to render states[1:]; states[0] warms up (shaders, texture upload)."""
    renderer = offscreen_renderer(env.model, WIDTH, HEIGHT, shadows=quality, reflections=quality)
    for i, state in enumerate(states):
        if i == 1:
            start = time.perf_counter()
        load(env, state, i / FPS)
        renderer.update_scene(env.data, camera="task")
        renderer.render()
    elapsed = time.perf_counter() - start
    renderer.close()
    return elapsed


def render_encode(env: mjk.Env, states: list[np.ndarray], quality: bool, out: Path) -> float:
    """Seconds to record states[1:] and finalise the MP4; states[0] warms up."""
    rec = mjk.VideoRecorder.open(env, out, WIDTH, HEIGHT, FPS, shadows=quality, reflections=quality)
    rec.use_camera("task")
    for i, state in enumerate(states):
        if i == 1:
            start = time.perf_counter()
        load(env, state, i / FPS)
        assert rec.record_frame()
    rec.close()
    elapsed = time.perf_counter() - start
    assert rec.frames_written == len(states)
    return elapsed


def main() -> None:
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()

    env, robot = tutorial_env()
    states = record_states(env, robot, args.frames)
    print(
        f"mjkdl VideoRecorder, {WIDTH}x{HEIGHT}, {args.frames} frames, best of {args.rounds} "
        f"rounds, MUJOCO_GL={os.environ.get('MUJOCO_GL')}, MuJoCo {mjk.mujoco_version()}"
    )
    print(
        f"{'shadows+reflections':>20} {'render fps':>11} {'render+encode fps':>18} {'overhead':>9}"
    )
    timed = args.frames - 1
    with tempfile.TemporaryDirectory() as tmp:
        for quality in (True, False):
            render, encode = [], []
            for k in tqdm(range(args.rounds), desc="rounds", disable=None, leave=False):
                render.append(render_only(env, states, quality))
                encode.append(render_encode(env, states, quality, Path(tmp) / f"{k}.mp4"))
            r, e = min(render), min(encode)
            label = "on" if quality else "off"
            print(f"{label:>20} {timed / r:>11.1f} {timed / e:>18.1f} {100 * (e / r - 1):>8.1f}%")
    env.close()


if __name__ == "__main__":
    main()
