"""docs/motion.md runs: its ```python blocks, in order, in one namespace, print what it says."""

from __future__ import annotations

from conftest import ROOT, menagerie
from test_docs import assert_blocks_run

MOTION_DOC = ROOT / "docs" / "motion.md"


def test_motion_doc_blocks_run_and_print_what_they_say() -> None:
    menagerie("franka_emika_panda")
    assert_blocks_run(MOTION_DOC, at_least=4)
