"""Teleoperation devices: the keypad's twist and commands, and a SpaceMouse fed recorded HID
reports through pyspacemouse's own decoder (no device here)."""

from __future__ import annotations

import struct

import pytest

from mjkdl.demos.devices import (
    KEYS_HELP,
    KP,
    KP_ENTER,
    Command,
    KeyboardDevice,
    SpaceMouseDevice,
    open_device,
    spacemouse_twist,
)


def test_held_keypad_keys_give_a_world_twist() -> None:
    held: list[str] = []
    kb = KeyboardDevice(held=lambda: held)
    held[:] = ["9", "6"]  # up and right
    r = kb.read()
    assert r.twist.tolist() == [0, 1, 1, 0, 0, 0] and r.commands == []
    held[:] = ["8", "2"]  # away and towards cancel
    assert kb.read().twist.tolist() == [0] * 6
    kb.on_key(KP["5"])  # rotation
    held[:] = ["4"]
    r = kb.read()
    assert r.commands == [Command.MODE] and r.twist.tolist() == [0, 0, 0, 0, -1, 0]
    assert kb.mode == "rotation"
    held[:] = []
    kb.on_key(KP["3"])  # a press without the held state moves for one period
    assert kb.read().twist.tolist() == [0, 0, 0, 0, 0, -1]
    assert kb.read().twist.tolist() == [0] * 6


def test_keypad_commands_and_the_help_text() -> None:
    kb = KeyboardDevice(held=list)
    for key in (KP["0"], KP_ENTER, KP["."], KP["-"], 65):  # 65 ('A') is MuJoCo's: ignored
        kb.on_key(key)
    assert kb.read().commands == [Command.GRIPPER, Command.SAVE, Command.DISCARD, Command.RESET]
    for line in ("8 / 2   away / towards you", "0       toggle the gripper", "Enter   save"):
        assert line in KEYS_HELP


class RecordedHID:
    """A HID device that plays back raw reports, as `hidapi` returns them."""

    def __init__(self, reports: list[bytes]) -> None:
        self.reports = list(reports)
        self.closed = False

    def read(self, size: int) -> bytes:
        return self.reports.pop(0) if self.reports else b""

    def close(self) -> None:
        self.closed = True


def report(channel: int, a: int, b: int, c: int) -> bytes:
    """A SpaceNavigator report: channel 1 translation, 2 rotation; int16 little-endian."""
    return bytes([channel]) + struct.pack("<hhh", a, b, c)


def spacenavigator(reports: list[bytes]) -> SpaceMouseDevice:
    pyspacemouse = pytest.importorskip("pyspacemouse")  # the [teleop] extra
    info = pyspacemouse.apply_axis_convention(
        pyspacemouse.get_device_specs()["SpaceNavigator"], pyspacemouse.AxisConvention.HID_Z_UP
    )
    return SpaceMouseDevice(0.1, device=pyspacemouse.SpaceMouseDevice(info, RecordedHID(reports)))


def test_spacemouse_reports_map_to_the_world_twist() -> None:
    # HID axes (USB HID usage tables): +x right, +y towards the user, +z down, rotations about
    # them; full scale 350 counts. The user faces the robot as the front camera does.
    cases = [
        (report(1, 0, -350, -175), [-1.0, 0.0, (0.5 - 0.1) / 0.9, 0.0, 0.0, 0.0]),  # away, up
        (report(1, 350, 0, 0), [0.0, 1.0, 0.0, 0.0, 0.0, 0.0]),  # right is +y
        (report(2, 350, 0, 0), [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]),  # tilt about "right": +y
        (report(2, 0, 350, 0), [0.0, 0.0, 0.0, 1.0, 0.0, 0.0]),  # about "towards you": +x
        (report(2, 0, 0, 350), [0.0, 0.0, 0.0, 0.0, 0.0, -1.0]),  # clockwise from above
        (report(1, 30, -20, 10), [0.0] * 6),  # inside the 10 % dead zone
    ]
    for raw, expected in cases:
        assert spacenavigator([raw]).read().twist == pytest.approx(expected), raw


def test_spacemouse_buttons_and_keys() -> None:
    left, right, none = bytes([3, 1]), bytes([3, 2]), bytes([3, 0])
    dev = spacenavigator([left, left, none, right])
    assert dev.read().commands == [Command.GRIPPER]
    assert dev.read().commands == []  # still held: one toggle per press
    assert dev.read().commands == []
    dev.on_key(KP["."])  # the window's keypad works beside the SpaceMouse
    assert dev.read().commands == [Command.DISCARD, Command.SAVE]
    dev.close()


def test_dead_zone_and_device_errors() -> None:
    class State:
        x, y, z, roll, pitch, yaw = 0.55, -1.0, 0.0, 0.2, 0.0, 0.0

    assert spacemouse_twist(State(), 0.5) == pytest.approx([1.0, 0.1, 0.0, 0.0, 0.0, 0.0])
    assert spacemouse_twist(State(), 0.0) == pytest.approx([1.0, 0.55, 0.0, 0.0, 0.2, 0.0])
    with pytest.raises(ValueError, match=r"--deadzone must be in \[0, 1\), got 1.0"):
        SpaceMouseDevice(1.0, device=object())
    with pytest.raises(
        KeyError, match="no device named 'joystick' in --device; known: keyboard, spacemouse"
    ):
        open_device("joystick")
    with pytest.raises(RuntimeError, match="no SpaceMouse could be opened"):
        open_device("spacemouse")  # none is plugged in here
    assert spacemouse_twist(State(), 0.99).tolist() == [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]  # full tilt
