"""MkDocs hook: the package version in the site's name.

The version is read from ``mjkdl/__init__.py`` without importing the package (which would need
MuJoCo and Pinocchio at docs build time); pyproject.toml reads the same line.
"""

from __future__ import annotations

import ast
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]


def version() -> str:
    """`mjkdl.__version__`, read from the source."""
    tree = ast.parse((ROOT / "mjkdl" / "__init__.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "__version__" for t in node.targets
        ):
            return str(ast.literal_eval(node.value))
    raise ValueError("mjkdl/__init__.py sets no __version__")


def on_config(config: Any) -> Any:
    config.site_name = f"mjkdl {version()}"
    config.extra["version"] = version()
    return config
