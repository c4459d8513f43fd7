"""Checks the task layer shares: counts, seeds, positive numbers, lists of names."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np

from ..errors import SpecError, SpecTypeError
from ..validate import real, text


def is_int(value: object) -> bool:
    """An `int` or NumPy integer, not a bool."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def integer(value: object, field: str, least: Literal[0, 1] = 1) -> int:
    """`value` as an int of at least `least` (1: counts and sizes, 0: seeds); a NumPy integer
    is fine, bools, floats and text are not."""
    what = "a positive integer" if least == 1 else "a non-negative integer"
    if not is_int(value):
        raise SpecTypeError(f"{field} must be {what}, got {value!r}")
    if value < least:  # type: ignore[operator]
        raise SpecError(f"{field} must be {what}, got {value!r}")
    return int(value)  # type: ignore[call-overload]


def positive(value: object, field: str) -> float:
    """`value` as a positive finite float."""
    out = real(value, field)
    if out <= 0:
        raise SpecError(f"{field} must be positive, got {value!r}")
    return out


def names(value: object, field: str, kind: str = "body") -> list[str]:
    """`value` as a list of names: a list or tuple of strings (one string is refused)."""
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise SpecTypeError(f"{field} must be a list of {kind} names, got {value!r}")
    return [text(v, f"{field}[{i}]") for i, v in enumerate(value)]
