"""A rover's ground map on the server: the orbital prior around its landing point, refined by
every Navcam pair that comes down (``server.terrain.fusion``, ``server.terrain.stereo``).

Ground code: it reads the orbital product the mapping team delivered
(``sim.world.orbital_map``) and the pairs and poses the rover sent, never the simulator's
truth. ``version`` counts the pairs fused; ``ground_map()`` is cached per version, so a reader
(the 3D view, the pointing advisor) can redraw only when it changes. Thread-safe.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from server.terrain.fusion import CELL_M, MapFusion, PoseSigma, prior_from_orbital
from server.terrain.ground_map import GroundMap
from server.terrain.stereo import SUPPORTED_WIDTHS, dense_points, window_px_for
from sim.world.orbital_map import MAX_HALF_M, orbital_product

FloatArray = NDArray[np.float64]

DEFAULT_HALF_M = 60.0  # the map's square around the landing point: 120 m, 481² cells


@dataclass(frozen=True)
class DownlinkedPair:
    """A Navcam pair as it reached the ground, with the pose the rover reported at capture.

    ``left_u8``, ``right_u8`` (width, width) rectified 8-bit images; ``mast_az_rad``,
    ``mast_el_rad`` the mast's pointing; ``p_mission_m`` (3,) the estimated body origin in the
    mission frame (N, E, Down; m) and ``q_b_ll`` [x, y, z, w] the estimated attitude (body in
    Local Level); ``position_sigma_m`` the onboard position 1σ (NaN: unknown, taken as 0).
    """

    left_u8: NDArray[np.uint8]
    right_u8: NDArray[np.uint8]
    width: int
    mast_az_rad: float
    mast_el_rad: float
    p_mission_m: FloatArray
    q_b_ll: FloatArray
    position_sigma_m: float = math.nan

    def __post_init__(self) -> None:
        if self.width not in SUPPORTED_WIDTHS:
            raise ValueError(f"width: must be one of {SUPPORTED_WIDTHS}, got {self.width!r}")
        q = np.asarray(self.q_b_ll, dtype=np.float64)
        if q.shape != (4,) or not np.all(np.isfinite(q)) or abs(np.linalg.norm(q) - 1.0) > 1e-6:
            raise ValueError(f"q_b_ll: must be a unit quaternion [x, y, z, w], got {self.q_b_ll!r}")
        sigma = self.position_sigma_m
        if not isinstance(sigma, int | float) or sigma < 0.0 or math.isinf(sigma):
            raise ValueError(f"position_sigma_m: must be finite and >= 0 or NaN, got {sigma!r}")


@dataclass(frozen=True)
class PairOutcome:
    """What a pair added: ``points`` kept, ``rejected`` pixels, ``cells`` measured, and the
    map's ``version`` after it."""

    points: int
    rejected: int
    cells: int
    version: int


class GroundMapService:
    """One rover's ground map (module docstring). ``site_name`` and ``terrain_seed`` name the
    orbital product of the site; ``landing_north_m``, ``landing_east_m`` where the mission's
    localisation puts the rover's start (the mission frame's origin) in that product's Site
    frame; ``half_m`` the map's half-size around it, ``cell_m`` its cell."""

    def __init__(
        self,
        site_name: str,
        terrain_seed: int,
        landing_north_m: float,
        landing_east_m: float,
        *,
        half_m: float = DEFAULT_HALF_M,
        cell_m: float = CELL_M,
    ) -> None:
        if not (isinstance(half_m, int | float) and 2.0 <= half_m <= MAX_HALF_M - 2.0):
            raise ValueError(f"half_m: must be in [2, {MAX_HALF_M - 2.0:g}] m, got {half_m!r}")
        if not (isinstance(cell_m, int | float) and 0.05 <= cell_m <= 2.0):
            raise ValueError(f"cell_m: must be in [0.05, 2] m, got {cell_m!r}")
        product = orbital_product(site_name, terrain_seed, landing_north_m, landing_east_m,
                                  half_m + 2.0)  # fmt: skip
        prior = prior_from_orbital(product, landing_north_m, landing_east_m, half_m, cell_m)
        self._fusion = MapFusion(prior)
        self._lock = threading.Lock()
        self._cached: GroundMap | None = None
        self._cached_version = -1

    @property
    def version(self) -> int:
        """The number of pairs fused so far (0: the orbital prior alone)."""
        return self._fusion.version

    @property
    def nearest_m(self) -> FloatArray:
        """Per cell, the horizontal distance of the nearest camera that measured it (inf:
        none), m: the range the cell was imaged from (a copy)."""
        with self._lock:
            return self._fusion.nearest_m.copy()

    def add(self, pair: DownlinkedPair) -> PairOutcome:
        """Fuse a downlinked pair into the map."""
        R_mission_b = Rotation.from_quat(pair.q_b_ll).inv().as_matrix()
        points = dense_points(
            pair.left_u8, pair.right_u8, pair.width, pair.mast_az_rad, pair.mast_el_rad,
            np.asarray(pair.p_mission_m, dtype=np.float64), R_mission_b,
        )  # fmt: skip
        sigma = 0.0 if math.isnan(pair.position_sigma_m) else float(pair.position_sigma_m)
        with self._lock:
            cells = self._fusion.add(points, PoseSigma(position_m=sigma), window_px_for(pair.width))
            version = self._fusion.version
        return PairOutcome(len(points.p_mission_m), points.n_rejected, cells, version)

    def add_pair(
        self,
        left_u8: ArrayLike,
        right_u8: ArrayLike,
        width: int,
        mast_az_rad: float,
        mast_el_rad: float,
        p_mission_m: ArrayLike,
        q_b_ll: ArrayLike,
        position_sigma_m: float = math.nan,
    ) -> PairOutcome:
        """``add`` with the pair's parts as arguments (``DownlinkedPair``)."""
        return self.add(
            DownlinkedPair(
                np.asarray(left_u8), np.asarray(right_u8), width, mast_az_rad, mast_el_rad,
                np.asarray(p_mission_m, dtype=np.float64), np.asarray(q_b_ll, dtype=np.float64),
                position_sigma_m,
            )
        )  # fmt: skip

    def ground_map(self) -> GroundMap:
        """The map now (cached per version; treat it as read-only)."""
        with self._lock:
            if self._cached is None or self._cached_version != self._fusion.version:
                self._cached = self._fusion.ground_map()
                self._cached_version = self._fusion.version
            return self._cached
