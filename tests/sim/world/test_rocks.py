"""Rock size-frequency model and rock placement (sim.world.rocks)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import ArrayLike
from scipy import integrate, stats

from sim.world.albedo import AlbedoStyle, AlbedoTexture
from sim.world.heightmap import FloatArray, HeightmapTerrain
from sim.world.noise import FractalNoise
from sim.world.rocks import (
    HEIGHT_TO_DIAMETER,
    RockField,
    RockPopulation,
    cumulative_area_fraction,
    cumulative_number_per_m2,
    number_density,
    q_of_k,
    sample_rocks,
    stamp_rocks,
)
from sim.world.terrain import BEDROCK


class _Level:
    """Ground at elevation zero (a GroundField)."""

    def at(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        return np.zeros(np.broadcast(np.asarray(x_m), np.asarray(y_m)).shape)

    def grid(self, i0: int, j0: int, n: int, spacing_m: float) -> FloatArray:
        return np.zeros((n, n))


def _rocky_plane(k: float, seed: int = 3) -> tuple[HeightmapTerrain, RockField]:
    field = RockField(seed, RockPopulation(k))
    tex = AlbedoTexture(0, AlbedoStyle(mean=0.2, contrast=0.1))
    return HeightmapTerrain("rocks", BEDROCK, _Level(), tex, stamp=field.stamp), field


# --- the size-frequency model -------------------------------------------------------------


def test_q_of_k_follows_golombek_and_rapp() -> None:
    # q(k) = 1.79 + 0.152/k: the fit of Golombek & Rapp 1997.
    assert q_of_k(0.07) == pytest.approx(1.79 + 0.152 / 0.07)
    assert q_of_k(0.20) == pytest.approx(2.55)
    # At D = 0 the cumulative area is the total rock abundance k.
    assert float(cumulative_area_fraction(0.0, 0.07)) == pytest.approx(0.07)


@pytest.mark.parametrize("k", [0.005, 0.07, 0.2])
def test_cumulative_number_integrates_the_density(k: float) -> None:
    for d in (0.05, 0.1, 0.3, 1.0):
        numeric = integrate.quad(lambda t: float(number_density(t, k)), d, np.inf, limit=200)[0]
        assert float(cumulative_number_per_m2(d, k)) == pytest.approx(numeric, rel=1e-7)


def test_density_times_rock_area_is_minus_the_area_fraction_slope() -> None:
    k = 0.07
    d = np.linspace(0.05, 2.0, 50)
    step = 1e-6
    slope = (cumulative_area_fraction(d + step, k) - cumulative_area_fraction(d - step, k)) / (
        2 * step
    )
    np.testing.assert_allclose(number_density(d, k) * np.pi * d**2 / 4, -slope, rtol=1e-6)


def test_sampled_diameters_follow_the_truncated_law() -> None:
    pop = RockPopulation(0.07, d_min_m=0.05, d_max_m=1.0)
    n_lo, n_hi = cumulative_number_per_m2(np.array([0.05, 1.0]), 0.07)

    def cdf(d: np.ndarray) -> np.ndarray:
        n = cumulative_number_per_m2(np.clip(d, 0.05, 1.0), 0.07)
        p: np.ndarray = (n_lo - n) / (n_lo - n_hi)
        return p

    sample = pop.sample_diameters(np.random.default_rng(0), 20_000)
    assert sample.min() >= 0.05 and sample.max() <= 1.0
    assert stats.kstest(sample, cdf).pvalue > 1e-3


@pytest.mark.parametrize("k", [0.07, 0.2])
def test_sampled_population_reproduces_the_area_fraction(k: float) -> None:
    # Over 3600 m², the area covered by rocks >= D must match F_k(D) (truncated to the
    # placed range) within 4 standard deviations of a Poisson population:
    # Var[covered area / A] = (1/A) ∫ n(t) a(t)² dt over t >= D.
    field = RockField(17, RockPopulation(k))
    side = 60.0
    rocks = field.rocks_in_box(0.0, side, 0.0, side)
    area = side * side
    expected_count = field.population.density_per_m2 * area
    assert abs(len(rocks) - expected_count) < 4 * np.sqrt(expected_count)
    rock_area = np.pi * rocks.semi_major_m * rocks.semi_minor_m
    np.testing.assert_allclose(rock_area, np.pi * rocks.diameter_m**2 / 4, rtol=1e-12)
    for d in (0.05, 0.1, 0.2, 0.4, 0.7):
        covered = rock_area[rocks.diameter_m >= d].sum() / area
        var = integrate.quad(
            lambda t: float(number_density(t, k)) * (np.pi * t * t / 4) ** 2, d, 1.0
        )[0]
        sigma = np.sqrt(var / area)
        assert abs(covered - float(field.population.area_fraction(d))) < 4 * sigma, d


def test_rock_heights_are_half_the_diameter() -> None:
    rocks = sample_rocks(RockPopulation(0.1), np.random.default_rng(4), 0.0, 0.0, 20.0)
    ratio = rocks.height_m / rocks.diameter_m
    assert ratio.mean() == pytest.approx(HEIGHT_TO_DIAMETER, abs=0.01)
    assert np.all(np.abs(ratio - HEIGHT_TO_DIAMETER) <= 0.1 + 1e-12)
    assert np.all(rocks.semi_minor_m <= rocks.semi_major_m)


# --- placement in the heightmap -------------------------------------------------------------


def test_stamped_rock_profile_is_a_half_ellipsoid() -> None:
    rocks = sample_rocks(RockPopulation(0.2), np.random.default_rng(5), 0.0, 0.0, 10.0)
    big = rocks.select(rocks.diameter_m > 0.4)
    assert len(big) >= 3
    spacing = 0.005
    for i in range(len(big)):
        one = big.select(np.arange(len(big)) == i)
        i0 = int(np.floor((one.x_m[0] - 0.7) / spacing))
        j0 = int(np.floor((one.y_m[0] - 0.7) / spacing))
        h = np.zeros((281, 281))
        stamp_rocks(h, one, i0, j0, spacing)
        # Peak = rock height (the 5 mm grid misses the apex by < 1 mm), area = π a b.
        assert h.max() == pytest.approx(one.height_m[0], abs=1e-3)
        covered = np.count_nonzero(h > 0) * spacing**2
        assert covered == pytest.approx(np.pi * one.diameter_m[0] ** 2 / 4, rel=0.03)


def test_rock_coverage_matches_the_boolean_model() -> None:
    # Rocks are a Poisson (Boolean) model: the fraction of ground under at least one rock
    # is 1 - exp(-F), F the summed area fraction. Grid nodes sample it without bias.
    k = 0.07
    terrain, field = _rocky_plane(k, seed=8)
    heights = np.stack([terrain.tile(i, j) for i in range(-2, 2) for j in range(-2, 2)])
    covered = np.mean(heights > 0.0)
    total = float(field.population.area_fraction(field.population.d_min_m))
    var = integrate.quad(lambda t: float(number_density(t, k)) * (np.pi * t * t / 4) ** 2, 0.05, 1)
    sigma = np.sqrt(var[0] / (16 * terrain.tile_size_m**2))
    assert abs(covered - (1 - np.exp(-total))) < 4 * sigma


def test_rocks_near_a_tile_border_reach_into_the_neighbour() -> None:
    terrain, field = _rocky_plane(0.2, seed=2)
    edge = terrain.tile_size_m  # border between tiles (0, *) and (1, *)
    rocks = field.rocks_in_box(edge - 0.6, edge, -20.0, 20.0)
    crossing = rocks.select(rocks.x_m + 0.9 * rocks.semi_minor_m > edge + 0.06)
    assert len(crossing) > 0
    # A point just across the border, on the rock's centre line, is raised by the rock
    # whose centre lies in the other tile.
    x = np.full(len(crossing), edge + 0.05)
    h = terrain.height_m(x, crossing.y_m)
    assert np.all(h > 0.0)
    assert terrain.tiles_built >= 2


def test_rock_cells_do_not_depend_on_generation_order() -> None:
    pop = RockPopulation(0.07)
    a = RockField(5, pop)
    b = RockField(5, pop, cache_cells=1)
    for ci, cj in [(3, 4), (-2, 0), (7, -9)]:
        b.rocks_in_cell(ci, cj)
    first = a.rocks_in_cell(-2, 0)
    second = b.rocks_in_cell(-2, 0)  # regenerated after eviction
    np.testing.assert_array_equal(first.x_m, second.x_m)
    np.testing.assert_array_equal(first.diameter_m, second.diameter_m)
    other = a.rocks_in_cell(-2, 1)  # the next cell East: its own rocks
    assert np.all((other.y_m >= 8.0) & (other.y_m < 16.0))
    n = min(len(first), len(other))
    assert not np.array_equal(first.diameter_m[:n], other.diameter_m[:n])


def test_rocks_sit_on_the_tangent_plane_of_the_ground() -> None:
    ground = FractalNoise(1, 0, [10.0], [3.0])  # a slope of up to ~45 %
    rocks = sample_rocks(RockPopulation(0.1), np.random.default_rng(6), 0.0, 0.0, 10.0, ground)
    np.testing.assert_allclose(rocks.base_m, ground.at(rocks.x_m, rocks.y_m), atol=1e-12)
    h = 1e-5
    slope_x = (ground.at(rocks.x_m + h, rocks.y_m) - ground.at(rocks.x_m - h, rocks.y_m)) / (2 * h)
    # Forward differences over half the rock's long axis: error ~ curvature x a / 4.
    np.testing.assert_allclose(rocks.slope_x, slope_x, atol=0.02)


def test_population_rejects_nonsense() -> None:
    with pytest.raises(ValueError):
        RockPopulation(0.0)
    with pytest.raises(ValueError):
        RockPopulation(0.07, d_min_m=0.5, d_max_m=0.2)
    with pytest.raises(ValueError):
        RockField(0, RockPopulation(0.07, d_max_m=5.0), cell_m=2.0)
