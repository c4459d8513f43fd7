"""The viewer's overlay switches, their keys, and the texts shown on screen."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco

# GLFW key codes (MuJoCo's mjKEY_* values). MuJoCo's viewer binds F1-F7, letters, digits and
# most punctuation; F8-F12 are free. Backspace is MuJoCo's own Reset shortcut.
KEY_FRAMES = 297  # F8
KEY_TRACE = 298  # F9
KEY_STATS = 299  # F10
KEY_PLOTS = 300  # F11
KEY_RECORD = 301  # F12
KEY_RESET = 259  # Backspace

HELP_KEYS = "F8\nF9\nF10\nF11\nF12\nBackspace"
HELP_ACTIONS = "frames\ntrace\nreal-time factor\nplots\nrecord video\nreset"

_FRAME_CYCLE = (
    int(mujoco.mjtFrame.mjFRAME_NONE),
    int(mujoco.mjtFrame.mjFRAME_BODY),
    int(mujoco.mjtFrame.mjFRAME_SITE),
)
_FRAME_NAMES = {
    int(mujoco.mjtFrame.mjFRAME_BODY): "body",
    int(mujoco.mjtFrame.mjFRAME_SITE): "site",
}
_FONT = int(mujoco.mjtFontScale.mjFONTSCALE_150)


@dataclass
class Overlays:
    """Which overlays are on. `frames` is MuJoCo's `mjtFrame` (none, body or site axes)."""

    frames: int = int(mujoco.mjtFrame.mjFRAME_NONE)
    trace: bool = True
    stats: bool = True
    plots: bool = True

    def cycle_frames(self) -> int:
        """Next frame mode: none -> body -> site -> none."""
        i = _FRAME_CYCLE.index(self.frames) if self.frames in _FRAME_CYCLE else 0
        self.frames = _FRAME_CYCLE[(i + 1) % len(_FRAME_CYCLE)]
        return self.frames


def texts(
    overlays: Overlays,
    title: str,
    sim_time: float,
    measured_rtf: float | None,
    target_rtf: float,
    recording: str | None,
) -> list[tuple[int, int, str, str]]:
    """Overlay texts for `Handle.set_texts`: the help line, and status when `stats` is on."""
    out = [(_FONT, int(mujoco.mjtGridPos.mjGRID_BOTTOMRIGHT), HELP_KEYS, HELP_ACTIONS)]
    labels, values = [title], [""]
    if overlays.stats:
        rtf = "-" if measured_rtf is None else f"{measured_rtf:.2f}x"
        target = "max" if target_rtf == 0 else f"{target_rtf:g}x"
        labels += ["time", "real-time"]
        values += [f"{sim_time:.3f} s", f"{rtf} (target {target})"]
    if overlays.frames in _FRAME_NAMES:
        labels.append("frames")
        values.append(_FRAME_NAMES[overlays.frames])
    if not overlays.trace:
        labels.append("trace")
        values.append("hidden")
    if recording is not None:
        labels.append("REC")
        values.append(recording)
    out.append(
        (_FONT, int(mujoco.mjtGridPos.mjGRID_TOPRIGHT), "\n".join(labels), "\n".join(values))
    )
    return out
