"""``bench.vo.ground_map`` in a quick version: one short drive on each site, its figures
finite and consistent with each other and with the cells they were computed from. No
figure's value against its target is asserted (TESTING.md: benchmarks measure)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from bench.vo.ground_map import SITES, drive_score, ground_map_metrics


@pytest.fixture(scope="module")
def quick() -> dict[str, Any]:
    return ground_map_metrics(drives_per_site=1, steps=1)


def test_the_figures_are_finite_and_consistent(quick: dict[str, Any]) -> None:
    assert quick["ground_map_drives"] == len(SITES) == 2
    assert quick["ground_map_pairs"] == 4  # the pair at the start and one after the step
    assert 0 < quick["ground_map_cells_scored"] <= quick["ground_map_imaged_cells"]
    for key, value in quick.items():
        assert isinstance(value, int | float) and math.isfinite(value), key
    assert 0.0 <= quick["ground_map_sigma_coverage_pct"] <= 100.0
    assert quick["ground_map_height_err_m_p95"] > 0.0
    per_site = [quick[f"ground_map_height_err_m_p95_{s}"] for s in SITES]
    assert min(per_site) <= quick["ground_map_height_err_m_p95"] <= max(per_site)
    assert quick["ground_map_disparity_z68"] > 0.0


def test_a_drive_scores_only_cells_the_stereo_measured() -> None:
    score = drive_score("meridiani", 3, 1)
    assert score.pairs == 2
    assert 0 < score.errors_m.size <= score.imaged_cells
    assert np.all(score.sigma_m > 0.0)
    # the ground's cells are measured: their σ is far below the orbital prior's (0.35 m)
    assert float(np.median(score.sigma_m)) < 0.1
