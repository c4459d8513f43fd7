"""The README's quickstart runs as written, from any directory, and holds the arm."""

from __future__ import annotations

import re

import numpy as np
from conftest import ROOT, menagerie


def test_quickstart_runs_and_holds(tmp_path, monkeypatch, capsys) -> None:
    menagerie("kinova_gen3")
    menagerie("robotiq_2f85")
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert blocks, "README has no python block"
    monkeypatch.chdir(tmp_path)  # not the repository: the table comes from the package
    namespace: dict = {}
    exec(compile(blocks[0], "README.md", "exec"), namespace)
    robot = namespace["robot"]
    printed = capsys.readouterr().out
    assert "R =" in printed and "p =" in printed  # a pinocchio.SE3 was printed
    # print(env) suggested the very call the quickstart makes
    tool = 'tool=mjk.ToolFrameSpec(tool_body="g_base", tcp_site="g_pinch")'
    assert f'scene.create_robot("base_link", "bracelet_link", {tool})' in printed
    assert namespace["env"].closed  # the with-block closed it
    key_home = np.array([0, 0.26179939, 3.14159265, -2.26892803, 0, 0.95993109, 1.57079633])
    assert np.abs(robot._pos_msr - key_home).max() < 1e-3  # gravity compensation held it
