"""Live plots of named signals against simulation time, drawn as MuJoCo figures."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ..errors import SpecError, unknown_name

Signal = Callable[[], ArrayLike]


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
    time into a rolling `window` of `points` samples; one `mjvFigure` per signal."""

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
        if not isinstance(name, str) or not name:
            raise SpecError(f"signal name must be a non-empty string, got {name!r}")
        if name in self._signals:
            raise SpecError(f"a signal named {name!r} is already plotted")
        if not callable(fn):
            raise SpecError(f"signal {name!r}: fn must be callable, got {fn!r}")
        n = len(_read(name, fn))
        names = [str(x) for x in labels] if labels is not None else [str(i) for i in range(n)]
        if len(names) != n:
            raise SpecError(f"signal {name!r} has {n} values but {len(names)} labels")
        self._signals[name] = _Trace(
            name, fn, names, np.zeros((self._points, n)), np.zeros(self._points)
        )

    def remove(self, name: str) -> None:
        """Stop plotting `name`."""
        if name not in self._signals:
            raise unknown_name("signal", name, self._signals, where="the viewer's plots")
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

    def figures(self, viewport: mujoco.MjrRect) -> list[tuple[mujoco.MjrRect, mujoco.MjvFigure]]:
        """Fresh figures for every signal, stacked up the left edge of `viewport`."""
        width = max(240, viewport.width // 4)
        height = max(150, viewport.height // 4)
        rows = max(1, viewport.height // height)
        out = []
        for k, sig in enumerate(self._signals.values()):
            rect = mujoco.MjrRect(
                viewport.left + (k // rows) * width,
                viewport.bottom + (k % rows) * height,
                width,
                height,
            )
            out.append((rect, self._figure(sig)))
        return out

    def _figure(self, sig: _Trace) -> mujoco.MjvFigure:
        fig = mujoco.MjvFigure()
        mujoco.mjv_defaultFigure(fig)
        fig.title = sig.name
        fig.xlabel = "time [s]"
        fig.xformat = "%.1f"
        fig.yformat = "%.2f"
        fig.flg_extend = 1
        fig.flg_legend = 1
        fig.figurergba[3] = 0.5
        fig.gridsize[:] = (3, 3)
        fig.range[0] = (-self._window, 0.0)
        order = (np.arange(sig.count) + sig.head - sig.count) % self._points
        now = sig.times[order[-1]] if sig.count else 0.0
        x = (sig.times[order] - now).astype(np.float32)
        for j, label in enumerate(sig.labels):
            fig.linename[j] = label.encode()[:99]
            fig.linedata[j, 0 : 2 * sig.count : 2] = x
            fig.linedata[j, 1 : 2 * sig.count : 2] = sig.values[order, j]
            fig.linepnt[j] = sig.count
        return fig


def _read(name: str, fn: Signal) -> np.ndarray:
    try:
        values = np.asarray(fn(), dtype=float)
    except (TypeError, ValueError) as err:
        raise SpecError(f"signal {name!r} must return numbers: {err}") from None
    if values.ndim > 1 or values.size > mujoco.mjMAXLINE or values.size == 0:
        raise SpecError(
            f"signal {name!r} must return 1 to {mujoco.mjMAXLINE} floats, got shape {values.shape}"
        )
    return values.reshape(-1)
