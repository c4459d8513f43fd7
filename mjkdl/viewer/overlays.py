"""The viewer's overlay switches, their keys, and the texts shown on screen."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco

# GLFW key codes (MuJoCo's mjKEY_* values). MuJoCo's viewer binds F1-F7, letters, digits and
# most punctuation; F8-F12 are free. Backspace is MuJoCo's own Reset shortcut. The on-screen
# box of `texts` lists them.
KEY_FRAMES = 297  # F8
KEY_TRACE = 298  # F9
KEY_STATS = 299  # F10
KEY_PLOTS = 300  # F11
KEY_RECORD = 301  # F12
KEY_RESET = 259  # Backspace

_FRAME_CYCLE = (
    int(mujoco.mjtFrame.mjFRAME_NONE),
    int(mujoco.mjtFrame.mjFRAME_BODY),
    int(mujoco.mjtFrame.mjFRAME_SITE),
)
_FRAME_NAMES = {
    int(mujoco.mjtFrame.mjFRAME_BODY): "body",
    int(mujoco.mjtFrame.mjFRAME_SITE): "site",
}
Text = tuple[int, int, str, str]  # (font scale, grid position, left column, right column)

_FONT = int(mujoco.mjtFontScale.mjFONTSCALE_150)
# Height of one text row at that font scale, and the box's margin, in pixels (measured on a
# screenshot of the window: 23.6 px a row); `text_height` reserves this much for the box.
_ROW_PX = 24
_BOX_PAD_PX = 8


@dataclass
class Overlays:
    """Which overlays are on. `frames` is MuJoCo's `mjtFrame` (none, body or site axes)."""

    frames: int = int(mujoco.mjtFrame.mjFRAME_NONE)
    trace: bool = True
    stats: bool = True
    plots: bool = True
    plot_page: int = 0  # which page of at most `plots.MAX_SHOWN` figures is shown

    def next_plot_page(self, pages: int) -> None:
        """F11: the next page of figures; after the last (or with one page), plots off; when
        off, plots on at the first page."""
        if not self.plots:
            self.plots, self.plot_page = True, 0
        elif self.plot_page + 1 < pages:
            self.plot_page += 1
        else:
            self.plots, self.plot_page = False, 0

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
    plots: str = "",
) -> list[Text]:
    """The overlay text for `Handle.set_texts`: one top-right box with the title, time and
    real-time factor (when `stats` is on), and every key with the state it toggles (`plots`
    says which figures are shown, e.g. "1-4 of 6")."""
    rows = [(title, "")]
    if overlays.stats:
        rtf = "-" if measured_rtf is None else f"{measured_rtf:.2f}x"
        target = "max" if target_rtf == 0 else f"{target_rtf:g}x"
        rows += [("time", f"{sim_time:.3f} s"), ("real-time", f"{rtf} (target {target})")]
    rows += [
        ("F8", f"frames: {_FRAME_NAMES.get(overlays.frames, 'off')}"),
        ("F9", f"trace: {_on(overlays.trace)}"),
        ("F10", f"time, real-time: {_on(overlays.stats)}"),
        ("F11", f"plots: {(plots or 'on') if overlays.plots else 'off'}"),
        ("F12", f"record: {recording or 'off'}"),
        ("Backspace", "reset"),
        ("Tab", "MuJoCo's panels; F1 its keys"),
    ]
    labels, values = zip(*rows, strict=True)
    return [(_FONT, int(mujoco.mjtGridPos.mjGRID_TOPRIGHT), "\n".join(labels), "\n".join(values))]


def text_height(texts: list[Text]) -> int:
    """Pixels the top-right box of `texts` takes from the top of the window."""
    rows = max((t[2].count("\n") + 1 for t in texts), default=0)
    return rows * _ROW_PX + 2 * _BOX_PAD_PX


def _on(flag: bool) -> str:
    return "on" if flag else "off"
