"""The ground's terrain map: what the ground knows of the heights and texture around a
rover, never the simulator's terrain.

A regular grid in the mission frame (the first Site: ``x`` North, ``y`` East, metres; heights
*up*, so a surface point is ``(x, y, -h)`` in mission coordinates). Cell ``(i, j)`` is
centred at ``(north0_m + i cell_m, east0_m + j cell_m)``. Every cell has a height, its 1σ
uncertainty, and what the ground knows of its texture:

- ``height_m``, ``sigma_m`` (ny, nx): the orbital DEM's where nothing better is known, the
  fused stereo heights where the rover has imaged the ground;
- ``albedo`` (ny, nx): the ground's estimate of the surface reflectance in [0, 1] (the
  orbital image's, or the rover's own images' where it has them);
- ``texture`` (ny, nx): the trackable-feature density the ground has measured there
  (features per m² of ground detected in the rover's images), NaN where no image covers
  the cell;
- ``imaged`` (ny, nx): cells some stereo pair has measured.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class GroundMap:
    """The ground's map (module docstring). Arrays are (ny, nx), row ``i`` along North."""

    north0_m: float
    east0_m: float
    cell_m: float
    height_m: FloatArray
    sigma_m: FloatArray
    albedo: FloatArray
    texture: FloatArray
    imaged: BoolArray

    def __post_init__(self) -> None:
        for name in ("north0_m", "east0_m", "cell_m"):
            value = getattr(self, name)
            if not isinstance(value, int | float) or not math.isfinite(value):
                raise ValueError(f"{name}: must be a finite number, got {value!r}")
        if not self.cell_m > 0.0:
            raise ValueError(f"cell_m: must be positive, got {self.cell_m}")
        shape = np.shape(self.height_m)
        if len(shape) != 2 or min(shape) < 2:
            raise ValueError(f"height_m: must be a 2-D grid of at least 2 x 2, got {shape}")
        for name in ("sigma_m", "albedo", "texture", "imaged"):
            if np.shape(getattr(self, name)) != shape:
                raise ValueError(f"{name}: must have height_m's shape {shape}")
        if not (np.all(np.isfinite(self.height_m)) and np.all(np.isfinite(self.sigma_m))):
            raise ValueError("height_m/sigma_m: must be finite")
        if np.any(np.asarray(self.sigma_m) <= 0.0):
            raise ValueError("sigma_m: must be positive")

    @property
    def shape(self) -> tuple[int, int]:
        ny, nx = np.shape(self.height_m)
        return int(ny), int(nx)

    def cell_of(self, north_m: FloatArray, east_m: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Fractional cell indices ``(i, j)`` of mission-frame points (may lie outside)."""
        i = (np.asarray(north_m, dtype=np.float64) - self.north0_m) / self.cell_m
        j = (np.asarray(east_m, dtype=np.float64) - self.east0_m) / self.cell_m
        return i, j

    def height_at(self, north_m: FloatArray, east_m: FloatArray) -> FloatArray:
        """Bilinear height (m, up) at mission-frame points, clamped to the grid's edge."""
        i, j = self.cell_of(north_m, east_m)
        ny, nx = self.shape
        i = np.clip(i, 0.0, ny - 1.000001)
        j = np.clip(j, 0.0, nx - 1.000001)
        i0, j0 = np.floor(i).astype(np.intp), np.floor(j).astype(np.intp)
        fi, fj = i - i0, j - j0
        h = np.asarray(self.height_m, dtype=np.float64)
        out: FloatArray = (1 - fi) * ((1 - fj) * h[i0, j0] + fj * h[i0, j0 + 1]) + fi * (
            (1 - fj) * h[i0 + 1, j0] + fj * h[i0 + 1, j0 + 1]
        )
        return out
