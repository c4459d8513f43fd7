"""Mutation testing, one module at a time, each against the tests that mirror it.

Every module gets its own copy of the checkout under `build/mutation/<module>/` with a
`[tool.mutmut]` that mutates that module only and runs only its own test files, so a
surviving mutant costs seconds instead of a whole-suite run. mutmut remembers results in each
copy, so a second run only retries what is new or changed.

    python scripts/mutation.py                    # all six modules, then the score table
    python scripts/mutation.py ik record -j 2     # some modules, two mutmut workers each
    python scripts/mutation.py --report           # the table from the last runs only

A module's score is killed / (all - equivalent); `docs/mutation.md` lists the equivalent
survivors with a reason each.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# module -> the test files that exercise it directly
MODULES: dict[str, list[str]] = {
    "chain": [
        "tests/test_chain.py",
        "tests/test_robot_parity.py",
        "tests/test_robot.py",
        "tests/test_urdf.py",
    ],
    "robot": ["tests/test_robot.py", "tests/test_robot_build.py", "tests/test_robot_parity.py"],
    "ik": ["tests/test_ik.py"],
    "scene": ["tests/test_scene.py", "tests/test_env.py", "tests/test_names.py"],
    "record": ["tests/test_record.py"],
    "compile": ["tests/test_compile.py", "tests/test_urdf.py", "tests/test_assets.py"],
}
# Tests mutmut cannot run: they start a fresh interpreter (the mutated package's trampolines
# find no mutmut configuration there), list methods by introspection (which sees the
# trampolines' copies) or check a warning's place in the stack (one frame deeper under a
# trampoline). Their kills are checked by hand, see docs/mutation.md.
UNRUNNABLE = [
    "tests/test_record.py::test_the_warning_points_at_the_users_with_block",
    "tests/test_compile.py::test_a_mujoco_notice_points_at_the_caller_of_the_compiling_function",
    "tests/test_scene.py::test_closed_scene_raises_everywhere",
    "tests/test_compile.py::test_fifo_asset_is_refused_without_hanging",
    "tests/test_record.py::test_renders_headless_without_mujoco_gl",
    "tests/test_scene.py::test_mujoco_log_goes_to_the_documented_place_not_the_working_directory",
]
KILLED = {"killed", "timeout", "segfault", "caught by type check"}


def _config(module: str) -> str:
    tests = [t for t in MODULES[module] if (ROOT / t).is_file()]
    selection = tests + [f"--deselect={t}" for t in UNRUNNABLE]
    lines = ",\n".join(f'    "{s}"' for s in selection)
    return (
        "[tool.mutmut]\n"
        'source_paths = ["mjkdl/"]\n'
        f'only_mutate = ["mjkdl/{module}.py"]\n'
        'also_copy = ["README.md", "docs/", "examples/", "benchmarks/"]\n'
        # Wall-clock limit per mutant: (estimated test time + 60 s) x 3. mutmut's estimate
        # leaves out fixture set-up, so the constant must cover building the scenes; the
        # default multiplier (15) makes each hanging mutant (a recorder waiting on a pipe)
        # minutes long.
        "timeout_constant = 60.0\n"
        "timeout_multiplier = 3.0\n"
        'pytest_add_cli_args = ["-p", "no:cacheprovider", "-q", "-x"]\n'
        f"pytest_add_cli_args_test_selection = [\n{lines},\n]\n"
    )


def _prepare(module: str) -> Path:
    """A copy of the tracked files at build/mutation/<module>, keeping mutmut's results."""
    dest = ROOT / "build" / "mutation" / module
    files = subprocess.run(
        ["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.split()
    for rel in files:
        target = dest / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        src = ROOT / rel
        if not target.exists() or target.read_bytes() != src.read_bytes():
            shutil.copy2(src, target)
    pyproject = (ROOT / "pyproject.toml").read_text()
    pyproject = re.sub(r"\[tool\.mutmut\].*?(?=^\[|\Z)", "", pyproject, flags=re.S | re.M)
    (dest / "pyproject.toml").write_text(pyproject + "\n" + _config(module))
    return dest


def _statuses(dest: Path) -> Counter[str]:
    out = subprocess.run(
        ["mutmut", "results", "--all", "true"], cwd=dest, capture_output=True, text=True
    ).stdout
    return Counter(line.rpartition(": ")[2].strip() for line in out.splitlines() if ": " in line)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("modules", nargs="*", help=f"some of {', '.join(MODULES)} (default all)")
    parser.add_argument("-j", "--jobs", type=int, default=1, help="mutmut workers per module")
    parser.add_argument("--report", action="store_true", help="print the table only")
    args = parser.parse_args()
    unknown = sorted(set(args.modules) - set(MODULES))
    if unknown:
        parser.error(f"unknown module(s) {', '.join(unknown)}; choose from {', '.join(MODULES)}")
    args.modules = args.modules or list(MODULES)
    # mutmut forks a worker per mutant from a process that has already rendered; Mesa's
    # llvmpipe threads do not survive a fork, so a forked worker's first render would wait on
    # them forever. LP_NUM_THREADS=0 makes llvmpipe render on the calling thread.
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"), LP_NUM_THREADS="0")
    for module in args.modules:
        dest = _prepare(module)
        if not args.report:
            print(f"--- mutmut on mjkdl/{module}.py ({', '.join(MODULES[module])})", flush=True)
            subprocess.run(
                ["mutmut", "run", "--max-children", str(args.jobs)], cwd=dest, env=env, check=False
            )
    print("\n| module | mutants | killed | survived | no tests | not run | raw score |")
    print("|---|---|---|---|---|---|---|")
    for module in args.modules:
        counts = _statuses(ROOT / "build" / "mutation" / module)
        killed = sum(counts[s] for s in KILLED)
        survived, untested = counts["survived"], counts["no tests"]
        pending = counts["not checked"]
        done = killed + survived + untested
        score = f"{100 * killed / done:.0f} %" if done else "-"
        print(
            f"| {module}.py | {sum(counts.values())} | {killed} | {survived} | {untested} "
            f"| {pending} | {score} |"
        )


if __name__ == "__main__":
    sys.exit(main())
