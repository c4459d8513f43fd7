"""Live plots of named signals against simulation time, drawn as MuJoCo figures."""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ..errors import SpecError, unknown_name

Signal = Callable[[], ArrayLike]

MAX_SHOWN = 4  # figures on screen at once; F11 pages through the rest
COLUMN_SHARE = 0.3  # of the window's width taken by the figure column (within 260-480 px)
MIN_HEIGHT = 100  # px: shorter figures have no room for a plot between title and tick labels
_CHROME_PX = 60  # px of a figure taken by its title, tick labels and margins
_LEGEND_ROW_PX = 17
_FORMAT_CHARS = 19  # MuJoCo's mjvFigure text fields (yformat, minwidth) hold this many
_TITLE_CHARS = 999  # and its title this many
_MARGIN = 4  # px between the overlay text and the first figure


@dataclass
class _Trace:
    name: str
    fn: Signal
    labels: list[str]
    values: np.ndarray  # (points, n) ring buffer
    times: np.ndarray  # (points,)
    head: int = 0
    count: int = 0


class SignalPlots:
    """Named signals, each a callable returning a float array, sampled against simulation
    time into a rolling `window` of `points` samples; one `mjvFigure` per signal, its y-axis
    fitted to the data on screen and labelled with the unit in the name's brackets."""

    def __init__(self, window: float = 5.0, points: int = 250) -> None:
        self._window = float(window)
        self._points = int(points)
        self._period = self._window / self._points
        self._signals: dict[str, _Trace] = {}
        self._next = -np.inf
        self._last = -np.inf

    @property
    def names(self) -> list[str]:
        """Signal names, in the order they were added."""
        return list(self._signals)

    def add(self, name: str, fn: Signal, labels: Sequence[str] | None = None) -> None:
        """Plot `fn()` (up to 100 floats, one line each) as `name`; `labels` name the lines.

        `fn` is called once here, so a bad signal fails now rather than mid-run.
        """
        if not isinstance(name, str) or not name or len(name) > _TITLE_CHARS:
            raise SpecError(
                f"signal name must be a string of 1 to {_TITLE_CHARS} characters, got {name!r}"
            )
        if name in self._signals:
            raise SpecError(f"a signal named {name!r} is already plotted")
        if not callable(fn):
            raise SpecError(f"signal {name!r}: fn must be callable, got {fn!r}")
        n = len(_read(name, fn))
        if labels is not None and (
            isinstance(labels, str) or not all(isinstance(x, str) for x in labels)
        ):
            raise SpecError(f"signal {name!r}: labels must be a list of strings, got {labels!r}")
        names = list(labels) if labels is not None else [str(i) for i in range(n)]
        if len(names) != n:
            raise SpecError(f"signal {name!r} has {n} values but {len(names)} labels")
        self._signals[name] = _Trace(
            name, fn, names, np.zeros((self._points, n)), np.zeros(self._points)
        )

    def remove(self, name: str) -> None:
        """Stop plotting `name`."""
        if not isinstance(name, str) or name not in self._signals:
            raise unknown_name("signal", str(name), self._signals, where="the viewer's plots")
        del self._signals[name]

    def sample(self, t: float) -> None:
        """Record every signal when `t` reached the next sample time (restart after a reset)."""
        if t < self._last:
            for sig in self._signals.values():
                sig.head = sig.count = 0
            self._next = -np.inf
        self._last = t
        if t < self._next:
            return
        self._next = t + self._period
        for sig in self._signals.values():
            values = _read(sig.name, sig.fn)
            if len(values) != sig.values.shape[1]:
                raise SpecError(
                    f"signal {sig.name!r} changed size from {sig.values.shape[1]} to {len(values)}"
                )
            sig.values[sig.head] = values
            sig.times[sig.head] = t
            sig.head = (sig.head + 1) % self._points
            sig.count = min(sig.count + 1, self._points)

    def figures(
        self, rects: Sequence[mujoco.MjrRect], page: int
    ) -> list[tuple[mujoco.MjrRect, mujoco.MjvFigure]]:
        """Fresh figures for page `page` of the signals, `len(rects)` to a page, one per rect."""
        per_page = max(1, len(rects))
        shown = list(self._signals.values())[page * per_page : (page + 1) * per_page]
        return [
            (rect, self._figure(sig, rect.height)) for rect, sig in zip(rects, shown, strict=False)
        ]

    def _figure(self, sig: _Trace, height: int) -> mujoco.MjvFigure:
        fig = mujoco.MjvFigure()
        mujoco.mjv_defaultFigure(fig)
        fig.title = sig.name
        fig.xformat = "%.1f s"  # time relative to now; the unit here saves an x-label row
        fig.flg_legend = int(len(sig.labels) * _LEGEND_ROW_PX <= height - _CHROME_PX)
        fig.figurergba[3] = 0.5
        fig.gridsize[:] = (3, 3)
        fig.range[0] = (-self._window, 0.0)
        order = (np.arange(sig.count) + sig.head - sig.count) % self._points
        now = sig.times[order[-1]] if sig.count else 0.0
        x = (sig.times[order] - now).astype(np.float32)
        values = sig.values[order]
        lo, hi = _y_range(values)
        fig.flg_extend = 0
        fig.range[1] = (lo, hi)
        fig.yformat = _y_format(hi - lo, _unit(sig.name))
        widest = fig.yformat % max(abs(lo), abs(hi))
        fig.minwidth = widest.replace(" ", "X")[:_FORMAT_CHARS]
        for j, label in enumerate(sig.labels):
            fig.linename[j] = label.encode()[:99]
            fig.linedata[j, 0 : 2 * sig.count : 2] = x
            fig.linedata[j, 1 : 2 * sig.count : 2] = values[:, j]
            fig.linepnt[j] = sig.count
        return fig


def column(viewport: mujoco.MjrRect, top: int, count: int) -> list[mujoco.MjrRect]:
    """Rectangles for up to `count` figures (at most `MAX_SHOWN`) stacked down the right edge
    of `viewport`, below its top `top` pixels (the overlay text); fewer when they would be
    shorter than `MIN_HEIGHT`. Each is 30 % of the window wide (within 260-480 px)."""
    width = min(max(round(viewport.width * COLUMN_SHARE), 260), 480, viewport.width // 2)
    free = viewport.height - top - _MARGIN
    fits = max(1, free // MIN_HEIGHT)
    count = min(count, MAX_SHOWN, fits)
    if count <= 0 or free <= 0:
        return []
    height = min(free // count, max(MIN_HEIGHT, viewport.height // 3))
    left = viewport.left + viewport.width - width
    ceiling = viewport.bottom + viewport.height - top
    return [mujoco.MjrRect(left, ceiling - (k + 1) * height, width, height) for k in range(count)]


def _unit(name: str) -> str:
    """The unit written in brackets at the end of a signal name: "torques [Nm]" -> "Nm"."""
    found = re.search(r"\[([^\[\]]+)\]\s*$", name)
    return found.group(1) if found else ""


def _y_range(values: np.ndarray) -> tuple[float, float]:
    """The y-axis range that fits `values` (points, lines) with a 10 % margin; [-1, 1]
    before any data. At least 1e-4 (or 0.1 % of the largest value) wide, so that a signal
    steady to rounding error is drawn flat rather than as magnified noise."""
    if values.size == 0:
        return -1.0, 1.0
    lo, hi = float(values.min()), float(values.max())
    floor = max(1e-4, 1e-3 * max(abs(lo), abs(hi)))
    pad = max(0.1 * (hi - lo), 0.5 * (floor - (hi - lo)))
    return lo - pad, hi + pad


def _y_format(span: float, unit: str) -> str:
    """A tick-label format with as many decimals as the axis span needs, then the unit (cut
    to fit MuJoCo's 19-character format field; the title keeps it whole)."""
    decimals = min(6, max(0, 1 - math.floor(math.log10(span)))) if span > 0 else 2
    number = f"%.{decimals}f"
    if not unit:
        return number
    room = _FORMAT_CHARS - len(number) - 1
    return f"{number} {unit.replace('%', '%%')[:room].rstrip('%')}"


def _read(name: str, fn: Signal) -> np.ndarray:
    out = fn()
    try:
        values = np.asarray(out)
    except ValueError:  # ragged nesting
        values = np.asarray(None)
    if values.dtype.kind not in "biuf":  # bools plot as 0/1; no text, None or complex
        raise SpecError(f"signal {name!r} must return numbers, got {out!r}")
    if values.ndim > 1 or values.size > mujoco.mjMAXLINE or values.size == 0:
        raise SpecError(
            f"signal {name!r} must return 1 to {mujoco.mjMAXLINE} floats, got shape {values.shape}"
        )
    return values.reshape(-1).astype(float)
