"""The sites' albedo texture evaluated by numba, for the Navcam renderer's millions of pixels.

``sim.world.albedo.AlbedoTexture.evaluate`` with a pixel footprint is the reference: value-noise
octaves and grain layers, each faded out below the footprint (see that module for the
model). Evaluated in numpy it makes ~25 passes over memory per layer; this kernel makes
one pass over the points with every layer fused, in parallel threads, about 5x faster.
It reads the texture's own lattice table, rotations, offsets and weights, so it draws the
same texture; the arithmetic is float64 throughout where the numpy version rounds the
in-cell fractions to float32, so values agree to ~1e-6 (tests/sim/sensors/test_navcam.py pins them).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from sim.sensors.navcam.trace import parallel_kernel
from sim.world.albedo import (
    _GRAIN_CORE,
    _GRAIN_MEAN,
    _GRAIN_STRIDE,
    _P,
    _R_MAX,
    _R_MIN,
    AlbedoTexture,
)

FloatArray = NDArray[np.float64]

_RIM_SCALE = 1.0 / (1.0 - _GRAIN_CORE**2)  # grain profile: (1 - d2) scaled to [0, 1] at the core


def band_limited_albedo(
    texture: AlbedoTexture, x_m: FloatArray, y_m: FloatArray, footprint_m: FloatArray
) -> FloatArray:
    """``texture.evaluate(x_m, y_m, footprint_m)`` (1-D arrays of one length) by numba."""
    style = texture.style
    n_oct = len(texture.cells_m)
    scales = np.array(
        [float(c) for c in texture.cells_m] + [g.cell_m for g in style.grains], dtype=np.float64
    )
    angles_cos = texture._cos[: scales.size]
    angles_sin = texture._sin[: scales.size]
    grains = style.grains
    out = np.empty(x_m.shape)
    _texture_kernel(
        np.ascontiguousarray(x_m, dtype=np.float64),
        np.ascontiguousarray(y_m, dtype=np.float64),
        np.ascontiguousarray(footprint_m, dtype=np.float64),
        texture._table,
        angles_cos / scales,
        angles_sin / scales,
        np.ascontiguousarray(texture._offsets[: scales.size, 0]),
        np.ascontiguousarray(texture._offsets[: scales.size, 1]),
        scales,
        style.contrast * np.asarray(texture._weights, dtype=np.float64),
        n_oct,
        np.array([g.probability for g in grains], dtype=np.float64),
        np.array([g.relative_contrast for g in grains], dtype=np.float64),
        np.array([g.probability * g.relative_contrast * _GRAIN_MEAN for g in grains]),
        style.mean,
        out,
    )
    return out


@parallel_kernel
def _texture_kernel(
    x: FloatArray,
    y: FloatArray,
    footprint: FloatArray,
    table: NDArray[np.float32],
    rot_a: FloatArray,
    rot_b: FloatArray,
    off_x: FloatArray,
    off_y: FloatArray,
    scales: FloatArray,
    octave_weight: FloatArray,
    n_oct: int,
    grain_probability: FloatArray,
    grain_contrast: FloatArray,
    grain_bias: FloatArray,
    mean: float,
    out: FloatArray,
) -> None:
    """Fused layers of ``AlbedoTexture.evaluate`` (sim.world.albedo): per point, each layer's
    lattice cell, its smoothstep value noise or grain, faded by the footprint."""
    mask = _P - 1
    row = _P + 1
    for n in numba.prange(x.size):
        fp = max(footprint[n], 1e-12)
        rel = 0.0
        for k in range(scales.size):
            fade = min(scales[k] / fp - 1.0, 1.0)  # 0 below the footprint, 1 above twice it
            if fade <= 0.0:
                continue
            gx = x[n] * rot_a[k] - y[n] * rot_b[k] + off_x[k]
            gy = x[n] * rot_b[k] + y[n] * rot_a[k] + off_y[k]
            fx = math.floor(gx)
            fy = math.floor(gy)
            u = gx - fx
            v = gy - fy
            idx = (fx & mask) * row + (fy & mask)
            if k < n_oct:
                su = u * u * (3.0 - 2.0 * u)
                sv = v * v * (3.0 - 2.0 * v)
                t00 = table[idx]
                r0 = t00 + su * (table[idx + row] - t00)
                t01 = table[idx + 1]
                r1 = t01 + su * (table[idx + row + 1] - t01)
                term = octave_weight[k] * (r0 + sv * (r1 - r0))
            else:
                g = k - n_oct
                radius = (table[idx + _GRAIN_STRIDE] + 1.0) * 0.5 * (_R_MAX - _R_MIN) + _R_MIN
                span = 1.0 - 2.0 * radius
                dx = u - (radius + span * (table[idx + 2 * _GRAIN_STRIDE] + 1.0) * 0.5)
                dy = v - (radius + span * (table[idx + 3 * _GRAIN_STRIDE] + 1.0) * 0.5)
                d2 = (dx * dx + dy * dy) / (radius * radius)
                amp = 0.0
                if (table[idx] + 1.0) * 0.5 < grain_probability[g]:
                    amp = (
                        0.6 + 0.8 * (table[idx + 4 * _GRAIN_STRIDE] + 1.0) * 0.5
                    ) * grain_contrast[g]
                f = min(max((1.0 - d2) * _RIM_SCALE, 0.0), 1.0)
                term = amp * f * f * (3.0 - 2.0 * f) - grain_bias[g]
            rel += term * fade
        out[n] = min(max(mean * (1.0 + rel), 0.0), 1.0)
