"""Drive primitives of the rover: straight, arc and turn in place, as batches of truth.

Each primitive starts from a ``DriveState`` and returns the truth sampled at the control
rate (``CONTROL_DT_S``, 8 Hz) from the start to the end, both included, with the state it
ends in: ``(TruthTrajectory, DriveState)``. Samples sit on the control grid
``t0 + k·CONTROL_DT_S``; the motion ends inside the last interval and the last sample shows
the rover at rest at the end. Sample 0 is the start pose (the previous primitive's last)
with this primitive's steering (the steering motion itself is not modelled).

Commanded motion (Ali et al. 2005 section 2.5): the body origin moves at ``speed_m_s``
(3.75 cm/s) along the path, or the body turns at ``rate_rad_s`` (2.1°/s, Ali et al. 2005
section 2.4.2). The corner wheels steer (angle positive turning the wheel's front to the
right, clockwise seen from above, as in Ali et al. 2005) so that every wheel rolls about the
turn centre (Ackermann geometry; all-wheel steering as in Volpe's memo, Ali et al. 2005 ref. 7):
a wheel at body ``(x_i, y_i)`` on an arc about ``(0, R)`` steers to
``atan(x_i / (R - y_i))`` and rolls ``hypot(x_i, R - y_i) / |R|`` times the path. The
middle wheels sit on the body y axis, so they roll straight on any arc and turn in place
(the turn centre of ``turn_in_place`` is the body origin). The wheels turn at the
commanded rates for the nominal radius, and a drive ends when they have turned the
commanded amount, as MER's wheel odometry decides (no visual odometry here).

Actual motion: along the track the ground moves ``ds (1 - s)`` (slip ``s`` from
``sim.rover.slip``, defined on the undeformed wheel radius as in Wong ch. 2, so the losses of a
sunk wheel are in ``s`` and sinkage only lowers the rover in ``sim.rover.settle``), whose
horizontal part is that times ``cos(θ_a)`` for the along-track slope ``θ_a``; lateral
creep ``c`` moves the rover sideways by ``ds c cos(θ_c)``; on an arc the heading follows
the horizontal path. A turn in place turns ``(1 - s)`` of the commanded angle and creeps
down the fall line. The planar motion is integrated step by step, each step's slip from the
slope under the rover at its start (the plane through the ground under the six wheels:
the gradient at the body position alone would answer to a rock under the belly); for
speed a window of steps is evaluated at once from guessed start poses and the steps whose
guess was right kept (``_integrate``: the sequential result, independent of the window).
Then the whole batch is settled on the terrain at once (``sim.rover.settle``), which gives
height, attitude and suspension. Poses that do not settle are counted in
``DriveState.unsettled_poses`` and logged, never hidden; in the truth, one that did not
converge (rare, about one in 10,000 on Gusev: a wheel caught between the ground and a rock
face) holds the suspension interpolated between its settled neighbours, so the sensors see
no jump where the solver gave up.

Signs: ``drive_arc`` with ``radius_m > 0`` turns about a centre on the rover's right (a
right turn, heading increasing), ``radius_m < 0`` about one on its left; ``angle_rad > 0``
is the heading change driven forwards. ``turn_in_place`` with ``angle_rad > 0`` turns
clockwise seen from above (to the right, heading increasing).

A dragged wheel (``drag``, ``sim.rover.drag``: a wheel the command leaves undriven, or
whose motor failed) adds its slip and yaw to each step and rolls little; without one the
arithmetic here is what it was.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, fields, replace

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.geometry import DRIVE_SPEED_M_S, TURN_RATE_RAD_S
from sequences.limits import MAX_DRIVE_M
from sim.errors import InputError
from sim.rover.drag import Drag
from sim.rover.geometry import MER_GEOMETRY, STEERED_INDEX, RoverGeometry
from sim.rover.settle import Settled, settle
from sim.rover.slip import SlipModel
from sim.rover.truth import CONTROL_DT_S, TruthTrajectory
from sim.world.terrain import Terrain

FloatArray = NDArray[np.float64]
log = logging.getLogger(__name__)

DEFAULT_SPEED_M_S = DRIVE_SPEED_M_S  # the flight software's, Ali et al. 2005 section 2.5
DEFAULT_TURN_RATE_RAD_S = TURN_RATE_RAD_S  # the flight software's, Ali et al. 2005 sec. 2.4.2
MAX_PATH_M = MAX_DRIVE_M  # one drive command (sequences.limits): longer is an input error
MAX_SPEED_M_S = 0.1  # twice MER's ~5 cm/s top speed (docs/REFERENCES.md)
MAX_TURN_RATE_RAD_S = math.radians(10.0)  # about five times MER's 2.1°/s
MAX_TURN_RAD = 4.0 * math.pi  # two full turns
CHUNK_STEPS = 256  # control steps evaluated together (32 s, 1.2 m at 3.75 cm/s)
FIXED_POINT_TOL_M = 1e-12  # a guessed start pose counts as right within this (m, rad)


@dataclass(frozen=True)
class DriveState:
    """The rover at rest between primitives (Site frame, SI units).

    ``p_s`` (3,) body origin (N, E, Down); ``q_s_b`` (4,) ``[x, y, z, w]``; ``yaw_rad``
    the heading (clockwise from North); ``rocker_rad``, ``bogie_rad`` (2,) suspension;
    ``wheel_angle_rad`` (6,) cumulative wheel rotations; ``steer_rad`` (4,) corner steering;
    ``slip`` the last slip ratio. ``max_gap_m`` and ``unsettled_poses`` describe the
    settling of the primitive that led here: the largest wheel gap of the settled poses and
    how many poses failed to settle (see ``sim.rover.settle``).
    """

    t_s: float
    p_s: FloatArray
    q_s_b: FloatArray
    yaw_rad: float
    rocker_rad: float
    bogie_rad: FloatArray
    wheel_angle_rad: FloatArray
    steer_rad: FloatArray
    slip: float = 0.0
    max_gap_m: float = 0.0
    unsettled_poses: int = 0

    def at_time(self, t_s: float) -> DriveState:
        """The same rover at rest at another time."""
        return replace(self, t_s=float(t_s))

    def as_trajectory(self) -> TruthTrajectory:
        """This state as a one-sample trajectory."""
        return TruthTrajectory(
            t_s=np.array([self.t_s]),
            p_s=self.p_s[None, :].copy(),
            q_s_b=self.q_s_b[None, :].copy(),
            rocker_rad=np.array([self.rocker_rad]),
            bogie_rad=self.bogie_rad[None, :].copy(),
            wheel_angle_rad=self.wheel_angle_rad[None, :].copy(),
            steer_rad=self.steer_rad[None, :].copy(),
            slip=np.array([self.slip]),
        )

    def suspension(self) -> FloatArray:
        """The settle unknowns ``(z, roll, pitch, rocker, bogie_l, bogie_r)``, (6,)."""
        _, pitch, roll = Rotation.from_quat(self.q_s_b).as_euler("ZYX")
        return np.array([self.p_s[2], roll, pitch, self.rocker_rad, *self.bogie_rad])


def _state_from(
    traj: TruthTrajectory, yaw_rad: float, settled: Settled, start: int = 0
) -> DriveState:
    """The state at the last sample of ``traj``; gap figures over ``settled[start:]``."""
    ok = settled.ok[start:]
    gaps = np.abs(settled.gap_m[start:][ok])
    return DriveState(
        t_s=float(traj.t_s[-1]),
        p_s=traj.p_s[-1].copy(),
        q_s_b=traj.q_s_b[-1].copy(),
        yaw_rad=float(yaw_rad),
        rocker_rad=float(traj.rocker_rad[-1]),
        bogie_rad=traj.bogie_rad[-1].copy(),
        wheel_angle_rad=traj.wheel_angle_rad[-1].copy(),
        steer_rad=traj.steer_rad[-1].copy(),
        slip=float(traj.slip[-1]),
        max_gap_m=float(gaps.max()) if gaps.size else 0.0,
        unsettled_poses=int(np.count_nonzero(~ok)),
    )


def initial_state(
    terrain: Terrain,
    t_s: float,
    x_m: float = 0.0,
    y_m: float = 0.0,
    yaw_rad: float = 0.0,
    slip_model: SlipModel | None = None,
) -> DriveState:
    """The rover settled at rest at ``(x_m, y_m)`` with heading ``yaw_rad``, wheels straight.

    The wheels sink as ``slip_model`` says at rest (default: the soil's static sinkage).
    """
    for name, value in (("t_s", t_s), ("x_m", x_m), ("y_m", y_m), ("yaw_rad", yaw_rad)):
        if not math.isfinite(value):
            raise InputError(name, "must be finite")
    geometry = MER_GEOMETRY if slip_model is None else slip_model.geometry
    sinkage = None if slip_model is None else slip_model.sinkage_m(0.0, x_m=x_m, y_m=y_m)
    s = settle(terrain, x_m, y_m, yaw_rad, sinkage_m=sinkage, geometry=geometry)
    traj = _trajectory(np.array([t_s]), s, np.zeros((1, 6)), np.zeros(4), np.zeros(1))
    return _state_from(traj, yaw_rad, s)


def _trajectory(
    t_s: FloatArray, s: Settled, wheel: FloatArray, steer: FloatArray, slip: FloatArray
) -> TruthTrajectory:
    return TruthTrajectory(
        t_s=t_s,
        p_s=s.p_s,
        q_s_b=s.q_s_b,
        rocker_rad=s.rocker_rad,
        bogie_rad=s.bogie_rad,
        wheel_angle_rad=wheel,
        steer_rad=np.broadcast_to(steer, (t_s.size, 4)).copy(),
        slip=slip,
    )


def _check(name: str, value: float, low: float, high: float) -> float:
    """``value`` as a float in ``(low, high]``, else InputError naming ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(name, f"must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise InputError(name, "must be a finite number")
    if not low < v <= high:
        raise InputError(name, f"must be in ({low:g}, {high:g}], got {v:g}")
    return v


def _schedule(total: float, rate: float, max_cycles: int | None = None) -> FloatArray:
    """Cumulative commanded amount at the control instants, ``min(k dt rate, total)``.

    Shape (K + 1,), from 0 to exactly ``total`` (K >= 1 steps of ``CONTROL_DT_S``).
    ``max_cycles``: the drive was halted after that many cycles (``cut_cycles``): the
    first ``max_cycles`` steps only, the same as the whole drive's.
    """
    steps = max(1, math.ceil(total / (rate * CONTROL_DT_S) - 1e-9))
    out: FloatArray = np.minimum(np.arange(steps + 1) * (CONTROL_DT_S * rate), total)
    out[-1] = total
    if max_cycles is not None:
        out = out[: cut_cycles(max_cycles) + 1]
    return out


def cut_cycles(max_cycles: int) -> int:
    """``max_cycles`` checked: a drive halted by fault protection after that many control
    cycles. Its truth is the uncut drive's up to there (the slip noise is drawn step by
    step, so its first draws are the same) and the rover stands where it stopped."""
    if isinstance(max_cycles, bool) or not isinstance(max_cycles, int) or max_cycles < 1:
        raise InputError("max_cycles", f"must be a whole number >= 1, got {max_cycles!r}")
    return max_cycles


def _slopes(
    terrain: Terrain, geometry: RoverGeometry, x: FloatArray, y: FloatArray, yaw: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Vehicle-scale slopes at body poses: ``(tan along track, tan across (rising right))``.

    The least-squares plane through the ground under the six wheels: slip and creep answer
    to the slope the whole rover stands on, not to a rock under its belly (the gradient at
    the body position alone swings by tens of degrees across a rock on Gusev).
    """
    wxy = geometry.wheel_xy_b()
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    h = terrain.height_m(
        x[:, None] + c * wxy[:, 0] - s * wxy[:, 1], y[:, None] + s * wxy[:, 0] + c * wxy[:, 1]
    )
    _, along, across = geometry.plane_fit_b() @ h.T
    return along, across


Step = tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]
Increments = Callable[[slice, FloatArray, FloatArray, FloatArray], Step]
"""``f(steps, x, y, yaw) -> (dx, dy, dyaw, slip, sinkage_m)`` for the steps ``steps``
(a slice), given the body pose at the start of each of them."""


def _integrate(start: DriveState, k_steps: int, increments: Increments) -> tuple[FloatArray, ...]:
    """Step the planar pose through ``k_steps`` steps, each from the pose it starts at.

    Exactly the sequential recursion, computed a window at a time: the window's start
    poses are guessed, the increments evaluated at them at once, and the steps whose start
    pose was guessed right (to ``FIXED_POINT_TOL_M``) accepted; the first wrong guess is
    now known exactly, so every pass accepts at least one step, and on smooth ground a
    whole window. Returns ``x, y, yaw`` (K + 1,), ``slip``, ``sinkage_m`` (K,).
    """
    pose = np.empty((3, k_steps + 1))
    pose[:, 0] = start.p_s[0], start.p_s[1], start.yaw_rad
    guess = np.full((3, k_steps + 1), np.nan)
    slip, sink = np.empty(k_steps), np.empty(k_steps)
    step = np.zeros(3)  # the last accepted increment: extrapolates new guesses
    cursor = 0
    while cursor < k_steps:
        hi = min(cursor + CHUNK_STEPS, k_steps)
        g = guess[:, cursor:hi].copy()
        g[:, 0] = pose[:, cursor]
        unknown = np.isnan(g[0])
        g[:, unknown] = pose[:, cursor, None] + step[:, None] * np.flatnonzero(unknown)
        dx, dy, dyaw, sl, sk = increments(slice(cursor, hi), g[0], g[1], g[2])
        new = pose[:, cursor, None] + np.cumsum(np.stack([dx, dy, dyaw]), axis=1)
        wrong = np.flatnonzero(np.any(np.abs(new[:, :-1] - g[:, 1:]) > FIXED_POINT_TOL_M, 0))
        n_ok = hi - cursor if wrong.size == 0 else int(wrong[0]) + 1
        pose[:, cursor + 1 : cursor + 1 + n_ok] = new[:, :n_ok]
        slip[cursor : cursor + n_ok], sink[cursor : cursor + n_ok] = sl[:n_ok], sk[:n_ok]
        guess[:, cursor + 1 : hi + 1] = new  # the next guesses for the steps not accepted
        step = np.array([dx[n_ok - 1], dy[n_ok - 1], dyaw[n_ok - 1]])
        cursor += n_ok
    return pose[0], pose[1], pose[2], slip, sink


def _path_increments(
    terrain: Terrain,
    ds: FloatArray,
    curvature: float,
    slip_model: SlipModel,
    drag: Drag | None = None,
) -> Increments:
    """Increments of a drive along a path of ``curvature`` (1/m) in steps ``ds`` (m)."""
    noise = slip_model.noise(ds)
    dragging = drag is not None and not slip_model.no_slip

    def f(steps: slice, x: FloatArray, y: FloatArray, yaw: FloatArray) -> Step:
        ta, tc = _slopes(terrain, slip_model.geometry, x, y, yaw)
        sample = slip_model.drive(np.arctan(ta), np.arctan(tc), noise[steps], x_m=x, y_m=y)
        # Slip is defined on the undeformed radius (Wong, ch. 2): the soil losses that
        # sinkage brings are already in the slip law, so sinkage only lowers the rover.
        rolled = ds[steps]
        veer: FloatArray | float = 0.0
        if dragging:  # the dragged wheel: more slip, and a yaw towards it (sim.rover.drag)
            assert drag is not None
            sample, veer = drag.path_sample(slip_model, ta, tc, sample)
        along = rolled * (1.0 - sample.slip) / np.sqrt(1.0 + ta**2)  # horizontal
        side = rolled * sample.creep / np.sqrt(1.0 + tc**2)
        turn = curvature * along
        if dragging:
            turn = turn + veer * rolled
        mid = yaw + 0.5 * turn
        chord = along * np.sinc(turn / (2.0 * np.pi))  # exact chord of the arc step
        dx = chord * np.cos(mid) - side * np.sin(mid)
        dy = chord * np.sin(mid) + side * np.cos(mid)
        return dx, dy, turn, sample.slip, sample.sinkage_m

    return f


def _turn_increments(
    terrain: Terrain,
    dpsi: FloatArray,
    mean_lever_m: float,
    slip_model: SlipModel,
    drag: Drag | None = None,
) -> Increments:
    """Increments of a turn in place in heading steps ``dpsi`` (rad): the turn slips, and
    the body creeps down the fall line by the creep fraction of the mean wheel travel."""
    rolled_cmd = np.abs(dpsi) * mean_lever_m
    noise = slip_model.noise(rolled_cmd)
    dragging = drag is not None and not slip_model.no_slip

    def f(steps: slice, x: FloatArray, y: FloatArray, yaw: FloatArray) -> Step:
        along, across = _slopes(terrain, slip_model.geometry, x, y, yaw)
        c, s = np.cos(yaw), np.sin(yaw)
        hx, hy = along * c - across * s, along * s + across * c  # back to North, East
        grade = np.hypot(hx, hy)
        sample = slip_model.turn(np.arctan(grade), noise[steps], x_m=x, y_m=y)
        if dragging:  # turning the dragged wheel round too (sim.rover.drag)
            assert drag is not None
            sample = drag.turn_sample(slip_model, np.arctan(grade), sample)
        creep = rolled_cmd[steps] * sample.creep / np.sqrt(1.0 + grade**2)
        down = np.where(grade > 0.0, creep / np.where(grade > 0.0, grade, 1.0), 0.0)
        turn = dpsi[steps] * (1.0 - sample.slip)  # slip on the undeformed radius, as above
        return -down * hx, -down * hy, turn, sample.slip, sample.sinkage_m

    return f


def _finish(
    terrain: Terrain,
    start: DriveState,
    motion: tuple[FloatArray, ...],
    steer: FloatArray,
    wheel_rad: FloatArray,
    slip_model: SlipModel,
    drag: Drag | None = None,
) -> tuple[TruthTrajectory, DriveState]:
    """Settle the planar motion and assemble the truth and the end state (a dragged
    wheel's rotation is what it rolls, ``Drag.wheel_rad``)."""
    x, y, yaw, slip, sink = motion
    if drag is not None:
        wheel_rad = drag.wheel_rad(wheel_rad, slip)
    geometry = slip_model.geometry
    n = x.size
    at_start = slip_model.sinkage_m(start.slip, x_m=x[0], y_m=y[0])
    sinkage = np.concatenate([[float(at_start)], sink])
    # The first pose is the start pose: settle it from the start's suspension, so the two
    # primitives join on the same solution; the rest as one path.
    guess = start.suspension()
    first = settle(
        terrain,
        x[:1],
        y[:1],
        yaw[:1],
        guess=guess if np.all(np.isfinite(guess)) else None,
        steer_rad=steer,
        sinkage_m=sinkage[:1],
        geometry=geometry,
    )
    rest = settle(
        terrain,
        x[1:],
        y[1:],
        yaw[1:],
        steer_rad=steer,
        sinkage_m=sinkage[1:],
        geometry=geometry,
        along_path=True,
    )
    settled = _bridge(_concat(first, rest))
    t: FloatArray = start.t_s + np.arange(n, dtype=np.float64) * CONTROL_DT_S
    wheels = start.wheel_angle_rad + wheel_rad
    traj = _trajectory(t, settled, wheels, steer, np.concatenate([[start.slip], slip]))
    end = _state_from(traj, float(yaw[-1]), settled, start=1)
    if end.unsettled_poses:
        log.warning(
            "%d of %d poses did not settle (six wheels on the ground within limits)",
            end.unsettled_poses,
            n - 1,
        )
    return traj, end


def _bridge(s: Settled) -> Settled:
    """Poses that did not converge take the suspension interpolated between their nearest
    converged neighbours (in sample order), so the truth has no jump where the solver gave
    up; they stay flagged (``converged`` False) and are counted by the caller."""
    bad = ~s.converged
    good = np.flatnonzero(s.converged)
    if not np.any(bad) or good.size == 0:
        return s
    idx = np.flatnonzero(bad)
    u = s.unknowns()
    u[idx] = np.column_stack([np.interp(idx, good, u[good, j]) for j in range(6)])
    q = Rotation.from_euler("ZYX", np.column_stack([s.yaw_rad, u[:, 2], u[:, 1]])).as_quat()
    p = s.p_s.copy()
    p[:, 2] = u[:, 0]
    return replace(
        s,
        p_s=p,
        q_s_b=q,
        roll_rad=u[:, 1],
        pitch_rad=u[:, 2],
        rocker_rad=u[:, 3],
        bogie_rad=u[:, 4:6],
    )


def _concat(a: Settled, b: Settled) -> Settled:
    return Settled(*(np.concatenate([getattr(a, f.name), getattr(b, f.name)]) for f in fields(a)))


def _arc_wheels(geometry: RoverGeometry, radius_m: float) -> tuple[FloatArray, FloatArray]:
    """Steering (4,) and roll per metre of body path (6,) for an arc of ``radius_m``."""
    wxy = geometry.wheel_xy_b()
    sign = math.copysign(1.0, radius_m)
    lever = radius_m - wxy[:, 1]  # from each wheel to the centre (0, R), across
    sigma = np.arctan2(wxy[:, 0] * sign, lever * sign)
    roll = np.hypot(wxy[:, 0], lever) / abs(radius_m)
    return sigma[list(STEERED_INDEX)], roll


def drive_straight(
    terrain: Terrain,
    start: DriveState,
    distance_m: float,
    slip_model: SlipModel,
    speed_m_s: float = DEFAULT_SPEED_M_S,
    max_cycles: int | None = None,
    drag: Drag | None = None,
) -> tuple[TruthTrajectory, DriveState]:
    """Drive ``distance_m`` (> 0, wheel odometry) straight ahead at ``speed_m_s``
    (``max_cycles``: halted after that many control cycles, ``cut_cycles``; ``drag``: the
    dragged wheels, ``sim.rover.drag``; the drive ends when the driven wheels have turned).

    >>> from sim.world.terrain import FlatTerrain
    >>> flat = FlatTerrain()
    >>> traj, end = drive_straight(flat, initial_state(flat, 0.0), 0.5, SlipModel.ideal(flat.soil))
    >>> round(float(end.p_s[0]), 12), len(traj)
    (0.5, 108)
    """
    d = _check("distance_m", distance_m, 0.0, MAX_PATH_M)
    v = _check("speed_m_s", speed_m_s, 0.0, MAX_SPEED_M_S)
    s_cmd = _schedule(d, v, max_cycles)
    ds = np.diff(s_cmd)
    motion = _integrate(start, ds.size, _path_increments(terrain, ds, 0.0, slip_model, drag))
    r = slip_model.geometry.wheel_radius_m
    wheel = np.outer(s_cmd, np.ones(6)) / r
    return _finish(terrain, start, motion, np.zeros(4), wheel, slip_model, drag)


def drive_arc(
    terrain: Terrain,
    start: DriveState,
    radius_m: float,
    angle_rad: float,
    slip_model: SlipModel,
    speed_m_s: float = DEFAULT_SPEED_M_S,
    max_cycles: int | None = None,
    drag: Drag | None = None,
) -> tuple[TruthTrajectory, DriveState]:
    """Drive forwards along an arc of ``radius_m`` through a heading change ``angle_rad``
    (``drag`` as ``drive_straight``'s).

    ``radius_m`` > 0: centre on the right (heading increases); < 0: on the left. Its size
    is the radius of the body origin's path, at least half the track. ``angle_rad`` > 0.
    """
    geometry = slip_model.geometry
    half_track = 0.5 * geometry.track_m
    radius = _check("radius_m", radius_m, -1e6, 1e6)
    if abs(radius) < half_track:
        raise InputError("radius_m", f"must be at least half the track, {half_track:g} m")
    angle = _check("angle_rad", angle_rad, 0.0, 2.0 * math.pi)
    v = _check("speed_m_s", speed_m_s, 0.0, MAX_SPEED_M_S)
    length = abs(radius) * angle
    if length > MAX_PATH_M:
        raise InputError("angle_rad", f"the arc is {length:g} m long, more than {MAX_PATH_M:g}")
    steer, roll = _arc_wheels(geometry, radius)
    s_cmd = _schedule(length, v, max_cycles)
    ds = np.diff(s_cmd)
    increments = _path_increments(terrain, ds, 1.0 / radius, slip_model, drag)
    motion = _integrate(start, ds.size, increments)
    wheel = np.outer(s_cmd, roll) / geometry.wheel_radius_m
    return _finish(terrain, start, motion, steer, wheel, slip_model, drag)


def turn_in_place(
    terrain: Terrain,
    start: DriveState,
    angle_rad: float,
    slip_model: SlipModel,
    rate_rad_s: float = DEFAULT_TURN_RATE_RAD_S,
    max_cycles: int | None = None,
    drag: Drag | None = None,
) -> tuple[TruthTrajectory, DriveState]:
    """Turn about the body origin by ``angle_rad`` (> 0 clockwise seen from above;
    ``drag`` as ``drive_straight``'s).

    Each corner wheel steers tangent to its circle about the origin, the middle ones roll
    straight; the left wheels roll forwards on a right turn.
    """
    angle = _check("angle_rad", angle_rad, -MAX_TURN_RAD, MAX_TURN_RAD)
    if angle == 0.0:
        raise InputError("angle_rad", "must not be zero")
    rate = _check("rate_rad_s", rate_rad_s, 0.0, MAX_TURN_RATE_RAD_S)
    geometry = slip_model.geometry
    wxy = geometry.wheel_xy_b()
    sigma = np.arctan(-wxy[:, 0] / wxy[:, 1])  # velocity ∝ (-y, x): keep |σ| < 90°
    lever = -wxy[:, 1] * np.cos(sigma) + wxy[:, 0] * np.sin(sigma)  # roll per rad, signed
    psi_cmd = math.copysign(1.0, angle) * _schedule(abs(angle), rate, max_cycles)
    dpsi = np.diff(psi_cmd)
    lever_m = float(np.mean(np.abs(lever)))
    increments = _turn_increments(terrain, dpsi, lever_m, slip_model, drag)
    motion = _integrate(start, dpsi.size, increments)
    wheel = np.outer(psi_cmd, lever) / geometry.wheel_radius_m
    steer = sigma[list(STEERED_INDEX)]
    return _finish(terrain, start, motion, steer, wheel, slip_model, drag)
