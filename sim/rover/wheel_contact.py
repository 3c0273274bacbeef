"""Contact of a rover wheel's rim with a terrain: the search for the contact point.

Implements the wheel-ground contact used by ``sim.rover.settle``: the contact kinematics of
Balaram 2000 section 2.2.4 with the full contact point on the rim instead of its one-parameter
model.

Contact of one wheel: a disk of radius ``r_eff`` (wheel radius minus sinkage) in the plane
normal to its axle ``a``. On smooth ground with upward unit normal ``n`` it touches at the
rim point lowest along ``n``, ``q = c + r_eff d`` with ``d = normalise(-n + (n·a) a)``, and
the gap is the signed distance of ``q`` from the surface along ``n``. For a locally planar
surface through ``S`` that is ``n·(c - S) - r_eff sqrt(1 - (n·a)^2)`` (as
``n·d = -sqrt(1 - (n·a)^2)``); its derivative in the settling unknowns is ``sim.rover.settle``'s
Newton Jacobian.

Finding ``q``: the rim point lowest along the local normal is the rim point of least
vertical clearance over the terrain, and we search for it as that minimum, because the
heightmaps are bilinear: their normal jumps at every 5 cm cell edge and on rock flanks,
where "lowest along the local normal" has no fixed point (an iteration on it flips between
faces) while the least clearance is always defined, and is the same point on smooth ground.
Per wheel and Newton iteration, one step of a bracketing search in the rim angle
(``contact``): the clearance and its slope at the bracket ends and at a trial inside (where
the end tangents meet: exact at a kink, a bisection on a smooth minimum). The tangents also
bound the minimum from below; a pose converges when every wheel's best clearance found is
within ``tol_m`` of zero and of that bound. A converged pose then gets a rim check
(``deeper``): samples round the lower rim, dense near the contact, sparse far round, looking
for a deeper basin (a rock touching further round the wheel); if there is one the search
moves there.

Frames: Site ``s`` (x North, y East, z Down). Rim angles are measured in the wheel plane
from the vertically lowest rim point (``Wheels.e_low``) towards ``Wheels.e_fwd``. Heights
are elevations (up); a surface point is ``(x, y, -h)`` in the Site frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim.compiled import kernel
from sim.rover.geometry import RoverGeometry, WheelKinematics, wheel_kinematics
from sim.world.terrain import Terrain

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

SCAN_HALF_RAD = float(np.deg2rad(85.0))  # rim angles searched either side of the bottom
TRUST_BRACKET_RAD = float(np.deg2rad(3.0))  # widest bracket whose tangent bound is used
NUDGE_RAD = 2e-4  # 26 µm of rim: how far inside its bracket a trial must be
MIN_STEP_RAD = float(np.deg2rad(0.5))  # smallest and largest move of a bracket that
MAX_STEP_BRACKET_RAD = float(np.deg2rad(10.0))  # lost the minimum
# Rim check offsets from the contact (degrees): 2.5° (5.7 mm) apart where the rim runs a
# hair above the ground (10° round, a 13 cm rim is 2 mm up), 15° apart where only a rock as
# tall as r (1 - cos Δ) reaches it; wide enough to cover ±85° from any contact angle.
_CHECK_DEG = (2.5, 5, 7.5, 10, 12.5, 15, 20, 25, 30, 40, 50, 60, 75, 90, 110, 130, 150, 170)
CHECK_OFFSETS_RAD = np.deg2rad(np.concatenate([-np.array(_CHECK_DEG[::-1]), _CHECK_DEG]))
CHECK_NEAR_RAD = float(np.deg2rad(2.5))
CHECK_SLACK_M = 3e-4  # a rim check counts a point this much below tol_m (see deeper)
REFINE_SAMPLES = 9  # resampling across a suspect minimum of the rim check
_CHECK_OWN = np.abs(CHECK_OFFSETS_RAD) < 1.5 * CHECK_NEAR_RAD  # next to the contact: its basin


def unit_normal(hx: FloatArray, hy: FloatArray) -> FloatArray:
    """Upward unit normal in the Site frame (z Down, so n_z < 0) from the slopes,
    ``(-hx, -hy, -1) / sqrt(hx² + hy² + 1)`` (summed in that order, as ``np.linalg.norm``
    sums the squares), shape ``(..., 3)``."""
    hx, hy = np.broadcast_arrays(np.asarray(hx, np.float64), np.asarray(hy, np.float64))
    out = np.empty((*hx.shape, 3))
    _unit_normal(
        np.ascontiguousarray(hx).reshape(-1),
        np.ascontiguousarray(hy).reshape(-1),
        out.reshape(-1, 3),
    )
    return out


@kernel
def _unit_normal(hx: FloatArray, hy: FloatArray, out: FloatArray) -> None:
    """``unit_normal`` of flat slope arrays into ``out`` (n, 3)."""
    for k in range(hx.size):
        norm = np.sqrt(hx[k] * hx[k] + hy[k] * hy[k] + 1.0)
        out[k, 0] = -hx[k] / norm
        out[k, 1] = -hy[k] / norm
        out[k, 2] = -1.0 / norm


def height_and_gradient(
    terrain: Terrain, x: FloatArray, y: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Height and slopes in one query where the terrain offers it (heightmaps do)."""
    both = getattr(terrain, "height_and_gradient", None)
    if both is not None:
        h, hx, hy = both(x, y)
        return np.asarray(h), np.asarray(hx), np.asarray(hy)
    hx, hy = terrain.gradient(x, y)
    return terrain.height_m(x, y), hx, hy


@dataclass(frozen=True)
class Wheels:
    """Wheel frames at some unknowns: Site-frame centres, axles, rim bases, (m, 6, 3)."""

    R: FloatArray  # (m, 3, 3) and its partials in roll and pitch
    dR_droll: FloatArray
    dR_dpitch: FloatArray
    kin: WheelKinematics
    centre: FloatArray
    axle: FloatArray
    e_low: FloatArray  # in the wheel plane, towards the vertically lowest rim point
    e_fwd: FloatArray  # in the wheel plane, axle x e_low
    r: FloatArray  # (m, 6) contact radius

    def take(self, idx: IntArray) -> Wheels:
        k = self.kin
        kin = WheelKinematics(
            k.centre_b[idx], k.axle_b[idx], k.link_rad[idx], k.dcentre_dq[idx], k.daxle_dq[idx]
        )
        return Wheels(
            self.R[idx],
            self.dR_droll[idx],
            self.dR_dpitch[idx],
            kin,
            self.centre[idx],
            self.axle[idx],
            self.e_low[idx],
            self.e_fwd[idx],
            self.r[idx],
        )


def wheels(
    geometry: RoverGeometry,
    rotation: tuple[FloatArray, FloatArray, FloatArray],
    u: FloatArray,
    x: FloatArray,
    y: FloatArray,
    steer: FloatArray,
    r_eff: FloatArray,
) -> Wheels:
    """The six wheel frames of ``m`` poses in the Site frame.

    ``rotation``: ``R_s_b`` and its partials in roll and pitch, (m, 3, 3) each, as
    ``sim.rover.settle.rotation_s_b`` returns them; ``u`` (m, 6) the settling unknowns
    ``(z, roll, pitch, rocker, bogie_l, bogie_r)`` (m, rad); ``x``, ``y`` (m,) the body
    origin's North and East (m); ``steer`` (m, 4) corner steering angles (rad); ``r_eff``
    (m, 6) contact radii (m).
    """
    R, dR_droll, dR_dpitch = rotation
    kin = wheel_kinematics(geometry, u[:, 3], u[:, 4:6], steer)
    Rt = R.transpose(0, 2, 1)  # row vectors times R^T apply R: batched matmul beats einsum
    centre = np.column_stack([x, y, u[:, 0]])[:, None, :] + kin.centre_b @ Rt
    axle = kin.axle_b @ Rt
    low = -axle[..., 2:3] * axle  # Site +z (Down) minus its component along the axle
    low[..., 2] += 1.0
    low /= np.linalg.norm(low, axis=-1, keepdims=True)
    return Wheels(R, dR_droll, dR_dpitch, kin, centre, axle, low, np.cross(axle, low), r_eff)


def _rim(
    terrain: Terrain, w: Wheels, theta: FloatArray, slope: bool = True
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Clearance at rim angles ``theta`` (m, 6, K), measured from the lowest rim point.

    Returns ``(f, df, point, normal)``: the vertical clearance ``f`` (m) of the rim point
    over the terrain, ``df/dθ`` (m/rad), the point (m, 6, K, 3) and the upward unit normal
    there; with ``slope=False`` only ``f`` (one height query, the others empty).
    The rim points (and their derivatives) come from one compiled pass (``_rim_points``):
    this is the solver's hot loop, and the rim check asks for 36 angles per wheel.
    """
    pos = np.empty((3, *theta.shape))
    der = np.empty((3, *theta.shape)) if slope else np.empty((3, 0, 0, 0))
    _rim_points(
        np.ascontiguousarray(w.centre),
        np.ascontiguousarray(w.e_low),
        np.ascontiguousarray(w.e_fwd),
        np.ascontiguousarray(w.r),
        np.ascontiguousarray(theta),
        pos,
        der,
    )
    if not slope:
        empty = np.empty(0)
        return -pos[2] - terrain.height_m(pos[0], pos[1]), empty, empty, empty
    h, hx, hy = height_and_gradient(terrain, pos[0], pos[1])
    df = -der[2] - hx * der[0] - hy * der[1]
    return -pos[2] - h, df, np.stack(tuple(pos), axis=-1), unit_normal(hx, hy)


@kernel
def _rim_points(
    centre: FloatArray,
    e_low: FloatArray,
    e_fwd: FloatArray,
    r: FloatArray,
    theta: FloatArray,
    pos: FloatArray,
    der: FloatArray,
) -> None:
    """Rim points ``c + r (e_low cos θ + e_fwd sin θ)`` at the angles ``theta`` (m, 6, K)
    into ``pos`` (3, m, 6, K), and their derivatives in ``θ`` into ``der`` if it is not
    empty; ``centre``, ``e_low``, ``e_fwd`` (m, 6, 3), ``r`` (m, 6)."""
    slope = der.size > 0
    lo = np.empty(3)
    fw = np.empty(3)
    for a in range(theta.shape[0]):
        for b in range(theta.shape[1]):
            for i in range(3):
                lo[i] = r[a, b] * e_low[a, b, i]
                fw[i] = r[a, b] * e_fwd[a, b, i]
            for k in range(theta.shape[2]):
                c = math.cos(theta[a, b, k])
                s = math.sin(theta[a, b, k])
                for i in range(3):
                    pos[i, a, b, k] = centre[a, b, i] + lo[i] * c + fw[i] * s
                    if slope:
                        der[i, a, b, k] = fw[i] * c - lo[i] * s


@kernel
def _clip(x: float, low: float, high: float) -> float:
    """``np.clip`` of one float, NaN included: ``min(max(x, low), high)``."""
    y = x if math.isnan(x) or x > low else low
    return y if math.isnan(y) or y < high else high


@kernel
def _minimum(a: float, b: float) -> float:
    """``np.minimum`` of two floats (NaN if either is)."""
    return a if math.isnan(a) or a <= b else b


@kernel
def _maximum(a: float, b: float) -> float:
    """``np.maximum`` of two floats (NaN if either is)."""
    return a if math.isnan(a) or a >= b else b


@kernel
def _tangent_meet(
    t0: float, f0: float, d0: float, t1: float, f1: float, d1: float
) -> tuple[float, float, bool]:
    """Where the tangents at ``t0`` (falling) and ``t1`` (rising) meet: (angle, value, ok).

    ``ok`` where the ends look convex (each tangent passes below the other end): then the
    value bounds the minimum between them from below, exactly where two plane faces meet
    in a kink, and the angle lies in ``[t0, t1]``.
    """
    den = d0 - d1
    t = (f1 - f0 + d0 * t0 - d1 * t1) / (den if den < 0.0 else -1.0)
    ok = (d0 <= 0.0) & (d1 >= 0.0) & (f1 + d1 * (t0 - t1) <= f0) & (f0 + d0 * (t1 - t0) <= f1)
    return _clip(t, t0, t1), f0 + d0 * (t - t0), ok


@kernel
def _holds_minimum(f0: float, d0: float, f1: float, d1: float) -> bool:
    """Whether an interval must hold a local minimum, from the clearance at its ends: it
    falls from the left end and rises into or ends higher at the right one, or mirrored."""
    return ((d0 <= 0.0) & ((d1 > 0.0) | (f1 > f0))) | ((d1 >= 0.0) & ((d0 < 0.0) | (f0 > f1)))


@dataclass(frozen=True)
class _Contact:
    """One search step's result per wheel, (m, 6) unless noted."""

    lo: FloatArray  # the next bracket
    hi: FloatArray
    theta: FloatArray  # angle of the lowest rim point found
    clearance: FloatArray  # its vertical clearance
    gap: FloatArray  # its distance along the normal
    error: FloatArray  # clearance minus a lower bound of the minimum (inf: none yet)
    point: FloatArray  # (m, 6, 3)
    normal: FloatArray  # (m, 6, 3)


def contact(terrain: Terrain, w: Wheels, lo: FloatArray, hi: FloatArray) -> _Contact:
    """One bracketing step of the rim-minimum search for every wheel.

    A bracket holding a minimum (``_holds_minimum``) is split at a trial: where the end
    tangents meet if the ends look convex, else the middle; the half that still holds a
    minimum and has the lowest point is kept. A bracket that lost the minimum (the pose
    moved) steps downhill by twice its width and is checked again next time. The logic
    per wheel runs in two compiled passes (``_trial_angles``, ``_split``) round the two
    clearance queries.
    """
    lo, hi = np.ascontiguousarray(lo), np.ascontiguousarray(hi)
    f, df, pts, nrm = _rim(terrain, w, np.stack([lo, hi], axis=-1))
    trial = np.empty(lo.shape)
    _trial_angles(lo, hi, f, df, trial)
    ft, dt, pt, nt = _rim(terrain, w, trial[..., None])
    out = np.empty((6, *lo.shape))
    point, normal = np.empty((*lo.shape, 3)), np.empty((*lo.shape, 3))
    _split(lo, hi, f, df, pts, nrm, trial, ft, dt, pt, nt, out, point, normal)
    new_lo, new_hi, theta, best, gap, error = out
    return _Contact(new_lo, new_hi, theta, best, gap, error, point, normal)


@kernel
def _trial_angles(
    lo: FloatArray, hi: FloatArray, f: FloatArray, df: FloatArray, trial: FloatArray
) -> None:
    """The trial angle of each bracket ``[lo, hi]`` (m, 6) from the clearance ``f`` and
    its slope ``df`` (m, 6, 2) at its ends (see ``contact``), into ``trial``."""
    for a in range(lo.shape[0]):
        for b in range(lo.shape[1]):
            t0, t1 = lo[a, b], hi[a, b]
            f0, f1, d0, d1 = f[a, b, 0], f[a, b, 1], df[a, b, 0], df[a, b, 1]
            valid = _holds_minimum(f0, d0, f1, d1)
            left = (not valid) & (f0 <= f1)  # downhill lies below lo (else above hi)
            step = _clip(2.0 * (t1 - t0), MIN_STEP_RAD, MAX_STEP_BRACKET_RAD)
            t_meet, _, convex = _tangent_meet(t0, f0, d0, t1, f1, d1)
            # Off the ends: at a kink the tangents meet exactly at the end already found,
            # and a sample just past it closes the bracket.
            nudge = _minimum(0.25 * (t1 - t0), NUDGE_RAD)
            t_meet = _clip(t_meet if convex else 0.5 * (t0 + t1), t0 + nudge, t1 - nudge)
            t = t_meet if valid else (t0 - step if left else t1 + step)
            trial[a, b] = _clip(t, -SCAN_HALF_RAD, SCAN_HALF_RAD)


@kernel
def _split(
    lo: FloatArray,
    hi: FloatArray,
    f: FloatArray,
    df: FloatArray,
    pts: FloatArray,
    nrm: FloatArray,
    trial: FloatArray,
    ft: FloatArray,
    dt: FloatArray,
    pt: FloatArray,
    nt: FloatArray,
    out: FloatArray,
    point: FloatArray,
    normal: FloatArray,
) -> None:
    """The next bracket of each wheel from its ends (``f``, ``df``, ``pts``, ``nrm``:
    (m, 6, 2) and (m, 6, 2, 3)) and its trial (``ft``, ``dt``, ``pt``, ``nt``: one
    sample); into ``out`` (6, m, 6) the new ``lo``, ``hi``, the best angle, its clearance,
    gap and error, and its ``point`` and ``normal`` (m, 6, 3)."""
    for a in range(lo.shape[0]):
        for b in range(lo.shape[1]):
            t0, t1, tt = lo[a, b], hi[a, b], trial[a, b]
            f0, f1, d0, d1 = f[a, b, 0], f[a, b, 1], df[a, b, 0], df[a, b, 1]
            fx, dx = ft[a, b, 0], dt[a, b, 0]
            valid = _holds_minimum(f0, d0, f1, d1)
            left = (not valid) & (f0 <= f1)
            right_ok = _holds_minimum(fx, dx, f1, d1)
            lowest_left = (dx > 0.0) if fx <= _minimum(f0, f1) else (f0 < f1)
            keep_left = _holds_minimum(f0, d0, fx, dx) & (lowest_left | (not right_ok))
            if valid and keep_left:
                nl, nh, fl, dl, fh, dh = t0, tt, f0, d0, fx, dx
            elif valid:
                nl, nh, fl, dl, fh, dh = tt, t1, fx, dx, f1, d1
            elif left:
                nl, nh, fl, dl, fh, dh = tt, t0, fx, dx, f0, d0
            else:
                nl, nh, fl, dl, fh, dh = t1, tt, f1, d1, fx, dx
            # Lower bound of the minimum in a narrow convex bracket: where the tangents
            # meet, or the lower end less the steeper end slope times the width.
            _, meet, convex = _tangent_meet(nl, fl, dl, nh, fh, dh)
            flat = _minimum(fl, fh) - _maximum(-dl, dh) * (nh - nl)
            trusted = convex & (nh - nl <= TRUST_BRACKET_RAD)
            lower = _maximum(meet, flat) if trusted else -np.inf
            # the best of lo, hi and the trial (np.argmin: the first NaN, else first least)
            j = 0
            if not math.isnan(f0):
                if math.isnan(f1):
                    j = 1
                else:
                    j = 1 if f1 < f0 else 0
                    if math.isnan(fx) or fx < (f1 if j == 1 else f0):
                        j = 2
            best = f0 if j == 0 else (f1 if j == 1 else fx)
            for i in range(3):
                point[a, b, i] = pts[a, b, j, i] if j < 2 else pt[a, b, 0, i]
                normal[a, b, i] = nrm[a, b, j, i] if j < 2 else nt[a, b, 0, i]
            out[0, a, b], out[1, a, b] = nl, nh
            out[2, a, b] = t0 if j == 0 else (t1 if j == 1 else tt)
            out[3, a, b] = best
            out[4, a, b] = best * -normal[a, b, 2]
            out[5, a, b] = best - lower


def deeper(
    terrain: Terrain, w: Wheels, clearance: FloatArray, theta: FloatArray, margin_m: float
) -> tuple[BoolArray, FloatArray, FloatArray]:
    """The rim check: is any rim point below the contact's ``clearance - margin_m``?

    Samples at ``CHECK_OFFSETS_RAD`` from the contact angle ``theta`` (k, 6). A sampled
    local minimum whose neighbours rise steeply enough that something deeper may hide
    between them is resampled finely. Returns ``(deeper (k, 6), lo, hi)`` with a bracket
    round the deepest point found, kept clear of the contact (or the search returns to it).
    """
    angles = np.clip(theta[..., None] + CHECK_OFFSETS_RAD, -SCAN_HALF_RAD, SCAN_HALF_RAD)
    f = _rim(terrain, w, angles, slope=False)[0]
    limit = clearance - margin_m
    best, centre = np.empty(limit.shape), np.empty(limit.shape)
    k, bound = np.empty(limit.shape, dtype=np.int64), np.empty(limit.shape)
    _scan_rim(f, angles, _CHECK_OWN, best, centre, k, bound)
    half = np.full(best.shape, CHECK_NEAR_RAD)
    suspect = (bound < limit) & (best >= limit)
    rows, cols = np.nonzero(suspect)
    if rows.size:
        n = np.arange(rows.size)
        kk = k[rows, cols]
        t_lo = angles[rows, cols, np.maximum(kk - 1, 0)]
        t_hi = angles[rows, cols, np.minimum(kk + 1, CHECK_OFFSETS_RAD.size - 1)]
        fine = np.linspace(t_lo, t_hi, REFINE_SAMPLES, axis=-1)
        grid = np.zeros((rows.size, 6, REFINE_SAMPLES))
        grid[n, cols] = fine
        ff = _rim(terrain, w.take(rows), grid, slope=False)[0][n, cols]
        jj = np.argmin(ff, axis=-1)
        better = ff[n, jj] < best[rows, cols]
        r, c = rows[better], cols[better]
        best[r, c] = ff[n, jj][better]
        centre[r, c] = fine[n, jj][better]
        half[r, c] = ((t_hi - t_lo) / (REFINE_SAMPLES - 1))[better]
    half = np.minimum(half, 0.5 * np.abs(centre - theta))
    return best < limit, centre - half, centre + half


@kernel
def _argmin(row: FloatArray) -> int:
    """``np.argmin`` of a 1-D array: the first minimum, or the first NaN if there is one."""
    j = 0
    for i in range(row.size):
        if math.isnan(row[i]):
            return i
        if row[i] < row[j]:
            j = i
    return j


@kernel
def _scan_rim(
    f: FloatArray,
    angles: FloatArray,
    own: BoolArray,
    best: FloatArray,
    centre: FloatArray,
    k_bound: IntArray,
    bound_min: FloatArray,
) -> None:
    """The rim check's scan of the clearances ``f`` (m, 6, K) sampled at ``angles``, one
    pass per wheel: the lowest sample (``best``, at ``centre``), and the sampled local
    minimum (not ``own``, the contact's basin) whose rise to its neighbours bounds the
    rim lowest between them, ``f - rise`` (its index ``k_bound``, the bound ``bound_min``;
    ``inf`` where there is none)."""
    n = f.shape[2]
    bound = np.empty(n)
    for a in range(f.shape[0]):
        for b in range(f.shape[1]):
            row = f[a, b]
            j = _argmin(row)
            best[a, b] = row[j]
            centre[a, b] = angles[a, b, j]
            for i in range(n):
                rise_l = row[i - 1] - row[i] if i > 0 else np.inf
                rise_r = row[i + 1] - row[i] if i < n - 1 else np.inf
                left = rise_r if math.isinf(rise_l) else rise_l
                right = rise_l if math.isinf(rise_r) else rise_r
                # np.maximum: NaN if either is
                rise = left if math.isnan(left) or left >= right else right
                if rise_l >= 0.0 and rise_r >= 0.0 and not own[i]:
                    bound[i] = row[i] - rise
                else:
                    bound[i] = np.inf
            kb = _argmin(bound)
            k_bound[a, b] = kb
            bound_min[a, b] = bound[kb]
