"""Render docs/tabletop.png, the README's picture, with mjkdl's own VideoRecorder.

    MUJOCO_GL=egl python docs/make_picture.py

Records a short MP4 of the tutorial scene (the arm at home, fingers open) through the `task`
camera, then keeps its last frame as a PNG.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import cv2

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "examples"))
from common import HOME, create_arm, tutorial_spec  # noqa: E402

import mjkdl as mjk  # noqa: E402


def main() -> None:
    with mjk.Env.build(tutorial_spec()) as env:
        robot = create_arm(env)
        env.on_reset = lambda ctx: robot.set_joint_pos(HOME, call_forward=False)
        env.reset()
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "tabletop.mp4"
            with mjk.VideoRecorder.open(env, path, 960, 540, fps=10) as recorder:
                recorder.use_camera("task")
                for _ in range(100):
                    robot.update()
                    robot.step()
                    recorder.record_frame()
            video = cv2.VideoCapture(str(path))
            frame = None
            while True:
                ok, image = video.read()
                if not ok:
                    break
                frame = image
            video.release()
    if frame is None:
        raise RuntimeError(f"no frame could be read back from {path}")
    out = ROOT / "docs" / "tabletop.png"
    cv2.imwrite(str(out), frame)
    print(f"wrote {out} ({frame.shape[1]}x{frame.shape[0]})")


if __name__ == "__main__":
    main()
