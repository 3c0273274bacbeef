"""The sampled world against the ground's map: within its σ, no rocks where it imaged."""

from __future__ import annotations

import numpy as np

from sim.rehearsal.inputs import GroundMapData, Priors
from sim.rehearsal.world import CubicGrid, map_surface, sampled_world


def test_cubic_grid_passes_through_samples_and_reproduces_a_plane() -> None:
    rng = np.random.default_rng(4)
    values = rng.standard_normal((12, 9))
    grid = CubicGrid.of(1.0, -2.0, 0.5, values)
    i, j = (a.astype(np.float64) for a in np.meshgrid(np.arange(12), np.arange(9), indexing="ij"))
    assert np.allclose(grid.at(1.0 + 0.5 * i, -2.0 + 0.5 * j), values, atol=1e-12)
    plane = CubicGrid.of(0.0, 0.0, 1.0, 3.0 * i - 2.0 * j + 1.0)
    x, y = rng.uniform(1.0, 8.0, 50), rng.uniform(1.0, 6.0, 50)  # away from the edges
    assert np.allclose(plane.at(x, y), 3.0 * x - 2.0 * y + 1.0, atol=1e-9)


def test_the_world_matches_the_map_within_its_sigma(ground_map: GroundMapData) -> None:
    """At the cells' centres the drawn map error, normalised by each cell's σ, has mean
    ~0 and standard deviation ~1, on the imaged (σ 2 cm) and orbital (σ 30 cm) cells."""
    n = ground_map.height_m.shape[0]
    inner = slice(20, n - 20)  # away from the map's edges (the smoothing's margin)
    offsets = ground_map.north0_m + ground_map.cell_m * np.arange(n)
    gn, ge = np.meshgrid(offsets[inner], offsets[inner], indexing="ij")
    z_imaged, z_orbital = [], []
    for seed in range(6):
        rng = np.random.default_rng(seed)
        world = sampled_world("gusev", ground_map, Priors(), (0.0, 0.0), 100 + seed, rng)
        z = (world.ground.map_part(gn, ge) - ground_map.height_m[inner, inner]) / (
            ground_map.sigma_m[inner, inner]
        )
        imaged = ground_map.imaged[inner, inner]
        z_imaged.append(z[imaged])
        z_orbital.append(z[~imaged])
    for zs in (np.concatenate(z_imaged), np.concatenate(z_orbital)):
        assert abs(float(np.mean(zs))) < 0.3
        assert 0.6 < float(np.std(zs)) < 1.4


def test_rocks_only_where_the_map_did_not_image(ground_map: GroundMapData) -> None:
    world = sampled_world("gusev", ground_map, Priors(), (0.0, 0.0), 7, np.random.default_rng(1))
    terrain = world.terrain()
    step = 0.05
    # imaged: |N|, |E| <= 5 m; keep a rock's reach (0.65 m) from the edge
    axis = np.arange(-4.2, 4.2, step)
    x, y = np.meshgrid(axis, axis, indexing="ij")
    on_nodes = np.round(x / step) * step, np.round(y / step) * step
    assert np.allclose(terrain.height_m(*on_nodes), world.ground.at(*on_nodes), rtol=0, atol=1e-9)
    # unimaged ground of Gusev's abundance (k = 0.07) has rocks standing on it
    axis = np.arange(8.0, 16.0, step)
    x, y = np.meshgrid(axis, axis, indexing="ij")
    on_nodes = np.round(x / step) * step, np.round(y / step) * step
    raised = terrain.height_m(*on_nodes) - world.ground.at(*on_nodes)
    assert np.max(raised) > 0.05
    assert np.min(raised) > -1e-9


def test_the_map_is_kept_per_process_by_its_digest(ground_map: GroundMapData) -> None:
    copy = GroundMapData(
        ground_map.north0_m,
        ground_map.east0_m,
        ground_map.cell_m,
        ground_map.height_m.copy(),
        ground_map.sigma_m.copy(),
        ground_map.albedo.copy(),
        ground_map.imaged.copy(),
    )
    assert map_surface(copy) is map_surface(ground_map)
    other = GroundMapData(
        copy.north0_m, copy.east0_m, copy.cell_m, copy.height_m + 0.1, copy.sigma_m,
        copy.albedo, copy.imaged,
    )  # fmt: skip
    assert map_surface(other) is not map_surface(ground_map)


def test_soil_drawn_around_the_site_nominal(ground_map: GroundMapData) -> None:
    frictions = [
        sampled_world(
            "gusev", ground_map, Priors(), (0.0, 0.0), 1, np.random.default_rng(s)
        ).soil.friction_angle_deg
        for s in range(40)
    ]
    assert abs(np.mean(frictions) - 35.0) < 1.0  # GUSEV_SOIL, 2 deg 1σ: mean within 3σ/√40
    assert 1.0 < np.std(frictions) < 3.0


def test_ground_grid_equals_at_on_its_nodes(ground_map: GroundMapData) -> None:
    """The ``GroundField`` contract, bit for bit (tiles agree on their shared edges), with the
    start's slope, on and off the map's edge, on both sites' relief."""
    from sim.rehearsal.world import StartSlope
    from sim.world.noise import grid_axes

    for site in ("gusev", "meridiani"):
        world = sampled_world(site, ground_map, Priors(), (0.0, 0.0), 3, np.random.default_rng(0))
        ground = world.ground.with_start_slope(StartSlope((1.0, 2.0), (0.05, -0.02)))
        for i0, j0 in ((0, 0), (-400, 160), (300, -500)):
            x, y = np.broadcast_arrays(*grid_axes(i0, j0, 41, 0.05))
            assert np.array_equal(ground.grid(i0, j0, 41, 0.05), ground.at(x, y))
