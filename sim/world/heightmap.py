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

A query is two compiled passes over its points (``sim.compiled``): one finds the tiles they
fall in, the other interpolates, with the arithmetic of the numpy it replaced (the settling
asks for millions of points per drive).

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

from sim.compiled import kernel
from sim.errors import InputError
from sim.world.noise import GroundField
from sim.world.terrain import Soil

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

RESOLUTION_M = 0.05  # grid spacing, see the module docstring
TILE_CELLS = 160  # cells per tile side: 8 m tiles at 5 cm
DEFAULT_CACHE_TILES = 128  # 128 x 161^2 x 8 B = 26 MB
MAX_COORD_M = 1.0e6  # queries beyond 1000 km of the Site origin are rejected
MAX_LUT_TILES = 65536  # a query's bounding box of tiles up to this size uses a lookup table


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

    def _shrink(self) -> None:
        """After a query that grew the pool, keep only the most recently used tiles."""
        if self._pool.shape[0] <= self._capacity:
            return
        keep = list(self._slot_of.items())[-self._capacity :]
        self._pool = self._pool[[slot for _, slot in keep]]  # fancy indexing copies
        self._slot_of = OrderedDict((tile, i) for i, (tile, _) in enumerate(keep))
        self._free = list(range(self._capacity - 1, len(keep) - 1, -1))

    def _interpolate(self, x_m: ArrayLike, y_m: ArrayLike, slopes: bool) -> FloatArray:
        """Bilinear height (and its slopes if ``slopes``) at the query points, (k, ...) with
        ``k`` 1 or 3 over ``(h, dh/dx, dh/dy)`` and the broadcast shape after it.

        One compiled pass finds the tiles the points fall in, the missing ones are built,
        and a second pass interpolates: the numpy form made some twenty passes over the
        points, and the rim checks of ``sim.rover.settle`` query hundreds of thousands.
        """
        x, y = np.broadcast_arrays(np.asarray(x_m, np.float64), np.asarray(y_m, np.float64))
        shape = x.shape
        out = np.empty((3 if slopes else 1, *shape))
        if x.size == 0:
            out[...] = 0.0
            return out
        xf, yf = np.ascontiguousarray(x).reshape(-1), np.ascontiguousarray(y).reshape(-1)
        box = np.empty(4, dtype=np.int64)
        bad = _tile_box(xf, yf, self.resolution_m, self.tile_cells, MAX_COORD_M, box)
        if bad:
            name = "x_m" if bad == 1 else "y_m"
            raise InputError(name, f"coordinates must be finite and within {MAX_COORD_M:g} m")
        ti0, ti1, tj0, tj1 = (int(b) for b in box)
        ni, nj = ti1 - ti0 + 1, tj1 - tj0 + 1
        flat = out.reshape(out.shape[0], -1)
        with self._lock:
            if ni * nj <= MAX_LUT_TILES:  # a lookup table over the bounding box of tiles
                present = np.full(ni * nj, ni * nj == 1)  # a single tile needs no marking
                if ni * nj > 1:
                    _mark_tiles(xf, yf, self.resolution_m, self.tile_cells, ti0, tj0, nj, present)
                keys = np.flatnonzero(present)
                lut = np.zeros(ni * nj, dtype=np.int64)
                lut[keys] = self._ensure([(ti0 + int(k) // nj, tj0 + int(k) % nj) for k in keys])
                per_point = False
            else:  # points spread over a huge area: a slot per point
                gi = np.floor(xf / self.resolution_m).astype(np.int64) // self.tile_cells
                gj = np.floor(yf / self.resolution_m).astype(np.int64) // self.tile_cells
                pairs, inverse = np.unique(np.stack([gi, gj], 1), axis=0, return_inverse=True)
                slots = self._ensure([(int(a), int(b)) for a, b in pairs])
                lut = np.asarray(slots, dtype=np.int64)[inverse.reshape(-1)]
                per_point = True
            _bilinear(
                xf,
                yf,
                self.resolution_m,
                self.tile_cells,
                self._pool.reshape(-1),
                lut,
                ti0,
                tj0,
                nj,
                per_point,
                flat,
            )
            self._shrink()
        return out

    def height_and_gradient(
        self, x_m: ArrayLike, y_m: ArrayLike
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(h, dh/dx, dh/dy)`` of the bilinear surface (m, m/m), shapes of the broadcast."""
        out = self._interpolate(x_m, y_m, slopes=True)
        return out[0, ...], out[1, ...], out[2, ...]

    def height_m(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        """Elevation (m, up) at Site North ``x_m`` and East ``y_m`` (metres); broadcasts."""
        out: FloatArray = self._interpolate(x_m, y_m, slopes=False)[0, ...]  # 0-d stays an array
        return out

    def gradient(self, x_m: ArrayLike, y_m: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """``(dh/dx, dh/dy)`` (m/m) of the bilinear surface: North and East slopes."""
        _, hx, hy = self.height_and_gradient(x_m, y_m)
        return hx, hy

    def albedo(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        """Reflectance in [0, 1] from the terrain's texture; broadcasts."""
        x, y = as_coordinates(x_m, y_m)
        return self._albedo(x, y)


@kernel
def _tile_of(coord_m: float, spacing_m: float, cells: int) -> int:
    """Tile index of a coordinate, ``floor(coord / spacing) // cells``. The second floor
    division is done in float64, exactly (the cell index is an integer below 2^53 and a
    nonzero remainder keeps the quotient at least ``1 / cells`` from an integer), because
    64-bit integer division is the slowest step of a height query."""
    return int(np.floor(np.floor(coord_m / spacing_m) / cells))


@kernel
def _tile_box(
    x: FloatArray, y: FloatArray, spacing_m: float, cells: int, bound_m: float, box: IntArray
) -> int:
    """Bounding box ``[ti0, ti1, tj0, tj1]`` of the points' tiles into ``box``; returns 1 (2)
    if an ``x`` (``y``) is not finite or beyond ``bound_m``, else 0."""
    for k in range(x.size):
        if not abs(x[k]) <= bound_m:  # NaN compares False
            return 1
    for k in range(y.size):
        if not abs(y[k]) <= bound_m:
            return 2
    ti0 = ti1 = _tile_of(x[0], spacing_m, cells)
    tj0 = tj1 = _tile_of(y[0], spacing_m, cells)
    for k in range(1, x.size):
        ti = _tile_of(x[k], spacing_m, cells)
        tj = _tile_of(y[k], spacing_m, cells)
        ti0, ti1 = min(ti0, ti), max(ti1, ti)
        tj0, tj1 = min(tj0, tj), max(tj1, tj)
    box[0], box[1], box[2], box[3] = ti0, ti1, tj0, tj1
    return 0


@kernel
def _mark_tiles(
    x: FloatArray,
    y: FloatArray,
    spacing_m: float,
    cells: int,
    ti0: int,
    tj0: int,
    nj: int,
    present: NDArray[np.bool_],
) -> None:
    """Mark the tiles the points fall in, ``present[(ti - ti0) nj + tj - tj0]``."""
    for k in range(x.size):
        ti = _tile_of(x[k], spacing_m, cells)
        tj = _tile_of(y[k], spacing_m, cells)
        present[(ti - ti0) * nj + (tj - tj0)] = True


@kernel
def _bilinear(
    x: FloatArray,
    y: FloatArray,
    spacing_m: float,
    cells: int,
    pool: FloatArray,
    lut: IntArray,
    ti0: int,
    tj0: int,
    nj: int,
    per_point: bool,
    out: FloatArray,
) -> None:
    """The bilinear surface over the tile samples in ``pool`` (flattened slots of
    ``(cells + 1)^2``): ``out[0]`` the height, ``out[1:3]`` (if present) its exact slopes.
    A point's slot is ``lut[k]`` if ``per_point``, else its tile's entry in the lookup
    table over the bounding box ``lut[(ti - ti0) nj + tj - tj0]``."""
    m = cells + 1
    slopes = out.shape[0] == 3
    for k in range(x.size):
        gx = x[k] / spacing_m
        gy = y[k] / spacing_m
        fx = np.floor(gx)
        fy = np.floor(gy)
        u = gx - fx
        v = gy - fy
        gi = int(fx)
        gj = int(fy)
        ti = int(np.floor(fx / cells))  # = gi // cells, see _tile_of
        tj = int(np.floor(fy / cells))
        slot = lut[k] if per_point else lut[(ti - ti0) * nj + (tj - tj0)]
        idx = slot * (m * m) + (gi - ti * cells) * m + (gj - tj * cells)
        h00 = pool[idx]
        h10 = pool[idx + m]
        h01 = pool[idx + 1]
        h11 = pool[idx + m + 1]
        dx = h10 - h00
        dy = h01 - h00
        twist = h11 - h10 - h01 + h00
        out[0, k] = h00 + u * dx + v * (dy + u * twist)  # bilinear interpolation
        if slopes:
            out[1, k] = (dx + v * twist) / spacing_m  # its exact partial derivatives
            out[2, k] = (dy + u * twist) / spacing_m
