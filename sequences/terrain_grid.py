"""The ground's terrain map as the validator takes it: a small grid of plain arrays.

The server crops the rover's ground map (``server.terrain``: the orbital DEM refined by the
Navcam stereo that came down) around the rover and hands it to the validation worker with the
rest of the ``ValidationContext`` (``server.validation.terrain``); the validator walks the
drives' nominal paths over it (``sequences.terrain_check``). ``sequences`` may not import
the server, so the map crosses as this frozen record, which pickles as a few arrays.

Frames (docs/CONVENTIONS.md): the mission frame, ``x`` North, ``y`` East, metres, heights
*up*. Cell ``(i, j)`` is centred at ``(north0_m + i cell_m, east0_m + j cell_m)``.
``site_origin_m`` is where the origin of the Site the context's pose is in
(``ValidationContext.site_index``) lies in the mission frame (North, East): the rover's
reported ``p_mission_est - p_s_est``, both of one downlink, so a Site point ``p_s`` lies at
``site_origin_m + p_s`` on the map (Sites are translations of the mission frame, both local
level).

>>> import numpy as np
>>> grid = TerrainGrid(0.0, 0.0, 1.0, np.array([[0.0, 1.0], [0.0, 1.0]]),
...                    np.full((2, 2), 0.3), np.zeros((2, 2), dtype=bool), (0.0, 0.0))
>>> grid.height_at(np.array([0.5]), np.array([0.25])).tolist()
[0.25]
>>> bool(np.isnan(grid.height_at(np.array([3.0]), np.array([0.0]))[0]))
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
MAX_CELLS = 1_000_000  # a grid larger than this is not a crop around the rover


@dataclass(frozen=True, eq=False)
class TerrainGrid:
    """A crop of the ground's map (module docstring). ``height_m`` (ny, nx) up and its 1σ
    ``sigma_m``; ``imaged`` the cells some stereo pair measured (elsewhere the orbital DEM
    alone); ``stereo_pairs`` how many pairs the ground had fused into it."""

    north0_m: float
    east0_m: float
    cell_m: float
    height_m: NDArray[np.floating]
    sigma_m: NDArray[np.floating]
    imaged: NDArray[np.bool_]
    site_origin_m: tuple[float, float]
    stereo_pairs: int = 0

    def __post_init__(self) -> None:
        for name in ("north0_m", "east0_m", "cell_m"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"{name}: must be a number, got {value!r}")
            if not math.isfinite(value):
                raise ValueError(f"{name}: must be finite, got {value!r}")
        if not self.cell_m > 0.0:
            raise ValueError(f"cell_m: must be positive, got {self.cell_m}")
        shape = np.shape(self.height_m)
        if len(shape) != 2 or min(shape) < 2 or shape[0] * shape[1] > MAX_CELLS:
            raise ValueError(f"height_m: must be a 2-D grid of 2 x 2 to {MAX_CELLS} cells, "
                             f"got {shape}")  # fmt: skip
        for name in ("sigma_m", "imaged"):
            if np.shape(getattr(self, name)) != shape:
                raise ValueError(f"{name}: must have height_m's shape {shape}")
        if not (np.all(np.isfinite(self.height_m)) and np.all(np.isfinite(self.sigma_m))):
            raise ValueError("height_m, sigma_m: must be finite")
        if np.any(np.asarray(self.sigma_m) < 0.0):
            raise ValueError("sigma_m: must be >= 0")
        origin = self.site_origin_m
        if len(origin) != 2 or not all(math.isfinite(float(v)) for v in origin):
            raise ValueError(f"site_origin_m: must be (North, East), finite, got {origin!r}")

    @property
    def shape(self) -> tuple[int, int]:
        ny, nx = np.shape(self.height_m)
        return int(ny), int(nx)

    def _cells(
        self, north_m: FloatArray, east_m: FloatArray
    ) -> tuple[NDArray[np.intp], NDArray[np.intp], FloatArray, FloatArray, NDArray[np.bool_]]:
        """The lower cell, the fractions, and which points lie on the grid."""
        i = (np.asarray(north_m, dtype=np.float64) - self.north0_m) / self.cell_m
        j = (np.asarray(east_m, dtype=np.float64) - self.east0_m) / self.cell_m
        ny, nx = self.shape
        inside = (i >= 0.0) & (i <= ny - 1) & (j >= 0.0) & (j <= nx - 1)  # False for NaN
        i = np.where(inside, i, 0.0).clip(0.0, ny - 1.000001)
        j = np.where(inside, j, 0.0).clip(0.0, nx - 1.000001)
        i0, j0 = i.astype(np.intp), j.astype(np.intp)  # floor: i, j >= 0
        return i0, j0, i - i0, j - j0, inside

    def height_at(self, north_m: FloatArray, east_m: FloatArray) -> FloatArray:
        """Bilinear height (m, up) at mission-frame points; NaN off the grid."""
        i0, j0, fi, fj, inside = self._cells(north_m, east_m)
        h = self.height_m  # float32 or float64: only the corners gathered are converted
        out = (1 - fi) * ((1 - fj) * h[i0, j0] + fj * h[i0, j0 + 1]) + fi * (
            (1 - fj) * h[i0 + 1, j0] + fj * h[i0 + 1, j0 + 1]
        )
        return np.where(inside, out, np.nan)

    def sigma_at(self, north_m: FloatArray, east_m: FloatArray) -> FloatArray:
        """The height 1σ (m) of the nearest cell; NaN off the grid."""
        i0, j0, fi, fj, inside = self._cells(north_m, east_m)
        out = self.sigma_m[i0 + np.rint(fi).astype(np.intp), j0 + np.rint(fj).astype(np.intp)]
        return np.where(inside, out.astype(np.float64), np.nan)

    def imaged_at(self, north_m: FloatArray, east_m: FloatArray) -> NDArray[np.bool_]:
        """Whether stereo measured the nearest cell (False off the grid)."""
        i0, j0, fi, fj, inside = self._cells(north_m, east_m)
        out = self.imaged[i0 + np.rint(fi).astype(np.intp), j0 + np.rint(fj).astype(np.intp)]
        return np.asarray(out, dtype=bool) & inside
