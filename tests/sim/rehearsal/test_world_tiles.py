"""A sampled world's tiles come from the relief's separable grid: equal, bit for bit, to the
relief taken point by point (what a run's outcomes rest on; the grid is only faster)."""

from __future__ import annotations

import numpy as np
import pytest

from sim.rehearsal.world import CubicGrid, MapSurface, SampledGround, StartSlope, UnresolvedRelief
from sim.world.noise import grid_axes


@pytest.mark.parametrize("site_name", ["gusev", "meridiani"])
@pytest.mark.parametrize(("i0", "j0"), [(0, 0), (-480, 320), (161, -803)])
def test_the_relief_grid_is_the_relief_at_its_nodes(site_name: str, i0: int, j0: int) -> None:
    relief = UnresolvedRelief(site_name, 123)
    x, y = np.broadcast_arrays(*grid_axes(i0, j0, 41, 0.05))
    pointwise = relief.at(x, y)
    assert np.array_equal(relief.grid(i0, j0, 41, 0.05), pointwise)
    assert np.ptp(pointwise) > 0.0  # a relief, not a constant


def test_the_map_grid_is_the_map_at_its_nodes() -> None:
    rng = np.random.default_rng(5)
    grid = CubicGrid.of(-3.0, 2.0, 0.25, rng.normal(0.0, 0.3, (60, 50)))
    for i0, j0, n in ((0, 0, 161), (-97, 130, 41), (400, -400, 20)):  # inside, edges, outside
        x, y = grid_axes(i0, j0, n, 0.05)
        bx, by = np.broadcast_arrays(x, y)
        assert np.array_equal(grid.on_axes(x[:, 0], y[0, :]), grid.at(bx, by))


def test_a_sampled_tile_is_the_ground_at_its_nodes() -> None:
    rng = np.random.default_rng(6)
    surface = CubicGrid.of(-10.0, -10.0, 0.25, rng.normal(0.0, 0.2, (81, 81)))
    error = CubicGrid.of(-10.0, -10.0, 0.25, rng.normal(0.0, 0.05, (81, 81)))
    ground = SampledGround(
        MapSurface(surface, np.full((81, 81), 0.1), np.zeros((81, 81), bool), -10.0, -10.0, 0.25),
        error,
        UnresolvedRelief("meridiani", 9),
        StartSlope((1.0, -2.0), (0.05, -0.02)),
    )
    x, y = np.broadcast_arrays(*grid_axes(-80, 20, 161, 0.05))
    assert np.array_equal(ground.grid(-80, 20, 161, 0.05), ground.at(x, y))
