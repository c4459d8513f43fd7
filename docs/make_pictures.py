"""Render the pictures of the README and the docs with mjkdl itself.

    MUJOCO_GL=egl python docs/make_pictures.py

* ``tabletop.png`` (README): the tutorial scene through its `task` camera, from an MP4 that
  `mjk.VideoRecorder` wrote and that is read back;
* ``scene.png``, ``robot.png`` (docs): offscreen renders of the same scene, the second with the
  chain's body frames drawn;
* ``control.png`` (docs): the Panda part-way round the figure eight of
  ``examples/cartesian_velocity.py``, its TCP's path so far drawn in;
* ``motion.png`` (docs): the Panda of ``examples/plan_shelves.py`` half-way along a planned
  trajectory from above one shelf to above the other, round the wall, its TCP path drawn in;
* ``task.png`` (docs): ``mjkdl/PandaReach-v0`` after a reset, through its `front` camera;
* ``viewer.png`` (docs): the real `SimulateViewer` window with four live figures, grabbed from
  a virtual display (needs Xvfb and ffmpeg's x11grab, which imageio-ffmpeg ships).

The docs pictures are kept under 200 kB each.
"""

from __future__ import annotations

import itertools
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import cv2
import gymnasium as gym
import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
sys.path.insert(0, str(ROOT / "examples"))
from cartesian_velocity import figure_eight  # noqa: E402
from common import HOME, create_arm, create_panda, panda, panda_scene, tutorial_spec  # noqa: E402
from plan_shelves import GRASP, HOVER, SHELF_A, SHELF_B, at, shelves  # noqa: E402

import mjkdl as mjk  # noqa: E402
import mjkdl.task  # noqa: E402  (registers the mjkdl/ tasks with Gymnasium)
from mjkdl.record import offscreen_renderer  # noqa: E402

MAX_BYTES = 200_000
MOTION_SEED = 1  # OMPL's seed for the planned path of motion.png
HOME_PANDA = [0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853]


def readme_picture(env: mjk.Env, robot: mjk.Robot) -> np.ndarray:
    """The last frame of a short MP4 of the scene through the `task` camera."""
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
    return frame


def render(
    env: mjk.Env, camera: mujoco.MjvCamera, frames: int = 0, path: np.ndarray | None = None
) -> np.ndarray:
    """An offscreen picture (BGR) through `camera`; `frames` is MuJoCo's `mjtFrame`, `path`
    (N x 3 world points) a polyline drawn into the scene."""
    option = mujoco.MjvOption()
    option.frame = frames
    with offscreen_renderer(env.model, 640, 400) as renderer:
        renderer.update_scene(env.data, camera=camera, scene_option=option)
        if path is not None:
            draw_path(renderer.scene, path)
        return renderer.render()[..., ::-1]


def draw_path(scene: mujoco.MjvScene, points: np.ndarray, radius: float = 0.004) -> None:
    """Append `points` to `scene` as a chain of thin orange capsules."""
    rgba = np.array([1.0, 0.5, 0.0, 1.0], dtype=np.float32)
    for a, b in itertools.pairwise(points):
        if scene.ngeom >= scene.maxgeom:
            raise RuntimeError(f"the path needs more than the scene's {scene.maxgeom} geoms")
        geom = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(
            geom, mujoco.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3), np.eye(3).ravel(), rgba
        )
        mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_CAPSULE, radius, a, b)
        scene.ngeom += 1


def orbit(lookat: list[float], distance: float, azimuth: float, elevation: float):
    camera = mujoco.MjvCamera()
    camera.lookat[:], camera.distance = lookat, distance
    camera.azimuth, camera.elevation = azimuth, elevation
    return camera


def control_picture(turn: float = 1.5 * np.pi) -> np.ndarray:
    """The Panda after `turn` s of the figure eight under `CartesianVelocityController`."""
    with mjk.Env.build(panda_scene([panda()])) as env:
        robot = create_panda(env)
        env.reset()
        robot.update()
        ctrl = mjk.CartesianVelocityController(robot)
        path = []
        for step in range(round(turn / env.model.opt.timestep)):
            robot.update()
            if step % 10 == 0:  # every 20 ms
                path.append(robot.fk_frame().translation.copy())
            ctrl.command(figure_eight(env.time())[1])
            robot.step()
        robot.update()
        path.append(robot.fk_frame().translation.copy())
        return render(env, orbit([0.3, 0.0, 0.4], 1.25, 215.0, -38.0), path=np.array(path))


def motion_picture() -> np.ndarray:
    """The Panda half-way from shelf A to shelf B over the wall, the planned TCP path drawn."""
    import ompl.util

    from mjkdl.plan import MotionPlanner, TrajectoryFollower

    ompl.util.RNG.setSeed(MOTION_SEED)
    with mjk.Env.build(panda_scene([panda()], shelves())) as env:
        robot = create_panda(env)
        grasp = robot.ik(at(SHELF_A, GRASP + HOVER), np.array(HOME_PANDA)).q
        env.on_reset = lambda ctx: robot.set_joint_pos(grasp, call_forward=False)
        env.reset()
        robot.update()
        trajectory = MotionPlanner(robot).plan(at(SHELF_B, GRASP + HOVER))
        times = np.linspace(0.0, trajectory.duration, 120)
        path = np.array([robot.fk_frame(trajectory.sample(t)[0]).translation for t in times])
        follower = TrajectoryFollower(robot)
        follower.start(trajectory)
        for _ in range(round(0.5 * trajectory.duration / env.timestep())):
            robot.update()
            follower.command()
            robot.step()
        return render(env, orbit([0.25, 0.0, 0.45], 2.2, 235.0, -25.0), path=path)


def task_picture() -> np.ndarray:
    """`mjkdl/PandaReach-v0` just after `reset(seed=0)`, as `render()` returns it."""
    env = gym.make("mjkdl/PandaReach-v0", render_mode="rgb_array", render_height=400)
    try:
        env.reset(seed=0)
        return env.render()[..., ::-1]  # type: ignore[index]
    finally:
        env.close()


def viewer_picture() -> np.ndarray | None:
    """The viewer window with four figures, grabbed from a private Xvfb (None without one)."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None or shutil.which("xdotool") is None:
        print("viewer.png skipped: needs Xvfb and xdotool")
        return None
    script = ROOT / "docs" / "_viewer_shot.py"
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "viewer.png"
        server = subprocess.Popen(  # -displayfd: Xvfb picks a free display and prints it
            [xvfb, "-displayfd", "1", "-screen", "0", "1280x1024x24", "-nolisten", "tcp"],
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        try:
            assert server.stdout is not None
            env = dict(os.environ, DISPLAY=f":{server.stdout.readline().strip()}")
            subprocess.run([sys.executable, str(script), str(out)], env=env, check=True)
            return cv2.imread(str(out))
        finally:
            server.terminate()
            server.wait(5)


def save(name: str, image: np.ndarray, limit: int | None = MAX_BYTES) -> None:
    out = DOCS / name
    cv2.imwrite(str(out), image, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    size = out.stat().st_size
    while limit is not None and size > limit:  # halve the colours' precision until it fits
        image = (image // 8) * 8 + 4
        cv2.imwrite(str(out), image, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        size = out.stat().st_size
    print(f"wrote {out} ({image.shape[1]}x{image.shape[0]}, {size / 1000:.0f} kB)")


def main() -> None:
    with mjk.Env.build(tutorial_spec()) as env:
        robot = create_arm(env)
        env.on_reset = lambda ctx: robot.set_joint_pos(HOME, call_forward=False)
        env.reset()
        save("tabletop.png", readme_picture(env, robot), limit=None)
        save("scene.png", render(env, orbit([0.15, 0.0, 0.75], 2.6, 135.0, -28.0)))
        body = int(mujoco.mjtFrame.mjFRAME_BODY)
        save("robot.png", render(env, orbit([0.1, 0.0, 1.0], 1.3, 120.0, -18.0), body))
    save("control.png", control_picture())
    save("motion.png", motion_picture())
    save("task.png", task_picture())
    shot = viewer_picture()
    if shot is not None:
        save("viewer.png", shot)


if __name__ == "__main__":
    main()
