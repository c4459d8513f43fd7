"""SimulateViewer: MuJoCo's passive viewer, stepped by the user's own control loop."""

from __future__ import annotations

import atexit
import math
import re
import signal
import threading
import time
import warnings
from collections import deque
from collections.abc import Callable, Sequence
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from ..closable import Closable
from ..errors import MjkdlError, SpecError
from ..names import model_id
from ..record import VideoRecorder, offscreen_renderer
from ..robot import Robot
from ..scene import Env, Scene
from ..validate import text
from . import overlays as ov
from .framing import frame
from .pacing import Pacer
from .plots import COLUMN_SHARE, Signal, SignalPlots, column
from .trace import Trace
from .window import Window

if TYPE_CHECKING:
    from mujoco.viewer import Handle
    from typing_extensions import Self

# Window refreshes: 60 per wall second and per simulated second (as MuJoCo's own viewer at
# real time). Each refresh also renews the mouse-perturbation force, so it must not go stale
# over many simulated steps when running faster than real time.
_SYNC_PERIOD = 1.0 / 60.0
_FULL_SYNC_PERIOD = 1.0
_OVERLAY_PERIOD = 0.1
_CLOSE_TIMEOUT = 5.0


class SimulateViewer(Closable):
    """An interactive window on a scene whose physics only the user's loop advances.

    ``viewer = SimulateViewer.open(robot, "title")``, then per control period: read the state,
    write commands, ``viewer.step()`` (one timestep, through ``robot.step()`` so pending
    commands apply). MuJoCo's passive viewer never steps physics itself. The window is
    refreshed 60 times per wall second and per simulated second; `realtime_factor` paces the
    loop.

    The free camera opens framed on the robots. Keys (besides MuJoCo's own; F1 lists those,
    Tab and Shift+Tab show its panels): F8 body/site frames, F9 trace, F10 real-time factor
    and time, F11 plots (the next page of at most four figures, then off), F12 start/stop an
    MP4 of the view, Backspace reset (`Env.reset()` with its hook, on your thread at the next
    `step()`). Mouse perturbation (double-click a body, Ctrl+drag) is MuJoCo's: the window
    writes the spring force into ``data.xfrc_applied`` at each refresh, so that field is the
    window's while it is open.

    Ctrl+C (SIGINT, when opened on the main thread) ends the session like closing the window:
    at the next `step()` or `is_running()` the recording is finalised, the window closes and
    both return False, so the loop ends without a traceback; a second Ctrl+C interrupts as
    usual.

    Needs a display (Linux: X11 or Xvfb); without one `open` raises `NoDisplayError`. On
    macOS run the script with ``mjpython`` (MuJoCo's launcher), as `launch_passive` requires.
    """

    def __init__(self, scene: Scene, robot: Robot | None, title: str) -> None:
        self._scene, self._robot, self._title = scene, robot, title
        self._keys: deque[int] = deque()
        self._overlays = ov.Overlays()
        self._frames_shown = self._overlays.frames
        self._pacer = Pacer(1.0)
        self._plots = SignalPlots()
        if robot is not None:
            names = robot.joint_names
            self._plots.add("joint positions [rad]", lambda: robot.jnt_pos_msr, names)
            self._plots.add("joint torques [Nm]", lambda: robot.jnt_trq_msr, names)
        self._plot_slots = 1  # figures per page, as last laid out
        self._shown: tuple[list[ov.Text], list[mujoco.MjrRect]] = ([], [])
        self._recorder: VideoRecorder | None = None
        self._record_error: str | None = None
        self._shot: mujoco.Renderer | None = None
        self._sync_due = self._full_sync_due = self._overlay_due = 0.0
        self._synced_time = -np.inf
        self._closed = False
        self._interrupted = False
        self._model = scene.model
        self._window = Window.launch(self._model, scene.data, self._on_key)
        atexit.register(self.close)
        self._sigint = self._catch_ctrl_c()
        viewport = self._window.handle.viewport
        aspect = viewport.width / viewport.height if viewport and viewport.height else 4 / 3
        covered = COLUMN_SHARE if self._plots.names else 0.0
        frame(self._window.handle.cam, self._model, scene.data, aspect, covered)
        self._trace = Trace(self._window.handle.user_scn, _scene_reserve(self._model))
        self._push_overlays()

    @classmethod
    def open(cls, robot_or_scene: Robot | Scene, title: str = "mjkdl") -> Self:
        """Open a window on a Robot's scene (plotting its joint positions and torques) or on
        a Scene/Env. Raises `NoDisplayError` when no window can be opened here."""
        if isinstance(robot_or_scene, Robot):
            robot = robot_or_scene
            scene = robot.scene
        elif isinstance(robot_or_scene, Scene):
            robot, scene = None, robot_or_scene
        else:
            kind = type(robot_or_scene).__name__
            raise SpecError(f"SimulateViewer.open takes a Robot, Scene or Env, got {kind}")
        if scene.closed:
            raise RuntimeError("SimulateViewer.open: the scene is closed")
        return cls(scene, robot, text(title, "SimulateViewer.open: title"))

    @property
    def handle(self) -> Handle:
        """MuJoCo's viewer handle (`cam`, `opt`, `perturb`, `user_scn`), for what mjkdl does
        not wrap. Replaced when the scene is rebuilt (the window reopens on the new model)."""
        return self._window.handle

    # ------------------------------------------------------------------ loop

    @property
    def realtime_factor(self) -> float:
        """Pacing of `step()`: 1.0 real time, 0.5 half speed, 0.0 as fast as possible."""
        return self._pacer.factor

    @realtime_factor.setter
    def realtime_factor(self, value: float) -> None:
        self._pacer.factor = value

    @property
    def measured_realtime_factor(self) -> float | None:
        """Real-time factor achieved over the last half second (None until measured)."""
        return self._pacer.measured

    def is_running(self) -> bool:
        """Whether the window is open (False after Ctrl+C, which it then closes)."""
        if self._interrupted and not self._closed:
            self._end_session()
        return not self._closed and self._window.is_running()

    def step(self) -> bool:
        """Advance one timestep (through the robot when opened on one), refresh the window,
        pace to `realtime_factor`; False, without stepping, once the window is closed or
        Ctrl+C was pressed."""
        self._check_open()
        if not self.is_running():
            return False
        if self._scene.model is not self._model:
            self._relaunch()
        if self._robot is not None:
            self._robot.step()
        else:
            self._scene.step()
        t = self._scene.time()
        self._plots.sample(t)
        reset = self._handle_keys()
        if self._overlays.frames != self._frames_shown:  # leaves MuJoCo's own F6 cycling alone
            self._window.handle.opt.frame = self._frames_shown = self._overlays.frames
        now = time.perf_counter()
        if reset or now >= self._sync_due or abs(t - self._synced_time) >= _SYNC_PERIOD:
            self._sync(now)  # also applies MuJoCo's own pending Backspace reset
        if reset:
            self._reset()
            self._sync(now)
        if self._recorder is not None:
            self._recorder.record_frame()
        if now >= self._overlay_due:
            self._push_overlays()
            self._overlay_due = now + _OVERLAY_PERIOD
        self._pacer.pace(self._scene.time())
        return self._window.is_running()

    def _on_key(self, key: int) -> None:
        """GLFW key callback: runs on the window thread, so it only queues the key."""
        self._keys.append(key)

    def _handle_keys(self) -> bool:
        """Apply queued keys on the user's thread; True when a reset was asked for."""
        reset = False
        while self._keys:
            key = self._keys.popleft()
            self._overlay_due = 0.0
            if key == ov.KEY_FRAMES:
                self._overlays.frames = int(self._window.handle.opt.frame)  # F6 may have moved it
                self._overlays.cycle_frames()
            elif key == ov.KEY_TRACE:
                self._overlays.trace = not self._overlays.trace
            elif key == ov.KEY_STATS:
                self._overlays.stats = not self._overlays.stats
            elif key == ov.KEY_PLOTS:
                pages = max(1, math.ceil(len(self._plots.names) / self._plot_slots))
                self._overlays.next_plot_page(pages)
            elif key == ov.KEY_RECORD:
                self._toggle_recording()
            elif key == ov.KEY_RESET:
                reset = True
        return reset

    def _sync(self, now: float) -> None:
        self._scene.refresh_poses()  # the window shows the state the last step reached
        full = now >= self._full_sync_due
        self._window.sync(full, hide_user_geoms=not self._overlays.trace)
        self._sync_due = now + _SYNC_PERIOD
        self._synced_time = self._scene.time()
        if full:
            self._full_sync_due = now + _FULL_SYNC_PERIOD

    def _reset(self) -> None:
        scene = self._scene
        if isinstance(scene, Env):
            scene.reset()
            return
        mujoco.mj_resetData(scene.model, scene.data)
        mujoco.mj_forward(scene.model, scene.data)
        if self._robot is not None:
            self._robot.sync_commands()

    # ------------------------------------------------------------------ camera

    def use_camera(self, name: str) -> None:
        """Look through model camera `name`; "" returns to the free (mouse-driven) camera."""
        self._check_open()
        cam = self._window.handle.cam
        if name == "":
            cam.type = mujoco.mjtCamera.mjCAMERA_FREE
            return
        cid = self._camera_id(name)
        cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
        cam.fixedcamid = cid

    def _camera_id(self, name: str) -> int:
        camera = mujoco.mjtObj.mjOBJ_CAMERA
        return model_id(self._scene.model, camera, "camera", name, "the scene")

    # ------------------------------------------------------------------ overlays

    @property
    def overlays(self) -> ov.Overlays:
        """The overlay switches, which the keys flip: `frames` (`mjtFrame`: none, body or
        site axes), `trace`, `stats` (time and real-time factor), `plots`."""
        return self._overlays

    def clear_trace(self) -> None:
        """Remove every trace segment."""
        self._check_open()
        self._trace.clear()

    def add_trace_segment(
        self, a: Sequence[float], b: Sequence[float], rgba: Sequence[float]
    ) -> bool:
        """Draw a world-frame segment `a`-`b`; False (nothing drawn) once `trace_capacity`
        segments are drawn, so keep traces bounded."""
        self._check_open()
        return self._trace.add(a, b, rgba)

    @property
    def trace_capacity(self) -> int:
        """Most trace segments the window holds at once (its scene's `maxgeom` less room for
        the model's own geoms and decorations)."""
        return self._trace.capacity

    def add_signal(self, name: str, fn: Signal, labels: Sequence[str] | None = None) -> None:
        """Plot `fn()` (a float array, one line per entry) live against simulation time."""
        self._plots.add(name, fn, labels)

    def remove_signal(self, name: str) -> None:
        """Stop plotting signal `name` (the defaults included)."""
        self._plots.remove(name)

    @property
    def signal_names(self) -> list[str]:
        """Plotted signals, in order."""
        return self._plots.names

    def _push_overlays(self) -> None:
        recording = None
        if self._recorder is not None:
            recording = f"{self._recorder.path.name}, {self._recorder.frames_written} frames"
        elif self._record_error is not None:
            recording = f"failed: {self._record_error}"
        viewport = self._window.handle.viewport
        count = len(self._plots.names)
        page = self._overlays.plot_page
        rects: list[mujoco.MjrRect] = []
        if viewport is not None and count:
            # The box's height depends on its rows alone, which the page label does not change.
            probe = self._texts(recording, "")
            rects = column(viewport, ov.text_height(probe), count)
        self._plot_slots = max(1, len(rects))
        page = min(page, max(0, math.ceil(count / self._plot_slots) - 1))  # after a resize
        first = page * self._plot_slots
        shown = f"{first + 1}-{min(count, first + self._plot_slots)} of {count}" if count else ""
        texts = self._texts(recording, shown)
        figures = self._plots.figures(rects, page) if self._overlays.plots else []
        self._window.show(texts, figures)
        self._shown = (texts, [rect for rect, _ in figures])  # what the window was sent

    def _texts(self, recording: str | None, plots: str) -> list[ov.Text]:
        return ov.texts(
            self._overlays,
            self._title,
            self._scene.time(),
            self._pacer.measured,
            self._pacer.factor,
            recording,
            plots,
        )

    def _draw_trace(self, scene: mujoco.MjvScene) -> None:
        if self._overlays.trace:
            self._trace.draw_into(scene)

    # ------------------------------------------------------------------ images

    def screenshot(self, width: int = 640, height: int = 480) -> np.ndarray:
        """An RGB image (height, width, 3) of what the window's camera sees, trace included,
        rendered offscreen."""
        self._check_open()
        model = self._scene.model
        shot = self._shot
        if shot is None or shot.model is not model or (shot.width, shot.height) != (width, height):
            if shot is not None:
                shot.close()
            self._shot = shot = offscreen_renderer(model, width, height)
        handle = self._window.handle
        shot.update_scene(self._scene.data, camera=handle.cam, scene_option=handle.opt)
        self._draw_trace(shot.scene)
        return shot.render()

    @property
    def recording(self) -> bool:
        """Whether the view is being recorded (F12 or `start_recording`)."""
        return self._recorder is not None

    def start_recording(
        self,
        path: str | Path | None = None,
        width: int = 1280,
        height: int = 720,
        fps: float = 30.0,
        *,
        shadows: bool = True,
        reflections: bool = True,
    ) -> Path:
        """Record what the window's camera shows to an MP4 (frames by simulation time, as
        `VideoRecorder`); default path ``<title>-<date>-<time>.mp4`` in the working folder.
        Rendering offscreen slows the loop: on software OpenGL turn shadows/reflections off."""
        self._check_open()
        if self._recorder is not None:
            return self._recorder.path
        if path is None:
            slug = re.sub(r"[^A-Za-z0-9_.-]+", "_", self._title).strip("_") or "mjkdl"
            path = Path.cwd() / f"{slug}-{time.strftime('%Y%m%d-%H%M%S')}.mp4"
        recorder = VideoRecorder.open(
            self._scene, path, width, height, fps, shadows=shadows, reflections=reflections
        )
        handle = self._window.handle
        recorder.follow_view(handle.cam, handle.opt, self._draw_trace)
        self._recorder, self._record_error = recorder, None
        recorder.record_frame()
        return recorder.path

    def stop_recording(self) -> Path | None:
        """Finalise the MP4 being recorded; its path (None when not recording)."""
        recorder, self._recorder = self._recorder, None
        if recorder is None:
            return None
        recorder.close()
        return recorder.path

    def _toggle_recording(self) -> None:
        if self._recorder is not None:
            self.stop_recording()
            return
        try:
            self.start_recording()
        except (MjkdlError, OSError) as err:  # from a key press: report, do not end the loop
            self._record_error = str(err)
            warnings.warn(f"SimulateViewer: recording did not start: {err}", stacklevel=4)

    # ------------------------------------------------------------------ rebuilds

    def _relaunch(self) -> None:
        """The scene was rebuilt (add_object/remove_object): reopen the window on the new
        model, keeping the camera, overlays, trace and recording."""
        old_model, old = self._model, self._window
        cam = old.handle.cam
        fixed = None
        if cam.type == mujoco.mjtCamera.mjCAMERA_FIXED:
            fixed = old_model.camera(cam.fixedcamid).name
        view = (cam.lookat.copy(), cam.distance, cam.azimuth, cam.elevation)
        old.close(_CLOSE_TIMEOUT)
        self._model = self._scene.model
        self._window = Window.launch(self._model, self._scene.data, self._on_key)
        handle = self._window.handle
        new = handle.cam
        new.lookat[:], new.distance, new.azimuth, new.elevation = view
        self.use_camera(fixed if fixed in self._scene.camera_names() else "")
        handle.opt.frame = self._frames_shown = self._overlays.frames
        self._trace.rebind(handle.user_scn, _scene_reserve(self._model))
        if self._recorder is not None:
            self._recorder.follow_view(handle.cam, handle.opt, self._draw_trace)
        self._sync_due = self._full_sync_due = self._overlay_due = 0.0

    # ------------------------------------------------------------------ lifecycle

    def _catch_ctrl_c(self) -> Callable[[int, FrameType | None], None] | None:
        """Turn the first SIGINT into the end of the session (see the class docstring); only
        on the main thread, and only over Python's default handler, never over the user's."""
        if threading.current_thread() is not threading.main_thread():
            return None
        previous = signal.getsignal(signal.SIGINT)
        if previous is not signal.default_int_handler:
            return None

        def on_sigint(signum: int, stack: FrameType | None) -> None:
            self._interrupted = True
            signal.signal(signal.SIGINT, previous)  # a second Ctrl+C interrupts as usual

        signal.signal(signal.SIGINT, on_sigint)
        return on_sigint

    def _release_ctrl_c(self) -> None:
        handler, self._sigint = self._sigint, None
        main = threading.current_thread() is threading.main_thread()
        if handler is not None and main and signal.getsignal(signal.SIGINT) is handler:
            signal.signal(signal.SIGINT, signal.default_int_handler)

    def _end_session(self) -> None:
        """After Ctrl+C: finalise the recording and close the window, as the user closing it
        would (`step()` then returns False; `close()` is still the caller's to call)."""
        self._release_ctrl_c()
        try:
            self.stop_recording()
        finally:
            if self._window.is_running():
                self._window.close(_CLOSE_TIMEOUT)

    def close(self) -> None:
        """Finalise a recording, close the window and wait (at most 5 s) for its thread."""
        if self._closed:
            return
        self._closed = True
        atexit.unregister(self.close)
        self._release_ctrl_c()
        try:
            self.stop_recording()
        finally:
            if self._shot is not None:
                self._shot.close()
                self._shot = None
            if not self._window.close(_CLOSE_TIMEOUT):
                warnings.warn(
                    f"SimulateViewer: the window thread did not stop within {_CLOSE_TIMEOUT} s",
                    stacklevel=2,
                )

    @property
    def closed(self) -> bool:
        """Whether `close()` was called."""
        return self._closed


def _scene_reserve(model: mujoco.MjModel) -> int:
    """Geoms the window's scene needs besides the trace: the model's, with room for frames
    (three arrows per body and site), contacts and labels."""
    return 4 * (model.ngeom + model.nbody + model.nsite) + 2000
