"""A sampled world's tiles come from the relief's separable grid: equal, bit for bit, to the
relief taken point by point (what a run's outcomes rest on; the grid is only faster)."""

from __future__ import annotations

import numpy as np
import pytest

from sim.rehearsal.world import UnresolvedRelief
from sim.world.noise import grid_axes


@pytest.mark.parametrize("site_name", ["gusev", "meridiani"])
@pytest.mark.parametrize(("i0", "j0"), [(0, 0), (-480, 320), (161, -803)])
def test_the_relief_grid_is_the_relief_at_its_nodes(site_name: str, i0: int, j0: int) -> None:
    relief = UnresolvedRelief(site_name, 123)
    x, y = np.broadcast_arrays(*grid_axes(i0, j0, 41, 0.05))
    pointwise = relief.at(x, y)
    assert np.array_equal(relief.grid(i0, j0, 41, 0.05), pointwise)
    assert np.ptp(pointwise) > 0.0  # a relief, not a constant
