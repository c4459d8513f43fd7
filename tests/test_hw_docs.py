"""docs/hardware.md runs: its ```python blocks, in order, in one namespace, against the
simulated Franka (lockstep, in another process), and print what it says."""

from __future__ import annotations

import pytest
from conftest import ROOT, menagerie
from test_docs import assert_blocks_run

HARDWARE_DOC = ROOT / "docs" / "hardware.md"


def test_hardware_doc_blocks_run_and_print_what_they_say(
    franka_server: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    menagerie("franka_emika_panda")
    monkeypatch.setenv("MJKDL_ROBOT_IP", franka_server)
    assert_blocks_run(HARDWARE_DOC, at_least=5)
