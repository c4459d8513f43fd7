"""The docs run: the ```python blocks of the pages in `PAGES` (the tutorial, getting started
and the layer pages), in order, in one namespace per page, print what the pages say.

A ```text block that directly follows a ```python block is the output that block must print.
A block whose first line is `# needs the NAME extra ...` runs only where that extra is
installed; without it the other blocks still run and are checked, and the test then skips,
naming the extra.
`...` matches any text within it. Numbers are checked as numbers: a decimal number (``0.700``)
within one unit of its last printed digit, a number in e-notation (``1e-09``, an error or a
drift) as an upper bound within a factor of 10; integers and other text match exactly. The
blocks run in a fresh interpreter with
`MUJOCO_GL=egl` (MuJoCo picks its GL backend at import, and pytest has imported it already)
and the repository root as the working directory, as the tutorial asks of its readers. There is
no display here, so `mjk.SimulateViewer` is replaced by a stand-in that steps the simulation a
fixed number of times, which still runs the viewer loops of the tutorial. This file is both
the test and, run as a script, the runner.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import subprocess
import sys
import traceback
from dataclasses import dataclass
from pathlib import Path

import pytest
from conftest import extra_missing, needs_extra

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT / "docs" / "tutorial.md"
PAGES = [TUTORIAL] + [
    ROOT / "docs" / f"{name}.md" for name in ("getting-started", "scene", "robot", "viewer")
]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```\s*$", re.MULTILINE | re.DOTALL)
# A decimal or e-notation number standing alone (not part of a name such as joint_1).
CHECKED_NUMBER = re.compile(
    r"(?<![\w.])[-+]?(?:\d+\.\d+(?:[eE][-+]?\d+)?|\d+[eE][-+]?\d+)(?![\w.])"
)
ANY_NUMBER = r"([-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)"
NEEDS_EXTRA = re.compile(r"# needs the (\S+) extra")


@dataclass
class Block:
    line: int
    code: str
    expected: str | None  # the ```text block right after it, if any
    extra: str | None = None  # the optional dependency group it needs ("# needs the warp extra")


def blocks(text: str) -> list[Block]:
    """The ```python blocks of `text`, each with the ```text block that follows it."""
    found: list[Block] = []
    end_of_previous = -1
    for match in FENCE.finditer(text):
        language, body = match.group(1), match.group(2)
        line = text.count("\n", 0, match.start()) + 1
        if language == "python":
            needs = NEEDS_EXTRA.match(body)
            found.append(Block(line, body, None, needs.group(1) if needs else None))
        elif language == "text" and found and found[-1].expected is None:
            between = text[end_of_previous : match.start()]
            if end_of_previous >= 0 and not between.strip():
                found[-1].expected = body
        end_of_previous = match.end()
    return found


def mismatch(expected: str, output: str) -> str | None:
    """Why `output` is not what `expected` shows (see the module docstring), or None."""
    clean = "\n".join(line.rstrip() for line in output.strip().splitlines())
    want = "\n".join(line.rstrip() for line in expected.strip().splitlines())
    numbers: list[str] = []
    parts = []
    for part in want.split("..."):
        pieces = CHECKED_NUMBER.split(part)
        numbers += CHECKED_NUMBER.findall(part)
        parts.append(ANY_NUMBER.join(re.escape(piece) for piece in pieces))
    found = re.fullmatch(".*?".join(parts), clean, re.DOTALL)
    if found is None:
        return "the text differs"
    for shown, got in zip(numbers, found.groups(), strict=True):
        if "e" in shown.lower():
            if abs(float(got)) > 10 * abs(float(shown)):
                return f"{got} is more than 10 times the {shown} shown"
        else:
            unit = 10.0 ** -len(shown.split(".")[1])
            if abs(float(got) - float(shown)) > unit * (1 + 1e-9):
                return f"{got} differs from the {shown} shown by more than {unit:g}"
    return None


def matches(expected: str, output: str) -> bool:
    """Whether `output` is what `expected` shows."""
    return mismatch(expected, output) is None


# ---------------------------------------------------------------------- the runner


class HeadlessViewer:
    """Stands in for `mjk.SimulateViewer` without a display: runs `STEPS` steps, then closes."""

    STEPS = 500

    def __init__(self, target) -> None:
        self._target, self._left = target, self.STEPS

    @classmethod
    def open(cls, robot_or_scene, title: str = "") -> HeadlessViewer:
        return cls(robot_or_scene)

    def is_running(self) -> bool:
        return self._left > 0

    def step(self) -> bool:
        self._target.step()
        self._left -= 1
        return self._left > 0

    def use_camera(self, name: str) -> None:
        pass

    def add_signal(self, name: str, fn, labels=None) -> None:
        fn()  # as the real viewer does, so a broken signal fails here too

    def clear_trace(self) -> None:
        pass

    def add_trace_segment(self, a, b, rgba) -> None:
        pass

    def close(self) -> None:
        self._left = 0

    def __enter__(self) -> HeadlessViewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def assert_blocks_run(path: Path, at_least: int) -> dict[str, object]:
    """Run `path`'s blocks in order in one namespace; each prints what the page says it does."""
    namespace: dict[str, object] = {}
    found = blocks(path.read_text())
    assert len(found) >= at_least
    unrun = [block for block in found if block.extra and extra_missing(block.extra)]
    for block in found:
        if block in unrun:
            continue
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            exec(compile(block.code, f"{path}:{block.line}", "exec"), namespace)
        if block.expected is not None:
            assert matches(block.expected, out.getvalue()), (
                f"{path.name} line {block.line} printed:\n{out.getvalue()}"
                f"\nexpected:\n{block.expected}"
            )
    for block in unrun:  # after the others ran and matched: skip (or fail) naming the extra
        assert block.extra is not None
        needs_extra(block.extra)
    return namespace


def run_blocks(path: Path) -> list[dict]:
    """Execute the blocks of `path` in one namespace; one result per block, stop at a failure."""
    import mjkdl as mjk

    mjk.SimulateViewer = HeadlessViewer
    namespace: dict = {"__name__": "__tutorial__"}
    results = []
    for block in blocks(path.read_text()):
        out = io.StringIO()
        try:
            with contextlib.redirect_stdout(out):
                exec(compile(block.code, f"{path.name}:{block.line}", "exec"), namespace)
        except BaseException:
            results.append({"line": block.line, "status": "error", "output": out.getvalue(),
                            "traceback": traceback.format_exc()})  # fmt: skip
            break
        results.append({"line": block.line, "status": "ok", "output": out.getvalue()})
    return results


# ---------------------------------------------------------------------- the tests


def test_blocks_are_found() -> None:
    found = blocks(TUTORIAL.read_text())
    assert len(found) >= 15
    assert sum(b.expected is not None for b in found) >= 8


def test_numbers_are_checked_as_numbers() -> None:
    assert matches("TCP drift after 1 s: 1e-09 m", "TCP drift after 1 s: 8e-09 m")
    assert mismatch("TCP drift after 1 s: 1e-09 m", "TCP drift after 1 s: 2e-03 m") == (
        "2e-03 is more than 10 times the 1e-09 shown"
    )
    assert matches("z = 0.700 m", "z = 0.701 m") and not matches("z = 0.700 m", "z = 0.702 m")
    assert not matches("7 joint_1 ... joint_7", "6 joint_1 ... joint_6")  # integers: exact
    assert matches("[0.7071 0.     0.7071]", "[0.7071 0.     0.7071]")
    assert matches("lifted 0.15 m, ... left", "lifted 0.16 m, anything left")


def test_docs_show_the_version_the_package_has() -> None:
    """One source: mjkdl.__version__; pyproject.toml and the docs' header read it, and the
    changelog has a section for it."""
    import importlib.util

    import mjkdl

    tomllib = pytest.importorskip("tomllib")  # Python >= 3.11

    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "docs" / "hooks.py")
    hooks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hooks)
    assert hooks.version() == mjkdl.__version__
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" in project["project"]["dynamic"] and "version" not in project["project"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "mjkdl.__version__"}
    changelog = (ROOT / "CHANGELOG.md").read_text()
    assert re.search(rf"^## {re.escape(mjkdl.__version__)} - \d{{4}}-\d\d-\d\d$", changelog, re.M)


def run_page(page: Path) -> list[dict]:
    """Run `page`'s blocks in a fresh interpreter (see the module docstring); the results."""
    env = dict(os.environ, MUJOCO_GL="egl")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    proc = subprocess.run(
        [sys.executable, __file__, str(page)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.splitlines()[-1])


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_page_runs_and_prints_what_it_says(page: Path) -> None:
    from conftest import menagerie

    menagerie("kinova_gen3")  # skips when the Menagerie models are not on this machine
    menagerie("robotiq_2f85")
    results = run_page(page)
    by_line = {b.line: b for b in blocks(page.read_text())}
    for result in results:
        where = f"docs/{page.name}, block at line {result['line']}"
        assert result["status"] == "ok", f"{where} raised:\n{result['traceback']}"
        expected = by_line[result["line"]].expected
        if expected is not None:
            why = mismatch(expected, result["output"])
            assert why is None, (
                f"{where}: {why}; it printed:\n{result['output']}\nbut the page shows:\n{expected}"
            )
    assert len(results) == len(by_line)


if __name__ == "__main__":
    if "MENAGERIE_ROOT" not in os.environ and (ROOT.parent / "shared" / "menagerie").is_dir():
        os.environ["MENAGERIE_ROOT"] = str(ROOT.parent / "shared" / "menagerie")
    os.chdir(ROOT)
    print(json.dumps(run_blocks(Path(sys.argv[1]))))
