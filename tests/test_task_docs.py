"""docs/task.md runs: its ```python blocks, in order, in one namespace, print what it says."""

from __future__ import annotations

import numpy as np
from conftest import ROOT, menagerie
from test_docs import assert_blocks_run

import mjkdl.task

TASK_DOC = ROOT / "docs" / "task.md"


def test_task_doc_blocks_run_and_print_what_they_say(monkeypatch, tmp_path) -> None:
    menagerie("franka_emika_panda")
    monkeypatch.chdir(tmp_path)  # the page writes episode.mp4 into the working folder
    viewed: list[tuple] = []

    # No display here: task.view records its call and runs a few steps headless instead.
    def fake_view(env, policy=None, plots=(), **kw) -> int:
        viewed.append((plots, kw))
        env.reset(seed=0)
        for _ in range(3):
            env.step(policy({}) if policy else np.zeros(env.action_space.shape))
        return 3

    monkeypatch.setattr(mjkdl.task, "view", fake_view)
    assert_blocks_run(TASK_DOC, at_least=7)
    assert viewed == [(["panda_tcp_pos", "goal_pose"], {})]


def test_physics_doc_blocks_run_and_print_what_they_say() -> None:
    assert_blocks_run(ROOT / "docs" / "physics.md", at_least=1)
