"""Quasi-static settling of the rocker-bogie rover on a terrain, vectorised over poses.

Given the body origin's horizontal position and the heading, the suspension has six free
coordinates ``u = (z, roll, pitch, rocker, bogie_left, bogie_right)`` and six contact
conditions, one per wheel: a rover with six wheels on the ground is a root of six equations
in six unknowns (the point of a rocker-bogie; the contact kinematics of seed 001 section
2.2.4 with the full contact point on the rim instead of its one-parameter model). Newton's
method solves all poses at once.

Contact of one wheel: a disk of radius ``r_eff`` (wheel radius minus sinkage) in the plane
normal to its axle ``a``. On smooth ground with upward unit normal ``n`` it touches at the
rim point lowest along ``n``, ``q = c + r_eff d`` with ``d = normalise(-n + (n·a) a)``, and
the gap is the signed distance of ``q`` from the surface along ``n``. For a locally planar
surface through ``S`` that is ``n·(c - S) - r_eff sqrt(1 - (n·a)^2)`` (as
``n·d = -sqrt(1 - (n·a)^2)``); its derivative in ``u`` is the Newton Jacobian.

Finding ``q``: the rim point lowest along the local normal is the rim point of least
vertical clearance over the terrain, and we search for it as that minimum, because the
heightmaps are bilinear: their normal jumps at every 5 cm cell edge and on rock flanks,
where "lowest along the local normal" has no fixed point (an iteration on it flips between
faces) while the least clearance is always defined, and is the same point on smooth ground.
Per wheel and Newton iteration, one step of a bracketing search in the rim angle: the
clearance and its slope at the bracket ends and at a trial inside (where the end tangents
meet: exact at a kink, a bisection on a smooth minimum). The tangents also bound the
minimum from below; a pose converges when every wheel's best clearance found is within
``tol_m`` of zero and of that bound. A converged pose then gets a rim check: samples round
the lower rim, dense near the contact, sparse far round, looking for a deeper basin (a
rock touching further round the wheel); if there is one the search moves there.

Newton's steps are scaled to at most 0.1 rad and 5 cm; a step that makes the largest gap
much worse is shortened along the same direction (a wheel pushed against a rock face has a
near-horizontal normal that asks for a long step), and late steps that are not converging
fast are halved (a wheel on two bumps has a gap that is the lower of two smooth pieces).
Along a path (``along_path``) every 8th pose is solved first and starts the others; a path
pose that still fails is retried by continuation from the settled pose before it.

Frames: Site ``s`` (x North, y East, z Down), body ``b`` (x forward, y right, z down);
``R_s_b = Rz(yaw) Ry(pitch) Rx(roll)`` about the Site axes, so ``yaw`` is the heading
clockwise from North, positive ``pitch`` is nose up and positive ``roll`` right side down.
Heights are elevations (up); a surface point is ``(x, y, -h)`` in the Site frame.

Flags: a pose is *converged* when all six gaps are below ``tol_m`` and the rim check found
nothing deeper than ``tol_m + CHECK_SLACK_M``; *within limits* when the rocker and bogie
angles are inside their joint stops. Poses failing either (a boulder no suspension could
straddle, a terrain returning NaN) are flagged, never silently returned as good.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from sim.errors import InputError
from sim.rover_geometry import MER_GEOMETRY, RoverGeometry, WheelKinematics, wheel_kinematics
from sim.terrain import Terrain

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

BLOCK_POSES = 4096  # poses solved together: bounds the memory of the rim checks
MAX_STEP_RAD = 0.1  # Newton step limit on the angles (rad), damps the first iterations
MAX_STEP_M = 0.05  # Newton step limit on the body height (m)
DAMP_AFTER = 10  # after this many iterations slow Newton steps are halved (_settle_block)
SCAN_HALF_RAD = float(np.deg2rad(85.0))  # rim angles searched either side of the bottom
FIRST_HALF_RAD = float(np.deg2rad(5.0))  # first bracket half-width round the predicted contact
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
CHECK_SLACK_M = 3e-4  # a rim check counts a point this much below tol_m (see _deeper)
REFINE_SAMPLES = 9  # resampling across a suspect minimum of the rim check
REJECT_FACTOR = 4.0  # a step is shortened if the largest gap grows this many times and
REJECT_MARGIN_M = 2e-3  # by this much: contact searches alone move it less
MIN_TRUST = 1.0 / 64.0  # shortest fraction of a Newton step
MAX_CHECKS = 3  # moves to a deeper basin before a pose is given up as not converged
PATH_STRIDE = 8  # along a path, settle every 8th pose first (3.75 cm apart at 3.75 cm/s)
PATH_BRACKET_RAD = float(np.deg2rad(1.0))  # contact bracket half-width from neighbours
CONTINUATION_STEPS = 4  # sub-steps from a settled pose to a path pose that did not settle


@dataclass(frozen=True)
class Settled:
    """Settled poses; first axis ``N`` over poses, wheel axis in ``WHEEL_NAMES`` order.

    - ``p_s`` body origin in the Site frame (N, E, Down), m, (N, 3).
    - ``q_s_b`` attitude ``[x, y, z, w]``, (N, 4); ``roll_rad``, ``pitch_rad``,
      ``yaw_rad`` its ZYX angles, (N,).
    - ``rocker_rad`` (N,) left rocker angle; ``bogie_rad`` (N, 2) [left, right].
    - ``contact_s`` (N, 6, 3) contact points (on the rims) in the Site frame, m;
      ``normal_s`` (N, 6, 3) upward unit surface normals there (Site frame, so z < 0).
    - ``gap_m`` (N, 6) signed wheel-to-ground distances (positive: above the ground).
    - ``converged``, ``within_limits`` (N,) flags; ``iterations`` (N,) Newton iterations.
    """

    p_s: FloatArray
    q_s_b: FloatArray
    roll_rad: FloatArray
    pitch_rad: FloatArray
    yaw_rad: FloatArray
    rocker_rad: FloatArray
    bogie_rad: FloatArray
    contact_s: FloatArray
    normal_s: FloatArray
    gap_m: FloatArray
    converged: BoolArray
    within_limits: BoolArray
    iterations: IntArray

    def __len__(self) -> int:
        return int(self.p_s.shape[0])

    @property
    def ok(self) -> BoolArray:
        """Converged and within the joint limits, (N,)."""
        out: BoolArray = self.converged & self.within_limits
        return out

    def unknowns(self) -> FloatArray:
        """The solver's unknowns ``(z, roll, pitch, rocker, bogie_l, bogie_r)``, (N, 6)."""
        return np.column_stack(
            [self.p_s[:, 2], self.roll_rad, self.pitch_rad, self.rocker_rad, self.bogie_rad]
        )


def rotation_s_b(
    roll: FloatArray, pitch: FloatArray, yaw: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``R_s_b = Rz(yaw) Ry(pitch) Rx(roll)`` and its partials in roll and pitch, (..., 3, 3).

    >>> R, _, _ = rotation_s_b(np.array(0.0), np.array(0.0), np.array(np.pi / 2))
    >>> np.round(R @ [1.0, 0.0, 0.0], 12)  # heading East: body x is Site +y
    array([0., 1., 0.])
    """
    cf, sf = np.cos(roll), np.sin(roll)
    ct, st = np.cos(pitch), np.sin(pitch)
    cp, sp = np.cos(yaw), np.sin(yaw)
    z = np.zeros_like(cf)

    def mat(rows: list[list[FloatArray]]) -> FloatArray:
        out: FloatArray = np.stack([np.stack(r, -1) for r in rows], -2)
        return out

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


def _dot(a: FloatArray, b: FloatArray) -> FloatArray:
    """Dot product over a last axis of length 3 (faster than einsum on small axes)."""
    out: FloatArray = a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]
    return out


def _unit_normal(hx: FloatArray, hy: FloatArray) -> FloatArray:
    """Upward unit normal in the Site frame (z Down, so n_z < 0) from the slopes."""
    n = np.stack([-hx, -hy, -np.ones_like(hx)], axis=-1)
    out: FloatArray = n / np.linalg.norm(n, axis=-1, keepdims=True)
    return out


def _height_and_gradient(
    terrain: Terrain, x: FloatArray, y: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Height and slopes in one query where the terrain offers it (heightmaps do)."""
    both = getattr(terrain, "height_and_gradient", None)
    if both is not None:
        h, hx, hy = both(x, y)
        return np.asarray(h), np.asarray(hx), np.asarray(hy)
    hx, hy = terrain.gradient(x, y)
    return terrain.height_m(x, y), hx, hy


def _initial_guess(
    terrain: Terrain,
    geometry: RoverGeometry,
    x: FloatArray,
    y: FloatArray,
    yaw: FloatArray,
    r_eff: FloatArray,
) -> FloatArray:
    """Unknowns from a least-squares plane through the terrain under the six wheels, (M, 6).

    The plane ``h = h0 + α f + β r`` (``f`` forward, ``r`` right of the heading) gives the
    attitude of a body parallel to it: ``tan(pitch) = α``,
    ``sin(roll) = -β / sqrt(1 + α² + β²)``; the joints start at zero.
    """
    wxy = geometry.wheel_xy_b()  # (6, 2) in the heading frame
    cp, sp = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    h = terrain.height_m(
        x[:, None] + cp * wxy[:, 0] - sp * wxy[:, 1], y[:, None] + sp * wxy[:, 0] + cp * wxy[:, 1]
    )
    h0, alpha, beta = np.linalg.pinv(np.column_stack([np.ones(6), wxy])) @ h.T
    norm = np.sqrt(1.0 + alpha**2 + beta**2)
    height = geometry.wheel_centre_z_m + np.mean(r_eff, axis=-1)
    zero = np.zeros_like(x)
    roll = -np.arcsin(np.clip(beta / norm, -1.0, 1.0))
    return np.column_stack([-(h0 + height * norm), roll, np.arctan(alpha), zero, zero, zero])


@dataclass(frozen=True)
class _Wheels:
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

    def take(self, idx: IntArray) -> _Wheels:
        k = self.kin
        kin = WheelKinematics(
            k.centre_b[idx], k.axle_b[idx], k.link_rad[idx], k.dcentre_dq[idx], k.daxle_dq[idx]
        )
        return _Wheels(
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


def _wheels(
    geometry: RoverGeometry,
    u: FloatArray,
    x: FloatArray,
    y: FloatArray,
    yaw: FloatArray,
    steer: FloatArray,
    r_eff: FloatArray,
) -> _Wheels:
    R, dR_droll, dR_dpitch = rotation_s_b(u[:, 1], u[:, 2], yaw)
    kin = wheel_kinematics(geometry, u[:, 3], u[:, 4:6], steer)
    Rt = R.transpose(0, 2, 1)  # row vectors times R^T apply R: batched matmul beats einsum
    centre = np.column_stack([x, y, u[:, 0]])[:, None, :] + kin.centre_b @ Rt
    axle = kin.axle_b @ Rt
    low = -axle[..., 2:3] * axle  # Site +z (Down) minus its component along the axle
    low[..., 2] += 1.0
    low /= np.linalg.norm(low, axis=-1, keepdims=True)
    return _Wheels(R, dR_droll, dR_dpitch, kin, centre, axle, low, np.cross(axle, low), r_eff)


def _rim(
    terrain: Terrain, w: _Wheels, theta: FloatArray, slope: bool = True
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Clearance at rim angles ``theta`` (m, 6, K), measured from the lowest rim point.

    Returns ``(f, df, point, normal)``: the vertical clearance ``f`` (m) of the rim point
    over the terrain, ``df/dθ`` (m/rad), the point (m, 6, K, 3) and the upward unit normal
    there; with ``slope=False`` only ``f`` (one height query, the others empty).
    Component arrays rather than (..., 3) stacks: this is the solver's hot loop.
    """
    c, s = np.cos(theta), np.sin(theta)
    pos, der = [], []
    for i in range(3):
        lo = (w.r * w.e_low[..., i])[..., None]
        fw = (w.r * w.e_fwd[..., i])[..., None]
        pos.append(w.centre[..., i, None] + lo * c + fw * s)
        der.append(fw * c - lo * s)
    if not slope:
        empty = np.empty(0)
        return -pos[2] - terrain.height_m(pos[0], pos[1]), empty, empty, empty
    h, hx, hy = _height_and_gradient(terrain, pos[0], pos[1])
    df = -der[2] - hx * der[0] - hy * der[1]
    return -pos[2] - h, df, np.stack(pos, axis=-1), _unit_normal(hx, hy)


def _tangent_meet(
    t0: FloatArray,
    f0: FloatArray,
    d0: FloatArray,
    t1: FloatArray,
    f1: FloatArray,
    d1: FloatArray,
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Where the tangents at ``t0`` (falling) and ``t1`` (rising) meet: (angle, value, ok).

    ``ok`` where the ends look convex (each tangent passes below the other end): then the
    value bounds the minimum between them from below, exactly where two plane faces meet
    in a kink, and the angle lies in ``[t0, t1]``.
    """
    den = d0 - d1
    t = (f1 - f0 + d0 * t0 - d1 * t1) / np.where(den < 0.0, den, -1.0)
    ok = (d0 <= 0.0) & (d1 >= 0.0) & (f1 + d1 * (t0 - t1) <= f0) & (f0 + d0 * (t1 - t0) <= f1)
    return np.clip(t, t0, t1), f0 + d0 * (t - t0), ok


def _holds_minimum(f0: FloatArray, d0: FloatArray, f1: FloatArray, d1: FloatArray) -> BoolArray:
    """Whether an interval must hold a local minimum, from the clearance at its ends: it
    falls from the left end and rises into or ends higher at the right one, or mirrored."""
    out: BoolArray = ((d0 <= 0.0) & ((d1 > 0.0) | (f1 > f0))) | (
        (d1 >= 0.0) & ((d0 < 0.0) | (f0 > f1))
    )
    return out


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


def _contact(terrain: Terrain, w: _Wheels, lo: FloatArray, hi: FloatArray) -> _Contact:
    """One bracketing step of the rim-minimum search for every wheel.

    A bracket holding a minimum (``_holds_minimum``) is split at a trial: where the end
    tangents meet if the ends look convex, else the middle; the half that still holds a
    minimum and has the lowest point is kept. A bracket that lost the minimum (the pose
    moved) steps downhill by twice its width and is checked again next time.
    """
    f, df, pts, nrm = _rim(terrain, w, np.stack([lo, hi], axis=-1))
    f0, f1, d0, d1 = f[..., 0], f[..., 1], df[..., 0], df[..., 1]
    valid = _holds_minimum(f0, d0, f1, d1)
    left = ~valid & (f0 <= f1)  # downhill lies below lo (else above hi)
    step = np.clip(2.0 * (hi - lo), MIN_STEP_RAD, MAX_STEP_BRACKET_RAD)
    t_meet, _, convex = _tangent_meet(lo, f0, d0, hi, f1, d1)
    # Off the ends: at a kink the tangents meet exactly at the end already found, and a
    # sample just past it closes the bracket.
    nudge = np.minimum(0.25 * (hi - lo), NUDGE_RAD)
    t_meet = np.clip(np.where(convex, t_meet, 0.5 * (lo + hi)), lo + nudge, hi - nudge)
    trial = np.where(valid, t_meet, np.where(left, lo - step, hi + step))
    trial = np.clip(trial, -SCAN_HALF_RAD, SCAN_HALF_RAD)
    ft, dt, pt, nt = (
        a[..., 0, :] if a.ndim == 4 else a[..., 0] for a in _rim(terrain, w, trial[..., None])
    )

    right_ok = _holds_minimum(ft, dt, f1, d1)
    lowest_left = np.where(ft <= np.minimum(f0, f1), dt > 0.0, f0 < f1)
    keep_left = _holds_minimum(f0, d0, ft, dt) & (lowest_left | ~right_ok)
    new_lo = np.where(valid, np.where(keep_left, lo, trial), np.where(left, trial, hi))
    new_hi = np.where(valid, np.where(keep_left, trial, hi), np.where(left, lo, trial))
    fl = np.where(valid, np.where(keep_left, f0, ft), np.where(left, ft, f1))
    dl = np.where(valid, np.where(keep_left, d0, dt), np.where(left, dt, d1))
    fh = np.where(valid, np.where(keep_left, ft, f1), np.where(left, f0, ft))
    dh = np.where(valid, np.where(keep_left, dt, d1), np.where(left, d0, dt))
    # Lower bound of the minimum in a narrow convex bracket: where the tangents meet, or
    # the lower end less the steeper end slope times the width.
    _, meet, convex = _tangent_meet(new_lo, fl, dl, new_hi, fh, dh)
    flat = np.minimum(fl, fh) - np.maximum(-dl, dh) * (new_hi - new_lo)
    trusted = convex & (new_hi - new_lo <= TRUST_BRACKET_RAD)
    lower = np.where(trusted, np.maximum(meet, flat), -np.inf)

    f3 = np.stack([f0, f1, ft], axis=-1)  # the best of lo, hi and the trial
    j = np.argmin(f3, axis=-1)
    best = np.take_along_axis(f3, j[..., None], -1)[..., 0]
    theta = np.take_along_axis(np.stack([lo, hi, trial], axis=-1), j[..., None], -1)[..., 0]
    jj = j[..., None, None]
    point = np.take_along_axis(np.concatenate([pts, pt[..., None, :]], -2), jj, -2)[..., 0, :]
    normal = np.take_along_axis(np.concatenate([nrm, nt[..., None, :]], -2), jj, -2)[..., 0, :]
    return _Contact(
        new_lo, new_hi, theta, best, best * -normal[..., 2], best - lower, point, normal
    )


def _deeper(
    terrain: Terrain, w: _Wheels, clearance: FloatArray, theta: FloatArray, margin_m: float
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
    j = np.argmin(f, axis=-1)
    best = np.take_along_axis(f, j[..., None], -1)[..., 0]
    centre = np.take_along_axis(angles, j[..., None], -1)[..., 0]
    half = np.full(best.shape, CHECK_NEAR_RAD)
    rise_l = np.full(f.shape, np.inf)
    rise_r = np.full(f.shape, np.inf)
    rise_l[..., 1:] = f[..., :-1] - f[..., 1:]
    rise_r[..., :-1] = f[..., 1:] - f[..., :-1]
    local_min = (rise_l >= 0.0) & (rise_r >= 0.0)
    rise = np.maximum(
        np.where(np.isinf(rise_l), rise_r, rise_l), np.where(np.isinf(rise_r), rise_l, rise_r)
    )
    own = np.abs(CHECK_OFFSETS_RAD) < 1.5 * CHECK_NEAR_RAD  # next to the contact: its basin
    bound = np.where(local_min & ~own, f - rise, np.inf)
    k = np.argmin(bound, axis=-1)
    suspect = (np.take_along_axis(bound, k[..., None], -1)[..., 0] < limit) & (best >= limit)
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


def _jacobian(w: _Wheels, n: FloatArray) -> FloatArray:
    """d gap / d u (m, 6, 6) of the planar gap ``n·c - r sqrt(1 - (n·a)^2)``, n held fixed:
    ``d gap = n·dc + k n·da`` with ``k = r (n·a) / sqrt(1 - (n·a)^2)``."""
    na = _dot(n, w.axle)
    k = (w.r * na / np.sqrt(np.clip(1.0 - na**2, 1e-12, None)))[..., None]
    lever_b = w.kin.centre_b + k * w.kin.axle_b  # both terms turn alike with roll and pitch
    J = np.empty((n.shape[0], 6, 6))
    J[:, :, 0] = n[..., 2]  # d centre / dz = Site +z
    J[:, :, 1] = _dot(n @ w.dR_droll, lever_b)  # n·(dR v) = (n^T dR)·v
    J[:, :, 2] = _dot(n @ w.dR_dpitch, lever_b)
    n_b = n @ w.R  # R^T n: the normal in the body frame
    J[:, :, 3:] = np.einsum("mki,mkiq->mkq", n_b, w.kin.dcentre_dq + k[..., None] * w.kin.daxle_dq)
    return J


def _solve(J: FloatArray, rhs: FloatArray) -> FloatArray:
    """Batched 6x6 solve; a singular system falls back to least squares (pseudo-inverse)."""
    try:
        return np.asarray(np.linalg.solve(J, rhs[..., None])[..., 0], dtype=np.float64)
    except np.linalg.LinAlgError:
        return np.asarray(np.einsum("mij,mj->mi", np.linalg.pinv(J), rhs), dtype=np.float64)


@dataclass
class _Block:
    """Solver state and results of a set of poses (first axis m)."""

    u: FloatArray
    lo: FloatArray
    hi: FloatArray
    theta: FloatArray
    gap: FloatArray
    contact: FloatArray
    normal: FloatArray
    converged: BoolArray
    iterations: IntArray


def _settle_block(
    terrain: Terrain,
    geometry: RoverGeometry,
    pose: tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray],
    u0: FloatArray,
    bracket0: tuple[FloatArray, FloatArray] | None,
    tol_m: float,
    max_iterations: int,
) -> _Block:
    """Newton on the six gaps of ``m`` poses ``(x, y, yaw, steer, r_eff)`` from ``u0``."""
    x, y, yaw, steer, r_eff = pose
    m = x.shape[0]
    nan6 = np.full((m, 6), np.nan)
    b = _Block(
        u0.copy(),
        nan6.copy(),
        nan6.copy(),
        nan6.copy(),
        nan6.copy(),
        np.full((m, 6, 3), np.nan),
        np.full((m, 6, 3), np.nan),
        np.zeros(m, dtype=bool),
        np.zeros(m, dtype=np.int64),
    )
    checks = np.zeros(m, dtype=np.int64)
    merit_prev = np.full(m, np.inf)  # the largest gap where the last step started
    u_prev = b.u.copy()
    lo_prev, hi_prev = b.lo.copy(), b.hi.copy()  # the contact brackets at u_prev
    last_step = np.zeros((m, 6))
    trust = np.ones(m)  # fraction of the (scaled) Newton step taken
    active = np.arange(m)
    for it in range(max_iterations + 1):
        w = _wheels(
            geometry, b.u[active], x[active], y[active], yaw[active], steer[active], r_eff[active]
        )
        if it == 0 and bracket0 is not None:
            b.lo, b.hi = bracket0[0].copy(), bracket0[1].copy()
        elif it == 0:  # round the rim point lowest along the normal under each wheel
            _, hx, hy = _height_and_gradient(terrain, w.centre[..., 0], w.centre[..., 1])
            n = _unit_normal(hx, hy)
            predicted = np.arctan2(-_dot(n, w.e_fwd), -_dot(n, w.e_low))
            b.lo, b.hi = predicted - FIRST_HALF_RAD, predicted + FIRST_HALF_RAD
        c = _contact(terrain, w, b.lo[active], b.hi[active])
        b.lo[active], b.hi[active], b.theta[active] = c.lo, c.hi, c.theta
        b.gap[active], b.contact[active], b.normal[active] = c.gap, c.point, c.normal
        b.iterations[active] = it
        done = (np.max(np.abs(c.gap), axis=1) < tol_m) & (np.max(c.error, axis=1) < tol_m)
        stop = np.zeros_like(done)
        moved = np.zeros(0, dtype=np.int64)
        idx = np.flatnonzero(done)
        if idx.size:
            deeper, lo, hi = _deeper(
                terrain, w.take(idx), c.clearance[idx], c.theta[idx], tol_m + CHECK_SLACK_M
            )
            bad = np.any(deeper, axis=1)
            redo = bad & (checks[active[idx]] < MAX_CHECKS)
            moved, flag = active[idx[redo]], deeper[redo]
            blo, bhi = b.lo[moved], b.hi[moved]
            blo[flag], bhi[flag] = lo[redo][flag], hi[redo][flag]
            b.lo[moved], b.hi[moved] = blo, bhi
            checks[moved] += 1
            done[idx[bad]] = False
            stop[idx[bad & ~redo]] = True  # gave up: flagged as not converged
            b.converged[active[idx[~bad]]] = True
        finite = np.all(np.isfinite(c.gap), axis=1) & np.all(np.isfinite(b.u[active]), axis=1)
        keep = ~done & ~stop & finite
        if not np.any(keep) or it == max_iterations:
            break
        # Backtracking: a step that made the largest gap much worse (a wheel pushed against
        # a rock face, whose near-horizontal normal asks for a long step) is shortened
        # along the same direction instead of taken.
        merit = np.max(np.abs(c.gap), axis=1)
        pose_ids = active[keep]
        worse = (merit[keep] > REJECT_FACTOR * merit_prev[pose_ids] + REJECT_MARGIN_M) & (
            trust[pose_ids] > MIN_TRUST
        )
        back = pose_ids[worse]
        trust[back] *= 0.25
        b.u[back] = u_prev[back] + trust[back, None] * last_step[back]
        b.lo[back], b.hi[back] = lo_prev[back], hi_prev[back]
        rows = np.flatnonzero(keep)[~worse]
        go = pose_ids[~worse]
        step = _solve(_jacobian(w.take(rows), c.normal[rows]), -c.gap[rows])
        # Scale (not clip) the step so it keeps its direction while far from the root.
        biggest = np.maximum(
            np.max(np.abs(step[:, 1:]), axis=1) / MAX_STEP_RAD, np.abs(step[:, 0]) / MAX_STEP_M
        )
        step /= np.maximum(biggest, 1.0)[:, None]
        # A wheel on two bumps has a gap that is the lower of two smooth pieces, and full
        # Newton steps can cycle between them: late steps that did not halve the largest
        # gap are halved.
        slow = (it >= DAMP_AFTER) & (merit[rows] > 0.5 * merit_prev[go])
        trust[go] = np.where(slow, 0.5, np.minimum(1.0, 2.0 * trust[go]))
        u_prev[go], merit_prev[go], last_step[go] = b.u[go], merit[rows], step
        lo_prev[go], hi_prev[go] = b.lo[go], b.hi[go]
        merit_prev[moved] = np.inf  # moved to a new basin: no step to judge against
        b.u[go] += trust[go, None] * step
        active = pose_ids
    return b


def _continue(
    terrain: Terrain,
    geometry: RoverGeometry,
    pose: tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray],
    blk: _Block,
    tol_m: float,
    max_iterations: int,
) -> None:
    """Retry the poses of a path that did not converge by continuation, in place.

    From the converged pose before, the rover is moved to the failed one in
    ``CONTINUATION_STEPS`` small steps, each settled from the last solution and contact
    angles: a wheel working its way up a rock face is followed instead of guessed.
    """
    x, y, yaw, steer, r_eff = pose
    for i in np.flatnonzero(~blk.converged):
        j = i - 1
        if j < 0 or not blk.converged[j]:
            continue
        u, theta = blk.u[j : j + 1], blk.theta[j : j + 1]
        turn = math.remainder(yaw[i] - yaw[j], 2.0 * math.pi)
        for k in range(1, CONTINUATION_STEPS + 1):
            t = k / CONTINUATION_STEPS
            sub = (
                x[j : j + 1] + t * (x[i] - x[j]),
                y[j : j + 1] + t * (y[i] - y[j]),
                yaw[j : j + 1] + t * turn,
                steer[j : j + 1] + t * (steer[i] - steer[j]),
                r_eff[j : j + 1] + t * (r_eff[i] - r_eff[j]),
            )
            bracket = (theta - PATH_BRACKET_RAD, theta + PATH_BRACKET_RAD)
            one = _settle_block(terrain, geometry, sub, u, bracket, tol_m, max_iterations)
            if not one.converged[0]:
                break
            u, theta = one.u, one.theta
        else:
            for f in fields(_Block):
                getattr(blk, f.name)[i] = getattr(one, f.name)[0]


def _as_poses(
    x_m: ArrayLike, y_m: ArrayLike, yaw_rad: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    arrays = []
    for name, value in (("x_m", x_m), ("y_m", y_m), ("yaw_rad", yaw_rad)):
        a = np.atleast_1d(np.asarray(value, dtype=float))
        if a.ndim != 1:
            raise InputError(name, f"must be a scalar or a 1-D array, got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise InputError(name, "must be finite")
        arrays.append(a)
    n = arrays[0].shape[0]
    for name, a in zip(("y_m", "yaw_rad"), arrays[1:], strict=True):
        if a.shape[0] != n:
            raise InputError(name, f"has {a.shape[0]} poses, x_m has {n}")
    return arrays[0], arrays[1], arrays[2]


def settle(
    terrain: Terrain,
    x_m: ArrayLike,
    y_m: ArrayLike,
    yaw_rad: ArrayLike,
    guess: Settled | ArrayLike | None = None,
    steer_rad: ArrayLike | None = None,
    sinkage_m: ArrayLike | None = None,
    geometry: RoverGeometry = MER_GEOMETRY,
    tol_m: float = 1e-4,
    max_iterations: int = 60,
    along_path: bool = False,
) -> Settled:
    """Settle the rover at ``N`` poses so that all six wheels touch ``terrain``.

    ``x_m``, ``y_m`` (N,): body-origin North and East in the Site frame; ``yaw_rad`` (N,)
    heading clockwise from North. ``steer_rad`` (N, 4) or (4,): corner steering angles
    (``STEERED_WHEELS`` order). ``sinkage_m``: scalar, (N,) or (N, 6) wheel sinkage,
    default the soil's static sinkage; the contact radius is ``wheel_radius - sinkage``.
    ``guess``: an earlier solution for the same ``N`` poses (or one pose, for all), or
    its ``unknowns()`` (N, 6) or (6,), to start Newton from; by default a plane fitted
    under the wheels. ``along_path``: the poses are
    consecutive samples of one motion a few mm apart; every ``PATH_STRIDE``-th is settled
    first and warm-starts those between. Gaps converge below ``tol_m``; see the module
    docstring for the flags of poses that do not.
    """
    x, y, yaw = _as_poses(x_m, y_m, yaw_rad)
    n = x.shape[0]
    steer = np.zeros(4) if steer_rad is None else np.asarray(steer_rad, dtype=float)
    if steer.shape not in ((4,), (n, 4)) or not np.all(np.isfinite(steer)):
        raise InputError("steer_rad", f"must be finite with shape (4,) or ({n}, 4)")
    steer = np.broadcast_to(steer, (n, 4))
    sink = np.asarray(terrain.soil.sinkage_m if sinkage_m is None else sinkage_m, dtype=float)
    try:
        sink6 = np.broadcast_to(sink[:, None] if sink.ndim == 1 else sink, (n, 6))
    except ValueError as exc:
        raise InputError("sinkage_m", f"must be a scalar, ({n},) or ({n}, 6)") from exc
    if (
        not np.all(np.isfinite(sink6))
        or np.any(sink6 < 0)
        or np.any(sink6 >= geometry.wheel_radius_m)
    ):
        raise InputError("sinkage_m", "must be finite, >= 0 and below the wheel radius")
    r_eff = geometry.wheel_radius_m - sink6
    start = None
    if guess is not None:
        g = guess.unknowns() if isinstance(guess, Settled) else np.asarray(guess, dtype=float)
        if g.shape not in ((6,), (1, 6), (n, 6)) or not np.all(np.isfinite(g)):
            raise InputError("guess", f"must be finite unknowns of 1 or {n} poses")
        start = np.broadcast_to(g, (n, 6))
    if not (np.isfinite(tol_m) and tol_m > 0.0):
        raise InputError("tol_m", "must be finite and > 0")

    def solve(
        idx: IntArray, u0: FloatArray | None, bracket0: tuple[FloatArray, FloatArray] | None
    ) -> _Block:
        """Settle the poses ``idx`` in blocks; no ``u0``: start from the plane fit."""
        parts = []
        for lo in range(0, idx.size, BLOCK_POSES):
            i, part = idx[lo : lo + BLOCK_POSES], slice(lo, lo + BLOCK_POSES)
            start = (
                _initial_guess(terrain, geometry, x[i], y[i], yaw[i], r_eff[i])
                if u0 is None
                else u0[part]
            )
            br = None if bracket0 is None else (bracket0[0][part], bracket0[1][part])
            pose = (x[i], y[i], yaw[i], steer[i], r_eff[i])
            parts.append(_settle_block(terrain, geometry, pose, start, br, tol_m, max_iterations))
        return _Block(
            *(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(_Block))
        )

    every = np.arange(n)
    if along_path and n >= 3 * PATH_STRIDE:
        # Settle every PATH_STRIDE-th pose; start the others from the interpolation of their
        # neighbours' solutions and contact angles: they converge in a step or two.
        coarse = np.unique(np.concatenate([every[::PATH_STRIDE], [n - 1]]))
        fine = np.setdiff1d(every, coarse)
        bc = solve(coarse, None if start is None else start[coarse], None)
        u_f = np.column_stack([np.interp(fine, coarse, bc.u[:, j]) for j in range(6)])
        th = np.column_stack([np.interp(fine, coarse, bc.theta[:, j]) for j in range(6)])
        bf = solve(fine, u_f, (th - PATH_BRACKET_RAD, th + PATH_BRACKET_RAD))
        blk = _Block(
            *(
                np.empty((n, *getattr(bc, f.name).shape[1:]), dtype=getattr(bc, f.name).dtype)
                for f in fields(_Block)
            )
        )
        for f in fields(_Block):
            getattr(blk, f.name)[coarse] = getattr(bc, f.name)
            getattr(blk, f.name)[fine] = getattr(bf, f.name)
        _continue(terrain, geometry, (x, y, yaw, steer, r_eff), blk, tol_m, max_iterations)
    else:
        blk = solve(every, start, None)

    u = blk.u
    R, _, _ = rotation_s_b(u[:, 1], u[:, 2], yaw)
    within = (np.abs(u[:, 3]) <= geometry.rocker_limit_rad) & np.all(
        np.abs(u[:, 4:6]) <= geometry.bogie_limit_rad, axis=1
    )
    q = np.full((n, 4), np.nan)  # a terrain that answered NaN leaves NaN unknowns
    finite = np.all(np.isfinite(R), axis=(1, 2))
    q[finite] = Rotation.from_matrix(R[finite]).as_quat()
    return Settled(
        p_s=np.column_stack([x, y, u[:, 0]]),
        q_s_b=q,
        roll_rad=u[:, 1].copy(),
        pitch_rad=u[:, 2].copy(),
        yaw_rad=yaw.copy(),
        rocker_rad=u[:, 3].copy(),
        bogie_rad=u[:, 4:6].copy(),
        contact_s=blk.contact,
        normal_s=blk.normal,
        gap_m=blk.gap,
        converged=blk.converged,
        within_limits=within,
        iterations=blk.iterations,
    )
