"""Deterministic lattice value noise: hashed lattice values, cubic B-spline octaves, fBm.

The sites' ground fields (``sim.world.sites``, tiled by ``sim.world.heightmap``) are built from
this noise, and the rock placement (``sim.world.rocks``) and the albedo texture
(``sim.world.albedo``) key
their random generators with ``derive_key``. Everything here is a pure function of a seed
and integer labels or lattice indices, so any region can be generated in any order with the
same values, bit for bit.

- ``derive_key`` and ``lattice_uniform`` hash integers with the 64-bit finaliser
  ``fmix64`` of MurmurHash3 (Appleby) into independent streams and into uniform lattice
  values in [-1, 1).
- ``FractalNoise`` is value noise (lattice values hashed from the seed and the integer
  lattice point, interpolated with a cubic B-spline; Ebert et al., *Texturing and
  Modeling*, ch. 2; Perlin 1985) summed over octaves (fractional Brownian motion). On a
  regular grid (``grid``, nodes from ``grid_axes``) the interpolation is separable, so an
  octave costs a few row and column gathers and weighted sums instead of per-point hashing.
- ``GroundField`` is the interface of a smooth elevation field that heightmap tiles are
  built from; ``FractalNoise`` satisfies it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

_MASK64 = (1 << 64) - 1
_K1 = np.uint64(0x9E3779B97F4A7C15)  # odd 64-bit constants (golden ratio, murmur3)
_K2 = np.uint64(0xC2B2AE3D27D4EB4F)
_M1 = np.uint64(0xFF51AFD7ED558CCD)  # murmur3 fmix64 multipliers
_M2 = np.uint64(0xC4CEB9FE1A85EC53)
_S33 = np.uint64(33)
_S11 = np.uint64(11)


def _fmix64_int(h: int) -> int:
    """Murmur3's 64-bit finaliser on a Python int (for deriving keys)."""
    h &= _MASK64
    h ^= h >> 33
    h = (h * 0xFF51AFD7ED558CCD) & _MASK64
    h ^= h >> 33
    h = (h * 0xC4CEB9FE1A85EC53) & _MASK64
    h ^= h >> 33
    return h


def derive_key(seed: int, *labels: int) -> int:
    """A 64-bit key for one independent random stream, from a seed and integer labels."""
    h = _fmix64_int(seed + 0x632BE59BD9B4E019)
    for label in labels:
        h = _fmix64_int(h ^ _fmix64_int(label + 0x9E3779B97F4A7C15))
    return h


def lattice_uniform(key: int, ix: IntArray, iy: IntArray) -> FloatArray:
    """Uniform deviates in [-1, 1) attached to integer lattice points ``(ix, iy)``.

    A pure function of ``(key, ix, iy)`` (murmur3 fmix64 of a mixed key), so any subset of
    the lattice can be generated in any order with the same values. Broadcasts.
    """
    with np.errstate(over="ignore"):
        h = (ix.astype(np.int64).view(np.uint64) * _K1) ^ (
            iy.astype(np.int64).view(np.uint64) * _K2
        )
        h ^= np.uint64(key)
        h ^= h >> _S33
        h *= _M1
        h ^= h >> _S33
        h *= _M2
        h ^= h >> _S33
    out: FloatArray = (h >> _S11).astype(np.float64) * (2.0 / 2.0**53) - 1.0
    return out


_TAPS = np.arange(-1, 3, dtype=np.int64)  # lattice points i-1 .. i+2 of a cubic B-spline


def _bspline_weights(t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Uniform cubic B-spline weights of lattice points ``i-1 .. i+2`` at fraction ``t``.

    They sum to one and make the field C2 (continuous curvature): unlike the linear or
    smoothstep interpolation of classic value noise, no slope plateaus at lattice points,
    so the axis-aligned lattice does not show as a blocky grain in the terrain.
    """
    t2 = t * t
    t3 = t2 * t
    s = 1.0 - t
    return (
        s * s * s / 6.0,
        (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0,
        (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
        t3 / 6.0,
    )


def _cell(
    g: FloatArray,
) -> tuple[IntArray, tuple[FloatArray, FloatArray, FloatArray, FloatArray]]:
    """Lattice cell index of lattice coordinates ``g`` and its four B-spline weights."""
    f = np.floor(g)
    return f.astype(np.int64), _bspline_weights(g - f)


def grid_axes(i0: int, j0: int, n: int, spacing_m: float) -> tuple[FloatArray, FloatArray]:
    """Coordinates (m) of grid nodes ``x = (i0 + a)·s``, ``y = (j0 + b)·s``, ``a, b < n``.

    Shapes ``(n, 1)`` and ``(1, n)``. The integer index is formed first, so every tile
    computes bit-identical coordinates for a shared node.
    """
    idx = np.arange(n, dtype=np.int64)
    x = ((i0 + idx) * spacing_m).astype(np.float64)[:, None]
    y = ((j0 + idx) * spacing_m).astype(np.float64)[None, :]
    return x, y


class GroundField(Protocol):
    """A smooth elevation field (m, up) defined everywhere, before rocks are added."""

    def at(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        """Elevation at arbitrary points (broadcasting arrays of Site x, y in metres)."""
        ...

    def grid(self, i0: int, j0: int, n: int, spacing_m: float) -> FloatArray:
        """Elevations on the grid ``x = (i0 + a) * spacing_m``, ``y = (j0 + b) * spacing_m``.

        Shape ``(n, n)`` indexed ``[a, b]``; must equal ``at`` on those points.
        """
        ...


class FractalNoise:
    """Sum of value-noise octaves: ``h = Σ_k A_k · v_k(x / c_k + o_k, y / c_k + p_k)``.

    ``v_k`` is the cubic B-spline interpolant of lattice values uniform in [-1, 1]
    (``lattice_uniform``), so ``|v_k| ≤ 1`` with a standard deviation of about 0.28.
    ``cells_m`` are the lattice spacings ``c_k`` (the feature size of each octave) and
    ``amplitudes_m`` the ``A_k``. Each octave draws its lattice and a random sub-cell
    offset ``(o_k, p_k)`` from ``derive_key(seed, stream, k)``, so octaves are independent
    and never share lattice lines.
    """

    def __init__(
        self, seed: int, stream: int, cells_m: Sequence[float], amplitudes_m: Sequence[float]
    ) -> None:
        if len(cells_m) != len(amplitudes_m) or not cells_m:
            raise ValueError("cells_m and amplitudes_m must be equally long and non-empty")
        if min(cells_m) <= 0.0:
            raise ValueError("cells_m must be positive")
        self.cells_m = tuple(float(c) for c in cells_m)
        self.amplitudes_m = tuple(float(a) for a in amplitudes_m)
        self._keys = tuple(derive_key(seed, stream, k) for k in range(len(cells_m)))
        offsets = [lattice_uniform(key, np.array([1, 2]), np.array([-7, -7])) for key in self._keys]
        self._offsets = tuple((0.5 * (o[0] + 1.0), 0.5 * (o[1] + 1.0)) for o in offsets)

    def _octaves(self) -> zip[tuple[float, float, int, tuple[float, float]]]:
        return zip(self.cells_m, self.amplitudes_m, self._keys, self._offsets, strict=True)

    def at(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        """Field value at arbitrary points (m); broadcasts. Equals ``grid`` on its nodes."""
        x, y = np.broadcast_arrays(np.asarray(x_m, np.float64), np.asarray(y_m, np.float64))
        out = np.zeros(x.shape)
        for c, amp, key, (ox, oy) in self._octaves():
            ix, wx = _cell(x / c + ox)
            iy, wy = _cell(y / c + oy)
            # All 16 lattice values in one hash call, shape (..., 4, 4) indexed [a, b].
            lat = lattice_uniform(
                key, (ix[..., None] + _TAPS)[..., :, None], (iy[..., None] + _TAPS)[..., None, :]
            )
            # Same operation order as grid(): along x first, then along y.
            rows = wx[0][..., None] * lat[..., 0, :]
            for a in range(1, 4):
                rows = rows + wx[a][..., None] * lat[..., a, :]
            acc = np.zeros(x.shape)
            for b in range(4):
                acc = acc + wy[b] * rows[..., b]
            out += amp * acc
        return out

    def grid(self, i0: int, j0: int, n: int, spacing_m: float) -> FloatArray:
        """Field on ``x = (i0 + a)·spacing_m``, ``y = (j0 + b)·spacing_m``, shape (n, n).

        Separable: per octave, interpolate the lattice along x (4 gathered rows), then
        along y (4 gathered columns). Each node's value depends only on its global indices,
        so neighbouring tiles agree exactly on shared nodes.
        """
        xg, yg = grid_axes(i0, j0, n, spacing_m)
        xs, ys = xg[:, 0], yg[0, :]
        out = np.zeros((n, n))
        for c, amp, key, (ox, oy) in self._octaves():
            ix, wx = _cell(xs / c + ox)
            iy, wy = _cell(ys / c + oy)
            lx = np.arange(ix[0] - 1, ix[-1] + 3, dtype=np.int64)
            ly = np.arange(iy[0] - 1, iy[-1] + 3, dtype=np.int64)
            lat = lattice_uniform(key, lx[:, None], ly[None, :])  # (Lx, Ly)
            ra = ix - 1 - lx[0]  # row of lattice point ix - 1
            rows = wx[0][:, None] * lat[ra]
            for a in range(1, 4):
                rows = rows + wx[a][:, None] * lat[ra + a]  # (n, Ly)
            cb = iy - 1 - ly[0]  # column of lattice point iy - 1
            acc = np.zeros((n, n))
            for b in range(4):
                acc = acc + wy[b][None, :] * rows[:, cb + b]
            out += amp * acc
        return out
