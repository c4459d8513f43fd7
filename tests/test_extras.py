"""The core works without any extra: importing it loads none, and what needs one says which."""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap

from conftest import ROOT

# Every extra's top-level modules (pyproject.toml's optional dependencies).
EXTRA_MODULES = [
    "torch",
    "warp",
    "mujoco_warp",
    "rsl_rl",
    "tensordict",
    "stable_baselines3",
    "sb3_contrib",
    "pylibfranka",
    "franky",
    "panda_py",
    "lerobot",
    "robomimic",
    "torchvision",
]


def run_without_extras(code: str) -> subprocess.CompletedProcess[str]:
    """Run `code` in a fresh interpreter where importing any extra's module fails, as it does
    where the extra is not installed."""
    blocker = textwrap.dedent(
        f"""
        import sys
        from importlib.abc import MetaPathFinder

        class NoExtras(MetaPathFinder):
            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] in {EXTRA_MODULES!r}:
                    raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
                return None

        sys.meta_path.insert(0, NoExtras())
        """
    )
    return subprocess.run(
        [sys.executable, "-c", blocker + textwrap.dedent(code)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_the_public_packages_import_without_any_extra() -> None:
    proc = run_without_extras(
        """
        import mjkdl, mjkdl.control, mjkdl.plan, mjkdl.task, mjkdl.demos, mjkdl.hw
        import mjkdl.hw.franka_sim, mjkdl.task.experts, mjkdl.demos.lerobot
        loaded = sorted(m for m in sys.modules if m.split(".")[0] in {extras!r})
        print("extras loaded:", loaded)
        """.replace("{extras!r}", repr(EXTRA_MODULES))
    )
    assert proc.returncode == 0, proc.stderr
    assert "extras loaded: []" in proc.stdout


def test_the_batch_without_the_batch_extra_names_it() -> None:
    proc = run_without_extras(
        """
        import mjkdl.task
        try:
            mjkdl.task.make_batch
        except ImportError as e:
            print(type(e).__name__, e)
        """
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == (
        "ImportError mjkdl.task.make_batch needs the batch extra (torch is not installed): "
        "pip install 'mjkdl[batch]'"
    )


def test_tests_need_extras_through_conftest_only() -> None:
    """A test that imports or looks for an extra's module by itself skips with words of its
    own, which the summary cannot group and CI's second pass cannot require: every test says
    it through `conftest.needs_extra` / `import_extra` instead."""
    modules = "|".join(map(re.escape, EXTRA_MODULES))
    own = re.compile(r"""(importorskip|find_spec)\(\s*["'](""" + modules + r""")["']""")
    found = [
        f"{path.name}:{text.count(chr(10), 0, hit.start()) + 1}: {hit.group(0)}"
        for path in sorted((ROOT / "tests").glob("*.py"))
        if path.name not in ("conftest.py", "test_extras.py")
        for text in [path.read_text()]
        for hit in own.finditer(text)
    ]
    assert not found, f"use conftest.needs_extra/import_extra: {found}"
