"""Whether a window can open here, and the error that says what to do instead."""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys

from ..errors import MjkdlError

_ALTERNATIVES = (
    "run without a window (the examples' --headless) and record with mjk.VideoRecorder "
    "(MUJOCO_GL=egl), or start a virtual display: Xvfb :99 -screen 0 1280x1024x24 & "
    "export DISPLAY=:99"
)


class NoDisplayError(MjkdlError, RuntimeError):
    """No display to open the viewer window on (or, on macOS, not running under mjpython)."""


def require_display() -> None:
    """Raise `NoDisplayError` unless an X (or Wayland) display can be opened.

    MuJoCo's viewer thread ends the whole process (`mju_error`) when GLFW cannot start, so the
    display is probed here first.
    """
    if sys.platform == "darwin" or sys.platform.startswith("win"):
        return
    wayland = os.environ.get("PYGLFW_LIBRARY_VARIANT", "").lower() == "wayland"
    if wayland and os.environ.get("WAYLAND_DISPLAY"):
        return
    name = os.environ.get("DISPLAY", "")
    if not name:
        raise NoDisplayError(
            f"SimulateViewer needs a display and DISPLAY is not set: {_ALTERNATIVES}"
        )
    opens, glx = _x_display_probe(name)
    if not opens:
        raise NoDisplayError(f"SimulateViewer cannot open display {name!r}: {_ALTERNATIVES}")
    if not glx:
        raise NoDisplayError(
            f"display {name!r} has no GLX extension, so OpenGL windows cannot open on it "
            f"(an Xvfb started with -extension GLX, or a remote X server without it): "
            f"{_ALTERNATIVES}"
        )


def no_display(reason: str) -> NoDisplayError:
    """The error for a window that failed to open for `reason`, with what to do instead."""
    return NoDisplayError(f"SimulateViewer could not open a window ({reason}): {_ALTERNATIVES}")


def _x_display_probe(name: str) -> tuple[bool, bool]:
    """Whether X display `name` opens and whether its server has the GLX extension, asked
    through libX11 (both True when libX11 is not found). GLFW without GLX makes MuJoCo's
    window thread end the process instead of raising."""
    lib = ctypes.util.find_library("X11")
    if lib is None:
        return True, True
    x11 = ctypes.CDLL(lib)
    x11.XOpenDisplay.restype = ctypes.c_void_p
    x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
    int_out = ctypes.POINTER(ctypes.c_int)
    x11.XQueryExtension.argtypes = [ctypes.c_void_p, ctypes.c_char_p, int_out, int_out, int_out]
    handle = x11.XOpenDisplay(name.encode())
    if not handle:
        return False, False
    try:
        codes = [ctypes.c_int() for _ in range(3)]
        glx = bool(x11.XQueryExtension(handle, b"GLX", *(ctypes.byref(c) for c in codes)))
    finally:
        x11.XCloseDisplay(handle)
    return True, glx
