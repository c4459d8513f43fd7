"""The one exception family mjkdl raises for bad input, each also a matching builtin."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class MjkdlError(Exception):
    """Base of every error mjkdl raises on purpose."""


class SpecError(MjkdlError, ValueError):
    """A scene description field holds a value that cannot be built."""


class SpecTypeError(SpecError, TypeError):
    """A scene description field holds a value of the wrong type (never coerced)."""


class UnknownNameError(MjkdlError, KeyError):
    """A body, site, joint, actuator, camera, keyframe or object name that does not exist."""

    def __str__(self) -> str:  # KeyError would repr() the message and add quotes
        return str(self.args[0]) if self.args else ""


class ModelFileError(MjkdlError, FileNotFoundError):
    """A model, mesh or asset file that is missing or unreadable."""


class BuildError(MjkdlError, ValueError):
    """MuJoCo refused to compile or attach what the spec describes."""


class SimulationError(MjkdlError, RuntimeError):
    """The simulation diverged (NaN, Inf or huge qpos/qvel/qacc/ctrl) or overflowed its
    contact or constraint buffers; `warnings` maps MuJoCo's warning name to (count, info)."""

    def __init__(self, message: str, time: float, warnings: dict[str, tuple[int, int]]) -> None:
        super().__init__(message)
        self.time = time
        self.warnings = warnings


class PlanningError(MjkdlError, RuntimeError):
    """No motion was found: a start or goal in collision, an unreachable pose, a timeout."""


class InfeasibleError(PlanningError):
    """The query has no solution, found out before the search's timeout: a start or goal in
    collision or outside the bounds, a pose no collision-free IK solution reaches, a goal in a
    pocket of free space it cannot leave. `reason` names which; `fraction` is how much of a
    Cartesian line was achieved (None for other queries)."""

    def __init__(self, message: str, reason: str = "", fraction: float | None = None) -> None:
        super().__init__(message)
        self.reason = reason
        self.fraction = fraction


class PlanningTimeout(PlanningError):
    """The search used its whole time without finding a path; one may still exist."""


def unknown_name(kind: str, name: str, known: Iterable[str], where: str = "") -> UnknownNameError:
    """A lookup error for `name` that lists the closest known names."""
    known = [k for k in known if k]
    close = difflib.get_close_matches(name, known, n=5, cutoff=0.5)
    place = f" in {where}" if where else ""
    hint = f"; close matches: {', '.join(close)}" if close else ""
    if not close and known and len(known) <= 12:
        hint = f"; known: {', '.join(known)}"
    return UnknownNameError(f"no {kind} named {name!r}{place}{hint}")
