"""The ground's terrain map, cut down for the validation worker (``sequences.terrain_grid``).

The validator checks each drive's tilt on the rover's ground map (``sequences.terrain_check``;
the map: ``server.terrain``, the orbital DEM refined by the stereo pairs that came down). The
worker gets its context as plain data (``server.validation.pool``), once per upload, so the
map is made small here:

- **Where stereo has not measured, the orbital DEM smoothed**: the DEM's noise is 0.25 m,
  correlated over about a post (1 m; ``sim.world.orbital_map``, after Kirk et al. 2008). Set
  down on it, the rover's 1.4 m footprint would read that noise as tilt: a median of about
  11 deg and tails past 30 deg on the real sites' maps, on ground whose relief at a few metres
  is under 10 deg. The heights of the cells no stereo pair measured are therefore smoothed
  by a Gaussian of ``ORBITAL_SMOOTHING_M`` (3 m, as the pointing advisor's planning surface,
  ``server.terrain.advice_api``): the noise's slope drops to about a degree and the hills
  stay. Measured cells keep their heights.
- **Coarser cells**: ``GRID_CELL_M`` 0.5 m (block means of the map's 0.25 m cells; the
  stereo's σ averaged, a block measured when most of its cells are), enough for a plane
  through wheels 0.7 m and 1.2 m apart.
- **Cropped** to ``CROP_HALF_M`` (40 m) around the rover's reported position, in float32:
  about 160² cells, under 0.3 MB pickled.

The smoothed, coarser map is kept per map version (``GroundMapService.version``), so an upload
pays only the crop. Ground code: the map and the rover's reported pose, never the truth.
"""

from __future__ import annotations

import math
import threading
import weakref
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter

from sequences.terrain_grid import TerrainGrid
from server.terrain.ground_map import GroundMap
from server.terrain.service import GroundMapService

ORBITAL_SMOOTHING_M = 3.0  # the unmeasured cells' smoothing (module docstring)
GRID_CELL_M = 0.5  # the validator's cell
CROP_HALF_M = 40.0  # the crop's half-size around the rover


@dataclass(frozen=True, eq=False)
class _Coarse:
    north0_m: float
    east0_m: float
    cell_m: float
    height_m: NDArray[np.float32]
    sigma_m: NDArray[np.float32]
    imaged: NDArray[np.bool_]


_CACHE: weakref.WeakKeyDictionary[GroundMapService, tuple[int, _Coarse]] = (
    weakref.WeakKeyDictionary()
)
_CACHE_LOCK = threading.Lock()


def coarse_map(gmap: GroundMap, cell_m: float = GRID_CELL_M) -> _Coarse:
    """``gmap`` with its unmeasured cells smoothed and its cells merged to about ``cell_m``
    (module docstring)."""
    height = np.asarray(gmap.height_m, dtype=np.float64)
    imaged = np.asarray(gmap.imaged, dtype=bool)
    smooth = gaussian_filter(height, ORBITAL_SMOOTHING_M / gmap.cell_m, mode="nearest")
    height = np.where(imaged, height, smooth)
    f = max(1, round(cell_m / gmap.cell_m))
    ny, nx = (gmap.shape[0] // f) * f, (gmap.shape[1] // f) * f

    def blocks(a: NDArray[np.float64]) -> NDArray[np.float64]:
        out: NDArray[np.float64] = a[:ny, :nx].reshape(ny // f, f, nx // f, f).mean(axis=(1, 3))
        return out

    offset = 0.5 * (f - 1) * gmap.cell_m  # a block's centre from its first cell's
    return _Coarse(
        gmap.north0_m + offset,
        gmap.east0_m + offset,
        f * gmap.cell_m,
        blocks(height).astype(np.float32),
        blocks(np.asarray(gmap.sigma_m, dtype=np.float64)).astype(np.float32),
        blocks(imaged.astype(np.float64)) >= 0.5,
    )


def crop(
    coarse: _Coarse,
    centre_m: tuple[float, float],
    site_origin_m: tuple[float, float],
    stereo_pairs: int,
    half_m: float = CROP_HALF_M,
) -> TerrainGrid | None:
    """The ``TerrainGrid`` of ``coarse`` within ``half_m`` of ``centre_m`` (North, East,
    mission frame); ``None`` when the rover is off the map."""
    ny, nx = coarse.height_m.shape
    lo_i = max(0, math.ceil((centre_m[0] - half_m - coarse.north0_m) / coarse.cell_m))
    hi_i = min(ny - 1, math.floor((centre_m[0] + half_m - coarse.north0_m) / coarse.cell_m))
    lo_j = max(0, math.ceil((centre_m[1] - half_m - coarse.east0_m) / coarse.cell_m))
    hi_j = min(nx - 1, math.floor((centre_m[1] + half_m - coarse.east0_m) / coarse.cell_m))
    if hi_i - lo_i < 1 or hi_j - lo_j < 1:
        return None
    rows, cols = slice(lo_i, hi_i + 1), slice(lo_j, hi_j + 1)
    return TerrainGrid(
        coarse.north0_m + lo_i * coarse.cell_m,
        coarse.east0_m + lo_j * coarse.cell_m,
        coarse.cell_m,
        coarse.height_m[rows, cols].copy(),
        coarse.sigma_m[rows, cols].copy(),
        coarse.imaged[rows, cols].copy(),
        (float(site_origin_m[0]), float(site_origin_m[1])),
        stereo_pairs,
    )


def rover_terrain(
    service: GroundMapService, p_mission_m: tuple[float, float], p_s_m: tuple[float, float]
) -> TerrainGrid | None:
    """The validator's map from the rover's ground map ``service``, around the rover's
    reported position ``p_mission_m`` (North, East in the mission frame) whose Site
    coordinates are ``p_s_m`` (the same downlink's): the Site's origin is their difference."""
    version = service.version  # before the map: a newer map is never kept as older
    gmap = service.ground_map()  # cached per version by the service
    with _CACHE_LOCK:
        kept = _CACHE.get(service)
    if kept is None or kept[0] != version:
        kept = (version, coarse_map(gmap))
        with _CACHE_LOCK:
            _CACHE[service] = kept
    origin = (p_mission_m[0] - p_s_m[0], p_mission_m[1] - p_s_m[1])
    return crop(kept[1], p_mission_m, origin, version)
