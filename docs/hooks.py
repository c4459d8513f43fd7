"""MkDocs hooks: the package version in the site's name, and the pages that land from other
branches (control, task, reliability) added to the navigation as soon as their files exist.

The version is read from ``mjkdl/__init__.py`` without importing the package (which would need
MuJoCo and Pinocchio at docs build time); pyproject.toml reads the same line.
"""

from __future__ import annotations

import ast
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[1]
# (title, page under docs/) of pages written on other branches: layers go under "Layers",
# the others before "Testing"
LAYER_PAGES = [("Control", "control.md"), ("Task", "task.md")]
OTHER_PAGES = [("Reliability", "reliability.md")]
# packages with an API reference page of their own, generated when the package exists
REFERENCE_PACKAGES = ["mjkdl.control", "mjkdl.task"]


def version() -> str:
    """`mjkdl.__version__`, read from the source."""
    tree = ast.parse((ROOT / "mjkdl" / "__init__.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "__version__" for t in node.targets
        ):
            return str(ast.literal_eval(node.value))
    raise ValueError("mjkdl/__init__.py sets no __version__")


def _present_packages() -> list[str]:
    return [p for p in REFERENCE_PACKAGES if (ROOT / Path(*p.split("."))).is_dir()]


def _section(nav: list[Any], title: str) -> list[Any]:
    for entry in nav:
        if isinstance(entry, dict) and title in entry:
            return entry[title]
    raise KeyError(f"mkdocs.yml has no nav section {title!r}")


def _listed(nav: list[Any], page: str) -> bool:
    return any(isinstance(e, dict) and page in e.values() for e in nav)


def on_config(config: Any) -> Any:
    config.site_name = f"mjkdl {version()}"
    config.extra["version"] = version()
    layers = _section(config.nav, "Layers")
    for title, page in LAYER_PAGES:
        if (ROOT / "docs" / page).is_file() and not _listed(layers, page):
            layers.insert(len(layers) - 1, {title: page})  # before "Viewer and recording"
    for title, page in OTHER_PAGES:
        if (ROOT / "docs" / page).is_file() and not _listed(config.nav, page):
            at = next(i for i, e in enumerate(config.nav) if isinstance(e, dict) and "Testing" in e)
            config.nav.insert(at, {title: page})
    reference = _section(config.nav, "API reference")
    for package in _present_packages():
        reference.append({package: f"reference/{package.split('.')[-1]}.md"})
    return config


def on_files(files: Files, config: Any) -> Files:
    for package in _present_packages():
        page = f"reference/{package.split('.')[-1]}.md"
        files.append(File.generated(config, page, content=f"# {package}\n\n::: {package}\n"))
    return files
