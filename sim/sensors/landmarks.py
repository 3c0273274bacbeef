"""Landmarks from an orbital map of the terrain, and their Navcam pixels (Jiang, Li et al. 2014,
eqs. 10-11).

An orbital image of resolution ``resolution_m`` (MRO CTX/MOC class: ~10 m, HiRISE: 0.25 m,
Jiang, Li et al. 2014 Table 1) shows distinctive points; the rover matches its Navcam images to it.

- Landmarks: the site is cut into ``spacing_m`` cells; in each, the point whose albedo
  departs most from the cell's mean, among samples at the map's resolution (no finer than
  ``spacing_m / 4``), is the landmark. Its true position is that point on the terrain.
- The map's matching error: the map gives each landmark at its true position plus
  Gaussian error of ``resolution_m`` (1σ) on each axis (North, East and height). That is
  how Jiang, Li et al. 2014 uses the resolution: "the accuracy heavily depends on the resolution".
  The error is drawn once per landmark: a landmark seen twice repeats its error.
- Pixels (eqs. 10-11): a level camera at the mast head, panned about body ``z`` so each
  matched landmark is near the image centre; ``u = f x_c/z_c``, ``v = f y_c/z_c`` relative
  to the principal point, plus white noise. The mast head sits at ``NAVCAM_OFFSET_B_M``
  (the camera bar of ``sim.sensors.navcam.camera``'s rover model, approximate).
- Matching: each image pair uses two landmarks between ``min_range_m`` and ``max_range_m``
  whose bearings differ by 60-120° (two lines of sight that cross well), drawn at random.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimation.fusion.radio.models import R_cam_b
from sim.errors import InputError
from sim.world.heightmap import HeightmapTerrain
from sim.world.mars_frames import mf_from_site_m
from sim.world.terrain import Terrain

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

NAVCAM_OFFSET_B_M = (0.45, -0.30, -1.30)  # body axes (x fwd, y right, z down): mast head
NAVCAM_FOCAL_PX = 512.0 / math.tan(math.radians(22.5))  # 1024 px over 45° (MER Navcam)
# R = 1e-6 in focal-length units (Jiang, Li et al. 2014 sec. 5)
PIXEL_SIGMA_PX = 1.0e-3 * NAVCAM_FOCAL_PX


@dataclass(frozen=True)
class LandmarkMap:
    """Landmarks in the Site frame (N, E, Down; m): truth and the map's version, (K, 3)."""

    true_s_m: FloatArray
    map_s_m: FloatArray
    resolution_m: float

    def map_mf_m(self, site_lat_rad: float, site_lon_east_rad: float) -> FloatArray:
        """The map's landmarks in Mars-fixed coordinates (m), (K, 3): what the rover stores."""
        return mf_from_site_m(self.map_s_m, site_lat_rad, site_lon_east_rad)


def matching_geometry(resolution_m: float) -> tuple[float, float, float]:
    """``(spacing_m, min_range_m, max_range_m)`` for a map of ``resolution_m``: features it
    resolves are ~4 resolutions apart (at least 8 m: one per Navcam-sized patch), and
    matching one is worth it where its error subtends a modest angle, 5 to 20 resolutions
    away, and at least 8 to 20 m away, where Navcam sees the ground well.

    Why not farther: a landmark's line of sight fixes the rover to within its map error
    plus its distance times the attitude error (eqs. 10-11 use the onboard attitude), so
    nearer is better as long as pairs 60-120° apart remain (an 8-20 m annulus holds ~16
    landmarks 8 m apart). Jiang, Li et al. 2014's case 4 measured the attitude's share: the true
    attitude in the camera alone takes its error from 0.37 to 0.26 m (seeds 0-9); in eq. 1 alone,
    nothing.
    """
    return (
        max(8.0, 4.0 * resolution_m),
        max(8.0, 5.0 * resolution_m),
        max(20.0, 20.0 * resolution_m),
    )


MAX_MATCHING_RANGE_M = 100.0  # the farthest ``matching_band`` reaches for a fine map


def matching_band(resolution_m: float, position_sigma_m: float) -> tuple[float, float]:
    """``(min_range_m, max_range_m)`` of the landmarks to match for a map of ``resolution_m``
    when the position is known to ``position_sigma_m`` (1σ, horizontal): the band of
    ``matching_geometry``, pushed out to three sigmas (50 m at most) so that a line of sight
    stays near its linearisation from a poor estimate (landmarks nearer than the error flip
    the predicted bearings and the EKF diverges), the far edge twice the near."""
    _, near, far = matching_geometry(resolution_m)
    near = max(near, min(3.0 * position_sigma_m, 50.0))
    return near, min(max(far, 2.0 * near), max(MAX_MATCHING_RANGE_M, far))


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
    centre_m: tuple[float, float] = (0.0, 0.0),
) -> LandmarkMap:
    """One landmark per ``spacing_m`` cell over ``centre_m + [-extent_m, extent_m]²`` of the
    Site frame (North, East)."""
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
    x, y = x + centre_m[0], y + centre_m[1]
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


class LandmarkTiles:
    """A site's orbital landmark map for a rover that may drive anywhere: square tiles of
    ``tile_cells`` landmark cells, each built (``build_landmark_map``) the first time the
    rover comes within reach of it, from its own seed, so that a tile's landmarks and map
    errors are the same however often it is built. The built tiles are a cache, not part of
    a session's checkpoint."""

    def __init__(
        self,
        terrain: Terrain,
        resolution_m: float,
        seed: int,
        spacing_m: float = 8.0,
        tile_cells: int = 12,
    ) -> None:
        if isinstance(tile_cells, bool) or not isinstance(tile_cells, int) or tile_cells < 2:
            raise InputError("tile_cells", f"must be an integer of at least 2, got {tile_cells!r}")
        if not (math.isfinite(resolution_m) and 0.0 < resolution_m <= 100.0):
            raise InputError("resolution_m", f"must be in (0, 100] m, got {resolution_m}")
        if not (math.isfinite(spacing_m) and 1.0 <= spacing_m <= 100.0):
            raise InputError("spacing_m", f"must be in [1, 100] m, got {spacing_m}")
        self.terrain = terrain
        self.resolution_m = float(resolution_m)
        self.seed = int(seed)
        self.spacing_m = float(spacing_m)
        self.tile_m = self.spacing_m * tile_cells
        self._tiles: dict[tuple[int, int], LandmarkMap] = {}

    def around(self, p_s_m: FloatArray, reach_m: float) -> LandmarkMap:
        """The landmarks of every tile within ``reach_m`` of ``p_s_m`` (North, East)."""
        lo = np.floor((np.asarray(p_s_m[:2]) - reach_m) / self.tile_m).astype(int)
        hi = np.floor((np.asarray(p_s_m[:2]) + reach_m) / self.tile_m).astype(int)
        maps = [self._tile(i, j) for i in range(lo[0], hi[0] + 1) for j in range(lo[1], hi[1] + 1)]
        return LandmarkMap(
            np.concatenate([m.true_s_m for m in maps]),
            np.concatenate([m.map_s_m for m in maps]),
            self.resolution_m,
        )

    def _tile(self, i: int, j: int) -> LandmarkMap:
        if (i, j) not in self._tiles:
            half = 0.5 * self.tile_m
            self._tiles[(i, j)] = build_landmark_map(
                self.terrain,
                self.resolution_m,
                np.random.default_rng([self.seed, 7005, i + 2**20, j + 2**20]),
                extent_m=half,
                spacing_m=self.spacing_m,
                centre_m=((i + 0.5) * self.tile_m, (j + 0.5) * self.tile_m),
            )
        return self._tiles[(i, j)]


class OrbitalDem:
    """The site's orbital elevation model onboard: ground heights (m, up; no rocks, as
    ``ground_height_m``) on posts ``post_m`` apart (HiRISE stereo DEMs: ~1 m), read
    bilinearly. Built in square tiles of ``tile_posts`` posts the first time a height there
    is asked for; the tiles are a cache, not part of a session's checkpoint."""

    def __init__(self, terrain: Terrain, post_m: float = 1.0, tile_posts: int = 64) -> None:
        if not (math.isfinite(post_m) and 0.05 <= post_m <= 100.0):
            raise InputError("post_m", f"must be in [0.05, 100] m, got {post_m}")
        if isinstance(tile_posts, bool) or not isinstance(tile_posts, int) or tile_posts < 2:
            raise InputError("tile_posts", f"must be an integer of at least 2, got {tile_posts!r}")
        self.terrain = terrain
        self.post_m = float(post_m)
        self.tile_posts = tile_posts
        self._tiles: dict[tuple[int, int], FloatArray] = {}

    def height_m(self, north_m: float, east_m: float) -> float:
        """Ground height (m, up) at Site-frame ``(north_m, east_m)``, bilinear in the posts."""
        u, v = north_m / self.post_m, east_m / self.post_m
        i, j = math.floor(u), math.floor(v)
        fu, fv = u - i, v - j
        h00, h01 = self._post(i, j), self._post(i, j + 1)
        h10, h11 = self._post(i + 1, j), self._post(i + 1, j + 1)
        return (1 - fu) * ((1 - fv) * h00 + fv * h01) + fu * ((1 - fv) * h10 + fv * h11)

    def _post(self, i: int, j: int) -> float:
        n = self.tile_posts
        key = (i // n, j // n)
        tile = self._tiles.get(key)
        if tile is None:
            idx = np.arange(n, dtype=np.float64)
            north = (key[0] * n + idx[:, None]) * self.post_m * np.ones((1, n))
            east = (key[1] * n + idx[None, :]) * self.post_m * np.ones((n, 1))
            tile = ground_height_m(self.terrain, north, east)
            self._tiles[key] = tile
        return float(tile[i % n, j % n])
