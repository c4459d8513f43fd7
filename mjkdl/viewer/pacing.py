"""Real-time pacing: simulation time follows wall time at a chosen factor, and is measured."""

from __future__ import annotations

import math
import time

from ..errors import SpecError
from ..validate import is_real

# Behind schedule by more than this (wall seconds): give up catching up and re-anchor, as
# MuJoCo's own viewer does, instead of running flat out to recover lost time.
_MAX_LAG = 0.1
_MEASURE_EVERY = 0.5


class Pacer:
    """Sleeps so that simulation time advances `factor` times as fast as wall time (0: no
    pacing) and measures the factor achieved over half-second windows."""

    def __init__(self, factor: float = 1.0) -> None:
        self._factor = _check(factor)
        self._anchor: tuple[float, float] | None = None  # (wall, sim)
        self._window: tuple[float, float] | None = None
        self._measured: float | None = None

    @property
    def factor(self) -> float:
        """Requested real-time factor: 1.0 real time, 0.5 half speed, 0.0 as fast as possible."""
        return self._factor

    @factor.setter
    def factor(self, value: float) -> None:
        self._factor = _check(value)
        self._anchor = None

    @property
    def measured(self) -> float | None:
        """Real-time factor achieved over the last half second (None until measured)."""
        return self._measured

    def pace(self, t: float) -> None:
        """Called after each step at simulation time `t`: sleep while ahead of schedule."""
        now = time.perf_counter()
        self._measure(now, t)
        if self._factor == 0.0:
            return
        if self._anchor is None or t < self._anchor[1]:
            self._anchor = (now, t)
            return
        wall0, sim0 = self._anchor
        ahead = wall0 + (t - sim0) / self._factor - now
        if ahead > 0:
            time.sleep(ahead)
        elif ahead < -_MAX_LAG:
            self._anchor = (now, t)

    def _measure(self, now: float, t: float) -> None:
        if self._window is None or t < self._window[1]:
            self._window = (now, t)
            return
        wall0, sim0 = self._window
        if now - wall0 >= _MEASURE_EVERY:
            self._measured = (t - sim0) / (now - wall0)
            self._window = (now, t)


def _check(factor: object) -> float:
    value = float(factor) if is_real(factor) else math.nan  # type: ignore[arg-type]
    if not (math.isfinite(value) and value >= 0):
        raise SpecError(f"realtime_factor must be a finite number >= 0, got {factor!r}")
    return value
