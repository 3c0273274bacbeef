"""The named sites (sim.world.sites): registry, input checks, and each site's terrain character."""

from __future__ import annotations

import numpy as np
import pytest

from sim.errors import InputError
from sim.world.heightmap import HeightmapTerrain
from sim.world.sites import (
    SITE_NAMES,
    ColumbiaHillsGround,
    RipplePlainsGround,
    make_terrain,
    site,
)
from sim.world.terrain import BEDROCK, GUSEV_SOIL, MERIDIANI_SAND, normal_up_s


def _slope_deg(h: np.ndarray, spacing_m: float) -> np.ndarray:
    hx = (h[2:, 1:-1] - h[:-2, 1:-1]) / (2 * spacing_m)
    hy = (h[1:-1, 2:] - h[1:-1, :-2]) / (2 * spacing_m)
    slope: np.ndarray = np.degrees(np.arctan(np.hypot(hx, hy)))
    return slope


def test_registry_names_places_and_soils() -> None:
    assert SITE_NAMES == ("gusev", "meridiani", "eq22", "flat")
    gusev, meridiani = site("gusev"), site("meridiani")
    assert (gusev.lat_deg, gusev.lon_east_deg) == (-14.57, 175.48)  # Spirit
    assert (meridiani.lat_deg, meridiani.lon_east_deg) == (-1.95, 354.47)  # Opportunity
    for name in ("eq22", "flat"):
        assert (site(name).lat_deg, site(name).lon_east_deg) == (-14.57, 175.48)
    assert gusev.soil == GUSEV_SOIL and meridiani.soil == MERIDIANI_SAND
    for name in SITE_NAMES:
        assert make_terrain(name, 0).soil == site(name).soil
        assert make_terrain(name, 0).name == name


def test_unknown_site_is_an_input_error_listing_the_choices() -> None:
    with pytest.raises(InputError) as err:
        make_terrain("utopia", 1)
    assert err.value.parameter == "site"
    assert "unknown site 'utopia'" in str(err.value)
    assert all(name in str(err.value) for name in SITE_NAMES)
    with pytest.raises(InputError):
        site("Gusev")  # names are exact


@pytest.mark.parametrize("seed", [-1, 1.5, "3", True, None, 2**63])
def test_bad_seed_is_an_input_error(seed: object) -> None:
    with pytest.raises(InputError) as err:
        make_terrain("gusev", seed)  # type: ignore[arg-type]
    assert err.value.parameter == "seed"


def test_numpy_integer_seed_is_accepted() -> None:
    a = make_terrain("meridiani", np.int64(5))  # type: ignore[arg-type]
    b = make_terrain("meridiani", 5)
    assert float(a.height_m(3.0, 4.0)) == float(b.height_m(3.0, 4.0))


@pytest.mark.parametrize("name", SITE_NAMES)
def test_every_site_fulfils_the_terrain_contract(name: str) -> None:
    t = make_terrain(name, 3)
    x, y = np.meshgrid(np.linspace(-3, 3, 7), np.linspace(-2, 2, 5), indexing="ij")
    h = t.height_m(x, y)
    hx, hy = t.gradient(x, y)
    a = t.albedo(x, y)
    assert h.shape == hx.shape == hy.shape == a.shape == (7, 5)
    assert np.all(np.isfinite(h)) and np.all((a >= 0) & (a <= 1))
    n = normal_up_s(t, x, y)
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-12)
    assert np.all(n[..., 2] < 0)  # up is -z in the Site frame (N, E, Down)


@pytest.mark.parametrize("seed", [0, 7, 2**40])
def test_ground_passes_through_the_site_origin(seed: int) -> None:
    for ground in (ColumbiaHillsGround(seed), RipplePlainsGround(seed)):
        assert float(ground.at(0.0, 0.0)) == 0.0
        assert abs(ground.grid(0, 0, 1, 0.05)[0, 0]) < 1e-12  # grid and at agree to rounding


@pytest.mark.parametrize("name", ["gusev", "meridiani"])
def test_terrain_is_deterministic_from_the_seed(name: str) -> None:
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-7.9, 7.9, size=(2, 5000))  # spans 4 tiles
    h1 = make_terrain(name, 99).height_m(x, y)
    fresh = make_terrain(name, 99)
    fresh.height_m(-x[::-1], y[::-1])  # build tiles in another order first
    np.testing.assert_array_equal(h1, fresh.height_m(x, y))
    np.testing.assert_array_equal(make_terrain(name, 99).albedo(x, y), fresh.albedo(x, y))
    other = make_terrain(name, 100).height_m(x, y)
    assert np.mean(h1 != other) > 0.99


def test_gusev_hills_reach_thirty_degrees_but_are_mostly_gentle() -> None:
    # Ground slopes at rover scale (1 m baseline) over 400 m x 400 m around the origin.
    ground = ColumbiaHillsGround(1)
    slope = _slope_deg(ground.grid(-200, -200, 401, 1.0), 1.0)
    assert slope.max() >= 25.0
    assert slope.max() < 45.0
    assert 3.0 < np.median(slope) < 10.0
    assert np.percentile(slope, 90) < 20.0
    # Near the origin (the landing plains) the ground is gentler than further out.
    near = slope[180:219, 180:219]
    assert np.median(near) < np.median(slope)
    assert near.max() < 20.0


def test_gusev_heightmap_follows_the_ground_between_rocks() -> None:
    t = make_terrain("gusev", 1)
    assert isinstance(t, HeightmapTerrain)
    x, y = np.meshgrid(np.arange(-6, 6, 0.05), np.arange(-6, 6, 0.05), indexing="ij")
    h = t.height_m(x, y)
    ground = t.ground.at(x, y)
    rock = h - ground
    assert np.all(rock >= -1e-9)  # rocks only add: max(ground, rock)
    assert 0.03 < np.mean(rock > 1e-3) < 0.1  # ~5.5 % of the ground under rocks for k = 0.07
    assert rock.max() > 0.1  # some decimetre rocks


def test_meridiani_is_flat_with_small_ripples() -> None:
    t = make_terrain("meridiani", 2)
    assert isinstance(t, HeightmapTerrain)
    x, y = np.meshgrid(np.arange(0, 20, 0.05), np.arange(0, 20, 0.05), indexing="ij")
    h = t.height_m(x, y)
    a = np.c_[x.ravel(), y.ravel(), np.ones(x.size)]
    residual = h.ravel() - a @ np.linalg.lstsq(a, h.ravel(), rcond=None)[0]
    assert 0.005 < residual.std() < 0.04  # rms relief: centimetres
    assert np.percentile(_slope_deg(h, 0.05), 99) < 10.0
    # Ripples: along the wind the profile's dominant wavelength is the crest spacing.
    ground = RipplePlainsGround(2)
    s = np.arange(0, 256, 0.05)
    c, si = np.cos(ground.wind_azimuth_rad), np.sin(ground.wind_azimuth_rad)
    profile = ground.at(s * c, s * si)
    detrended = profile - np.polyval(np.polyfit(s, profile, 3), s)
    power = np.abs(np.fft.rfft(detrended * np.hanning(s.size))) ** 2
    freq = np.fft.rfftfreq(s.size, 0.05)
    band = freq > 1 / 50.0
    peak_wavelength = 1 / freq[band][np.argmax(power[band])]
    assert 3.0 < peak_wavelength < 5.5
    # Crest-to-trough height: a few centimetres.
    assert 0.02 < np.percentile(detrended, 99) - np.percentile(detrended, 1) < 0.2


def test_eq22_is_balarams_surface() -> None:
    t = make_terrain("eq22", 0)
    x = np.array([0.0, 0.5, 0.5, 1.0, -0.7])
    y = np.array([0.0, 0.2, -0.2, 1.0, 0.4])
    # Equation 22 of Balaram 2000, written out independently of sim.world.terrain.
    bump = 0.25 * np.exp(-5 * (6.25 * (x - 0.5) ** 2 + 6.25 * (y - 0.2) ** 2))
    dip = 0.25 * np.exp(-4 * (6.25 * (x - 0.5) ** 2 + 6.25 * (y + 0.2) ** 2))
    expected = 0.2 * (bump - dip + 0.5 * np.sin(0.75 * x * y))
    np.testing.assert_allclose(t.height_m(x, y), expected, atol=1e-15)
    assert t.soil == BEDROCK


def test_flat_is_level() -> None:
    t = make_terrain("flat", 0)
    x = np.linspace(-100, 100, 11)
    assert np.all(t.height_m(x, x) == 0.0)
    hx, hy = t.gradient(x, -x)
    assert np.all(hx == 0.0) and np.all(hy == 0.0)


def test_meridiani_is_darker_and_less_contrasted_than_gusev() -> None:
    rng = np.random.default_rng(1)
    x, y = rng.uniform(-20, 20, size=(2, 100_000))
    gusev = make_terrain("gusev", 4).albedo(x, y)
    meridiani = make_terrain("meridiani", 4).albedo(x, y)
    assert meridiani.mean() < 0.75 * gusev.mean()
    assert meridiani.std() < 0.5 * gusev.std()
