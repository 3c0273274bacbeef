"""The orbital product (sim.world.orbital_map): the error model it states, against the
terrain it was made from, and its determinism."""

from __future__ import annotations

import numpy as np
import pytest

from sim.errors import InputError
from sim.world.orbital_map import (
    IMAGE_M_PX,
    POST_M,
    SMOOTHING_SIGMA_M,
    VERTICAL_SIGMA_M,
    OrbitalProduct,
    orbital_product,
)
from sim.world.sites import make_terrain


def _posts(product: OrbitalProduct) -> tuple[np.ndarray, ...]:
    ny, nx = product.height_m.shape
    n = product.north0_m + product.post_m * np.arange(ny)
    e = product.east0_m + product.post_m * np.arange(nx)
    return np.meshgrid(n, e, indexing="ij")


@pytest.mark.parametrize("site_name", ["gusev", "meridiani"])
def test_the_dem_errs_by_its_stated_precision_and_is_not_the_truth(site_name: str) -> None:
    product = orbital_product(site_name, 5, 0.0, 0.0, 30.0)
    assert product.post_m == POST_M == 1.0
    assert product.height_m.shape == (61, 61)
    gn, ge = _posts(product)
    truth = make_terrain(site_name, 5).height_m(gn, ge)
    err = product.height_m - truth
    # noise of the stated σ (3721 posts, correlated over ~3 posts: a loose band), no bias
    assert 0.8 * VERTICAL_SIGMA_M < float(np.std(err)) < 1.3 * VERTICAL_SIGMA_M
    assert abs(float(np.mean(err))) < 0.1
    assert not np.any(np.abs(err) < 1e-9)  # no post is the truth sampled exactly


def test_the_noise_is_correlated_over_the_matcher_window() -> None:
    """Neighbouring posts' errors correlate (the matching window), posts 5 m apart hardly."""
    product = orbital_product("meridiani", 2, 0.0, 0.0, 40.0)
    gn, ge = _posts(product)
    err = product.height_m - make_terrain("meridiani", 2).height_m(gn, ge)
    err = err - err.mean()

    def corr(lag: int) -> float:
        a, b = err[:, :-lag].ravel(), err[:, lag:].ravel()
        return float(np.corrcoef(a, b)[0, 1])

    # a unit Gaussian smoothing of white noise correlates lag k by exp(-k² / 4)
    assert corr(1) == pytest.approx(np.exp(-0.25), abs=0.1)
    assert abs(corr(5)) < 0.1


def test_no_rock_below_the_resolution_survives() -> None:
    """The DEM's relief over a square is the terrain's smoothed with the matcher's σ: its
    roughness between neighbouring posts, noise aside, is far below the terrain's."""
    product = orbital_product("gusev", 1, 0.0, 0.0, 20.0)
    assert product.smoothing_sigma_m == SMOOTHING_SIGMA_M
    terrain = make_terrain("gusev", 1)
    fine = np.arange(-15.0, 15.0, 0.05)
    gn, ge = np.meshgrid(fine, fine, indexing="ij")
    truth = terrain.height_m(gn, ge)
    # the truth's 5 cm relief (rocks, roughness) against the DEM's at the same points
    dem = product.height_at(gn, ge)
    step_truth = np.percentile(np.abs(np.diff(truth, axis=1)), 99.9)
    step_dem = np.percentile(np.abs(np.diff(dem, axis=1)), 99.9)
    assert step_dem < step_truth


def test_the_product_is_fixed_by_site_and_seed_and_overlaps_agree() -> None:
    a = orbital_product("meridiani", 7, 0.0, 0.0, 20.0)
    b = orbital_product("meridiani", 7, 6.0, -4.0, 15.0)
    c = orbital_product("meridiani", 8, 0.0, 0.0, 20.0)
    points_n, points_e = np.array([0.0, 3.5, -5.25]), np.array([0.0, -2.0, 1.5])
    np.testing.assert_allclose(a.height_at(points_n, points_e), b.height_at(points_n, points_e))
    np.testing.assert_allclose(a.albedo_at(points_n, points_e), b.albedo_at(points_n, points_e))
    assert not np.allclose(a.height_at(points_n, points_e), c.height_at(points_n, points_e))
    assert not a.height_m.flags.writeable


def test_the_orthoimage_is_the_albedo_blurred_at_its_pixel() -> None:
    product = orbital_product("gusev", 3, 0.0, 0.0, 10.0)
    assert product.image_m_px == IMAGE_M_PX
    assert product.albedo.shape == (81, 81)
    terrain = make_terrain("gusev", 3)
    n = product.image_north0_m + IMAGE_M_PX * np.arange(81)
    gn, ge = np.meshgrid(n, n, indexing="ij")
    sharp = terrain.albedo(gn, ge)
    assert abs(float(product.albedo.mean() - sharp.mean())) < 0.02
    assert float(np.std(product.albedo)) < float(np.std(sharp))  # band-limited and blurred
    assert np.corrcoef(product.albedo.ravel(), sharp.ravel())[0, 1] > 0.3


def test_bad_arguments_are_named() -> None:
    with pytest.raises(InputError, match="half_m"):
        orbital_product("gusev", 1, 0.0, 0.0, 1e4)
    with pytest.raises(InputError, match="centre_north_m"):
        orbital_product("gusev", 1, float("nan"), 0.0, 10.0)
    with pytest.raises(InputError, match="site"):
        orbital_product("olympus", 1, 0.0, 0.0, 10.0)
