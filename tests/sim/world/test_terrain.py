"""Lattice noise (sim.world.noise), heightmap tiles (sim.world.heightmap), albedo texture
(sim.world.albedo)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, stats

from sim.errors import InputError
from sim.world.albedo import AlbedoStyle, AlbedoTexture, GrainLayer
from sim.world.heightmap import RESOLUTION_M, HeightmapTerrain
from sim.world.noise import FractalNoise, derive_key, lattice_uniform
from sim.world.sites import GUSEV_ALBEDO, MERIDIANI_ALBEDO, make_terrain
from sim.world.terrain import BEDROCK


def _texture() -> AlbedoTexture:
    return AlbedoTexture(5, AlbedoStyle(mean=0.2, contrast=0.2))


def _rough_terrain(cache_tiles: int = 128) -> HeightmapTerrain:
    """A bare (rock-free) fractal terrain with relief at every scale down to the grid."""
    ground = FractalNoise(11, 0, [20.0, 5.0, 1.0, 0.2], [2.0, 0.5, 0.1, 0.02])
    return HeightmapTerrain("test", BEDROCK, ground, _texture(), cache_tiles=cache_tiles)


# --- lattice noise -----------------------------------------------------------------------


def test_lattice_values_are_uniform_and_uncorrelated() -> None:
    ix, iy = np.meshgrid(np.arange(-150, 150), np.arange(-150, 150), indexing="ij")
    v = lattice_uniform(derive_key(3, 1), ix, iy).ravel()
    assert stats.kstest(v, stats.uniform(loc=-1.0, scale=2.0).cdf).pvalue > 1e-3
    assert abs(np.corrcoef(v[:-1], v[1:])[0, 1]) < 0.02  # neighbours along y
    other = lattice_uniform(derive_key(4, 1), ix, iy).ravel()
    assert abs(np.corrcoef(v, other)[0, 1]) < 0.02  # another seed: another lattice


def test_noise_octave_variance_matches_bspline_theory() -> None:
    # One octave interpolates iid U(-1, 1) lattice values (variance 1/3) with cubic
    # B-spline weights w_a(t); over a uniform fraction t the variance is
    # (1/3) * (∫ Σ_a w_a(t)² dt)², integrated here independently of the code.
    def w2(t: float) -> float:
        w = np.array(
            [(1 - t) ** 3, 3 * t**3 - 6 * t**2 + 4, -3 * t**3 + 3 * t**2 + 3 * t + 1, t**3]
        )
        return float(np.sum((w / 6.0) ** 2))

    expected_std = np.sqrt(integrate.quad(w2, 0.0, 1.0)[0] ** 2 / 3.0)
    field = FractalNoise(8, 0, [1.0], [1.0]).grid(0, 0, 1500, 0.29)
    assert field.std() == pytest.approx(expected_std, rel=0.03)
    assert abs(field.mean()) < 0.02


def test_grid_evaluation_equals_point_evaluation() -> None:
    noise = FractalNoise(2, 7, [30.0, 3.0, 0.3], [1.0, 0.2, 0.01])
    grid = noise.grid(-97, 40, 60, 0.05)
    a, b = np.meshgrid(np.arange(60), np.arange(60), indexing="ij")
    points = noise.at((-97 + a) * 0.05, (40 + b) * 0.05)  # same node arithmetic as grid()
    np.testing.assert_allclose(grid, points, rtol=0, atol=1e-12)


# --- heightmap geometry --------------------------------------------------------------------


def test_bilinear_surface_passes_through_samples() -> None:
    t = _rough_terrain()
    tile = t.tile(-1, 2)
    n = t.tile_cells
    a = np.array([0, 7, 80, n])
    b = np.array([0, 33, 159, n])
    x = (-1 * n + a) * t.resolution_m
    y = (2 * n + b) * t.resolution_m
    np.testing.assert_allclose(t.height_m(x, y), tile[a, b], rtol=0, atol=1e-12)
    # Midway along a cell edge the bilinear surface is the mean of the two nodes.
    mid = t.height_m(x[1] + 0.5 * t.resolution_m, y[1])
    assert float(mid) == pytest.approx(0.5 * (tile[7, 33] + tile[8, 33]), abs=1e-12)


def test_gradient_is_the_derivative_of_the_height() -> None:
    t = make_terrain("gusev", 21)  # rocks and hills: large, rapidly varying slopes
    assert isinstance(t, HeightmapTerrain)
    rng = np.random.default_rng(0)
    cell = rng.integers(-200, 200, size=(2, 2000))
    frac = rng.uniform(0.01, 0.99, size=(2, 2000))  # stay inside a cell for the differences
    x, y = (cell + frac) * RESOLUTION_M
    step = 1e-6
    fd_x = (t.height_m(x + step, y) - t.height_m(x - step, y)) / (2 * step)
    fd_y = (t.height_m(x, y + step) - t.height_m(x, y - step)) / (2 * step)
    hx, hy = t.gradient(x, y)
    np.testing.assert_allclose(hx, fd_x, rtol=0, atol=1e-6)
    np.testing.assert_allclose(hy, fd_y, rtol=0, atol=1e-6)
    h, hx2, hy2 = t.height_and_gradient(x, y)
    np.testing.assert_array_equal(h, t.height_m(x, y))
    np.testing.assert_array_equal(hx2, hx)
    np.testing.assert_array_equal(hy2, hy)
    assert np.max(np.hypot(hx, hy)) > 0.5  # the sample really contains steep ground


@pytest.mark.parametrize("name", ["gusev", "meridiani"])
def test_tiles_join_seamlessly(name: str) -> None:
    t = make_terrain(name, 4)  # rocks straddle tile edges too
    assert isinstance(t, HeightmapTerrain)
    for ti, tj in [(0, 0), (-1, 0), (-1, -1), (3, -2)]:
        here = t.tile(ti, tj)
        np.testing.assert_array_equal(here[-1, :], t.tile(ti + 1, tj)[0, :])  # bit for bit
        np.testing.assert_array_equal(here[:, -1], t.tile(ti, tj + 1)[:, 0])
    # Approaching an edge from both sides gives the same height and no step.
    edge = t.tile_size_m
    y = np.linspace(-20.0, 20.0, 4001)
    below = t.height_m(edge - 1e-9, y)
    above = t.height_m(edge + 1e-9, y)
    np.testing.assert_allclose(below, above, rtol=0, atol=1e-8)


def test_queries_vectorise_over_any_shape() -> None:
    t = _rough_terrain()
    rng = np.random.default_rng(1)
    x = rng.uniform(-30, 30, size=(3, 4, 5))
    y = rng.uniform(-30, 30, size=(3, 4, 5))
    h = t.height_m(x, y)
    hx, hy = t.gradient(x, y)
    assert h.shape == hx.shape == hy.shape == (3, 4, 5)
    one_by_one = np.array(
        [float(t.height_m(a, b)) for a, b in zip(x.ravel(), y.ravel(), strict=True)]
    )
    np.testing.assert_array_equal(h.ravel(), one_by_one)
    assert t.height_m(1.0, 2.0).shape == ()
    assert t.height_m(np.zeros((0, 3)), 0.0).shape == (0, 3)
    assert t.height_m(np.arange(4.0), 1.0).shape == (4,)  # broadcasting


def test_cache_eviction_rebuilds_identical_tiles() -> None:
    small = _rough_terrain(cache_tiles=2)
    big = _rough_terrain()
    x = np.linspace(-24.0, 24.0, 25)
    first = small.height_m(x[:, None], x[None, :])  # one query needs 49 tiles: pool grows
    for xi in x:  # then row by row: tiles come and go
        small.height_m(xi, x)
    again = small.height_m(x[:, None], x[None, :])
    np.testing.assert_array_equal(first, again)
    np.testing.assert_array_equal(first, big.height_m(x[:, None], x[None, :]))
    assert small.tiles_built > big.tiles_built  # tiles were evicted and rebuilt


def test_long_drives_in_every_direction_build_only_nearby_tiles() -> None:
    t = _rough_terrain()
    s = np.linspace(0.0, 100.0, 10001)
    for heading in np.radians(np.arange(0, 360, 45)):
        h = t.height_m(s * np.cos(heading), s * np.sin(heading))
        assert np.all(np.isfinite(h))
        # Relief of the test surface is bounded by the sum of its amplitudes.
        assert np.max(np.abs(h)) <= 2.62
    # A 100 m ray crosses at most 100·(|cos|+|sin|)/8 + 1 ≈ 19 tiles of 8 m; the bounding
    # box of all rays would hold 26² = 676.
    assert t.tiles_built <= 8 * 19


def _bilinear_reference(
    t: HeightmapTerrain, x: np.ndarray, y: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The heightmap's surface in numpy, point by point from its public tiles: the
    arithmetic of the compiled query (``sim.world.heightmap._bilinear``) before it was
    compiled, so the two must agree bit for bit."""
    gx, gy = x / t.resolution_m, y / t.resolution_m
    fx, fy = np.floor(gx), np.floor(gy)
    u, v = gx - fx, gy - fy
    gi, gj = fx.astype(np.int64), fy.astype(np.int64)
    ti, tj = gi // t.tile_cells, gj // t.tile_cells
    a, b = gi - ti * t.tile_cells, gj - tj * t.tile_cells
    h00, h10, h01, h11 = (np.empty(x.shape) for _ in range(4))
    for tile in {(int(p), int(q)) for p, q in zip(ti, tj, strict=True)}:
        on = (ti == tile[0]) & (tj == tile[1])
        samples = t.tile(*tile)
        h00[on], h10[on] = samples[a[on], b[on]], samples[a[on] + 1, b[on]]
        h01[on], h11[on] = samples[a[on], b[on] + 1], samples[a[on] + 1, b[on] + 1]
    dx, dy = h10 - h00, h01 - h00
    twist = h11 - h10 - h01 + h00
    h = h00 + u * dx + v * (dy + u * twist)
    return h, (dx + v * twist) / t.resolution_m, (dy + u * twist) / t.resolution_m


@pytest.mark.parametrize(
    ("far_m", "half_m"), [(0.0, 3.0), (0.0, 30.0), (6.0e5, 30.0)], ids=["one", "lut", "far"]
)
def test_compiled_queries_equal_the_numpy_reference(far_m: float, half_m: float) -> None:
    # One tile (8 m, centred on 4 m), a lookup table over many, and a slot per point (two
    # clusters 600 km apart: a bounding box of more than MAX_LUT_TILES tiles): all bit for
    # bit the reference, nodes and cell edges included.
    t = make_terrain("gusev", 3)
    rng = np.random.default_rng(5)
    x = 4.0 + rng.uniform(-half_m, half_m, 1000)
    y = -4.0 + rng.uniform(-half_m, half_m, 1000)
    x[:2], y[:2] = [5.0 * RESOLUTION_M, 2.0], [-3.0 * RESOLUTION_M, -6.0]  # a node, an edge
    x[500:] += far_m
    h, hx, hy = t.height_and_gradient(x.reshape(20, 50), y.reshape(20, 50))
    ref = _bilinear_reference(t, x, y)
    for got, want in zip((h, hx, hy), ref, strict=True):
        np.testing.assert_array_equal(got.ravel(), want)
    fresh = make_terrain("gusev", 3)
    np.testing.assert_array_equal(fresh.height_m(x, y), ref[0])
    tiles = {(int(a), int(b)) for a, b in np.floor(np.stack([x, y]) / fresh.tile_size_m).T}
    assert fresh.tiles_built == len(tiles)  # only the tiles the points fall in


@pytest.mark.parametrize("bad", [np.nan, np.inf, 2.0e6])
def test_bad_coordinates_raise_input_error(bad: float) -> None:
    t = _rough_terrain()
    with pytest.raises(InputError) as err:
        t.height_m(np.array([0.0, bad]), 0.0)
    assert err.value.parameter == "x_m"
    with pytest.raises(InputError) as err:
        t.height_and_gradient(0.0, np.array([bad, 0.0]))
    assert err.value.parameter == "y_m"
    with pytest.raises(InputError):
        t.albedo(0.0, bad)


# --- albedo --------------------------------------------------------------------------------


@pytest.mark.parametrize("style", [GUSEV_ALBEDO, MERIDIANI_ALBEDO])
def test_albedo_stays_in_unit_interval_with_site_mean(style: AlbedoStyle) -> None:
    tex = AlbedoTexture(9, style)
    rng = np.random.default_rng(2)
    x, y = rng.uniform(-100.0, 100.0, size=(2, 200_000))
    a = tex(x, y)
    assert np.all((a >= 0.0) & (a <= 1.0))
    assert a.mean() == pytest.approx(style.mean, rel=0.05)


def test_albedo_contrast_is_the_relative_standard_deviation() -> None:
    style = AlbedoStyle(mean=0.2, contrast=0.15)  # no grains: fBm alone
    rng = np.random.default_rng(3)
    x, y = rng.uniform(-300.0, 300.0, size=(2, 200_000))
    a = AlbedoTexture(4, style)(x, y)
    assert a.std() / a.mean() == pytest.approx(0.15, rel=0.1)


def test_grain_layers_keep_the_mean() -> None:
    # Grains only (no fBm): the analytic grain mean subtracted in the code must leave the
    # area mean at style.mean; without it the mean would shift by p·c·E[profile·r²] ≈ 3.7 %.
    style = AlbedoStyle(
        mean=0.2,
        contrast=0.0,
        grains=(GrainLayer(cell_m=0.01, probability=0.5, relative_contrast=-0.5),),
    )
    rng = np.random.default_rng(4)
    x, y = rng.uniform(-50.0, 50.0, size=(2, 400_000))
    a = AlbedoTexture(6, style)(x, y)
    sem = a.std() / np.sqrt(a.size)
    assert abs(a.mean() - 0.2) < 4 * sem
    assert a.min() < 0.2 * 0.65  # dark grains exist


def test_albedo_has_millimetre_detail_and_is_continuous() -> None:
    for name in ("gusev", "meridiani", "eq22", "flat"):
        t = make_terrain(name, 12)
        rng = np.random.default_rng(5)
        x, y = rng.uniform(-3.0, 3.0, size=(2, 20_000))
        d_1mm = np.abs(t.albedo(x + 0.001, y) - t.albedo(x, y))
        d_1um = np.abs(t.albedo(x + 1e-6, y) - t.albedo(x, y))
        assert np.median(d_1mm) > 1e-4, name  # points 1 mm apart differ
        assert np.mean(d_1mm > 0) > 0.99, name
        assert np.max(d_1um) < 0.02 * np.max(d_1mm), name  # but nothing jumps


def test_albedo_footprint_filters_fine_detail() -> None:
    tex = AlbedoTexture(7, GUSEV_ALBEDO)
    rng = np.random.default_rng(6)
    x, y = rng.uniform(-3.0, 3.0, size=(2, 20_000))
    sharp = np.abs(tex.evaluate(x + 0.001, y) - tex.evaluate(x, y))
    blurred = np.abs(tex.evaluate(x + 0.001, y, 0.05) - tex.evaluate(x, y, 0.05))
    assert np.median(blurred) < 0.1 * np.median(sharp)
    np.testing.assert_array_equal(tex.evaluate(x, y, 100.0), GUSEV_ALBEDO.mean)  # all faded
    per_point = tex.evaluate(x[:5], y[:5], np.array([1e-4, 1e-3, 1e-2, 1e-1, 1.0]))
    for i, fp in enumerate([1e-4, 1e-3, 1e-2, 1e-1, 1.0]):
        assert per_point[i] == pytest.approx(tex.evaluate(x[i], y[i], fp), abs=1e-7)


def test_albedo_is_deterministic_from_the_seed() -> None:
    rng = np.random.default_rng(7)
    x, y = rng.uniform(-10.0, 10.0, size=(2, 1000))
    a = AlbedoTexture(1, GUSEV_ALBEDO)(x, y)
    np.testing.assert_array_equal(a, AlbedoTexture(1, GUSEV_ALBEDO)(x, y))
    assert np.mean(a != AlbedoTexture(2, GUSEV_ALBEDO)(x, y)) > 0.99
