"""Record the pick-and-place task to an MP4 through the `task` camera, without a window.

The task is the one of `pick_place.py` (same scene, plan and state machine); only the loop
differs: after every physics step `recorder.record_frame()` is called, and the recorder keeps
the frames that fall on its frame clock (simulation time), so the video plays at real speed
whatever the timestep. Rendering is offscreen through `mujoco.Renderer`; on a machine without
a display set `MUJOCO_GL=egl`. This example never opens a window (`--headless` is accepted and
changes nothing).

    MUJOCO_GL=egl python examples/record_video.py --output out/pick_place.mp4
"""

from __future__ import annotations

import argparse
from pathlib import Path

from common import REPO_ROOT, parse_args, run
from pick_place import report, setup

import mjkdl as mjk

TAIL = 0.5  # seconds recorded after the task is done


def options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--output", type=Path, default=REPO_ROOT / "out" / "pick_place.mp4", help="MP4 to write"
    )
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, default=720)
    parser.add_argument("--fps", type=int, default=30)
    parser.add_argument("--seed", type=int, default=None, help="jitter the cube start (±2 cm)")
    parser.add_argument(
        "--preview",
        action="store_true",
        help="no shadows or reflections: several times faster on software OpenGL",
    )


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=30.0, extra=options)
    offscreen = argparse.Namespace(**{**vars(args), "headless": True})
    args.output.parent.mkdir(parents=True, exist_ok=True)
    tail = argparse.Namespace(headless=True, duration=TAIL)
    env, robot, task = setup(args.seed)
    with env:
        quality = {"shadows": not args.preview, "reflections": not args.preview}
        with mjk.VideoRecorder.open(
            env, str(args.output), args.width, args.height, args.fps, **quality
        ) as rec:
            rec.use_camera("task")
            run(
                env,
                task.control,
                offscreen,
                robot=robot,
                until=lambda: task.done,
                after_step=rec.record_frame,
            )
            run(env, task.control, tail, robot=robot, after_step=rec.record_frame)
        size = args.output.stat().st_size
        print(
            f"video: {args.output} ({args.width}x{args.height} at {args.fps} fps, "
            f"{env.time():.2f} s simulated, {size / 1e6:.2f} MB)"
        )
        success = report(task)
    return 0 if success or not task.done else 1  # not done: stopped by --duration


if __name__ == "__main__":
    raise SystemExit(main())
