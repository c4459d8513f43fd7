"""SimulateViewer under a virtual display (Xvfb): stepping, overlays, recording, closing.

Without Xvfb (or xdotool, for the tests that press keys or grab the screen) these tests skip;
with ``MJKDL_REQUIRE_DISPLAY=1`` (set by CI) they fail instead, so a CI box missing them cannot
pass with the viewer untested.
"""

from __future__ import annotations

import itertools
import os
import re
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path
from typing import NoReturn

import cv2
import mujoco
import numpy as np
import pytest
from conftest import (
    HOME,
    ROOT,
    base_spec,
    gripper_tool,
    sigint_as_from_a_terminal,
    table_object,
    tutorial_spec,
)
from screen import grab_window

import mjkdl as mjk
from mjkdl.viewer import overlays as keys
from mjkdl.viewer import plots
from mjkdl.viewer.pacing import Pacer

Arm = tuple[mjk.Env, mjk.Robot, mjk.SimulateViewer]
REQUIRE_DISPLAY = os.environ.get("MJKDL_REQUIRE_DISPLAY") == "1"


def unavailable(reason: str) -> NoReturn:
    """Skip for `reason`, or fail under MJKDL_REQUIRE_DISPLAY=1."""
    if REQUIRE_DISPLAY:
        pytest.fail(f"{reason}, and MJKDL_REQUIRE_DISPLAY=1 asks for every viewer test to run")
    pytest.skip(reason)


def tool(name: str) -> str:
    """Path of command-line tool `name` (Xvfb, xdotool), or skip/fail without it."""
    path = shutil.which(name)
    if path is None:
        unavailable(f"{name} is not installed (apt-get install xvfb xdotool)")
    return path


def start_xvfb(*options: str) -> tuple[subprocess.Popen, str]:
    """A private Xvfb server on a free display number, with extra `options`; (server, name)."""
    xvfb = tool("Xvfb")
    number = next(
        n
        for n in range(99, 199)
        if not Path(f"/tmp/.X11-unix/X{n}").exists() and not Path(f"/tmp/.X{n}-lock").exists()
    )
    socket = Path(f"/tmp/.X11-unix/X{number}")
    server = subprocess.Popen(
        [xvfb, f":{number}", "-screen", "0", "1280x1024x24", "-nolisten", "tcp", *options],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 10.0
    while not socket.exists():
        if server.poll() is not None or time.monotonic() > deadline:
            server.kill()
            pytest.fail(f"Xvfb :{number} did not start (exit code {server.poll()})")
        time.sleep(0.05)
    return server, f":{number}"


@pytest.fixture(scope="module")
def display() -> Iterator[str]:
    """The running display, or a private Xvfb started for this module."""
    if os.environ.get("DISPLAY"):
        yield os.environ["DISPLAY"]
        return
    server, name = start_xvfb()
    os.environ["DISPLAY"] = name
    try:
        yield name
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
    xdotool = tool("xdotool")
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


# ---------------------------------------------------------------------- the window as seen


def settled_grab(viewer: mjk.SimulateViewer) -> np.ndarray:
    """A grab once the window has drawn the latest overlays (software GL: ~0.2 s a frame)."""
    tool("xdotool")
    viewer._push_overlays()
    time.sleep(2.0)
    return grab_window()


def robot_mask(env: mjk.Scene, cam: mujoco.MjvCamera, width: int, height: int) -> np.ndarray:
    """Pixels showing the Gen3 (bodies under `base_link`) or its gripper through `cam`, from
    MuJoCo's segmentation rendering: the reference for what the overlays must not hide."""
    model = env.model
    base = env.body_id("base_link")
    robot = np.zeros(model.nbody, dtype=bool)
    for b in range(model.nbody):
        a = b
        while a > 0 and a != base:
            a = model.body_parentid[a]
        robot[b] = a == base
    with mujoco.Renderer(model, height, width) as renderer:
        renderer.enable_segmentation_rendering()
        renderer.update_scene(env.data, camera=cam)
        seg = renderer.render()
    geom = seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM)
    ids = np.where(geom, seg[..., 0], 0)
    return geom & robot[model.geom_bodyid[ids]]


@pytest.fixture
def layout_arm(display: str) -> Iterator[Arm]:
    """A fresh tutorial arm at home, in its own window (the grabs need the only window)."""
    env = mjk.Env.build(tutorial_spec())
    robot = env.create_robot("base_link", "bracelet_link", tool=gripper_tool())
    robot.set_joint_pos(np.array(HOME))
    robot.sync_commands()
    viewer = mjk.SimulateViewer.open(robot, "layout")
    viewer.realtime_factor = 0.0
    try:
        yield env, robot, viewer
    finally:
        viewer.close()
        env.close()


def test_free_camera_opens_framed_on_the_robot(layout_arm: Arm) -> None:
    env, _robot, viewer = layout_arm
    w, h = 320, 240
    framed = robot_mask(env, viewer.handle.cam, w, h)
    default = mujoco.MjvCamera()
    mujoco.mjv_defaultFreeCamera(env.model, default)  # MuJoCo's own choice: the whole scene
    unframed = robot_mask(env, default, w, h)
    rows, cols = np.nonzero(framed)
    assert rows.min() > 0 and cols.min() > 0 and rows.max() < h - 1
    # Centred in the part of the window the figure column (30 % on the right) leaves free.
    free = (1.0 - plots.COLUMN_SHARE) * w
    assert abs(cols.mean() - free / 2) < 0.1 * w and abs(rows.mean() / h - 0.5) < 0.2
    assert rows.max() - rows.min() > 0.4 * h  # the arm fills a good part of the view
    assert framed.sum() > 3 * unframed.sum(), (framed.sum(), unframed.sum())


def test_four_figures_leave_the_robot_and_the_text_uncovered(layout_arm: Arm) -> None:
    """The real window, grabbed with and without four figures: what the figures change lies
    in the reported column, below the text box, and hides almost none of the robot."""
    env, robot, viewer = layout_arm
    viewer.add_signal("TCP height [m]", lambda: [robot.fk_frame().translation[2]])
    viewer.add_signal("cube height [m]", lambda: [env.body_frame("cube").translation[2]])
    viewer._on_key(keys.KEY_STATS)  # no clock in the text box: it must not change between grabs
    _run(viewer, robot, 50)
    with_figures = settled_grab(viewer)
    texts, rects = viewer._shown
    assert "plots: 1-4 of 4" in texts[0][3] and len(rects) == 4
    viewer._on_key(keys.KEY_PLOTS)  # one page: F11 turns the figures off
    _run(viewer, robot, 1)
    without = settled_grab(viewer)
    assert viewer._shown[1] == [] and "plots: off" in viewer._shown[0][0][3]
    height, width = without.shape[:2]
    viewport = viewer.handle.viewport
    assert (viewport.width, viewport.height) == (width, height)

    # The text box: its white letters in the top-right corner, measured on the grab.
    letters = without[: height // 2, width - 150 : width - 4].min(axis=2) > 180
    text_bottom = int(np.nonzero(letters.any(axis=1))[0].max())
    changed = np.abs(with_figures.astype(int) - without.astype(int)).max(axis=2) > 40
    figure_area = np.zeros_like(changed)
    for k, r in enumerate(rects):
        top = height - (r.bottom + r.height)  # MjrRect counts from the bottom
        assert top >= text_bottom, f"figure {k} starts at row {top}, the text ends at {text_bottom}"
        if k:
            assert r.bottom + r.height <= rects[k - 1].bottom, "figures overlap"
        assert r.left + r.width <= width and r.bottom >= 0
        figure_area[top : top + r.height, r.left : r.left + r.width] = True
    label_row = changed & ~figure_area  # only the F11 label ("1-4 of 4" -> "off") may differ
    rows = np.nonzero(label_row.any(axis=1))[0]
    assert rows.size == 0 or (rows.max() <= text_bottom and np.ptp(rows) < 30), rows
    assert changed[figure_area].mean() > 0.2  # the figures are really drawn where reported

    robot_pixels = cv2.resize(
        robot_mask(env, viewer.handle.cam, width // 2, height // 2).astype(np.uint8),
        (width, height), interpolation=cv2.INTER_NEAREST,
    ).astype(bool)  # fmt: skip
    assert robot_pixels.mean() > 0.03
    hidden = (robot_pixels & changed).sum() / robot_pixels.sum()
    assert hidden < 0.05, f"the figures cover {hidden:.1%} of the robot"
    cv2.imwrite(str(Path(os.environ.get("MJKDL_SHOTS", "/tmp")) / "mjkdl-layout.png"), with_figures)


def test_figure_column_scales_with_the_window_and_pages_the_rest() -> None:
    big = plots.column(mujoco.MjrRect(0, 0, 1920, 1080), 250, 6)
    assert len(big) == plots.MAX_SHOWN == 4
    assert {r.width for r in big} == {480} and {r.left for r in big} == {1920 - 480}
    assert big[0].bottom + big[0].height == 1080 - 250
    assert all(a.bottom == b.bottom + b.height for a, b in itertools.pairwise(big))
    assert big[-1].bottom >= 0 and big[-1].height == (1080 - 250 - 4) // 4
    small = plots.column(mujoco.MjrRect(0, 0, 640, 480), 250, 6)
    assert len(small) == (480 - 250 - 4) // plots.MIN_HEIGHT == 2
    assert {r.width for r in small} == {260}  # 30 % of 640 px is below the 260 px minimum
    assert plots.column(mujoco.MjrRect(0, 0, 640, 480), 250, 1)[0].height == 160  # a third

    overlays = keys.Overlays()
    seen = []
    for _ in range(4):
        overlays.next_plot_page(pages=2)
        seen.append((overlays.plots, overlays.plot_page))
    assert seen == [(True, 1), (False, 0), (True, 0), (True, 1)]


def test_y_axis_fits_the_data_and_shows_its_unit() -> None:
    signals = plots.SignalPlots(window=1.0, points=10)
    value = [0.0]
    signals.add("torque [Nm]", lambda: [value[0], -value[0]])
    for k in range(10):
        value[0] = 2.0 * k
        signals.sample(0.1 * k)
    ((_, fig),) = signals.figures([mujoco.MjrRect(0, 0, 300, 200)], 0)
    lo, hi = fig.range[1]
    assert lo == pytest.approx(-18.0 - 3.6) and hi == pytest.approx(18.0 + 3.6)  # 10 % margin
    assert fig.yformat == "%.0f Nm" and fig.yformat % hi == "22 Nm"
    assert list(fig.linedata[1, 1:20:2]) == [-2.0 * k for k in range(10)]
    assert fig.flg_legend == 1  # two lines fit in 200 px
    signals.add("pressure [newton per square millimetre %]", lambda: [1e5])
    signals.sample(2.0)
    (_, fig), (_, long_unit) = signals.figures([mujoco.MjrRect(0, 0, 300, 200)] * 2, 0)
    assert long_unit.yformat == "%.0f newton per squ"  # MuJoCo's field holds 19 characters
    assert long_unit.title == "pressure [newton per square millimetre %]"
    with pytest.raises(mjk.SpecError, match="1 to 999 characters"):
        signals.add("x" * 1000, lambda: [0.0])


@pytest.mark.parametrize(
    ("out", "shown"),
    [(None, "None"), ("abc", "'abc'"), (["1", "2"], "['1', '2']"), ([1j], "[1j]")],
)
def test_a_signal_must_return_numbers(out, shown) -> None:
    signals = plots.SignalPlots(window=1.0, points=10)
    with pytest.raises(mjk.SpecError) as err:
        signals.add("s", lambda: out)
    assert str(err.value) == f"signal 's' must return numbers, got {shown}"
    value: list[object] = [[0.5, 1.5]]
    signals.add("ok", lambda: value[0])
    value[0] = [True, False]  # bools plot as 0 and 1
    signals.sample(0.0)
    value[0] = None  # a signal that goes bad mid-run is named too
    with pytest.raises(mjk.SpecError) as err:
        signals.sample(1.0)
    assert str(err.value) == "signal 'ok' must return numbers, got None"


@pytest.mark.parametrize("labels", ["ab", [1, 2], ["a", None]])
def test_signal_labels_must_be_strings(labels) -> None:
    signals = plots.SignalPlots(window=1.0, points=10)
    with pytest.raises(mjk.SpecError) as err:
        signals.add("s", lambda: [0.0, 1.0], labels=labels)
    assert str(err.value) == f"signal 's': labels must be a list of strings, got {labels!r}"
    assert signals.names == []


@pytest.mark.parametrize("name", [None, 3])
def test_removing_a_signal_by_a_name_that_is_not_text_names_it(name) -> None:
    signals = plots.SignalPlots(window=1.0, points=10)
    signals.add("q", lambda: [0.0])
    with pytest.raises(KeyError) as err:
        signals.remove(name)
    assert err.value.args[0] == f"no signal named '{name}' in the viewer's plots; known: q"


@pytest.mark.parametrize("factor", ["1", True, None, [1.0], float("nan"), -1.0])
def test_realtime_factor_must_be_a_number(factor) -> None:
    pacer = Pacer(0.5)
    with pytest.raises(mjk.SpecError) as err:
        pacer.factor = factor
    assert str(err.value) == f"realtime_factor must be a finite number >= 0, got {factor!r}"
    assert pacer.factor == 0.5
    pacer.factor = np.float32(2.0)
    assert pacer.factor == 2.0


def test_a_title_that_is_not_text_is_refused_before_a_window_opens() -> None:
    with mjk.Scene.build(base_spec()) as scene, pytest.raises(mjk.SpecTypeError) as err:
        mjk.viewer.SimulateViewer.open(scene, title=None)  # no display needed to refuse it
    assert str(err.value) == "SimulateViewer.open: title must be a string, got None"


def test_ctrl_c_ends_the_loop_and_finalises_the_recording(display: str, tmp_path: Path) -> None:
    script = textwrap.dedent(
        f"""
        import signal, sys
        sys.path.insert(0, {str(ROOT)!r})
        import mjkdl as mjk
        spec = mjk.SceneSpec(timestep=0.002, add_floor=True, add_skybox=False)
        scene = mjk.Scene.build(spec)
        viewer = mjk.SimulateViewer.open(scene, "ctrl c")
        viewer.start_recording(sys.argv[1], 160, 120, 30, shadows=False, reflections=False)
        print("looping", flush=True)
        while viewer.step():
            pass
        print(f"stopped after {{scene.time():.3f}} s", flush=True)
        viewer.close()
        restored = signal.getsignal(signal.SIGINT) is signal.default_int_handler
        print("default handler back:", restored)
        """
    )
    video = tmp_path / "interrupted.mp4"
    proc = subprocess.Popen(
        [sys.executable, "-c", script, str(video)], cwd=tmp_path, env=dict(os.environ),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=sigint_as_from_a_terminal,
    )  # fmt: skip
    try:
        assert proc.stdout is not None and proc.stdout.readline() == "looping\n"
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    simulated = float(re.search(r"stopped after ([\d.]+) s", out).group(1))
    assert simulated > 0.3 and "default handler back: True" in out
    cap = cv2.VideoCapture(str(video))
    frames = 0
    while cap.read()[0]:
        frames += 1
    assert abs(frames - (1 + 30 * simulated)) <= 2, (frames, simulated)


def test_display_without_glx_raises_instead_of_exiting(monkeypatch) -> None:
    """Without GLX, MuJoCo's window thread would end the whole process (mju_error)."""
    server, name = start_xvfb("-extension", "GLX")
    try:
        monkeypatch.setenv("DISPLAY", name)
        with (
            mjk.Scene.build(base_spec()) as scene,
            pytest.raises(mjk.NoDisplayError, match=f"display '{name}' has no GLX"),
        ):
            mjk.SimulateViewer.open(scene, "no glx")
    finally:
        server.terminate()
        server.wait(5)


def test_steps_advance_exactly_one_timestep_each(arm: Arm) -> None:
    env, robot, viewer = arm
    assert viewer.is_running()
    assert viewer.signal_names == ["joint positions [rad]", "joint torques [Nm]"]
    t0, dt = env.time(), env.timestep()
    _run(viewer, robot, 200)
    assert round((env.time() - t0) / dt) == 200
    assert env.time() - t0 == pytest.approx(200 * dt, abs=1e-9)


def test_trace_is_bounded_by_the_user_scene(arm: Arm) -> None:
    env, robot, viewer = arm
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
    # The window's scene holds the user scene's geoms and the model's: room is left for those.
    scn = viewer.handle.user_scn
    assert total == viewer.trace_capacity and scn.ngeom == total
    assert total <= scn.maxgeom - 4 * (env.model.ngeom + env.model.nbody + env.model.nsite)
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
    assert labels.split("\n") == ["t", "F8", "F9", "F10", "F11", "F12", "Backspace", "Tab"]
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


def test_f11_pages_through_six_signals_four_at_a_time(arm: Arm) -> None:
    _env, robot, viewer = arm
    extra = [f"extra {k} [m]" for k in range(4)]
    for name in extra:
        viewer.add_signal(name, lambda: [0.0])
    try:
        pages = []
        for _ in range(4):
            _run(viewer, robot, 1)
            viewer._push_overlays()
            texts, rects = viewer._shown
            label = re.search(r"plots: (.*)", texts[0][3]).group(1)
            pages.append((label, len(rects)))
            viewer._on_key(keys.KEY_PLOTS)
        assert pages == [("1-4 of 6", 4), ("5-6 of 6", 2), ("off", 0), ("1-4 of 6", 4)]
    finally:
        for name in extra:
            viewer.remove_signal(name)


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
    xdotool = tool("xdotool")
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
