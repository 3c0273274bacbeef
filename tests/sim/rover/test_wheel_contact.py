"""The compiled passes of the rim search (``sim.rover.wheel_contact``) against the numpy
they replaced, on random wheels and random clearance profiles."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from sim.rover import wheel_contact as wc
from sim.rover.geometry import MER_GEOMETRY
from sim.rover.settle import rotation_s_b
from sim.world.sites import make_terrain

FloatArray = NDArray[np.float64]


def _random_wheels(rng: np.random.Generator, m: int) -> wc.Wheels:
    u = np.column_stack(
        [
            rng.uniform(-0.4, -0.2, m),
            rng.uniform(-0.3, 0.3, (m, 2)),
            rng.uniform(-0.4, 0.4, (m, 3)),
        ]
    )
    yaw = rng.uniform(-np.pi, np.pi, m)
    x, y = rng.uniform(-20.0, 20.0, (2, m))
    steer = rng.uniform(-0.5, 0.5, (m, 4))
    r_eff = MER_GEOMETRY.wheel_radius_m - rng.uniform(0.0, 0.02, (m, 6))
    return wc.wheels(MER_GEOMETRY, rotation_s_b(u[:, 1], u[:, 2], yaw), u, x, y, steer, r_eff)


def _rim_reference(
    terrain: wc.Terrain, w: wc.Wheels, theta: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """``_rim`` as it was written in numpy before its points were compiled."""
    c, s = np.cos(theta), np.sin(theta)
    pos, der = [], []
    for i in range(3):
        lo = (w.r * w.e_low[..., i])[..., None]
        fw = (w.r * w.e_fwd[..., i])[..., None]
        pos.append(w.centre[..., i, None] + lo * c + fw * s)
        der.append(fw * c - lo * s)
    h, hx, hy = wc.height_and_gradient(terrain, pos[0], pos[1])
    df = -der[2] - hx * der[0] - hy * der[1]
    return -pos[2] - h, df, np.stack(pos, axis=-1), wc.unit_normal(hx, hy)


@pytest.mark.parametrize("k", [1, 2, 36])
def test_rim_points_equal_the_numpy_reference(k: int) -> None:
    # Equal to the last bit where numba and numpy call the same sin and cos (they do on
    # the machines we know); 1e-12 m leaves room for a maths library that rounds otherwise.
    terrain = make_terrain("gusev", 2)
    rng = np.random.default_rng(11)
    w = _random_wheels(rng, 50)
    theta = rng.uniform(-wc.SCAN_HALF_RAD, wc.SCAN_HALF_RAD, (50, 6, k))
    got, want = wc._rim(terrain, w, theta), _rim_reference(terrain, w, theta)
    for a, b in zip(got, want, strict=True):
        assert a.shape == b.shape
        np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-12)
    f_only = wc._rim(terrain, w, theta, slope=False)[0]
    np.testing.assert_array_equal(f_only, got[0])


def _scan_reference(f: FloatArray, angles: FloatArray) -> tuple[FloatArray, ...]:
    """The rim check's scan as it was written in numpy (``deeper`` before compiling)."""
    j = np.argmin(f, axis=-1)
    best = np.take_along_axis(f, j[..., None], -1)[..., 0]
    centre = np.take_along_axis(angles, j[..., None], -1)[..., 0]
    rise_l = np.full(f.shape, np.inf)
    rise_r = np.full(f.shape, np.inf)
    with np.errstate(invalid="ignore"):  # inf - inf: NaN, as in the kernel
        rise_l[..., 1:] = f[..., :-1] - f[..., 1:]
        rise_r[..., :-1] = f[..., 1:] - f[..., :-1]
        local_min = (rise_l >= 0.0) & (rise_r >= 0.0)
        rise = np.maximum(
            np.where(np.isinf(rise_l), rise_r, rise_l), np.where(np.isinf(rise_r), rise_l, rise_r)
        )
        own = np.abs(wc.CHECK_OFFSETS_RAD) < 1.5 * wc.CHECK_NEAR_RAD
        bound = np.where(local_min & ~own, f - rise, np.inf)
    k = np.argmin(bound, axis=-1)
    return best, centre, k, np.take_along_axis(bound, k[..., None], -1)[..., 0]


def test_rim_scan_equals_the_numpy_reference() -> None:
    rng = np.random.default_rng(3)
    n = wc.CHECK_OFFSETS_RAD.size
    # Coarse values (many ties, flat runs), smooth ones, and NaN and infinities here and
    # there: argmin's first-minimum and first-NaN rules, np.maximum's NaN.
    f = np.round(rng.normal(0.0, 1.0, (400, 6, n)), 1)
    f[200:] = np.cumsum(rng.normal(0.0, 0.01, (200, 6, n)), axis=-1)
    special = rng.random(f.shape)
    f[special < 0.003] = np.nan
    f[(special > 0.003) & (special < 0.006)] = np.inf
    f[(special > 0.006) & (special < 0.008)] = -np.inf
    angles = rng.uniform(-1.5, 1.5, f.shape)
    best, centre = np.empty(f.shape[:2]), np.empty(f.shape[:2])
    k, bound = np.empty(f.shape[:2], dtype=np.int64), np.empty(f.shape[:2])
    wc._scan_rim(f, angles, wc._CHECK_OWN, best, centre, k, bound)
    for got, want in zip((best, centre, k, bound), _scan_reference(f, angles), strict=True):
        np.testing.assert_array_equal(got, want)
