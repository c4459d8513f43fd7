"""The MuJoCo passive-viewer window: open, sync, overlays, and a close that cannot hang."""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable, Sequence
from types import ModuleType
from typing import TYPE_CHECKING

import mujoco

from .display import no_display, require_display
from .overlays import Text

if TYPE_CHECKING:
    from mujoco.viewer import Handle

_OPEN_TIMEOUT = 60.0
# MuJoCo's side panels (Tab, Shift+Tab) start hidden: the scene gets the whole window.
_PANELS_HIDDEN = {"show_left_ui": False, "show_right_ui": False}
_PUSHER_JOIN = 2.0

Figure = tuple[mujoco.MjrRect, mujoco.MjvFigure]


class Window:
    """One `mujoco.viewer.launch_passive` window and the thread that renders it.

    MuJoCo's passive mode never steps physics: the window shows the state copied at `sync()`.
    Overlay texts and figures go through a helper thread, because MuJoCo's `set_texts` and
    `set_figures` wait for the window to consume the previous request (a whole frame, ~0.2 s
    under Xvfb with software OpenGL).
    """

    def __init__(self, handle: Handle, thread: threading.Thread | None) -> None:
        self._handle = handle
        self._thread = thread
        self._cv = threading.Condition()
        self._pending: tuple[list[Text], list[Figure]] | None = None
        self._stopping = False
        self._pusher = threading.Thread(target=self._push_loop, name="mjkdl-viewer-overlays")
        self._pusher.daemon = True
        self._pusher.start()

    @classmethod
    def launch(
        cls, model: mujoco.MjModel, data: mujoco.MjData, on_key: Callable[[int], None]
    ) -> Window:
        """Open a window on `model`/`data`; `on_key(keycode)` runs on the window's thread."""
        require_display()
        try:
            import mujoco.viewer as mjviewer
        except (ImportError, RuntimeError) as err:
            raise no_display(f"mujoco.viewer needs GLFW: {err}") from None
        if sys.platform == "darwin":
            try:
                handle = mjviewer.launch_passive(model, data, key_callback=on_key, **_PANELS_HIDDEN)
            except RuntimeError as err:
                raise no_display(f"{err}; on macOS run the script with `mjpython`") from None
            return cls(handle, None)
        return cls(*_launch_watched(mjviewer, model, data, on_key))

    # ------------------------------------------------------------------ state

    @property
    def handle(self) -> Handle:
        """MuJoCo's viewer handle (camera `cam`, options `opt`, `user_scn`, `viewport`)."""
        return self._handle

    def is_running(self) -> bool:
        """Whether the window is open (False once closed by the user or by `close()`)."""
        alive = self._thread is None or self._thread.is_alive()
        return alive and self._handle.is_running()

    def sync(self, full: bool, hide_user_geoms: bool = False) -> None:
        """Copy the state to the window and take back its edits (perturbation forces, resets).

        A state-only sync costs ~0.1 ms against ~3 ms or more for a `full` one, which also
        copies the model (picking up option edits made in the window's panels).
        `hide_user_geoms` shows the frame without the user scene's geoms (the trace).
        """
        scn = self._handle.user_scn
        count = scn.ngeom
        if hide_user_geoms:
            scn.ngeom = 0
        try:
            self._handle.sync(state_only=not full)
        finally:
            scn.ngeom = count

    def show(self, texts: Sequence[Text], figures: Sequence[Figure]) -> None:
        """Replace the overlay texts and figures; never blocks (the latest request wins)."""
        with self._cv:
            self._pending = (list(texts), list(figures))
            self._cv.notify()

    # ------------------------------------------------------------------ closing

    def close(self, timeout: float = 5.0) -> bool:
        """Close the window and wait up to `timeout` s for its thread; True when it ended.

        The window thread must end before the interpreter exits: GLFW torn down under a
        running render loop segfaults, or hangs on an X error under Xvfb.
        """
        deadline = time.monotonic() + timeout
        with self._cv:
            self._stopping = True
            self._cv.notify()
        # Let a pending set_texts/set_figures finish while the render loop still consumes it.
        self._pusher.join(min(_PUSHER_JOIN, timeout))
        self._handle.close()  # MuJoCo 4: requests the exit and returns at once
        if self._thread is not None:
            self._thread.join(max(0.0, deadline - time.monotonic()))
            return not self._thread.is_alive()
        return True

    def _push_loop(self) -> None:
        while True:
            with self._cv:
                while self._pending is None and not self._stopping:
                    self._cv.wait()
                if self._stopping or self._pending is None:
                    return
                texts, figures = self._pending
                self._pending = None
            if not self._handle.is_running():
                continue
            try:
                self._handle.set_texts(texts)
                self._handle.set_figures(figures)
            except mujoco.UnexpectedError:  # the window went away between check and call
                return


def _launch_watched(
    mjviewer: ModuleType,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    on_key: Callable[[int], None],
) -> tuple[Handle, threading.Thread | None]:
    """`launch_passive` from a helper thread, watched: it waits forever for a handle when the
    window thread dies before creating one."""
    handles: list[Handle] = []
    errors: list[Exception] = []
    before = set(threading.enumerate())

    def launch() -> None:
        try:
            handles.append(
                mjviewer.launch_passive(model, data, key_callback=on_key, **_PANELS_HIDDEN)
            )
        except Exception as err:
            errors.append(err)

    helper = threading.Thread(target=launch, name="mjkdl-viewer-launch", daemon=True)
    helper.start()
    window: threading.Thread | None = None
    deadline = time.monotonic() + _OPEN_TIMEOUT
    while helper.is_alive():
        helper.join(0.05)
        if window is None:
            window = _window_thread(before)
        if window is not None and not window.is_alive() and helper.is_alive():
            raise no_display("the viewer thread ended before the window opened")
        if time.monotonic() > deadline:
            raise no_display(f"no window within {_OPEN_TIMEOUT:.0f} s")
    if errors:
        (err,) = errors
        raise no_display(f"{type(err).__name__}: {err}") from err
    return handles[0], window or _window_thread(before)


def _window_thread(before: set[threading.Thread]) -> threading.Thread | None:
    """The thread `launch_passive` started to run the window (`_launch_internal`)."""
    for thread in threading.enumerate():
        if thread not in before and "_launch_internal" in thread.name:
            return thread
    return None
