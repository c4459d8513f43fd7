"""MuJoCo Menagerie model lookup through the `mujoco-menagerie` package."""

from __future__ import annotations

import difflib
import os
from pathlib import Path

import mujoco_menagerie

from .errors import ModelFileError, UnknownNameError
from .validate import text


def names() -> list[str]:
    """Every robot name Menagerie knows (no download)."""
    return mujoco_menagerie.names()


def model_path(name: str) -> str:
    """Path of the MJCF of Menagerie robot `name` (its default robot file, not the scene).

    Reads from `MENAGERIE_ROOT` when set, else from the package's cache (downloading once).
    """
    text(name, "menagerie.model_path(name)")
    try:
        robot = mujoco_menagerie.get(name)
    except mujoco_menagerie.UnknownRobotError:
        close = difflib.get_close_matches(name, names(), n=5, cutoff=0.4)
        hint = f"; close matches: {', '.join(close)}" if close else ""
        raise UnknownNameError(f"no MuJoCo Menagerie robot named {name!r}{hint}") from None
    try:
        path = robot.xml(robot.default_model)
    except mujoco_menagerie.MenagerieError as err:
        root = os.environ.get("MENAGERIE_ROOT")
        where = (
            f"MENAGERIE_ROOT={root} has no folder {name!r}; point it at a Menagerie checkout"
            if root
            else "set MENAGERIE_ROOT to a Menagerie checkout, or go online so "
            "mujoco-menagerie can download it"
        )
        raise ModelFileError(
            f"MuJoCo Menagerie model {name!r} is not available: {where} ({err})"
        ) from None
    if not Path(path).is_file():
        raise ModelFileError(f"MuJoCo Menagerie model {name!r}: {path} does not exist")
    return str(path)
