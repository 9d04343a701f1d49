"""`dexaug bench paper`: the paper's figures are read right, and a measured row is complete."""

from __future__ import annotations

import math

import pytest

from dexaug.bench_paper import Row, markdown, measure, paper_figures
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = pytest.mark.slow


def test_paper_figures_match_the_paper() -> None:
    paper = paper_figures()
    assert paper[("demo", "005_tomato_soup_can", "FSG+Aff")] == [0.042, 2.88e-2, 6.00e-3, 60.5]
    assert paper[("manual", "043_phillips_screwdriver", "FSG+Aff-FinIter")][0] == 2.536
    assert ("manual", "024_bowl", "FSG") not in paper      # the paper's NaN rows
    table = markdown([Row("024_bowl", "manual", "FSG", 0, 5, "time budget")], paper)
    assert "0/5 (budget)" in table and "— / —" in table


@needs_menagerie
@needs_ycb
def test_one_demo_row_is_measured() -> None:
    (row,) = measure(["062_dice"], ["FSG+Aff+LinkPen"], ["demo"], n=4, budget_s=30.0,
                     workers=1, six_dir=True)
    assert row.found == 4 and row.stopped == "done"
    assert 0 < row.time_per_result_s < 30
    for pct in (row.valid_pct, row.lift_drop_pct, row.dgb_pct, row.six_dir_pct):
        assert 0.0 <= pct <= 100.0
    assert math.isfinite(row.penetration_mm) and row.palm_spread_mm > 0
    assert "| 062_dice | demo | FSG+Aff+LinkPen | 4/4 |" in markdown([row], paper_figures())


