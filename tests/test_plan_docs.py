"""docs/motion.md and docs/planning-your-arm.md run: their ```python blocks, in order, in one
namespace per page, print what the pages say."""

from __future__ import annotations

from conftest import ROOT, menagerie
from test_docs import assert_blocks_run

MOTION_DOC = ROOT / "docs" / "motion.md"
ARM_DOC = ROOT / "docs" / "planning-your-arm.md"


def test_motion_doc_blocks_run_and_print_what_they_say() -> None:
    menagerie("franka_emika_panda")
    assert_blocks_run(MOTION_DOC, at_least=4)


def test_planning_for_your_arm_blocks_run_and_print_what_they_say() -> None:
    assert_blocks_run(ARM_DOC, at_least=9)
