"""docs/control.md runs: its ```python blocks, in order, in one namespace, print what it says."""

from __future__ import annotations

import contextlib
import io

from conftest import ROOT, menagerie
from test_docs import blocks, matches

CONTROL_DOC = ROOT / "docs" / "control.md"


def test_control_doc_blocks_run_and_print_what_they_say() -> None:
    menagerie("franka_emika_panda")
    namespace: dict[str, object] = {}
    found = blocks(CONTROL_DOC.read_text())
    assert len(found) >= 4
    for block in found:
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            exec(compile(block.code, f"{CONTROL_DOC}:{block.line}", "exec"), namespace)
        if block.expected is not None:
            assert matches(block.expected, out.getvalue()), (
                f"docs/control.md line {block.line} printed:\n{out.getvalue()}"
                f"\nexpected:\n{block.expected}"
            )
