"""Every benchmark still runs, at a few steps, and prints its figures (not their values:
timing belongs to the benchmarks themselves, run on a quiet machine)."""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys

import pytest
from conftest import ROOT, menagerie, needs_extra

BENCHMARKS = ROOT / "benchmarks"
NUMBER = r"([-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)"


@pytest.fixture(scope="module", autouse=True)
def _models() -> None:
    for name in ("kinova_gen3", "robotiq_2f85", "franka_emika_panda"):
        menagerie(name)


def run_benchmark(name: str, *args: str) -> str:
    """Run `benchmarks/<name>.py *args` from its folder in a fresh interpreter; its stdout."""
    env = dict(os.environ, MUJOCO_GL="egl", LP_NUM_THREADS="0")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    proc = subprocess.run(
        [sys.executable, f"{name}.py", *args],
        cwd=BENCHMARKS,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, f"{name} exited {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    return proc.stdout


@pytest.mark.parametrize(
    ("name", "args", "figure"),
    [
        ("control_loop", (), r"seed settled\s+ratio to raw: median"),
        ("cartesian_velocity", ("--steps", "20"), r"Panda \+ hand, POSITION\s+"),
        ("ik", ("--targets", "10", "--repeat", "1"), r"first pass:\s+median"),
        ("step_check", ("--blocks", "2", "--steps", "50"), r"scene\.step\(\) / raw mj_step:"),
        ("record", ("--frames", "4", "--rounds", "1"), r"\n\s+off"),
        (
            "demos",
            ("--episodes", "1", "--camera-episodes", "1", "--rounds", "1"),
            r"recording:",
        ),
        (
            "planning",
            ("--queries", "3", "--execute", "1"),
            r"Gen3 \+ 2F-85: 3 random queries.*\n\s+solved:",
        ),
        (
            "osc",
            ("--blocks", "2", "--calls", "20"),
            r"Gen3 \+ 2F-85, planning clutter .*\n\s+mj_step:.*\n\s+torques\(\):",
        ),
        (
            "task_env",
            ("--blocks", "1", "--camera-blocks", "1", "--vector-seconds", "0.5"),
            r"async vector env, 128x128 camera, 1 sub-env\(s\):",
        ),
        (
            "batch",
            (
                "--worlds",
                "1",
                "--scaling",
                "1",
                "--rounds",
                "1",
                "--seconds",
                "0.1",
                "--async-envs",
                "1",
                "--no-first-step",
            ),
            r"batch \(mujoco\), 1 worlds, \d+ threads",
        ),
        (
            "grasp",
            ("--seeds", "1"),
            r"\| franka_hand\(\) 20 N, grasping\(\) \(the tasks'\) \| \d+\.\d / \d+\.\d mm \|",
        ),
        ("experts", ("--seeds", "1"), r"\| `mjkdl/PandaStack-v0` \|"),
    ],
)
def test_benchmark_runs_and_prints_its_figures(name, args, figure) -> None:
    if name == "batch":
        needs_extra("batch")
    out = run_benchmark(name, *args)
    found = re.search(figure + r"\s*" + NUMBER, out)
    assert found, f"no {figure!r} followed by a number in the output of {name}:\n{out}"
    value = float(found.group(1))
    assert math.isfinite(value) and value > 0


@pytest.mark.parametrize(
    ("run", "args", "figure"),
    [
        (
            "ppo-reach",
            ("--steps", "64"),
            r"ppo-reach: \d+% success after 2048 steps, ",
        ),  # a rollout
        ("bc-pick", ("--demos", "2", "--epochs", "1"), r"bc-pick: \d+% success after 1 steps, "),
    ],
)
def test_learning_runs_and_saves_its_curve(run, args, figure, tmp_path) -> None:
    needs_extra("rl")
    out = run_benchmark("learning", run, *args, "--results", str(tmp_path))
    assert re.search(figure + NUMBER + " s wall", out), out
    curve = __import__("json").loads((tmp_path / f"{run}.json").read_text())["curve"]
    assert curve and 0.0 <= curve[-1]["success"] <= 1.0


def test_rslrl_learning_run_records_its_seed(tmp_path) -> None:
    """An rsl-rl run on the CPU engine: evaluated on the held-out seeds, its settings and its
    PyTorch seed saved with the curve."""
    needs_extra("warp-rl")
    args = ("--device", "cpu", "--envs", "2", "--iterations", "1", "--seed", "3")
    out = run_benchmark("learning", "rslrl-reach", *args, "--results", str(tmp_path))
    assert re.search(r"\b48 steps: \d+% \(", out), out
    record = __import__("json").loads((tmp_path / "rslrl-reach.json").read_text())
    assert record["seed"] == 3 and record["num_envs"] == 2
    assert [p["steps"] for p in record["curve"]] == [48]
