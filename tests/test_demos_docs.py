"""docs/demos.md runs: its ```python blocks, in order, in one namespace, print what it says."""

from __future__ import annotations

import pytest
from conftest import ROOT, menagerie
from test_docs import assert_blocks_run

DEMOS_DOC = ROOT / "docs" / "demos.md"


def test_demos_doc_blocks_run_and_print_what_they_say(
    monkeypatch: pytest.MonkeyPatch, tmp_path
) -> None:
    menagerie("franka_emika_panda")
    monkeypatch.chdir(tmp_path)  # the page writes its files into the working folder
    assert_blocks_run(DEMOS_DOC, at_least=5)
    assert (tmp_path / "pick_lerobot" / "meta" / "info.json").is_file()
