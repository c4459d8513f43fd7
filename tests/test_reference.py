"""The API reference (docs/reference, built by mkdocstrings) has an entry for every public name
of the public packages, and the simulated Franka's command line as it is."""

from __future__ import annotations

import importlib
import os
import re
import subprocess
import sys

import pytest
from conftest import ROOT

PACKAGES = ["mjkdl", "mjkdl.control", "mjkdl.hw", "mjkdl.plan", "mjkdl.task", "mjkdl.demos"]
ANCHOR = re.compile(r'id="(mjkdl[\w.]*)"')


@pytest.fixture(scope="module")
def anchors(tmp_path_factory: pytest.TempPathFactory) -> set[str]:
    """The ids of every object the built reference shows (mkdocstrings: its dotted path)."""
    site = tmp_path_factory.mktemp("site")
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--quiet", "--site-dir", str(site)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env=dict(os.environ, NO_MKDOCS_2_WARNING="1"),
    )
    assert proc.returncode == 0, proc.stderr
    return {
        a for page in (site / "reference").rglob("*.html") for a in ANCHOR.findall(page.read_text())
    }


def public_names(package: str) -> list[str]:
    """`__all__`, and the names the package loads on first use (listed by its `__dir__`)."""
    module = importlib.import_module(package)
    lazy = set(dir(module)) - set(vars(module))
    return sorted(set(module.__all__) | lazy)


def entries_for(package: str, name: str) -> set[str]:
    """The dotted paths under which the reference may show `package.name`: where it is
    exported and where it is defined."""
    paths = {f"{package}.{name}"}
    try:
        obj = getattr(importlib.import_module(package), name)
    except ImportError:  # a lazy name whose extra is missing: any path under the package
        return paths
    qualname = getattr(obj, "__qualname__", None)
    if isinstance(getattr(obj, "__module__", None), str) and qualname:
        paths.add(f"{obj.__module__}.{qualname}")
    for module_name, module in list(sys.modules.items()):
        if module_name.startswith("mjkdl") and getattr(module, name, None) is obj:
            paths.add(f"{module_name}.{name}")
    return paths


@pytest.mark.parametrize("package", PACKAGES)
def test_every_public_name_has_a_reference_entry(package: str, anchors: set[str]) -> None:
    missing = []
    for name in public_names(package):
        paths = entries_for(package, name)
        lazy_prefix = f"{package}."
        found = paths & anchors or (
            len(paths) == 1
            and any(a.startswith(lazy_prefix) and a.endswith(f".{name}") for a in anchors)
        )
        if not found:
            missing.append(name)
    assert not missing, f"{package}: no entry in docs/reference for {missing}"


def test_the_reference_shows_the_simulators_command_line() -> None:
    page = (ROOT / "docs" / "reference" / "hw.md").read_text()
    shown = re.search(r"```text\n(usage: python -m mjkdl\.hw\.franka_sim.*?)```", page, re.DOTALL)
    assert shown, "docs/reference/hw.md has no --help block"
    proc = subprocess.run(
        [sys.executable, "-m", "mjkdl.hw.franka_sim", "--help"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
        env=dict(os.environ, COLUMNS="100"),
    )
    assert proc.stdout.strip() == shown.group(1).strip()


def test_the_check_sees_a_name_without_an_entry(anchors: set[str]) -> None:
    """The check above would catch a name left out: one removed from the anchors is missed."""
    paths = entries_for("mjkdl.hw", "FrankaArm")
    assert paths & anchors
    assert not paths & (anchors - paths)
