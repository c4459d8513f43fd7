"""Teleoperation devices: each gives a twist in [-1, 1]^6 and commands at the control rate.

Keyboard keys are on the numeric keypad, which MuJoCo's viewer leaves alone (it binds
letters, digits, punctuation, F1-F7; mjkdl's viewer F8-F12 and Backspace). The motion keys
count while held: on X11 their state is read from the X server (python-xlib), elsewhere each
press moves for one control period.
"""

from __future__ import annotations

import enum
import os
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import MjkdlError, SpecError, unknown_name


class Command(enum.Enum):
    """One-shot requests a device makes besides moving."""

    GRIPPER = "toggle the gripper"
    MODE = "switch the motion keys between translation and rotation"
    SAVE = "save the episode, start the next seed"
    DISCARD = "discard the episode, restart the same seed"
    RESET = "drop the episode, start the next seed"


class DeviceError(MjkdlError, RuntimeError):
    """A device that cannot be opened (not plugged in, missing package)."""


# GLFW key codes of the keypad (what MuJoCo's viewer passes to its key callback).
KP = {str(i): 320 + i for i in range(10)} | {".": 330, "/": 331, "*": 332, "-": 333, "+": 334}
KP_ENTER = 335
# Motion keys: keypad digit -> (world axis, sign), as seen from the `front` camera (which
# looks at the robot from +x): 8 pushes away from you (-x), 6 right (+y), 9 up (+z).
MOTION = {"8": (0, -1), "2": (0, 1), "4": (1, -1), "6": (1, 1), "9": (2, 1), "3": (2, -1)}
COMMAND_KEYS = {
    KP["0"]: Command.GRIPPER,
    KP["5"]: Command.MODE,
    KP_ENTER: Command.SAVE,
    KP["."]: Command.DISCARD,
    KP["-"]: Command.RESET,
}
KEYS_HELP = """keyboard keys (numeric keypad, Num Lock either way; directions as seen
from the front camera, which faces the robot):
  8 / 2   away / towards you  (-x / +x)
  4 / 6   left / right        (-y / +y)
  9 / 3   up / down           (+z / -z)
  5       switch translation <-> rotation (about the same directions)
  0       toggle the gripper (open <-> closed)
  Enter   save the episode and start the next seed
  .       discard the episode and restart its seed
  -       drop the episode and start the next seed
An episode that ends by itself is saved when it succeeded. Close the window to stop.
SpaceMouse: push/tilt the cap; left button toggles the gripper, right button saves."""


@dataclass
class Reading:
    """What a device says for one control period."""

    twist: np.ndarray  # [vx, vy, vz, wx, wy, wz], each in [-1, 1]
    commands: list[Command]


class _XKeys:
    """Which keypad keys are held, from the X server's key map (X11 only)."""

    def __init__(self) -> None:
        from Xlib import XK, display

        self._display = display.Display()
        self._codes = {
            d: self._display.keysym_to_keycode(XK.string_to_keysym(f"KP_{d}")) for d in MOTION
        }

    def held(self) -> list[str]:
        keymap = self._display.query_keymap()
        return [d for d, c in self._codes.items() if keymap[c // 8] & (1 << (c % 8))]

    def close(self) -> None:
        self._display.close()


class KeyboardDevice:
    """The numeric keypad in the viewer window (see `KEYS_HELP`)."""

    name = "keyboard"

    def __init__(self, held: Callable[[], list[str]] | None = None) -> None:
        self._lock = threading.Lock()
        self._pressed: list[int] = []
        self._rotate = False
        self._x: _XKeys | None = None
        if held is None and os.environ.get("DISPLAY"):
            try:
                self._x = _XKeys()
                held = self._x.held
            except Exception:  # no python-xlib or no X server: presses move for a period
                self._x = None
        self._held = held

    def on_key(self, key: int) -> None:
        """The window's key callback (its thread): queue the key."""
        with self._lock:
            self._pressed.append(key)

    def read(self) -> Reading:
        """The twist of the held (or just pressed) motion keys, and the commands pressed."""
        with self._lock:
            pressed, self._pressed = self._pressed, []
        commands = [COMMAND_KEYS[k] for k in pressed if k in COMMAND_KEYS]
        if Command.MODE in commands:
            self._rotate = not self._rotate
        digits = set(self._held()) if self._held is not None else set()
        digits |= {d for d in MOTION if KP[d] in pressed}
        twist = np.zeros(6)
        base = 3 if self._rotate else 0
        for d in digits:
            axis, sign = MOTION[d]
            twist[base + axis] += sign
        return Reading(np.clip(twist, -1.0, 1.0), commands)

    @property
    def mode(self) -> str:
        """`translation` or `rotation`: what the motion keys do now."""
        return "rotation" if self._rotate else "translation"

    def close(self) -> None:
        """Let go of the X connection."""
        if self._x is not None:
            self._x.close()
            self._x = None


def spacemouse_twist(state: Any, deadzone: float) -> np.ndarray:
    """A pyspacemouse state in its `HID_Z_UP` convention (x right, y away from you, z up;
    roll, pitch, yaw about them; each in [-1, 1]) as a world twist in [-1, 1]^6 for a user
    who faces the robot as the `front` camera does: away is -x, right is +y. Axes inside
    `deadzone` read 0; the rest is rescaled to start from 0 at its edge."""
    raw = np.array([state.x, state.y, state.z, state.roll, state.pitch, state.yaw], dtype=float)
    mag = np.abs(raw)
    dev = np.where(mag <= deadzone, 0.0, np.sign(raw) * (mag - deadzone) / (1.0 - deadzone))
    x, y, z, rx, ry, rz = np.clip(dev, -1.0, 1.0)
    return np.array([-y, x, z, -ry, rx, rz])


class SpaceMouseDevice:
    """A 3Dconnexion SpaceMouse through pyspacemouse (`pip install 'mjkdl[teleop]'`): the cap
    gives the twist, the left button toggles the gripper, the right one saves."""

    name = "spacemouse"

    def __init__(self, deadzone: float = 0.1, device: Any = None) -> None:
        if not 0.0 <= deadzone < 1.0:
            raise SpecError(f"--deadzone must be in [0, 1), got {deadzone!r}")
        self._deadzone = deadzone
        self._buttons: Sequence[int] = ()
        if device is None:
            try:
                import pyspacemouse
            except ImportError:
                raise DeviceError(
                    "--device spacemouse needs pyspacemouse: pip install 'mjkdl[teleop]'"
                ) from None
            try:
                device = pyspacemouse.open(axis_convention=pyspacemouse.AxisConvention.HID_Z_UP)
            except Exception as err:  # no device, no permission on /dev/hidraw*
                raise DeviceError(f"no SpaceMouse could be opened: {err}") from None
        self._device = device
        self.keyboard = KeyboardDevice(held=list)  # the window's keys still save and discard

    def on_key(self, key: int) -> None:
        """The window's key callback: the keypad's commands work beside the SpaceMouse."""
        self.keyboard.on_key(key)

    def read(self) -> Reading:
        """The cap's twist and the buttons pressed since the last read (rising edges)."""
        state = self._device.read()
        buttons = list(state.buttons)
        old = list(self._buttons) or [0] * len(buttons)
        rising = [i for i, (b, o) in enumerate(zip(buttons, old, strict=False)) if b and not o]
        self._buttons = buttons
        commands = self.keyboard.read().commands
        commands += [c for i, c in ((0, Command.GRIPPER), (1, Command.SAVE)) if i in rising]
        return Reading(spacemouse_twist(state, self._deadzone), commands)

    def close(self) -> None:
        """Close the HID device."""
        close = getattr(self._device, "close", None)
        if callable(close):
            close()


DEVICES = ("keyboard", "spacemouse")


def open_device(name: str, deadzone: float = 0.1) -> KeyboardDevice | SpaceMouseDevice:
    """The device called `name` (`keyboard` or `spacemouse`)."""
    if name == "keyboard":
        return KeyboardDevice()
    if name == "spacemouse":
        return SpaceMouseDevice(deadzone)
    raise unknown_name("device", name, DEVICES, "--device")
