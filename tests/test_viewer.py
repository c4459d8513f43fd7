"""SimulateViewer under a virtual display (Xvfb): stepping, overlays, recording, closing."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import mujoco
import numpy as np
import pytest
from conftest import HOME, ROOT, base_spec, gripper_tool, table_object, tutorial_spec

import mjkdl as mjk
from mjkdl.viewer import overlays as keys

Arm = tuple[mjk.Env, mjk.Robot, mjk.SimulateViewer]


@pytest.fixture(scope="module")
def display() -> Iterator[str]:
    """The running display, or a private Xvfb started for this module."""
    if os.environ.get("DISPLAY"):
        yield os.environ["DISPLAY"]
        return
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        pytest.skip("no DISPLAY and no Xvfb binary to start one (apt-get install xvfb)")
    number = next(
        n
        for n in range(99, 199)
        if not Path(f"/tmp/.X11-unix/X{n}").exists() and not Path(f"/tmp/.X{n}-lock").exists()
    )
    socket = Path(f"/tmp/.X11-unix/X{number}")
    server = subprocess.Popen(
        [xvfb, f":{number}", "-screen", "0", "1280x1024x24", "-nolisten", "tcp"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 10.0
    while not socket.exists():
        if server.poll() is not None or time.monotonic() > deadline:
            server.kill()
            pytest.fail(f"Xvfb :{number} did not start (exit code {server.poll()})")
        time.sleep(0.05)
    os.environ["DISPLAY"] = f":{number}"
    try:
        yield os.environ["DISPLAY"]
    finally:
        import glfw

        glfw.terminate()  # else Xlib exits the process when its server goes away
        del os.environ["DISPLAY"]
        server.terminate()
        server.wait(5)


@pytest.fixture(scope="module")
def arm(display: str) -> Iterator[Arm]:
    """The tutorial Env with its arm, and one viewer on the arm for the module's tests."""
    env = mjk.Env.build(tutorial_spec())
    robot = env.create_robot("base_link", "bracelet_link", tool=gripper_tool())
    viewer = mjk.SimulateViewer.open(robot, "test viewer")
    viewer.realtime_factor = 0.0
    yield env, robot, viewer
    viewer.close()
    env.close()


def _run(viewer: mjk.SimulateViewer, robot: mjk.Robot | None, steps: int) -> None:
    for _ in range(steps):
        if robot is not None:
            robot.update()
        assert viewer.step()


def _object_spec() -> mjk.SceneSpec:
    cube = mjk.SceneObject(
        name="cube", shape=mjk.Shape.BOX, size=[0.03] * 3, pos=[0.0, 0.0, 0.8], mass=0.1
    )
    return base_spec(objects=[table_object(), cube])


def test_object_only_scene_steps_and_closes_within_five_seconds(display: str, recwarn) -> None:
    with mjk.Scene.build(_object_spec()) as scene:
        viewer = mjk.SimulateViewer.open(scene, "objects")
        viewer.realtime_factor = 0.0
        assert viewer.signal_names == []
        _run(viewer, None, 200)
        assert scene.time() == pytest.approx(200 * scene.timestep(), abs=1e-9)
        start = time.perf_counter()
        viewer.close()
        elapsed = time.perf_counter() - start
        assert elapsed < 5.0, f"close took {elapsed:.2f} s"
        assert not viewer.is_running()
        assert not [w for w in recwarn if "SimulateViewer" in str(w.message)]
        viewer.close()  # idempotent
        with pytest.raises(RuntimeError, match="SimulateViewer is closed"):
            viewer.step()


def test_a_rebuilt_scene_reopens_the_window(display: str) -> None:
    with mjk.Env.build(_object_spec()) as env:
        viewer = mjk.SimulateViewer.open(env, "rebuild")
        viewer.realtime_factor = 0.0
        try:
            viewer.use_camera("")
            _run(viewer, None, 10)
            old = viewer.handle
            env.add_object(
                mjk.SceneObject(
                    name="pillar",
                    shape=mjk.Shape.BOX,
                    size=[0.05, 0.05, 0.2],
                    pos=[0.2, 0.0, 0.9],
                    mass=0.5,
                )
            )
            _run(viewer, None, 10)
            assert viewer.handle is not old and viewer.handle.m.nbody == env.model.nbody
            assert env.time() == pytest.approx(20 * env.timestep(), abs=1e-9)
            assert viewer.is_running() and not old.is_running()
        finally:
            viewer.close()


def test_quitting_from_the_window_ends_the_users_loop(display: str) -> None:
    """Ctrl+Q (MuJoCo's File > Quit) in the window: step() turns False, close() is quick."""
    xdotool = shutil.which("xdotool")
    if xdotool is None:
        pytest.skip("xdotool is not installed")
    with mjk.Scene.build(_object_spec()) as scene:
        viewer = mjk.SimulateViewer.open(scene, "quit")
        try:
            _run(viewer, None, 5)
            subprocess.run([xdotool, "mousemove", "400", "300", "key", "ctrl+q"], check=True)
            deadline = time.monotonic() + 10.0
            while viewer.step() and time.monotonic() < deadline:
                time.sleep(0.01)
            assert not viewer.is_running()
            stepped = scene.time()
            assert viewer.step() is False and scene.time() == stepped  # no step once closed
        finally:
            start = time.perf_counter()
            viewer.close()
            assert time.perf_counter() - start < 5.0


def test_open_without_a_display_says_what_to_do(monkeypatch) -> None:
    with mjk.Scene.build(base_spec()) as scene:
        monkeypatch.delenv("DISPLAY", raising=False)
        monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
        with pytest.raises(mjk.NoDisplayError, match="DISPLAY is not set") as err:
            mjk.SimulateViewer.open(scene, "no display")
        assert isinstance(err.value, RuntimeError) and isinstance(err.value, mjk.MjkdlError)
        assert "--headless" in str(err.value) and "VideoRecorder" in str(err.value)
        monkeypatch.setenv("DISPLAY", ":4242")
        with pytest.raises(mjk.NoDisplayError, match="cannot open display ':4242'"):
            mjk.SimulateViewer.open(scene, "no display")


def test_exiting_without_close_neither_crashes_nor_hangs(display: str) -> None:
    """A window left open at exit: the atexit guard joins its thread (else: segfault or hang)."""
    script = textwrap.dedent(
        f"""
        import sys
        sys.path.insert(0, {str(ROOT)!r})
        import mjkdl as mjk
        spec = mjk.SceneSpec(timestep=0.002, add_floor=True, add_skybox=False)
        scene = mjk.Scene.build(spec)
        viewer = mjk.SimulateViewer.open(scene, "left open")
        viewer.realtime_factor = 0.0
        for _ in range(50):
            viewer.step()
        print("screenshot std", round(float(viewer.screenshot(64, 48).std()), 1))
        """
    )
    env = dict(os.environ, MUJOCO_GL="egl")
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, f"exit code {done.returncode}: {done.stderr[-2000:]}"
    assert "screenshot std" in done.stdout
    assert time.perf_counter() - start < 30.0


def test_steps_advance_exactly_one_timestep_each(arm: Arm) -> None:
    env, robot, viewer = arm
    assert viewer.is_running()
    assert viewer.signal_names == ["joint positions [rad]", "joint torques [Nm]"]
    t0, dt = env.time(), env.timestep()
    _run(viewer, robot, 200)
    assert round((env.time() - t0) / dt) == 200
    assert env.time() - t0 == pytest.approx(200 * dt, abs=1e-9)


def test_trace_is_bounded_by_the_user_scene(arm: Arm) -> None:
    _env, robot, viewer = arm
    viewer.clear_trace()
    drawn = [
        viewer.add_trace_segment([0.0, 0.0, 1e-4 * i], [0.1, 0.0, 1e-4 * i], [1, 0.5, 0.1, 1])
        for i in range(10_000)
    ]
    assert all(drawn)
    _run(viewer, robot, 5)
    total = 10_000
    while viewer.add_trace_segment([0, 0, 0], [0, 0, 0.1], [0, 1, 0, 1]):
        total += 1
    assert total == viewer.trace_capacity == viewer.handle.user_scn.maxgeom
    assert viewer.add_trace_segment([0, 0, 0], [0, 0, 0.1], [0, 1, 0, 1]) is False
    _run(viewer, robot, 5)
    viewer.clear_trace()
    assert viewer.add_trace_segment([0, 0, 0], [0, 0, 0.1], [0, 1, 0, 1]) is True
    with pytest.raises(mjk.SpecError, match="3, 3 and 4 numbers"):
        viewer.add_trace_segment([0, 0], [0, 0, 0.1], [0, 1, 0, 1])
    with pytest.raises(mjk.SpecError, match="finite"):
        viewer.add_trace_segment([0, 0, np.nan], [0, 0, 0.1], [0, 1, 0, 1])
    viewer.clear_trace()


def test_use_camera_switches_the_view_and_names_unknown_cameras(arm: Arm) -> None:
    env, robot, viewer = arm
    viewer.clear_trace()
    viewer.use_camera("task")
    cam = viewer.handle.cam  # the window's own camera, which screenshots render through
    assert cam.type == mujoco.mjtCamera.mjCAMERA_FIXED
    assert cam.fixedcamid == env.camera_names().index("task")
    _run(viewer, robot, 1)
    task = viewer.screenshot(320, 240)
    viewer.use_camera("")
    assert cam.type == mujoco.mjtCamera.mjCAMERA_FREE
    free = viewer.screenshot(320, 240)
    assert np.abs(free.astype(int) - task.astype(int)).mean() > 5.0
    with pytest.raises(mjk.UnknownNameError, match="close matches: task") as err:
        viewer.use_camera("tsak")
    assert isinstance(err.value, KeyError)


def test_screenshot_shows_the_table_against_the_floor(arm: Arm) -> None:
    _env, _robot, viewer = arm
    viewer.clear_trace()
    viewer.use_camera("task")
    image = viewer.screenshot(320, 240)
    assert image.shape == (240, 320, 3) and image.std() > 20.0
    table = image[100:130, 140:180].reshape(-1, 3).mean(axis=0)
    floor = image[220:240, 0:30].reshape(-1, 3).mean(axis=0)
    assert np.abs(table - floor).sum() > 60.0, (table, floor)
    viewer.use_camera("")


def test_each_overlay_key_toggles_its_overlay(arm: Arm) -> None:
    _env, robot, viewer = arm
    viewer.use_camera("task")
    viewer.clear_trace()
    red = [1.0, 0.0, 0.0, 1.0]
    for k in range(40):  # a red fence across the table, in front of the task camera
        viewer.add_trace_segment([-0.3, -0.2, 0.75 + 0.005 * k], [0.5, -0.2, 0.75 + 0.005 * k], red)

    def red_pixels() -> int:
        img = viewer.screenshot(320, 240).astype(int)
        return int(((img[..., 0] > 200) & (img[..., 1] < 60) & (img[..., 2] < 60)).sum())

    body, site = int(mujoco.mjtFrame.mjFRAME_BODY), int(mujoco.mjtFrame.mjFRAME_SITE)
    expected_frames = [body, site, int(mujoco.mjtFrame.mjFRAME_NONE)]
    for want in expected_frames:
        viewer._on_key(keys.KEY_FRAMES)  # what GLFW calls on the window thread
        _run(viewer, robot, 1)
        assert viewer.overlays.frames == want
        assert int(viewer.handle.opt.frame) == want
    shown = red_pixels()
    viewer._on_key(keys.KEY_TRACE)
    _run(viewer, robot, 1)
    assert viewer.overlays.trace is False
    assert shown > 200 and red_pixels() == 0
    for key, flag in ((keys.KEY_STATS, "stats"), (keys.KEY_PLOTS, "plots")):
        viewer._on_key(key)
        _run(viewer, robot, 1)
        assert getattr(viewer.overlays, flag) is False
    ((_, _, labels, values),) = keys.texts(viewer.overlays, "t", 1.0, 0.5, 1.0, None)
    assert labels.split("\n") == ["t", "F8", "F9", "F10", "F11", "F12", "Backspace"]
    assert "trace: off" in values and "plots: off" in values and "record: off" in values
    for key in (keys.KEY_TRACE, keys.KEY_STATS, keys.KEY_PLOTS):
        viewer._on_key(key)
    _run(viewer, robot, 1)
    assert viewer.overlays == keys.Overlays()
    ((_, _, labels, values),) = keys.texts(viewer.overlays, "t", 1.0, 0.5, 1.0, "v.mp4")
    assert labels.split("\n")[1:3] == ["time", "real-time"]
    assert "0.50x (target 1x)" in values and "record: v.mp4" in values
    viewer.clear_trace()
    viewer.use_camera("")


def test_reset_key_runs_the_env_reset_hook_on_the_users_thread(arm: Arm) -> None:
    env, robot, viewer = arm
    calls = []

    def hook(ctx: mjk.ResetContext) -> None:
        calls.append(time.monotonic())
        robot.set_joint_pos(np.array(HOME), call_forward=False)

    env.on_reset = hook
    try:
        _run(viewer, robot, 20)
        assert env.time() > 0 and calls == []
        viewer._on_key(keys.KEY_RESET)
        assert viewer.step()
        assert len(calls) == 1
        assert env.time() == 0.0
        robot.update()
        assert np.allclose(robot.jnt_pos_msr, HOME)
    finally:
        env.on_reset = None


def test_backspace_in_the_window_resets_through_env_reset(arm: Arm) -> None:
    """A real key press: MuJoCo resets the data at the next sync, then the Env hook runs."""
    xdotool = shutil.which("xdotool")
    if xdotool is None:
        pytest.skip("xdotool is not installed (the key handling itself is tested above)")
    env, robot, viewer = arm
    times = []
    env.on_reset = lambda ctx: times.append(ctx.data.time)
    try:
        _run(viewer, robot, 20)
        subprocess.run([xdotool, "mousemove", "400", "300", "key", "BackSpace"], check=True)
        deadline = time.monotonic() + 10.0
        while not times and time.monotonic() < deadline:
            _run(viewer, robot, 1)
            time.sleep(0.01)
        assert times == [0.0]
        assert env.time() == 0.0
    finally:
        env.on_reset = None


def test_mouse_perturbation_force_reaches_the_users_steps(arm: Arm) -> None:
    """MuJoCo's window writes the spring force of a perturbation into xfrc_applied at sync."""
    env, robot, viewer = arm
    cube = env.body_id("cube")
    z0 = float(env.data.xpos[cube, 2])
    pert = viewer.handle.perturb
    pert.select, pert.localpos[:] = cube, 0.0
    pert.localmass = env.model.body_subtreemass[cube]
    pert.refselpos[:] = env.data.xpos[cube] + [0.0, 0.0, 0.3]
    pert.refpos[:] = pert.refselpos
    pert.refquat[:] = env.data.xquat[cube]
    pert.active = int(mujoco.mjtPertBit.mjPERT_TRANSLATE)
    try:
        _run(viewer, robot, 300)
        assert env.data.xpos[cube, 2] - z0 > 0.05
    finally:
        pert.active, pert.select = 0, 0
        env.set_body_pose("cube", [0.35, 0.10, 0.725])
    _run(viewer, robot, 30)  # the next window refresh clears the force
    assert not env.data.xfrc_applied.any()


def test_recording_from_the_viewer(arm: Arm, tmp_path: Path, monkeypatch) -> None:
    env, robot, viewer = arm
    fast = {"shadows": False, "reflections": False}
    path = viewer.start_recording(tmp_path / "view.mp4", 640, 360, 30, **fast)
    assert viewer.recording
    _run(viewer, robot, round(1.0 / env.timestep()) - 1)  # the start captured the first frame
    assert viewer.stop_recording() == path and not viewer.recording
    cap = cv2.VideoCapture(str(path))
    size = (cap.get(cv2.CAP_PROP_FRAME_WIDTH), cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    frames = 0
    while cap.read()[0]:
        frames += 1
    assert size == (640, 360) and abs(frames - 30) <= 1

    monkeypatch.chdir(tmp_path)  # F12 writes <title>-<date>-<time>.mp4 in the working folder
    viewer._on_key(keys.KEY_RECORD)
    _run(viewer, robot, 20)
    assert viewer.recording
    viewer._on_key(keys.KEY_RECORD)
    _run(viewer, robot, 1)
    assert not viewer.recording
    (video,) = tmp_path.glob("test_viewer-*.mp4")
    assert cv2.VideoCapture(str(video)).read()[0]
