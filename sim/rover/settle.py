"""Quasi-static settling of the rocker-bogie rover on a terrain, vectorised over poses.

Given the body origin's horizontal position and the heading, the suspension has six free
coordinates ``u = (z, roll, pitch, rocker, bogie_left, bogie_right)`` and six contact
conditions, one per wheel: a rover with six wheels on the ground is a root of six equations
in six unknowns (the point of a rocker-bogie; the contact kinematics of Balaram 2000 section
2.2.4 with the full contact point on the rim instead of its one-parameter model). Newton's
method solves all poses at once.

Each wheel's gap, its contact point ``q`` on the rim and the upward surface normal ``n``
there come from ``sim.rover.wheel_contact`` (the contact model and the search for ``q``; one
search step per wheel and Newton iteration, then a rim check on converged poses). For a
locally planar surface through ``S`` the gap is ``n·(c - S) - r_eff sqrt(1 - (n·a)^2)``
(wheel centre ``c``, axle ``a``, contact radius ``r_eff``); its derivative in ``u`` with
``n`` held fixed is the Newton Jacobian (``_jacobian``). A pose converges when every
wheel's contact search has converged within ``tol_m`` and the gaps are below ``tol_m``.

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

Flags: a pose is *converged* when all six gaps are below ``tol_m``, the rim check found
nothing deeper than ``tol_m + CHECK_SLACK_M`` and no joint is folded (``FOLDED_RAD``);
*within limits* when the rocker and bogie angles are inside their joint stops. Poses failing
either (a boulder no suspension could straddle, a terrain returning NaN) are flagged, never
silently returned as good.

Newton ignores the joint stops, so that a pose needing a joint past its stop is found and
flagged (not within limits) rather than pinned on the stop. But the six contact equations
also have roots no rocker-bogie stands in: under a pillar too tall to straddle, the bogie
can turn on end (1.63 rad under a 1 m bump) with one wheel on each flank. A joint at a
quarter turn or more from its parent link is such a fold: the bogie's two wheels, level at
zero, then stand one above the other or have swapped ends; the rocker's front wheel stands
over its pivot. Whether Newton reaches such a root within ``max_iterations`` depends on the
last bits of its arithmetic; the flag must not, so a folded root never counts as converged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from sim.compiled import kernel
from sim.errors import InputError
from sim.rover.geometry import MER_GEOMETRY, RoverGeometry
from sim.rover.wheel_contact import (
    CHECK_SLACK_M,
    Wheels,
    contact,
    deeper,
    height_and_gradient,
    unit_normal,
    wheels,
)
from sim.world.terrain import Terrain

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

BLOCK_POSES = 4096  # poses solved together: bounds the memory of the rim checks
MAX_STEP_RAD = 0.1  # Newton step limit on the angles (rad), damps the first iterations
MAX_STEP_M = 0.05  # Newton step limit on the body height (m)
DAMP_AFTER = 10  # after this many iterations slow Newton steps are halved (_settle_block)
FIRST_HALF_RAD = float(np.deg2rad(5.0))  # first bracket half-width round the predicted contact
REJECT_FACTOR = 4.0  # a step is shortened if the largest gap grows this many times and
REJECT_MARGIN_M = 2e-3  # by this much: contact searches alone move it less
MIN_TRUST = 1.0 / 64.0  # shortest fraction of a Newton step
MAX_CHECKS = 3  # moves to a deeper basin before a pose is given up as not converged
PATH_STRIDE = 8  # along a path, settle every 8th pose first (3.75 cm apart at 3.75 cm/s)
PATH_BRACKET_RAD = float(np.deg2rad(1.0))  # contact bracket half-width from neighbours
CONTINUATION_STEPS = 4  # sub-steps from a settled pose to a path pose that did not settle
FOLDED_RAD = 0.5 * math.pi  # a joint this far from zero has folded its link on end


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
    angles = np.broadcast_arrays(
        np.asarray(roll, np.float64), np.asarray(pitch, np.float64), np.asarray(yaw, np.float64)
    )
    shape = angles[0].shape
    out = np.empty((3, angles[0].size, 3, 3))
    roll_f, pitch_f, yaw_f = (np.ascontiguousarray(a).reshape(-1) for a in angles)
    _rotations(roll_f, pitch_f, yaw_f, out)
    out = out.reshape(3, *shape, 3, 3)
    return out[0], out[1], out[2]


@kernel
def _rotations(roll: FloatArray, pitch: FloatArray, yaw: FloatArray, out: FloatArray) -> None:
    """``rotation_s_b`` of flat angle arrays into ``out`` (3, n, 3, 3): R and its partials."""
    for k in range(roll.size):
        cf, sf = np.cos(roll[k]), np.sin(roll[k])
        ct, st = np.cos(pitch[k]), np.sin(pitch[k])
        cp, sp = np.cos(yaw[k]), np.sin(yaw[k])
        R, dR_droll, dR_dpitch = out[0, k], out[1, k], out[2, k]
        R[0, 0], R[0, 1], R[0, 2] = cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf
        R[1, 0], R[1, 1], R[1, 2] = sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf
        R[2, 0], R[2, 1], R[2, 2] = -st, ct * sf, ct * cf
        dR_droll[0, 0] = 0.0
        dR_droll[0, 1] = cp * st * cf + sp * sf
        dR_droll[0, 2] = -cp * st * sf + sp * cf
        dR_droll[1, 0] = 0.0
        dR_droll[1, 1] = sp * st * cf - cp * sf
        dR_droll[1, 2] = -sp * st * sf - cp * cf
        dR_droll[2, 0], dR_droll[2, 1], dR_droll[2, 2] = 0.0, ct * cf, -ct * sf
        dR_dpitch[0, 0], dR_dpitch[0, 1], dR_dpitch[0, 2] = -cp * st, cp * ct * sf, cp * ct * cf
        dR_dpitch[1, 0], dR_dpitch[1, 1], dR_dpitch[1, 2] = -sp * st, sp * ct * sf, sp * ct * cf
        dR_dpitch[2, 0], dR_dpitch[2, 1], dR_dpitch[2, 2] = -ct, -st * sf, -st * cf


def _dot(a: FloatArray, b: FloatArray) -> FloatArray:
    """Dot product over a last axis of length 3 (faster than einsum on small axes)."""
    out: FloatArray = a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]
    return out


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
    h0, alpha, beta = geometry.plane_fit_b() @ h.T
    norm = np.sqrt(1.0 + alpha**2 + beta**2)
    height = geometry.wheel_centre_z_m + np.mean(r_eff, axis=-1)
    zero = np.zeros_like(x)
    roll = -np.arcsin(np.clip(beta / norm, -1.0, 1.0))
    return np.column_stack([-(h0 + height * norm), roll, np.arctan(alpha), zero, zero, zero])


def _jacobian(w: Wheels, n: FloatArray) -> FloatArray:
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
        u = b.u[active]
        rotation = rotation_s_b(u[:, 1], u[:, 2], yaw[active])
        w = wheels(geometry, rotation, u, x[active], y[active], steer[active], r_eff[active])
        if it == 0 and bracket0 is not None:
            b.lo, b.hi = bracket0[0].copy(), bracket0[1].copy()
        elif it == 0:  # round the rim point lowest along the normal under each wheel
            _, hx, hy = height_and_gradient(terrain, w.centre[..., 0], w.centre[..., 1])
            n = unit_normal(hx, hy)
            predicted = np.arctan2(-_dot(n, w.e_fwd), -_dot(n, w.e_low))
            b.lo, b.hi = predicted - FIRST_HALF_RAD, predicted + FIRST_HALF_RAD
        c = contact(terrain, w, b.lo[active], b.hi[active])
        b.lo[active], b.hi[active], b.theta[active] = c.lo, c.hi, c.theta
        b.gap[active], b.contact[active], b.normal[active] = c.gap, c.point, c.normal
        b.iterations[active] = it
        done = (np.max(np.abs(c.gap), axis=1) < tol_m) & (np.max(c.error, axis=1) < tol_m)
        stop = np.zeros_like(done)
        moved = np.zeros(0, dtype=np.int64)
        idx = np.flatnonzero(done)
        if idx.size:
            deep, lo, hi = deeper(
                terrain, w.take(idx), c.clearance[idx], c.theta[idx], tol_m + CHECK_SLACK_M
            )
            bad = np.any(deep, axis=1)
            redo = bad & (checks[active[idx]] < MAX_CHECKS)
            moved, flag = active[idx[redo]], deep[redo]
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
    folded = np.any(np.abs(u[:, 3:6]) >= FOLDED_RAD, axis=1)  # NaN compares False
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
        converged=blk.converged & ~folded,
        within_limits=within,
        iterations=blk.iterations,
    )
