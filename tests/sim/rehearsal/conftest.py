"""A small ground map and a report for the rehearsal tests (fixed numbers, no server)."""

from __future__ import annotations

import numpy as np
import pytest

from sim.rehearsal.inputs import GroundMapData, ReportedStart

CELL_M = 0.25
HALF_M = 20.0


def plane_map(imaged_half_m: float = 5.0, sigma_m: float = 0.3) -> GroundMapData:
    """A 40 m square map in the mission frame: a gentle plane (2 % North, 1 % East),
    imaged (σ 2 cm) within ``imaged_half_m`` of the origin, orbital (``sigma_m``) elsewhere."""
    n = round(2 * HALF_M / CELL_M) + 1
    offsets = -HALF_M + CELL_M * np.arange(n)
    gn, ge = np.meshgrid(offsets, offsets, indexing="ij")
    imaged = (np.abs(gn) <= imaged_half_m) & (np.abs(ge) <= imaged_half_m)
    height = 0.02 * gn + 0.01 * ge - 0.3
    sigma = np.where(imaged, 0.02, sigma_m)
    return GroundMapData(-HALF_M, -HALF_M, CELL_M, height, sigma, np.full((n, n), 0.2), imaged)


def report(**changes: object) -> ReportedStart:
    """The rover at rest near the origin, heading North, Fine, as it would report it."""
    values: dict[str, object] = {
        "site": "gusev",
        "mission": "spirit",
        "t_s": 131415044.434,
        "q_b_ll_est": (0.0, 0.0, 0.0, 1.0),
        "p_s_est": (0.5, 0.2, 0.0),
        "p_mission_est": (0.5, 0.2, 0.0),
        "aqf": "Fine",
        "imu_integration_s": 80.0,
        "position_sigma_m": 0.05,
    }
    values.update(changes)
    return ReportedStart(**values)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def ground_map() -> GroundMapData:
    return plane_map()
