"""MuJoCo Menagerie model lookup through the `mujoco-menagerie` package.

Models come from `MENAGERIE_ROOT` when it is set (a folder holding Menagerie's model folders:
a clone of https://github.com/google-deepmind/mujoco_menagerie), else from the package's
cache, which downloads each model once. `python -m mjkdl.menagerie` lists what is found where.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from pathlib import Path

import mujoco_menagerie

from ..compile import note_missing
from ..errors import ModelFileError, UnknownNameError
from ..validate import text

_CLONE = "git clone https://github.com/google-deepmind/mujoco_menagerie"


def names() -> list[str]:
    """Every robot name Menagerie knows (no download)."""
    return mujoco_menagerie.names()


@dataclass(frozen=True)
class Source:
    """Where models come from: `MENAGERIE_ROOT` (`root` set) or the package's cache (`cache`)."""

    root: Path | None
    """The `MENAGERIE_ROOT` folder, None when the variable is unset."""
    cache: Path
    """The `mujoco-menagerie` package's download cache (used when `root` is None)."""

    def problem(self) -> str:
        """Why no model can be found here ("" when the source is usable)."""
        if self.root is None or self.root.is_dir():
            return ""
        what = "is not a folder" if self.root.exists() else "does not exist"
        return (
            f"MENAGERIE_ROOT={self.root} {what}: point it at a Menagerie clone ({_CLONE}), "
            "or unset it so the mujoco-menagerie package downloads models into its cache"
        )


def source() -> Source:
    """Where `model_path` looks, as the environment says now."""
    cache = mujoco_menagerie.Cache()
    return Source(cache.root, cache.dir)


def available() -> dict[str, str]:
    """Model name -> folder of every Menagerie model present without a download."""
    where = source()
    if where.problem():
        return {}
    cache = mujoco_menagerie.Cache()
    found = {}
    for robot in mujoco_menagerie.robots():
        if where.root is not None:
            folder = where.root / robot.name
            if folder.is_dir():
                found[robot.name] = str(folder)
        elif cache.is_cached(robot):
            found[robot.name] = str(cache.model_path(robot))
    return found


def model_path(name: str) -> str:
    """Path of the MJCF of Menagerie robot `name` (its default robot file, not the scene).

    Reads from `MENAGERIE_ROOT` when set, else from the package's cache (downloading once).
    Inside `mjkdl.compile.stand_in` a missing model gives its would-be path (the scene then
    compiles to the stand-in) instead of raising.
    """
    text(name, "menagerie.model_path(name)")
    try:
        return _model_path(name)
    except ModelFileError as err:
        if not note_missing(str(err)):
            raise
        return str(Path(source().root or "mujoco_menagerie") / name / f"{name}.xml")


def _model_path(name: str) -> str:
    try:
        robot = mujoco_menagerie.get(name)
    except mujoco_menagerie.UnknownRobotError:
        close = difflib.get_close_matches(name, names(), n=5, cutoff=0.4)
        hint = f"; close matches: {', '.join(close)}" if close else ""
        raise UnknownNameError(f"no MuJoCo Menagerie robot named {name!r}{hint}") from None
    where = source()
    if problem := where.problem():
        raise ModelFileError(f"MuJoCo Menagerie model {name!r} is not available: {problem}")
    try:
        path = robot.xml(robot.default_model)
    except mujoco_menagerie.MenagerieError as err:
        hint = (
            f"MENAGERIE_ROOT={where.root} has no folder {name!r}; point it at a Menagerie clone "
            f"({_CLONE})"
            if where.root is not None
            else "set MENAGERIE_ROOT to a Menagerie clone, or go online so "
            "mujoco-menagerie can download it"
        )
        raise ModelFileError(
            f"MuJoCo Menagerie model {name!r} is not available: {hint} ({err})"
        ) from None
    if not Path(path).is_file():
        raise ModelFileError(f"MuJoCo Menagerie model {name!r}: {path} does not exist")
    return str(path)


def report() -> tuple[str, bool]:
    """What `python -m mjkdl.menagerie` prints, and whether models can be found at all."""
    where = source()
    if problem := where.problem():
        return problem, False
    if where.root is not None:
        lines = [f"MuJoCo Menagerie models from MENAGERIE_ROOT={where.root}"]
    else:
        lines = [
            "MENAGERIE_ROOT is not set: models come from the mujoco-menagerie package's cache "
            f"at {where.cache}, downloaded on first use"
        ]
    found = available()
    width = max((len(n) for n in found), default=0)
    lines += [f"  {name:<{width}}  {folder}" for name, folder in sorted(found.items())]
    missing = len(names()) - len(found)
    lines.append(
        f"{len(found)} models here, {missing} more known to Menagerie"
        + (" (not in this folder)" if where.root is not None else " (downloaded when asked for)")
    )
    return "\n".join(lines), True
