"""The compiled passes of the settling against the numpy they replaced, on random inputs:
the suspension's kinematics (``sim.rover.geometry``) and the rim search
(``sim.rover.wheel_contact``), to the last bit (and the sign of zero)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from sim.rover import wheel_contact as wc
from sim.rover.geometry import MER_GEOMETRY, STEERED_INDEX, RoverGeometry, wheel_kinematics
from sim.rover.settle import rotation_s_b
from sim.world.sites import make_terrain
from sim.world.terrain import Terrain

FloatArray = NDArray[np.float64]


def _kinematics_reference(
    geometry: RoverGeometry, rocker: FloatArray, bogie: FloatArray, steer: FloatArray
) -> tuple[FloatArray, ...]:
    """``wheel_kinematics`` as it was written in numpy before it was compiled."""
    lead = np.broadcast_shapes(rocker.shape, bogie.shape[:-1])
    rocker = np.broadcast_to(rocker, lead)
    bogie = np.broadcast_to(bogie, (*lead, 2))
    p, f_off, b_off, m_off, r_off = geometry._offsets()

    def rot_xz(angle: FloatArray, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        c, s = np.cos(angle), np.sin(angle)
        return c * v[0] + s * v[1], -s * v[0] + c * v[1]

    def gen_y(v: FloatArray) -> FloatArray:
        out = np.zeros_like(v)
        out[..., 0] = v[..., 2]
        out[..., 2] = -v[..., 0]
        return out

    centre = np.empty((*lead, 6, 3))
    link = np.empty((*lead, 6))
    dcentre = np.zeros((*lead, 6, 3, 3))
    half = 0.5 * geometry.track_m
    for side, (rock_sign, idx) in enumerate(((1.0, (0, 1, 2)), (-1.0, (3, 4, 5)))):
        rho = rock_sign * rocker
        beta = bogie[..., side]
        fx, fz = rot_xz(rho, f_off)
        bx, bz = rot_xz(rho, b_off)
        mx, mz = rot_xz(rho + beta, m_off)
        rx, rz = rot_xz(rho + beta, r_off)
        y = -half if side == 0 else half
        i_f, i_m, i_r = idx
        centre[..., i_f, :] = np.stack([p[0] + fx, np.full(lead, y), p[1] + fz], axis=-1)
        centre[..., i_m, :] = np.stack([p[0] + bx + mx, np.full(lead, y), p[1] + bz + mz], -1)
        centre[..., i_r, :] = np.stack([p[0] + bx + rx, np.full(lead, y), p[1] + bz + rz], -1)
        link[..., i_f] = rho
        link[..., i_m] = rho + beta
        link[..., i_r] = rho + beta
        pivot = np.array([p[0], 0.0, p[1]])
        bogie_pivot = np.stack([p[0] + bx, np.zeros(lead), p[1] + bz], axis=-1)
        for i in idx:
            arm = centre[..., i, :].copy()
            arm[..., 1] = 0.0
            dcentre[..., i, :, 0] = rock_sign * gen_y(arm - pivot)
            if i != i_f:
                dcentre[..., i, :, 1 + side] = gen_y(arm - bogie_pivot)
    steer = np.broadcast_to(steer, (*lead, 4))
    sigma = np.zeros((*lead, 6))
    sigma[..., list(STEERED_INDEX)] = steer
    ax_x, ax_z = rot_xz(link, np.stack([-np.sin(sigma), np.zeros_like(sigma)]))
    axle = np.stack([ax_x, np.cos(sigma), ax_z], axis=-1)
    daxle = np.zeros((*lead, 6, 3, 3))
    g_axle = gen_y(axle)
    for side, (rock_sign, idx) in enumerate(((1.0, (0, 1, 2)), (-1.0, (3, 4, 5)))):
        for i in idx:
            daxle[..., i, :, 0] = rock_sign * g_axle[..., i, :]
            if i != idx[0]:
                daxle[..., i, :, 1 + side] = g_axle[..., i, :]
    return centre, axle, link, dcentre, daxle


@pytest.mark.parametrize("lead", [(), (7,), (3, 5), (0,)])
def test_kinematics_equal_the_numpy_reference(lead: tuple[int, ...]) -> None:
    rng = np.random.default_rng(2)
    rocker = rng.uniform(-1.0, 1.0, lead)
    bogie = rng.uniform(-1.5, 1.5, (*lead, 2))
    steer = np.where(rng.random((*lead, 4)) < 0.3, 0.0, rng.uniform(-1.6, 1.6, (*lead, 4)))
    geometry = RoverGeometry(track_m=1.1, bogie_pivot_z_m=0.03)
    for s in (steer, np.zeros(4)):
        got = wheel_kinematics(geometry, rocker, bogie, s)
        want = _kinematics_reference(geometry, rocker, bogie, s)
        for name, value in zip(
            ("centre_b", "axle_b", "link_rad", "dcentre_dq", "daxle_dq"), want, strict=True
        ):
            np.testing.assert_array_equal(getattr(got, name), value, err_msg=name)
            np.testing.assert_array_equal(np.signbit(getattr(got, name)), np.signbit(value))


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
    terrain: Terrain, w: wc.Wheels, theta: FloatArray
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


def _contact_reference(
    terrain: Terrain, w: wc.Wheels, lo: FloatArray, hi: FloatArray
) -> tuple[FloatArray, ...]:
    """``contact`` as it was written in numpy before its per-wheel logic was compiled."""

    def tangent_meet(
        t0: FloatArray,
        f0: FloatArray,
        d0: FloatArray,
        t1: FloatArray,
        f1: FloatArray,
        d1: FloatArray,
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        den = d0 - d1
        t = (f1 - f0 + d0 * t0 - d1 * t1) / np.where(den < 0.0, den, -1.0)
        ok = (d0 <= 0.0) & (d1 >= 0.0) & (f1 + d1 * (t0 - t1) <= f0) & (f0 + d0 * (t1 - t0) <= f1)
        return np.clip(t, t0, t1), f0 + d0 * (t - t0), ok

    def holds(f0: FloatArray, d0: FloatArray, f1: FloatArray, d1: FloatArray) -> FloatArray:
        out: FloatArray = ((d0 <= 0.0) & ((d1 > 0.0) | (f1 > f0))) | (
            (d1 >= 0.0) & ((d0 < 0.0) | (f0 > f1))
        )
        return out

    f, df, pts, nrm = wc._rim(terrain, w, np.stack([lo, hi], axis=-1))
    f0, f1, d0, d1 = f[..., 0], f[..., 1], df[..., 0], df[..., 1]
    valid = holds(f0, d0, f1, d1)
    left = ~valid & (f0 <= f1)
    step = np.clip(2.0 * (hi - lo), wc.MIN_STEP_RAD, wc.MAX_STEP_BRACKET_RAD)
    t_meet, _, convex = tangent_meet(lo, f0, d0, hi, f1, d1)
    nudge = np.minimum(0.25 * (hi - lo), wc.NUDGE_RAD)
    t_meet = np.clip(np.where(convex, t_meet, 0.5 * (lo + hi)), lo + nudge, hi - nudge)
    trial = np.where(valid, t_meet, np.where(left, lo - step, hi + step))
    trial = np.clip(trial, -wc.SCAN_HALF_RAD, wc.SCAN_HALF_RAD)
    ft, dt, pt, nt = (
        a[..., 0, :] if a.ndim == 4 else a[..., 0] for a in wc._rim(terrain, w, trial[..., None])
    )
    right_ok = holds(ft, dt, f1, d1)
    lowest_left = np.where(ft <= np.minimum(f0, f1), dt > 0.0, f0 < f1)
    keep_left = holds(f0, d0, ft, dt) & (lowest_left | ~right_ok)
    new_lo = np.where(valid, np.where(keep_left, lo, trial), np.where(left, trial, hi))
    new_hi = np.where(valid, np.where(keep_left, trial, hi), np.where(left, lo, trial))
    fl = np.where(valid, np.where(keep_left, f0, ft), np.where(left, ft, f1))
    dl = np.where(valid, np.where(keep_left, d0, dt), np.where(left, dt, d1))
    fh = np.where(valid, np.where(keep_left, ft, f1), np.where(left, f0, ft))
    dh = np.where(valid, np.where(keep_left, dt, d1), np.where(left, d0, dt))
    _, meet, convex = tangent_meet(new_lo, fl, dl, new_hi, fh, dh)
    flat = np.minimum(fl, fh) - np.maximum(-dl, dh) * (new_hi - new_lo)
    trusted = convex & (new_hi - new_lo <= wc.TRUST_BRACKET_RAD)
    lower = np.where(trusted, np.maximum(meet, flat), -np.inf)
    f3 = np.stack([f0, f1, ft], axis=-1)
    j = np.argmin(f3, axis=-1)
    best = np.take_along_axis(f3, j[..., None], -1)[..., 0]
    theta = np.take_along_axis(np.stack([lo, hi, trial], axis=-1), j[..., None], -1)[..., 0]
    jj = j[..., None, None]
    point = np.take_along_axis(np.concatenate([pts, pt[..., None, :]], -2), jj, -2)[..., 0, :]
    normal = np.take_along_axis(np.concatenate([nrm, nt[..., None, :]], -2), jj, -2)[..., 0, :]
    return new_lo, new_hi, theta, best, best * -normal[..., 2], best - lower, point, normal


class _Holes:
    """Gusev with NaN heights in narrow stripes: the NaN paths of the search."""

    def __init__(self) -> None:
        self.terrain = make_terrain("gusev", 2)
        self.soil = self.terrain.soil

    def height_and_gradient(
        self, x: FloatArray, y: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        h, hx, hy = self.terrain.height_and_gradient(x, y)
        hole = np.mod(x, 0.5) < 0.01
        return np.where(hole, np.nan, h), hx, np.where(hole, np.nan, hy)


@pytest.mark.parametrize("holes", [False, True])
def test_contact_step_equals_the_numpy_reference(holes: bool) -> None:
    terrain = _Holes() if holes else make_terrain("gusev", 2)
    rng = np.random.default_rng(17)
    w = _random_wheels(rng, 400)
    # brackets wide and narrow, some round the minimum, some beside it, some degenerate
    lo = rng.uniform(-0.6, 0.6, (400, 6))
    hi = lo + rng.choice([0.0, 1e-4, 0.01, 0.05, 0.3], (400, 6))
    got = wc.contact(terrain, w, lo, hi)  # type: ignore[arg-type]
    want = _contact_reference(terrain, w, lo, hi)  # type: ignore[arg-type]
    fields = ("lo", "hi", "theta", "clearance", "gap", "error", "point", "normal")
    for name, value in zip(fields, want, strict=True):
        np.testing.assert_array_equal(getattr(got, name), value, err_msg=name)


def _rotation_reference(
    roll: FloatArray, pitch: FloatArray, yaw: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``rotation_s_b`` as it was written in numpy before it was compiled."""
    cf, sf = np.cos(roll), np.sin(roll)
    ct, st = np.cos(pitch), np.sin(pitch)
    cp, sp = np.cos(yaw), np.sin(yaw)
    z = np.zeros_like(cf)

    def mat(rows: list[list[FloatArray]]) -> FloatArray:
        return np.stack([np.stack(r, -1) for r in rows], -2)

    R = mat(
        [
            [cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf],
            [sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf],
            [-st, ct * sf, ct * cf],
        ]
    )
    dR_droll = mat(
        [
            [z, cp * st * cf + sp * sf, -cp * st * sf + sp * cf],
            [z, sp * st * cf - cp * sf, -sp * st * sf - cp * cf],
            [z, ct * cf, -ct * sf],
        ]
    )
    dR_dpitch = mat(
        [
            [-cp * st, cp * ct * sf, cp * ct * cf],
            [-sp * st, sp * ct * sf, sp * ct * cf],
            [-ct, -st * sf, -st * cf],
        ]
    )
    return R, dR_droll, dR_dpitch


@pytest.mark.parametrize("shape", [(), (9,), (4, 6)])
def test_rotations_equal_the_numpy_reference(shape: tuple[int, ...]) -> None:
    rng = np.random.default_rng(23)
    roll, pitch, yaw = (rng.uniform(-np.pi, np.pi, shape) for _ in range(3))
    for got, want in zip(
        rotation_s_b(roll, pitch, yaw), _rotation_reference(roll, pitch, yaw), strict=True
    ):
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(np.signbit(got), np.signbit(want))


def test_unit_normal_equals_numpy_norm() -> None:
    rng = np.random.default_rng(29)
    hx = rng.normal(0.0, 1.0, (50, 6, 2)) * rng.choice([1e-3, 1.0, 100.0], (50, 6, 2))
    hy = rng.normal(0.0, 1.0, (50, 6, 2)) * rng.choice([1e-3, 1.0, 100.0], (50, 6, 2))
    n = np.stack([-hx, -hy, -np.ones_like(hx)], axis=-1)
    np.testing.assert_array_equal(
        wc.unit_normal(hx, hy), n / np.linalg.norm(n, axis=-1, keepdims=True)
    )
    assert wc.unit_normal(np.zeros(0), np.zeros(0)).shape == (0, 3)
