"""Procedural surface reflectance: a continuous texture with detail from metres to ~1 mm.

The texture is what the Navcam renderer will paint on the terrain, so it must be defined at
any point (x, y) of the Site frame (North, East, metres), continuous, deterministic from the
seed, rich in detail at the scale a Navcam pixel sees on the ground (about 1-3 mm at 1.5-3 m
range: 0.82 mrad/pixel, docs/REFERENCES.md), and cheap: ~1 s for a 1024 x 1024 image.

Model (Ebert et al., *Texturing and Modeling*, ch. 2; fractal sums of value noise, Perlin
1985)::

    albedo = mean · (1 + contrast · t(x, y) + Σ_layers g_l(x, y))        clipped to [0, 1]
    t      = Σ_k w_k v_k(R_k [x, y] / c_k + o_k) / (σ_v · sqrt(Σ_k w_k²)),  w_k = (c_k/c_0)^β

``v_k`` are value-noise octaves with lattice spacing ``c_k`` halving from ``coarsest_m`` down
to ``finest_m`` or just below (4 m to 0.98 mm: 13 octaves), each rotated by the golden
angle from the previous one so no two octaves share lattice directions; ``σ_v`` is the
standard deviation of one octave (below), so ``t`` has unit variance and ``contrast`` is
the relative standard deviation of the albedo. Each grain
layer ``g_l`` scatters round grains (one per cell at most, jittered inside its cell of size
``cell_m``, with a smooth edge) brighter or darker than the soil; its area mean is
subtracted so ``mean`` stays the area-average albedo.

Speed: lattice values come from one seeded 1024 x 1024 table (4 MB) instead of a per-point
hash (about 3x faster in numpy). Each octave therefore repeats after 1024 cells, but octaves are
rotated and offset differently, so their sum does not repeat.

Anti-aliasing: ``evaluate(x, y, footprint_m)`` fades out octaves and grains smaller than
the footprint of a pixel on the ground (replacing them with their mean), so a renderer can
ask for a band-limited texture far from the camera.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.world.noise import derive_key

FloatArray = NDArray[np.float64]

_TABLE_BITS = 10
_P = 1 << _TABLE_BITS  # lattice table period in cells
_GOLDEN_ANGLE_RAD = np.pi * (3.0 - np.sqrt(5.0))
# Variance of one value-noise octave with lattice values uniform on [-1, 1] (variance 1/3):
# Var = (1/3) · (E[(1-s)² + s²])², s the smoothstep of a uniform fraction, and
# E[(1-s)² + s²] = 1 - 2·E[s] + 2·E[s²] = 1 - 1 + 2·13/35 = 26/35.
_SIGMA_V = float(np.sqrt((26.0 / 35.0) ** 2 / 3.0))
_GRAIN_CORE = 0.6  # grain profile is 1 inside 0.6 r and falls smoothly to 0 at r
_R_MIN, _R_MAX = 0.15, 0.35  # grain radius range, in cells
_GRAIN_STRIDE = 210_011  # table distance between a cell's independent grain uniforms
_F32 = np.float32


@dataclass(frozen=True)
class GrainLayer:
    """Round grains on a jittered grid: at most one per ``cell_m`` square cell.

    ``probability`` that a cell holds a grain; radius uniform in ``[0.15, 0.35]·cell_m``
    (small enough that the jittered centres do not line up on the grid);
    ``relative_contrast`` is the grain's albedo change relative to the mean (negative for
    dark grains), scaled per grain by a uniform factor in [0.6, 1.4].
    """

    cell_m: float
    probability: float
    relative_contrast: float


@dataclass(frozen=True)
class AlbedoStyle:
    """Per-site look: Lambert ``mean`` albedo, relative standard deviation ``contrast``,
    octaves from ``coarsest_m`` to ``finest_m``, spectral exponent ``beta`` (larger puts
    more of the contrast in the large patches), and grain layers."""

    mean: float
    contrast: float
    coarsest_m: float = 4.0
    finest_m: float = 0.001
    beta: float = 0.3
    grains: tuple[GrainLayer, ...] = ()


def _grain_profile(d2: NDArray[np.floating]) -> NDArray[np.floating]:
    """Grain brightness profile of ``d2`` = (distance / radius)²: 1 inside the core, a C1
    smoothstep down to 0 at the rim; keeps the dtype of ``d2``."""
    f = np.clip((1.0 - d2) * (1.0 / (1.0 - _GRAIN_CORE**2)), 0.0, 1.0).astype(d2.dtype)
    out: NDArray[np.floating] = f * f * (3.0 - 2.0 * f)
    return out


def _grain_mean_fraction() -> float:
    """``E[g] / relative_contrast`` per unit probability: mean of profile·r² over cells."""
    d = np.linspace(0.0, 1.0, 20001)
    disc = float(np.trapezoid(_grain_profile(d * d) * 2.0 * np.pi * d, d))  # ∫ profile dA / r²
    r2 = (_R_MAX**3 - _R_MIN**3) / (3.0 * (_R_MAX - _R_MIN))  # E[r²], r uniform, in cells²
    return disc * r2


_GRAIN_MEAN = _grain_mean_fraction()


def _lattice_table(rng: np.random.Generator) -> NDArray[np.float32]:
    """The value-noise lattice, periodic, padded so the grain layers' strided lookups
    never run off the end (drawn first from the texture's generator)."""
    table = rng.uniform(-1.0, 1.0, (_P + 1, _P + 1)).astype(np.float32)
    table[_P, :] = table[0, :]  # periodic wrap so index+1 never leaves the table
    table[:, _P] = table[:, 0]
    out: NDArray[np.float32] = np.concatenate(
        [table.reshape(-1), table.reshape(-1)[: 4 * _GRAIN_STRIDE]]
    )
    return out


class AlbedoTexture:
    """The reflectance texture of one terrain: ``texture(x_m, y_m)`` in [0, 1]; vectorised.

    Deterministic from ``seed``: the same seed gives the same values bit for bit.
    """

    def __init__(self, seed: int, style: AlbedoStyle) -> None:
        if not (0.0 < style.mean < 1.0 and style.contrast >= 0.0):
            raise ValueError("albedo mean must be in (0, 1) and contrast >= 0")
        if not 0.0 < style.finest_m <= style.coarsest_m:
            raise ValueError("need 0 < finest_m <= coarsest_m")
        self.style = style
        self._seed = seed
        rng = np.random.default_rng(derive_key(seed, 0xA1BED0))
        self._table = _lattice_table(rng)  # the rng's first draws; the offsets follow
        n_oct = int(np.ceil(np.log2(style.coarsest_m / style.finest_m) - 1e-9)) + 1  # last ≤ finest
        self.cells_m = style.coarsest_m * 0.5 ** np.arange(n_oct)
        w = (self.cells_m / style.coarsest_m) ** style.beta
        self._weights = w / (_SIGMA_V * np.sqrt(np.sum(w * w)))
        angles = _GOLDEN_ANGLE_RAD * np.arange(n_oct + len(style.grains))
        self._cos = np.cos(angles)
        self._sin = np.sin(angles)
        self._offsets = rng.uniform(0.0, _P, (n_oct + len(style.grains), 2))

    def __call__(self, x_m: FloatArray, y_m: FloatArray) -> FloatArray:
        return self.evaluate(x_m, y_m)

    def _lattice(
        self, k: int, x: FloatArray, y: FloatArray, cell: float
    ) -> tuple[NDArray[np.int64], NDArray[np.float32], NDArray[np.float32]]:
        """Table index of the cell corner and in-cell fractions in layer ``k``'s lattice.

        Positions are rotated and scaled in float64 (millimetre cells at kilometres need
        it); the fractions are then float32, plenty for interpolation and twice as fast.
        """
        a = self._cos[k] / cell
        b = self._sin[k] / cell
        gx = x * a
        gx -= y * b
        gx += self._offsets[k, 0]
        gy = x * b
        gy += y * a
        gy += self._offsets[k, 1]
        fx = np.floor(gx)
        fy = np.floor(gy)
        gx -= fx
        gy -= fy
        idx = fx.astype(np.int64)
        idx &= _P - 1
        idx *= _P + 1
        iy = fy.astype(np.int64)
        iy &= _P - 1
        idx += iy
        return idx, gx.astype(_F32), gy.astype(_F32)

    def _octave(self, k: int, x: FloatArray, y: FloatArray) -> NDArray[np.float32]:
        """Value noise octave ``k`` in [-1, 1] (float32), smoothstep-interpolated."""
        idx, u, v = self._lattice(k, x, y, float(self.cells_m[k]))
        u = u * u * (_F32(3.0) - _F32(2.0) * u)
        v = v * v * (_F32(3.0) - _F32(2.0) * v)
        t = self._table
        a = t.take(idx)
        r0 = t.take(idx + (_P + 1))
        r0 -= a
        r0 *= u
        r0 += a
        a = t.take(idx + 1)
        r1 = t.take(idx + (_P + 2))
        r1 -= a
        r1 *= u
        r1 += a
        r1 -= r0
        r1 *= v
        r1 += r0
        return r1

    def _grains(self, layer_index: int, x: FloatArray, y: FloatArray) -> NDArray[np.floating]:
        """Zero-mean grain layer ``layer_index``, relative to the mean albedo."""
        g = self.style.grains[layer_index]
        idx, u, v = self._lattice(len(self.cells_m) + layer_index, x, y, g.cell_m)
        t = self._table
        half = _F32(0.5)

        def uniform(j: int) -> NDArray[np.float32]:
            """The cell's j-th independent uniform on [0, 1), from a distant table entry."""
            w = t.take(idx + j * _GRAIN_STRIDE)
            w += _F32(1.0)
            w *= half
            return w

        radius = uniform(1)
        radius *= _F32(_R_MAX - _R_MIN)
        radius += _F32(_R_MIN)  # in cells
        span = _F32(1.0) - _F32(2.0) * radius  # grain inside its cell: no neighbour search
        dx = u - (radius + span * uniform(2))
        dy = v - (radius + span * uniform(3))
        d2 = (dx * dx + dy * dy) / (radius * radius)
        amp = np.where(uniform(0) < g.probability, _F32(0.6) + _F32(0.8) * uniform(4), _F32(0))
        amp *= _F32(g.relative_contrast)
        out: NDArray[np.floating] = amp * _grain_profile(d2)
        out -= _F32(g.probability * g.relative_contrast * _GRAIN_MEAN)
        return out

    def evaluate(
        self, x_m: ArrayLike, y_m: ArrayLike, footprint_m: ArrayLike | None = None
    ) -> FloatArray:
        """Albedo in [0, 1] at Site-frame points (m); broadcasts ``x_m``, ``y_m``.

        ``footprint_m`` (optional, broadcastable): the ground size of a pixel; octaves and
        grains smaller than it fade to their mean (fully gone below 1x, full above 2x).
        """
        x, y = np.broadcast_arrays(np.asarray(x_m, np.float64), np.asarray(y_m, np.float64))
        shape = x.shape
        x = x.reshape(-1)
        y = y.reshape(-1)
        fp = None
        if footprint_m is not None:
            fp = np.broadcast_to(np.asarray(footprint_m, np.float64), shape).reshape(-1)
        rel = np.zeros(x.shape)  # albedo change relative to the mean
        n_oct = len(self.cells_m)
        scales = [float(c) for c in self.cells_m] + [g.cell_m for g in self.style.grains]
        for k, scale in enumerate(scales):
            fade: FloatArray | None = None
            sel: NDArray[np.intp] | None = None  # points where this layer is not faded out
            if fp is not None:
                fade = np.clip(scale / np.maximum(fp, 1e-12) - 1.0, 0.0, 1.0)
                sel = np.flatnonzero(fade > 0.0)
                if sel.size == 0:
                    continue
                if sel.size == x.size:
                    sel = None
                else:
                    fade = fade[sel]
            xs, ys = (x, y) if sel is None else (x[sel], y[sel])
            if k < n_oct:
                term = (self.style.contrast * self._weights[k]) * self._octave(k, xs, ys)
            else:
                term = self._grains(k - n_oct, xs, ys)
            if fade is not None:
                term = term * fade
            if sel is None:
                rel += term
            else:
                rel[sel] += term
        out = np.clip(self.style.mean * (1.0 + rel), 0.0, 1.0)
        return out.reshape(shape)
