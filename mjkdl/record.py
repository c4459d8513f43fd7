"""Offscreen MP4 recording of a scene: `mujoco.Renderer` in, H.264 through imageio-ffmpeg out.

Frames follow simulation time, not calls: call `record_frame()` after every step and the
recorder keeps one frame per 1/fps simulated seconds, so N simulated seconds make an N-second
video at any timestep. Encoding (imageio-ffmpeg's own ffmpeg, libx264, yuv420p) runs on a
background thread behind a small bounded queue, so it overlaps with rendering.

Headless machines: set ``MUJOCO_GL=egl`` before importing mujoco (or mjkdl). On Linux the
recorder renders through EGL also when MuJoCo picked GLFW because MUJOCO_GL was unset; set
``MUJOCO_GL=glfw`` to insist on GLFW.

Nothing is lost silently: `open` creates the output file to prove it is writable, `close`
reads the finished MP4 back with imageio-ffmpeg's ffmpeg and raises `RecordingError` naming the
path when it is unreadable or holds another frame count than was recorded (a full disk, a
killed encoder). Frames per call are bounded: `fps` is at most `MAX_FPS`, and a jump of more
than one simulated second between two captures (editing ``data.time``) is treated like a
reset, one frame and a new segment, so one `record_frame()` writes at most ``ceil(fps) + 1``.

Quality vs speed: shadows and reflections (MuJoCo's ``mjRND_SHADOW``/``mjRND_REFLECTION`` scene
flags) are on by default and cost most of the render time on software OpenGL (Mesa llvmpipe):
at 1280x720 about 5-6 frames/s with both on against 18-19 with both off
(`benchmarks/record.py`). Pass ``shadows=False, reflections=False`` for fast previews.
"""

from __future__ import annotations

import enum
import math
import os
import queue
import sys
import threading
import warnings
import weakref
from collections.abc import Callable, Generator
from pathlib import Path
from typing import TYPE_CHECKING

import imageio_ffmpeg
import mujoco
import numpy as np

from .closable import Closable
from .errors import MjkdlError, SimulationError, SpecError, SpecTypeError
from .names import model_id
from .validate import flag, path_text, real, text

if TYPE_CHECKING:
    from typing_extensions import Self

    from .scene import Scene

# libx264 "ultrafast": the encoder must not take CPU from software rendering (benchmarks/record.py).
_X264_PARAMS = ["-preset", "ultrafast", "-crf", "23"]
_QUEUE_FRAMES = 4
_EPS = 1e-6
MIN_FPS = 0.01  # frames per simulated second: one per 100 s; ffmpeg's MP4 muxer fails near 1e-6
MAX_FPS = 240.0  # frames per simulated second; beyond it a video only repeats frames
_FREE = int(mujoco.mjtCamera.mjCAMERA_FREE)
_TRACKING = int(mujoco.mjtCamera.mjCAMERA_TRACKING)
_FIXED = int(mujoco.mjtCamera.mjCAMERA_FIXED)


class RecordingError(MjkdlError, OSError):
    """The finished video is not what was recorded: unreadable, or frames are missing."""


class VideoWriteError(RecordingError):
    """The video cannot be written: missing folder, no permission, or the encoder failed."""


class ImageWriteError(MjkdlError, OSError):
    """An image cannot be written: missing folder, no permission, or no writer for its type."""


class OffscreenRenderError(MjkdlError, RuntimeError):
    """No OpenGL context for offscreen rendering could be created on this machine."""


class VideoResolution(enum.Enum):
    """Preset frame sizes (16:9), as (width, height)."""

    R480p = (854, 480)
    R720p = (1280, 720)
    R1080p = (1920, 1080)

    @property
    def width(self) -> int:
        """Frame width, pixels."""
        return self.value[0]

    @property
    def height(self) -> int:
        """Frame height, pixels."""
        return self.value[1]


def check_offscreen_size(model: mujoco.MjModel, width: object, height: object) -> None:
    """Refuse a frame size that is not a positive integer or exceeds the model's offscreen
    buffer (`offwidth`/`offheight`), without making an OpenGL context."""
    for field, value, limit, attr in (
        ("width", width, model.vis.global_.offwidth, "offwidth"),
        ("height", height, model.vis.global_.offheight, "offheight"),
    ):
        if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value <= 0:
            raise SpecError(f"{field} must be a positive integer, got {value!r}")
        if value > limit:
            raise SpecError(
                f"{field} {value} exceeds the model's offscreen buffer ({attr} = {limit}); "
                f"use a smaller size or raise model.vis.global_.{attr} (<visual><global "
                f'{attr}="..."/> in MJCF)'
            )


def offscreen_renderer(
    model: mujoco.MjModel,
    width: int,
    height: int,
    *,
    shadows: bool = True,
    reflections: bool = True,
) -> mujoco.Renderer:
    """A `mujoco.Renderer` of `width`x`height` with the given quality flags.

    Checks the size against the model's offscreen buffer, prefers EGL to an implicit GLFW
    backend (see the module notes) and raises `OffscreenRenderError` when no OpenGL context
    can be made.
    """
    check_offscreen_size(model, width, height)
    if _EGL_INHERITED:
        raise OffscreenRenderError(
            "this process was forked from one that had already rendered through EGL, and an "
            "OpenGL context does not survive a fork; render in the parent only after starting "
            "the workers, or start them with 'spawn' or 'forkserver' (gymnasium.make_vec(..., "
            "vector_kwargs={'context': 'spawn'}), multiprocessing.get_context('spawn'))"
        )
    shadows = flag(shadows, "shadows")
    reflections = flag(reflections, "reflections")
    try:
        renderer = _new_renderer(model, int(width), int(height))
    except mujoco.FatalError as err:
        backend = os.environ.get("MUJOCO_GL") or "default (glfw)"
        raise OffscreenRenderError(
            f"cannot create an OpenGL context for offscreen rendering (MUJOCO_GL={backend}): "
            f"{err}. On a machine without a display set MUJOCO_GL=egl (or osmesa) before "
            "importing mujoco or mjkdl."
        ) from None
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = shadows
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = reflections
    return renderer


def _check_view(model: mujoco.MjModel, camera: mujoco.MjvCamera, where: str) -> None:
    """Refuse a camera `model` cannot be seen through: MuJoCo ends the process (mju_error in
    mjv_updateScene) on an unknown type, a fixed camera or tracked body outside the model, and
    on mjCAMERA_USER when nothing set the scene's camera; a free or tracking camera placed by
    a NaN or infinity renders black frames."""
    kind = camera.type
    if kind == _FIXED:
        if not 0 <= camera.fixedcamid < model.ncam:
            raise _not_in_scene(where, "fixedcamid", camera.fixedcamid, "camera", model.ncam)
        return
    if kind == _TRACKING:
        if not 0 <= camera.trackbodyid < model.nbody:
            raise _not_in_scene(where, "trackbodyid", camera.trackbodyid, "body", model.nbody)
    elif kind != _FREE:
        raise SpecError(
            f"{where}: camera.type {kind} is not mjCAMERA_FREE (0), mjCAMERA_TRACKING (1) or "
            "mjCAMERA_FIXED (2)"
        )
    lookat = camera.lookat.tolist()
    if not all(map(math.isfinite, (*lookat, camera.distance, camera.azimuth, camera.elevation))):
        raise SpecError(
            f"{where}: the camera's lookat {lookat}, distance {camera.distance}, azimuth "
            f"{camera.azimuth} and elevation {camera.elevation} must be finite"
        )


def _not_in_scene(where: str, field: str, index: int, kind: str, count: int) -> SpecError:
    ids = "none" if count == 0 else "1: 0" if count == 1 else f"{count}: 0..{count - 1}"
    return SpecError(f"{where}: camera.{field} {index} is not a {kind} of the scene (it has {ids})")


_BACKEND_LOCK = threading.Lock()


# Set in a child process forked after its parent had opened MuJoCo's EGL display: OpenGL
# does not survive a fork (Mesa's llvmpipe loses its rendering threads and the child hangs
# at its first frame; NVIDIA's EGL reports an incomplete framebuffer), so offscreen
# rendering there is refused with the fix instead.
_EGL_INHERITED = False


def _note_fork() -> None:
    global _EGL_INHERITED
    egl = sys.modules.get("mujoco.egl")
    if egl is not None and getattr(egl, "EGL_DISPLAY", None) is not None:
        _EGL_INHERITED = True


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_note_fork)


def _new_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    """`mujoco.Renderer` on EGL when MuJoCo's backend is an implicit GLFW, else MuJoCo's own.

    MuJoCo fixes its offscreen GL backend from MUJOCO_GL when `mujoco` is imported (GLFW when
    unset) and the Renderer reads it from `mujoco.rendering.classic.gl_context.GLContext`.
    GLFW needs a display and is not thread-safe next to the viewer's own GLFW thread; EGL
    needs neither. An explicit ``MUJOCO_GL=glfw`` is respected.
    """
    from mujoco.rendering.classic import gl_context

    chosen = getattr(gl_context, "GLContext", None)
    glfw_backend = getattr(chosen, "__module__", "") == "mujoco.glfw"
    asked_glfw = os.environ.get("MUJOCO_GL", "").strip().lower() == "glfw"
    if sys.platform.startswith("linux") and glfw_backend and not asked_glfw:
        with _BACKEND_LOCK:
            try:
                from mujoco.egl import GLContext as egl_context

                gl_context.GLContext = egl_context
                return mujoco.Renderer(model, height=height, width=width)
            except Exception:  # no usable EGL here: fall back to MuJoCo's choice
                pass
            finally:
                gl_context.GLContext = chosen
    return mujoco.Renderer(model, height=height, width=width)


def _output_path(path: str | os.PathLike[str]) -> tuple[Path, bool]:
    """The checked output path and whether this call created the (empty) file."""
    p = Path(path_text(path, "video path")).expanduser()
    if p.suffix.lower() != ".mp4":
        raise SpecError(f"video path must end in .mp4, got {str(path)!r}")
    folder = p.parent.resolve()
    if not folder.is_dir():
        raise VideoWriteError(
            f"cannot write video {str(p)!r}: folder {str(folder)!r} does not exist"
        )
    if not os.access(folder, os.W_OK) or (p.exists() and not os.access(p, os.W_OK)):
        raise VideoWriteError(f"cannot write video {str(p)!r}: permission denied")
    existed = p.exists()
    try:  # what the permission bits do not tell: a read-only mount, a directory; no truncation
        with open(p, "ab"):
            pass
    except OSError as err:
        raise VideoWriteError(f"cannot write video {str(p)!r}: {err.strerror}") from None
    return p, not existed


def save_image(path: str | os.PathLike[str], rgb: np.ndarray) -> Path:
    """Write an RGB image (H×W×3 uint8, as `mujoco.Renderer.render()` and camera observations
    give it) or a grey one (H×W uint8) to `path`; the suffix picks the format (.png, .jpg).

    Through OpenCV, which mjkdl depends on; `cv2.imwrite` itself expects BGR, this does not.
    """
    p = Path(path_text(path, "save_image(path)")).expanduser()
    if not isinstance(rgb, np.ndarray):
        raise SpecTypeError(f"save_image(rgb) must be a NumPy array, got {type(rgb).__name__}")
    if rgb.dtype != np.uint8 or not (rgb.ndim == 2 or (rgb.ndim == 3 and rgb.shape[2] == 3)):
        raise SpecError(
            f"save_image(rgb) must be uint8 of shape (H, W, 3) or (H, W), got {rgb.dtype} of "
            f"shape {rgb.shape} (a depth image: scale it to 0..255 and cast it to uint8 first)"
        )
    if rgb.size == 0:
        raise SpecError(f"save_image(rgb) is empty (shape {rgb.shape})")
    import cv2  # only here: importing OpenCV takes a noticeable fraction of a second

    if not cv2.haveImageWriter(str(p)):
        raise ImageWriteError(
            f"cannot write image {str(p)!r}: no image writer for suffix {p.suffix!r}; use .png "
            "(lossless) or .jpg"
        )
    folder = p.parent.resolve()
    if not folder.is_dir():
        raise ImageWriteError(
            f"cannot write image {str(p)!r}: folder {str(folder)!r} does not exist"
        )
    image = rgb if rgb.ndim == 2 else np.ascontiguousarray(rgb[:, :, ::-1])  # OpenCV's BGR
    try:
        written = cv2.imwrite(str(p), image)
    except cv2.error as err:  # a directory of that name, among others
        raise ImageWriteError(f"cannot write image {str(p)!r}: {err.msg or err}") from None
    if not written:
        raise ImageWriteError(f"cannot write image {str(p)!r}: permission denied or disk full")
    return p


class _FrameClock:
    """How many frames are due at a simulation time: one per 1/fps simulated seconds.

    The first call is always due; a jump back in time (a reset) or more than one second
    forward starts a new segment, so a call is never due more than ``ceil(fps) + 1`` frames.
    """

    def __init__(self, fps: float) -> None:
        self._fps = fps
        self._t0: float | None = None
        self._n0 = 0
        self._last = 0.0

    def due(self, t: float, written: int) -> int:
        if self._t0 is None or t < self._last or t - self._last > 1.0 + _EPS:
            self._t0, self._n0 = t, written
        self._last = t
        target = self._n0 + math.floor((t - self._t0) * self._fps + _EPS) + 1
        return max(0, target - written)


def h264_writer(
    path: Path, width: int, height: int, fps: float, x264_params: list[str]
) -> Generator[None, np.ndarray | None, None]:
    """imageio-ffmpeg's started H.264 (yuv420p) writer of RGB frames into `path`; `send`
    it H×W×3 uint8 frames, `close` it to finish the file."""
    writer = imageio_ffmpeg.write_frames(
        str(path),
        (width, height),
        fps=fps,
        codec="libx264",
        pix_fmt_in="rgb24",
        pix_fmt_out="yuv420p",
        quality=None,
        macro_block_size=1,
        ffmpeg_log_level="error",
        output_params=x264_params,
    )
    writer.send(None)  # starts ffmpeg
    return writer


class _Encoder:
    """H.264 writer (imageio-ffmpeg) fed by a daemon thread from a bounded frame queue."""

    def __init__(self, path: Path, width: int, height: int, fps: float) -> None:
        self._path = path
        self._writer = h264_writer(path, width, height, fps, _X264_PARAMS)
        self._queue: queue.Queue[np.ndarray | None] = queue.Queue(maxsize=_QUEUE_FRAMES)
        self._error: Exception | None = None
        self._thread = threading.Thread(target=self._run, name="mjkdl-video-encoder", daemon=True)
        self._thread.start()

    def put(self, frame: np.ndarray, copies: int) -> None:
        self._raise_error()
        for _ in range(copies):
            self._queue.put(frame)

    def close(self) -> None:
        """Flush the queue, finalise the MP4 and re-raise an encoder failure, if any."""
        if self._thread.is_alive():
            self._queue.put(None)
            self._thread.join()
        self._writer.close()
        self._raise_error()

    def _run(self) -> None:
        while (frame := self._queue.get()) is not None:
            if self._error is None:
                try:
                    self._writer.send(frame)
                except Exception as err:  # ffmpeg died: keep draining so put() never blocks
                    self._error = err

    def _raise_error(self) -> None:
        if self._error is not None:
            err, self._error = self._error, None
            first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
            raise VideoWriteError(
                f"video encoder failed writing {str(self._path)!r}: {first}"
            ) from err


class VideoRecorder(Closable):
    """Records what a camera sees in a `Scene` into an H.264 MP4, sampled by simulation time.

    Open with `VideoRecorder.open` or `VideoRecorder.open_preset`; call `record_frame()` after
    stepping; `close()` (or leave the `with` block, also on an exception) finalises the file.
    The default camera is MuJoCo's free camera; `use_camera(name)` picks a model camera.
    """

    def __init__(
        self,
        scene: Scene,
        path: Path,
        width: int,
        height: int,
        fps: float,
        shadows: bool,
        reflections: bool,
    ) -> None:
        self._scene = scene
        self._path = path
        self._width, self._height, self._fps = width, height, fps
        self._flags = {"shadows": shadows, "reflections": reflections}
        self._model = scene.model
        self._renderer = offscreen_renderer(self._model, width, height, **self._flags)
        self._camera_name = ""
        self._camera = self._make_camera("")
        self._option: mujoco.MjvOption | None = None
        self._overlay: Callable[[mujoco.MjvScene], None] | None = None
        self._following = False  # a follow_view camera, kept over rebuilds, checked per frame
        self._clock = _FrameClock(fps)
        self._frames = 0
        try:
            self._encoder: _Encoder | None = _Encoder(path, width, height, fps)
        except BaseException:
            self._renderer.close()
            raise
        # Finalise the file at interpreter exit if the user never closes the recorder.
        self._finalizer = weakref.finalize(self, _Encoder.close, self._encoder)

    @classmethod
    def open(
        cls,
        scene: Scene,
        path: str | os.PathLike[str],
        width: int,
        height: int,
        fps: float = 30.0,
        *,
        shadows: bool = True,
        reflections: bool = True,
    ) -> Self:
        """Start an MP4 of `width`x`height` (even numbers, within the model's offscreen buffer)
        at `fps` (from `MIN_FPS` to `MAX_FPS`) frames per simulated second. The folder must
        exist and be writable: the file is created here."""
        from .scene import Scene

        if not isinstance(scene, Scene):
            raise SpecError(f"VideoRecorder needs a Scene or Env, got {type(scene).__name__}")
        if scene.closed:
            raise RuntimeError("VideoRecorder.open: the scene is closed")
        for field, value in (("width", width), ("height", height)):
            if isinstance(value, (int, np.integer)) and value > 0 and value % 2:
                raise SpecError(f"{field} must be even for H.264 yuv420p video, got {value}")
        rate = real(fps, "fps")
        if not MIN_FPS <= rate <= MAX_FPS:
            raise SpecError(
                f"fps must be from {MIN_FPS:g} to {MAX_FPS:g} frames per simulated second, "
                f"got {fps!r}"
            )
        shadows = flag(shadows, "shadows")
        reflections = flag(reflections, "reflections")
        out, created = _output_path(path)
        try:
            return cls(scene, out, width, height, rate, shadows, reflections)
        except BaseException:
            if created:
                out.unlink(missing_ok=True)
            raise

    @classmethod
    def open_preset(
        cls,
        scene: Scene,
        path: str | os.PathLike[str],
        resolution: VideoResolution,
        fps: float = 60.0,
        *,
        shadows: bool = True,
        reflections: bool = True,
    ) -> Self:
        """`open` with the frame size of a `VideoResolution` preset."""
        if not isinstance(resolution, VideoResolution):
            raise SpecError(f"resolution must be a VideoResolution, got {resolution!r}")
        return cls.open(
            scene,
            path,
            resolution.width,
            resolution.height,
            fps,
            shadows=shadows,
            reflections=reflections,
        )

    # ------------------------------------------------------------------ properties

    @property
    def path(self) -> Path:
        """The MP4 being written."""
        return self._path

    @property
    def fps(self) -> float:
        """Frames per simulated second (and the video's playback rate)."""
        return self._fps

    @property
    def frames_written(self) -> int:
        """Frames sent to the video so far."""
        return self._frames

    @property
    def closed(self) -> bool:
        """Whether `close()` was called."""
        return self._encoder is None

    # ------------------------------------------------------------------ camera

    def use_camera(self, name: str) -> None:
        """Record through model camera `name`; "" selects MuJoCo's free camera."""
        self._check_open()
        self._camera = self._make_camera(text(name, "use_camera: name"))
        self._camera_name = name
        self._option = None
        self._overlay = None
        self._following = False

    def follow_view(
        self,
        camera: mujoco.MjvCamera,
        option: mujoco.MjvOption | None = None,
        overlay: Callable[[mujoco.MjvScene], None] | None = None,
    ) -> None:
        """Record through a live `MjvCamera` (a viewer's), with its visualisation options;
        `overlay(scene)` may append extra geoms (a trace) after each scene update.

        The view is kept over rebuilds of the scene. Its camera must be one MuJoCo can render
        in the scene (free, tracking a body, or a fixed model camera); as it is live, this is
        checked again before every frame.
        """
        self._check_open()
        if not isinstance(camera, mujoco.MjvCamera):
            raise SpecTypeError(f"follow_view: camera must be a mujoco.MjvCamera, got {camera!r}")
        if option is not None and not isinstance(option, mujoco.MjvOption):
            raise SpecTypeError(
                f"follow_view: option must be a mujoco.MjvOption or None, got {option!r}"
            )
        if overlay is not None and not callable(overlay):
            raise SpecTypeError(f"follow_view: overlay must be callable or None, got {overlay!r}")
        _check_view(self._scene.model, camera, "follow_view")
        self._camera, self._option, self._overlay = camera, option, overlay
        self._following = True

    def _make_camera(self, name: str) -> mujoco.MjvCamera:
        model = self._scene.model  # newer than self._model after a rebuild not yet recorded
        cam = mujoco.MjvCamera()
        if name == "":
            mujoco.mjv_defaultFreeCamera(model, cam)
            return cam
        cid = model_id(model, mujoco.mjtObj.mjOBJ_CAMERA, "camera", name, "the scene")
        cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
        cam.fixedcamid = cid
        return cam

    # ------------------------------------------------------------------ recording

    def record_frame(self) -> bool:
        """Capture the current state if a frame is due at this simulation time.

        Returns whether a frame was rendered. When the simulation advanced by several frame
        periods since the last capture, the frame is repeated so the video keeps real speed.
        """
        self._check_open()
        if self._scene.closed:
            raise RuntimeError("VideoRecorder.record_frame: the scene is closed")
        data = self._scene.data
        encoder = self._encoder
        assert encoder is not None  # open: _check_open passed
        t = float(data.time)
        if not math.isfinite(t):
            raise SimulationError(
                f"record_frame: the simulation time data.time is {t}; frames are taken by "
                "simulation time, which must be finite",
                t,
                {},
            )
        copies = self._clock.due(t, self._frames)
        if copies == 0:
            return False
        if self._scene.model is not self._model:
            self._rebind()
        if self._following:
            _check_view(self._model, self._camera, "record_frame")
        renderer = self._renderer
        self._scene.refresh_poses()  # a camera on a moving body: the state the step reached
        renderer.update_scene(data, camera=self._camera, scene_option=self._option)
        if self._overlay is not None:
            self._overlay(renderer.scene)
        encoder.put(renderer.render(), copies)
        self._frames += copies
        return True

    def _rebind(self) -> None:
        """Follow a scene rebuilt by add_object/remove_object: new model, new GL context."""
        if not self._following:  # a followed view is checked by record_frame
            self._camera = self._make_camera(self._camera_name)
        self._renderer.close()
        self._model = self._scene.model
        self._renderer = offscreen_renderer(self._model, self._width, self._height, **self._flags)

    # ------------------------------------------------------------------ lifecycle

    def close(self) -> None:
        """Finalise the MP4 (waits for the encoder), free the renderer and check the file.

        Raises `RecordingError` naming the path when the file cannot be read back or holds
        another number of frames than `frames_written`. Idempotent.
        """
        if self._encoder is None:
            return
        self._encoder = None
        try:
            self._finalizer()
        finally:
            self._renderer.close()
        self._verify()

    def __exit__(self, *exc: object) -> None:
        """Close; while an exception propagates a bad file is a warning, not a new error."""
        if exc[0] is None:
            self.close()
            return
        try:
            self.close()
        except RecordingError as err:
            warnings.warn(str(err), RuntimeWarning, stacklevel=2)

    def _verify(self) -> None:
        path = self._path
        if self._frames == 0:
            raise RecordingError(f"no frame was recorded: {str(path)!r} holds no video")
        try:
            frames, _ = imageio_ffmpeg.count_frames_and_secs(str(path))
        except (RuntimeError, OSError) as err:
            detail = str(err).strip().splitlines()[-1] if str(err).strip() else type(err).__name__
            raise RecordingError(f"video {str(path)!r} cannot be read back: {detail}") from None
        if frames != self._frames:
            raise RecordingError(
                f"video {str(path)!r} holds {frames} frames, {self._frames} were recorded"
            )
