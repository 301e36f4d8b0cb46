"""localize.offline.report: the accuracy table compares each mode's mean error with the paper's."""

from __future__ import annotations

import pytest

from localize.offline.report import versus_paper


@pytest.mark.parametrize("error,paper,text", [
    (0.35, 0.1, "3.5x worse"),  # 3.5 times the paper's error
    (0.05, 0.1, "2.0x better"),
    (0.1, 0.1, "1.0x better"),
    (0.0, 0.1, "100000000.0x better"),
])
def test_versus_paper(error: float, paper: float, text: str) -> None:
    assert versus_paper(error, paper) == text
