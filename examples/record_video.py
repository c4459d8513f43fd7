"""Record the pick-and-place task to an MP4 through the `task` camera, without a window.

The task is the one of `pick_place.py` (same scene, plan and state machine); only the loop
differs: after every physics step `recorder.record_frame()` is called, and the recorder keeps
the frames that fall on its frame clock (simulation time), so the video plays at real speed
whatever the timestep. Rendering is offscreen through `mujoco.Renderer`; on a machine without
a display set `MUJOCO_GL=egl`. This example never opens a window (`--headless` is accepted and
changes nothing); on a terminal a progress bar counts the simulated seconds.

The defaults (854x480, 30 fps, `--quality fast`: no shadows, reflections or multisampling)
finish in well under a minute on software OpenGL; `--quality full` looks better and renders
several times slower.

    MUJOCO_GL=egl python examples/record_video.py --out pick_place.mp4
"""

from __future__ import annotations

import argparse
from pathlib import Path

from common import parse_args, run
from pick_place import report, setup

import mjkdl as mjk

TAIL = 0.5  # seconds recorded after the task is done


def options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("pick_place.mp4"),
        help="MP4 to write (default: pick_place.mp4 in the current directory)",
    )
    parser.add_argument("--width", type=int, default=854)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--fps", type=int, default=30)
    parser.add_argument("--seed", type=int, default=None, help="jitter the cube start (±2 cm)")
    parser.add_argument(
        "--quality",
        choices=["fast", "full"],
        default="fast",
        help="full: shadows, reflections and 4x multisampling, several times slower on "
        "software OpenGL (default: fast)",
    )


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=30.0, extra=options)
    offscreen = argparse.Namespace(**{**vars(args), "headless": True})
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tail = argparse.Namespace(headless=True, duration=TAIL)
    env, robot, task = setup(args.seed)
    with env:
        full = args.quality == "full"
        # Multisampling is fixed when the renderer's OpenGL context is made (MuJoCo's
        # offsamples, 4 by default): on software OpenGL it is most of a frame's cost.
        env.model.vis.quality.offsamples = 4 if full else 0
        with mjk.VideoRecorder.open(
            env, str(args.out), args.width, args.height, args.fps, shadows=full, reflections=full
        ) as rec:
            rec.use_camera("task")
            run(
                env,
                task.control,
                offscreen,
                robot=robot,
                title="recording",
                until=lambda: task.done,
                after_step=rec.record_frame,
            )
            run(env, task.control, tail, robot=robot, after_step=rec.record_frame)
        size = args.out.stat().st_size
        print(
            f"video: {args.out} ({args.width}x{args.height} at {args.fps} fps, "
            f"{env.time():.2f} s simulated, {size / 1e6:.2f} MB)"
        )
        success = report(task)
    return 0 if success or not task.done else 1  # not done: stopped by --duration


if __name__ == "__main__":
    raise SystemExit(main())
