"""Landmarks from an orbital map of the terrain, and their Navcam pixels (seed 004, eqs. 10-11).

An orbital image of resolution ``resolution_m`` (MRO CTX/MOC class: ~10 m, HiRISE: 0.25 m,
seed 004 Table 1) shows distinctive points; the rover matches its Navcam images to it.

- Landmarks: the site is cut into ``spacing_m`` cells; in each, the point whose albedo
  departs most from the cell's mean, among samples at the map's resolution (no finer than
  ``spacing_m / 4``), is the landmark. Its true position is that point on the terrain.
- The map's matching error: the map gives each landmark at its true position plus
  Gaussian error of ``resolution_m`` (1σ) on each axis (North, East and height). That is
  how seed 004 uses the resolution: "the accuracy heavily depends on the resolution".
  The error is drawn once per landmark: a landmark seen twice repeats its error.
- Pixels (eqs. 10-11): a level camera at the mast head, panned about body ``z`` so each
  matched landmark is near the image centre; ``u = f x_c/z_c``, ``v = f y_c/z_c`` relative
  to the principal point, plus white noise. The mast head sits at ``NAVCAM_OFFSET_B_M``
  (the camera bar of ``sim.navcam``'s rover model, approximate).
- Matching: each image pair uses two landmarks between ``min_range_m`` and ``max_range_m``
  whose bearings differ by 60-120° (two lines of sight that cross well), drawn at random.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimation.fusion.radio_models import R_cam_b
from sim.errors import InputError
from sim.heightmap import HeightmapTerrain
from sim.mars_frames import R_ll_mf, site_mf_m
from sim.terrain import Terrain

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

NAVCAM_OFFSET_B_M = (0.45, -0.30, -1.30)  # body axes (x fwd, y right, z down): mast head
NAVCAM_FOCAL_PX = 512.0 / math.tan(math.radians(22.5))  # 1024 px over 45° (MER Navcam)


@dataclass(frozen=True)
class LandmarkMap:
    """Landmarks in the Site frame (N, E, Down; m): truth and the map's version, (K, 3)."""

    true_s_m: FloatArray
    map_s_m: FloatArray
    resolution_m: float

    def map_mf_m(self, site_lat_rad: float, site_lon_east_rad: float) -> FloatArray:
        """The map's landmarks in Mars-fixed coordinates (m), (K, 3): what the rover stores.

        The Site frame is the LL frame of its origin, a point of the reference ellipsoid.
        """
        R = R_ll_mf(site_lat_rad, site_lon_east_rad)
        out: FloatArray = site_mf_m(site_lat_rad, site_lon_east_rad) + self.map_s_m @ R
        return out


def ground_height_m(terrain: Terrain, x_m: FloatArray, y_m: FloatArray) -> FloatArray:
    """Height (m) of the ground without rocks: what an orbital elevation model resolves,
    and where albedo landmarks lie. Analytic terrains have no rocks."""
    if isinstance(terrain, HeightmapTerrain):
        out: FloatArray = np.asarray(terrain.ground.at(x_m, y_m), dtype=np.float64)
    else:
        out = np.asarray(terrain.height_m(x_m, y_m), dtype=np.float64)
    return out


def build_landmark_map(
    terrain: Terrain,
    resolution_m: float,
    rng: np.random.Generator,
    extent_m: float = 100.0,
    spacing_m: float = 8.0,
) -> LandmarkMap:
    """One landmark per ``spacing_m`` cell over ``[-extent_m, extent_m]²`` of the Site frame."""
    if not (math.isfinite(resolution_m) and 0.0 < resolution_m <= 100.0):
        raise InputError("resolution_m", f"must be in (0, 100] m, got {resolution_m}")
    if not (math.isfinite(spacing_m) and 1.0 <= spacing_m <= 100.0):
        raise InputError("spacing_m", f"must be in [1, 100] m, got {spacing_m}")
    if not (math.isfinite(extent_m) and spacing_m <= extent_m <= 5000.0):
        raise InputError("extent_m", f"must be in [spacing_m, 5000] m, got {extent_m}")
    cells = int(2 * extent_m // spacing_m)
    k = max(1, min(4, int(spacing_m // resolution_m)))  # samples per cell side
    corner = -extent_m + spacing_m * np.arange(cells)
    offsets = (np.arange(k) + 0.5) * (spacing_m / k)
    x = (corner[:, None, None, None] + offsets[None, None, :, None]) * np.ones((1, cells, k, k))
    y = (corner[None, :, None, None] + offsets[None, None, None, :]) * np.ones((cells, 1, k, k))
    albedo = np.asarray(terrain.albedo(x, y), dtype=np.float64).reshape(cells, cells, k * k)
    score = np.abs(albedo - albedo.mean(axis=-1, keepdims=True))
    best = np.argmax(score, axis=-1)[..., None]
    xs = np.take_along_axis(x.reshape(cells, cells, k * k), best, -1).ravel()
    ys = np.take_along_axis(y.reshape(cells, cells, k * k), best, -1).ravel()
    down = -ground_height_m(terrain, xs, ys)
    true_s = np.stack([xs, ys, down], axis=-1)
    map_s = true_s + resolution_m * rng.standard_normal(true_s.shape)
    return LandmarkMap(true_s, map_s, float(resolution_m))


def choose_pair(
    p_s_m: FloatArray,
    yaw_rad: float,
    landmarks_s_m: FloatArray,
    rng: np.random.Generator,
    min_range_m: float = 8.0,
    max_range_m: float = 40.0,
) -> tuple[IntArray, FloatArray] | None:
    """Two landmarks to image from ``p_s_m`` and the mast pans (rad, right of body x, whole
    degrees as commanded) that centre them; None when no pair is in reach."""
    d = landmarks_s_m[:, :2] - p_s_m[:2]
    dist = np.hypot(d[:, 0], d[:, 1])
    near = np.flatnonzero((dist >= min_range_m) & (dist <= max_range_m))
    if near.size < 2:
        return None
    bearing = np.arctan2(d[near, 1], d[near, 0])
    first = int(rng.integers(near.size))
    sep = np.abs(np.angle(np.exp(1j * (bearing - bearing[first]))))
    good = np.flatnonzero((sep >= math.radians(60.0)) & (sep <= math.radians(120.0)))
    if good.size == 0:
        return None
    second = int(good[rng.integers(good.size)])
    chosen = near[[first, second]]
    pans = np.radians(np.round(np.degrees(bearing[[first, second]] - yaw_rad)))
    return chosen.astype(np.int64), pans


def navcam_pixels(
    p_s_m: FloatArray,
    R_s_b: FloatArray,
    pans_rad: FloatArray,
    targets_s_m: FloatArray,
    sigma_px: float,
    rng: np.random.Generator,
    focal_px: float = NAVCAM_FOCAL_PX,
) -> FloatArray:
    """Eqs. 10-11: measured ``(u, v)`` (n, 2) px of Site-frame points ``targets_s_m`` (n, 3)
    from a rover with body origin ``p_s_m`` and attitude ``R_s_b``, mast pans ``pans_rad``.

    The Site and LL frames differ by distance / Mars radius (1e-5 rad at 40 m), ignored.
    """
    if not (math.isfinite(sigma_px) and sigma_px >= 0.0):
        raise InputError("sigma_px", f"must be non-negative, got {sigma_px}")
    camera_s = p_s_m + R_s_b @ np.asarray(NAVCAM_OFFSET_B_M)
    out = np.empty((targets_s_m.shape[0], 2))
    for i, target in enumerate(targets_s_m):
        c = R_cam_b(float(pans_rad[i])) @ (R_s_b.T @ (target - camera_s))
        if c[2] <= 0.0:
            raise InputError("targets_s_m", f"landmark {i} is behind the camera")
        out[i] = focal_px * c[:2] / c[2]  # eq. 10
    noisy: FloatArray = out + sigma_px * rng.standard_normal(out.shape)  # eq. 11
    return noisy
