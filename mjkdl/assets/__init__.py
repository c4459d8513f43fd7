"""Model files shipped inside the package, so scripts find them from any working directory.

`mjk.assets.path("table")` is the absolute path of `mjkdl/assets/table.xml`: a 1.2 m x 1.0 m
table, 0.70 m tall, with its origin and its `table_top` site at the centre of the top surface.
"""

from __future__ import annotations

from pathlib import Path

from mjkdl.errors import UnknownNameError

_FOLDER = Path(__file__).resolve().parent


def names() -> list[str]:
    """Every asset name `path` accepts, sorted."""
    return sorted(p.stem for p in _FOLDER.glob("*.xml"))


def path(name: str) -> str:
    """Absolute path of the MJCF file of asset `name` (e.g. "table")."""
    file = _FOLDER / f"{name}.xml"
    if not isinstance(name, str) or not name or file.parent != _FOLDER or not file.is_file():
        raise UnknownNameError(f"no mjkdl asset named {name!r}; available: {', '.join(names())}")
    return str(file)
