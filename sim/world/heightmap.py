"""Heightmap terrain: lazily generated, cached square tiles with bilinear height and slope.

The surface is a bilinear interpolation of elevation samples on a regular grid in the Site
frame (x North, y East, metres; elevations up). The grid is cut into square tiles that are
generated on first use from a deterministic *ground field* (``sim.world.noise.GroundField``: a
pure function of the seed and the global grid indices, so tile ``(i, j)`` never depends on
which tiles were built before) plus every rock that reaches into the tile (``sim.world.rocks``).
Tiles share their edge samples: both tiles compute the edge from the same global indices
with the same arithmetic, so the surface is continuous across tile edges, bit for bit.

Design numbers (approximate, chosen for the MER wheel and the Navcam):

- ``RESOLUTION_M = 0.05``: a MER wheel is 0.26 m across with a contact patch of a few cm, so
  5 cm resolves the wheel-scale relief and rocks from ~0.1 m up. Finer detail (what the
  Navcam resolves within a few metres) is carried by the albedo texture, not the geometry:
  halving the spacing would cost 4x the memory and build time.
- ``TILE_CELLS = 160`` (8 m tiles, 161 x 161 samples, 207 kB in float64): larger than the
  rover (1.6 m x 2.3 m) so a rover query touches at most four tiles, larger than the biggest
  rock so rocks spill only into the eight neighbours, small enough to build in a few ms.
- ``DEFAULT_CACHE_TILES = 128`` (26 MB, a 90 m x 90 m patch): least recently used tiles are
  dropped and rebuilt on demand; a single query needing more tiles at once grows the pool
  for its duration, then the pool shrinks back.

The ground fields are fractal value noise (``sim.world.noise``; Ebert et al., *Texturing and
Modeling*, ch. 2; Perlin 1985), evaluated on the tile grid with separable interpolation.
"""

from __future__ import annotations

import logging
import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.errors import InputError
from sim.world.noise import GroundField
from sim.world.terrain import Soil

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

RESOLUTION_M = 0.05  # grid spacing, see the module docstring
TILE_CELLS = 160  # cells per tile side: 8 m tiles at 5 cm
DEFAULT_CACHE_TILES = 128  # 128 x 161^2 x 8 B = 26 MB
MAX_COORD_M = 1.0e6  # queries beyond 1000 km of the Site origin are rejected


class AlbedoField(Protocol):
    """Reflectance texture (``sim.world.albedo.AlbedoTexture`` satisfies it)."""

    def __call__(self, x_m: FloatArray, y_m: FloatArray) -> FloatArray: ...


TileStamper = Callable[[FloatArray, int, int, float], None]
"""``stamp(heights, i0, j0, spacing_m)`` adds features (rocks) in place into the samples
``heights[a, b]`` at ``x = (i0 + a)·spacing_m``, ``y = (j0 + b)·spacing_m``."""


def as_coordinates(x_m: ArrayLike, y_m: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Broadcast query coordinates to float64 arrays; InputError if non-finite or too far."""
    x, y = np.broadcast_arrays(np.asarray(x_m, np.float64), np.asarray(y_m, np.float64))
    for name, arr in (("x_m", x), ("y_m", y)):
        # One reduction: max(|x|) is NaN if any x is NaN, and NaN <= bound is False.
        if arr.size and not np.abs(arr).max() <= MAX_COORD_M:
            raise InputError(name, f"coordinates must be finite and within {MAX_COORD_M:g} m")
    return x, y


class HeightmapTerrain:
    """A ``Terrain`` made of lazily built, cached heightmap tiles (see the module docstring).

    Tile ``(ti, tj)`` covers ``x in [ti·T, (ti+1)·T]``, ``y in [tj·T, (tj+1)·T]`` with
    ``T = tile_cells · resolution_m``; its samples are ``ground.grid`` on that square plus
    whatever ``stamp`` adds (rocks). ``height_m`` is the bilinear interpolant of the samples
    and ``gradient`` its exact derivative, so heights and normals agree everywhere.
    Thread-safe (one lock around the cache).
    """

    def __init__(
        self,
        name: str,
        soil: Soil,
        ground: GroundField,
        albedo: AlbedoField,
        stamp: TileStamper | None = None,
        resolution_m: float = RESOLUTION_M,
        tile_cells: int = TILE_CELLS,
        cache_tiles: int = DEFAULT_CACHE_TILES,
    ) -> None:
        if resolution_m <= 0.0 or tile_cells < 2 or cache_tiles < 1:
            raise ValueError("resolution_m > 0, tile_cells >= 2 and cache_tiles >= 1 required")
        self.name = name
        self.soil = soil
        self.ground = ground
        self._albedo = albedo
        self._stamp = stamp
        self.resolution_m = float(resolution_m)
        self.tile_cells = int(tile_cells)
        self._m = self.tile_cells + 1  # samples per tile side (edges shared)
        self._capacity = int(cache_tiles)
        self._pool = np.empty((cache_tiles, self._m, self._m))
        self._slot_of: OrderedDict[tuple[int, int], int] = OrderedDict()
        self._free = list(range(cache_tiles - 1, -1, -1))
        self._lock = threading.Lock()
        self.tiles_built = 0  # a counter for diagnostics and tests

    @property
    def texture(self) -> AlbedoField:
        """The reflectance texture ``albedo`` evaluates: a renderer can ask it for detail
        band-limited to its pixels (``sim.world.albedo.AlbedoTexture.evaluate``)."""
        return self._albedo

    @property
    def tile_size_m(self) -> float:
        return self.tile_cells * self.resolution_m

    def tile(self, ti: int, tj: int) -> FloatArray:
        """A copy of tile ``(ti, tj)``'s samples, shape ``(tile_cells+1,)*2``, ``[a, b]`` at
        ``x = (ti·tile_cells + a)·resolution_m``, ``y = (tj·tile_cells + b)·resolution_m``."""
        with self._lock:
            (slot,) = self._ensure([(int(ti), int(tj))])
            out: FloatArray = self._pool[slot].copy()
        return out

    def _build(self, ti: int, tj: int, out: FloatArray) -> None:
        i0, j0 = ti * self.tile_cells, tj * self.tile_cells
        out[...] = self.ground.grid(i0, j0, self._m, self.resolution_m)
        if self._stamp is not None:
            self._stamp(out, i0, j0, self.resolution_m)
        self.tiles_built += 1

    def _ensure(self, tiles: list[tuple[int, int]]) -> list[int]:
        """Make every tile resident (building missing ones) and return their pool slots."""
        if len(tiles) > self._pool.shape[0]:
            extra = len(tiles) - self._pool.shape[0]
            logging.getLogger(__name__).debug("growing tile pool by %d tiles", extra)
            start = self._pool.shape[0]
            self._pool = np.concatenate([self._pool, np.empty((extra, self._m, self._m))])
            self._free.extend(range(start, start + extra))
        for t in tiles:  # mark the resident ones most recently used so they are not evicted
            if t in self._slot_of:
                self._slot_of.move_to_end(t)
        slots = []
        for t in tiles:
            slot = self._slot_of.get(t)
            if slot is None:
                slot = self._free.pop() if self._free else self._slot_of.popitem(last=False)[1]
                try:
                    self._build(t[0], t[1], self._pool[slot])
                except BaseException:
                    self._free.append(slot)  # do not leak the slot of a failed build
                    raise
                self._slot_of[t] = slot
            slots.append(slot)
        return slots

    def _corners(
        self, x: FloatArray, y: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
        """Cell corner heights and in-cell fractions for flat query arrays."""
        gx = x / self.resolution_m
        gy = y / self.resolution_m
        fx = np.floor(gx)
        fy = np.floor(gy)
        u = gx - fx
        v = gy - fy
        gi = fx.astype(np.int64)
        gj = fy.astype(np.int64)
        ti = gi // self.tile_cells
        tj = gj // self.tile_cells
        local = (gi - ti * self.tile_cells) * self._m + (gj - tj * self.tile_cells)
        with self._lock:
            slot = self._slots(ti, tj)
            flat = self._pool.reshape(-1)
            idx = slot * (self._m * self._m) + local
            h00 = flat.take(idx)
            h10 = flat.take(idx + self._m)
            h01 = flat.take(idx + 1)
            h11 = flat.take(idx + self._m + 1)
            self._shrink()
        return h00, h10, h01, h11, u, v

    def _shrink(self) -> None:
        """After a query that grew the pool, keep only the most recently used tiles."""
        if self._pool.shape[0] <= self._capacity:
            return
        keep = list(self._slot_of.items())[-self._capacity :]
        self._pool = self._pool[[slot for _, slot in keep]]  # fancy indexing copies
        self._slot_of = OrderedDict((tile, i) for i, (tile, _) in enumerate(keep))
        self._free = list(range(self._capacity - 1, len(keep) - 1, -1))

    def _slots(self, ti: IntArray, tj: IntArray) -> IntArray:
        """Pool slot of each query point's tile (building tiles as needed)."""
        ti0, ti1, tj0, tj1 = int(ti.min()), int(ti.max()), int(tj.min()), int(tj.max())
        ni, nj = ti1 - ti0 + 1, tj1 - tj0 + 1
        if ni * nj == 1:
            (s,) = self._ensure([(ti0, tj0)])
            return np.full(ti.shape, s, dtype=np.int64)
        if ni * nj <= 65536:  # dense lookup table over the bounding box of tiles
            rel = (ti - ti0) * nj + (tj - tj0)
            present = np.zeros(ni * nj, dtype=bool)
            present[rel] = True
            keys = np.flatnonzero(present)
            tiles = [(ti0 + int(k) // nj, tj0 + int(k) % nj) for k in keys]
            lut = np.zeros(ni * nj, dtype=np.int64)
            lut[keys] = self._ensure(tiles)
            out: IntArray = lut[rel]
            return out
        pairs, inverse = np.unique(np.stack([ti, tj], axis=1), axis=0, return_inverse=True)
        slots = np.asarray(self._ensure([(int(a), int(b)) for a, b in pairs]), dtype=np.int64)
        out = slots[inverse.reshape(-1)]
        return out

    def height_and_gradient(
        self, x_m: ArrayLike, y_m: ArrayLike
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(h, dh/dx, dh/dy)`` of the bilinear surface (m, m/m), shapes of the broadcast."""
        x, y = as_coordinates(x_m, y_m)
        if x.size == 0:
            return np.zeros(x.shape), np.zeros(x.shape), np.zeros(x.shape)
        h00, h10, h01, h11, u, v = self._corners(x.reshape(-1), y.reshape(-1))
        dx = h10 - h00
        dy = h01 - h00
        twist = h11 - h10 - h01 + h00
        h = h00 + u * dx + v * (dy + u * twist)  # bilinear interpolation
        hx = (dx + v * twist) / self.resolution_m  # its exact partial derivatives
        hy = (dy + u * twist) / self.resolution_m
        return h.reshape(x.shape), hx.reshape(x.shape), hy.reshape(x.shape)

    def height_m(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        """Elevation (m, up) at Site North ``x_m`` and East ``y_m`` (metres); broadcasts."""
        x, y = as_coordinates(x_m, y_m)
        if x.size == 0:
            return np.zeros(x.shape)
        h00, h10, h01, h11, u, v = self._corners(x.reshape(-1), y.reshape(-1))
        h = h00 + u * (h10 - h00) + v * ((h01 - h00) + u * (h11 - h10 - h01 + h00))
        return h.reshape(x.shape)

    def gradient(self, x_m: ArrayLike, y_m: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """``(dh/dx, dh/dy)`` (m/m) of the bilinear surface: North and East slopes."""
        _, hx, hy = self.height_and_gradient(x_m, y_m)
        return hx, hy

    def albedo(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        """Reflectance in [0, 1] from the terrain's texture; broadcasts."""
        x, y = as_coordinates(x_m, y_m)
        return self._albedo(x, y)
