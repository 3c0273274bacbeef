"""The ground's terrain map (server.terrain): dense stereo on a rendered pair against the
terrain it was rendered from, the fusion's plane fits, alignment and σ against synthetic
points with known errors, and the per-rover service from the orbital prior to a fused pair.
The tests read the truth to score the ground code; the ground code itself never does
(tests/test_truth_layout.py)."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation.vo.stereo_rig import NAVCAM
from server.terrain.fusion import BODY_HEIGHT_M, MapFusion, PoseSigma, Prior, tied_prior
from server.terrain.service import DownlinkedPair, GroundMapService
from server.terrain.stereo import StereoPoints, dense_points
from sim.sensors.navcam.camera import NavcamPair, render_navcam_pair
from sim.world.orbital_map import orbital_product
from sim.world.sites import make_terrain

SITE, SEED = "gusev", 11
START = (4.0, -3.0)  # where the rover stands in the site, m
EL_RAD = math.radians(-35.0)


def _u8(dn: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(dn * (255.0 / 4095.0)), 0, 255).astype(np.uint8)


@cache
def _pair(width: int) -> tuple[NavcamPair, np.ndarray]:
    """A rendered pair from a level rover at START, and the mission frame's origin in the
    site (the body origin there)."""
    terrain = make_terrain(SITE, SEED)
    h0 = float(terrain.height_m(*START))
    p_s = np.array([START[0], START[1], -(h0 + BODY_HEIGHT_M)])
    q_s_b = Rotation.from_euler("z", 0.6).as_quat()
    el, az = math.radians(50.0), math.radians(140.0)
    sun = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), -math.sin(el)])
    pair = render_navcam_pair(terrain, p_s, q_s_b, sun, NAVCAM.at_resolution(width), 0.0, EL_RAD,
                              rng=np.random.default_rng(3))  # fmt: skip
    return pair, p_s


def _truth_up(north_m: np.ndarray, east_m: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """The truth's height (up) in the mission frame whose origin is ``origin`` (site)."""
    terrain = make_terrain(SITE, SEED)
    out: np.ndarray = np.asarray(terrain.height_m(north_m + origin[0], east_m + origin[1]))
    return np.asarray(out + float(origin[2]), dtype=np.float64)


def test_dense_stereo_puts_the_points_on_the_terrain_within_their_sigma() -> None:
    pair, origin = _pair(256)
    R = Rotation.from_quat(pair.q_s_b).as_matrix()
    pts = dense_points(_u8(pair.left), _u8(pair.right), 256, 0.0, EL_RAD, np.zeros(3), R)
    assert len(pts.p_mission_m) > 0.4 * 256 * 256  # most of the ground is matched
    assert len(pts.features_mission_m) > 50
    err = -pts.p_mission_m[:, 2] - _truth_up(pts.p_mission_m[:, 0], pts.p_mission_m[:, 1], origin)
    assert abs(float(np.median(err))) < 0.005  # no bias (SGBM alone was a third of a px short)
    z = np.abs(err) / pts.sigma_up_m
    assert 0.85 < float(np.mean(z <= 2.0)) < 0.995  # σ neither too small nor far too large


def _plane_points(rng: np.random.Generator, n: int, sigma: float, tilt: float) -> StereoPoints:
    """Points on ``h = 0.1 + tilt·north`` over [0, 4] x [-2, 2] m, height noise ``sigma``."""
    p = np.column_stack([rng.uniform(0.0, 4.0, n), rng.uniform(-2.0, 2.0, n), np.zeros(n)])
    h = 0.1 + tilt * p[:, 0] + sigma * rng.standard_normal(n)
    p[:, 2] = -h
    return StereoPoints(p, np.full(n, sigma), np.full(n, 100.0), np.array([-1.0, 0.0, -1.5]),
                        np.zeros((0, 3)), n, 0)  # fmt: skip


def _prior(height: float = 0.0) -> Prior:
    shape = (41, 41)  # 0.25 m cells over [-5, 5] m
    return Prior(-5.0, -5.0, 0.25, np.full(shape, height), np.full(shape, 0.5), np.full(shape, 0.2))


def test_fused_cells_recover_a_plane_with_honest_sigma() -> None:
    rng = np.random.default_rng(0)
    fusion = MapFusion(_prior())
    cells = fusion.add(_plane_points(rng, 60_000, 0.02, 0.1), PoseSigma(0.0, 0.0, 0.0), 1)
    assert cells > 200
    ground = fusion.ground_map()
    i, j = np.nonzero(ground.imaged)
    north = ground.north0_m + ground.cell_m * i
    err = ground.height_m[i, j] - (0.1 + 0.1 * north)
    assert abs(float(np.mean(err))) < 0.001
    z = np.abs(err) / ground.sigma_m[i, j]
    assert 0.9 < float(np.mean(z <= 2.0)) <= 1.0
    assert float(np.max(ground.sigma_m[i, j])) < 0.05  # far better than the prior's 0.5 m
    assert float(np.median(ground.sigma_m[i, j])) < 0.005
    assert not np.any(ground.imaged[:, :2])  # cells nobody imaged keep the prior's σ ...
    np.testing.assert_allclose(ground.sigma_m[~ground.imaged], 0.5, rtol=1e-3)
    # ... and its heights, tied by the median stereo - prior residual where far from them
    offset = float(np.median(ground.height_m[ground.imaged]))
    from scipy.ndimage import distance_transform_edt

    far = distance_transform_edt(~ground.imaged) * ground.cell_m > 4.0
    assert far.any()
    np.testing.assert_allclose(ground.height_m[far], offset, atol=2e-3)


def test_the_orbital_ground_meets_a_measured_patch_without_a_step() -> None:
    """A DEM 0.3 m off where the rover is: tied, the measured patch's edge has no step."""
    shape = (41, 41)
    prior_h = np.full(shape, 0.3)
    stereo_h = np.zeros(shape)
    imaged = np.zeros(shape, dtype=bool)
    imaged[15:26, 15:26] = True
    tied = tied_prior(prior_h, stereo_h, imaged, 0.25)
    assert abs(float(tied[0, 0])) < 1e-9  # the offset removed far away too
    assert float(np.max(np.abs(np.diff(tied, axis=0)))) < 1e-6  # no step anywhere
    rough = prior_h + 0.1 * np.random.default_rng(3).standard_normal(shape)
    tied = tied_prior(rough, stereo_h, imaged, 0.25)
    edge = np.abs(tied[15:26, 14] - 0.0)  # the orbital cells beside the patch
    assert float(np.mean(edge)) < float(np.mean(np.abs(rough[15:26, 14])))


def test_a_second_pair_is_aligned_onto_the_first() -> None:
    """A pair whose pose is 4 cm low (a drive's vertical drift) lands on the map made by
    the first pair, and the pose's σ it reported does not stay in the cells' σ."""
    rng = np.random.default_rng(1)
    fusion = MapFusion(_prior())
    fusion.add(_plane_points(rng, 40_000, 0.02, 0.0), PoseSigma(0.0, 0.0, 0.0), 1)
    second = _plane_points(rng, 40_000, 0.02, 0.0)
    second.p_mission_m[:, 2] += 0.04  # Down: 4 cm lower
    fusion.add(second, PoseSigma(0.05, 0.0, 0.0), 1)
    assert fusion.offsets_m[1] == pytest.approx(-0.04, abs=0.002)
    ground = fusion.ground_map()
    err = ground.height_m[ground.imaged] - 0.1
    assert float(np.percentile(np.abs(err), 95)) < 0.01
    assert float(np.median(ground.sigma_m[ground.imaged])) < 0.02


def test_a_mismatched_blob_in_a_cell_is_dropped() -> None:
    rng = np.random.default_rng(2)
    points = _plane_points(rng, 60_000, 0.01, 0.0)
    cell = (np.abs(points.p_mission_m[:, 0] - 2.0) < 0.1) & (
        np.abs(points.p_mission_m[:, 1]) < 0.05
    )
    cell &= rng.uniform(size=cell.shape) < 0.35
    points.p_mission_m[cell, 2] -= 0.5  # a third of one cell's points half a metre too high
    fusion = MapFusion(_prior())
    fusion.add(points, PoseSigma(0.0, 0.0, 0.0), 1)
    ground = fusion.ground_map()
    i, j = ground.cell_of(np.array(2.0), np.array(0.0))
    cell_ij = (round(float(i)), round(float(j)))
    assert ground.height_m[cell_ij] == pytest.approx(0.1, abs=0.01)


def test_the_service_refines_the_orbital_prior_with_a_pair() -> None:
    pair, origin = _pair(256)
    service = GroundMapService(SITE, SEED, START[0], START[1], half_m=12.0)
    prior = service.ground_map()
    assert service.version == 0 and not prior.imaged.any()
    assert np.all(np.isnan(prior.texture))
    # the prior: the orbital product tied at the landing point, σ the DEM's and the tie's
    product = orbital_product(SITE, SEED, START[0], START[1], 14.0)
    assert prior.height_at(np.array(3.0), np.array(2.0)) == pytest.approx(
        float(product.height_at(START[0] + 3.0, START[1] + 2.0))
        - float(product.height_at(*START)) - BODY_HEIGHT_M, abs=1e-9,
    )  # fmt: skip
    outcome = service.add_pair(_u8(pair.left), _u8(pair.right), 256, 0.0, EL_RAD, np.zeros(3),
                               Rotation.from_quat(pair.q_s_b).inv().as_quat(), 0.0)  # fmt: skip
    assert outcome.version == service.version == 1 and outcome.cells > 100
    ground = service.ground_map()
    assert ground is service.ground_map()  # cached per version
    near = ground.imaged & (service.nearest_m <= 5.0)
    assert np.count_nonzero(near) == outcome.cells - np.count_nonzero(ground.imaged & ~near)
    i, j = np.nonzero(near)
    truth = _truth_up(
        ground.north0_m + ground.cell_m * i, ground.east0_m + ground.cell_m * j, origin
    )
    err = ground.height_m[i, j] - truth
    assert float(np.percentile(np.abs(err), 95)) < 0.05
    assert float(np.mean(np.abs(err) <= 2.0 * ground.sigma_m[i, j])) > 0.85
    prior_err = prior.height_m[i, j] - truth
    assert float(np.sqrt(np.mean(err**2))) < 0.25 * float(np.sqrt(np.mean(prior_err**2)))
    assert np.all(np.isfinite(ground.texture[ground.imaged])) and np.nanmax(ground.texture) > 0
    assert np.all((ground.albedo >= 0.0) & (ground.albedo <= 1.0))


def test_bad_pairs_are_refused_by_name() -> None:
    left = np.zeros((256, 256), np.uint8)
    q = np.array([0.0, 0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="width"):
        DownlinkedPair(left, left, 300, 0.0, 0.0, np.zeros(3), q)
    with pytest.raises(ValueError, match="q_b_ll"):
        DownlinkedPair(left, left, 256, 0.0, 0.0, np.zeros(3), np.array([0.0, 0.0, 0.0, 2.0]))
    with pytest.raises(ValueError, match="position_sigma_m"):
        DownlinkedPair(left, left, 256, 0.0, 0.0, np.zeros(3), q, -1.0)
    with pytest.raises(ValueError, match="left_u8"):
        dense_points(left[:100], left, 256, 0.0, 0.0, np.zeros(3), np.eye(3))
    with pytest.raises(ValueError, match="mast_el_rad"):
        dense_points(left, left, 256, 0.0, math.nan, np.zeros(3), np.eye(3))
    with pytest.raises(ValueError, match="R_mission_b"):
        dense_points(left, left, 256, 0.0, 0.0, np.zeros(3), 2.0 * np.eye(3))
    with pytest.raises(ValueError, match="half_m"):
        GroundMapService(SITE, SEED, 0.0, 0.0, half_m=1.0)
