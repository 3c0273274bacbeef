"""A dragged wheel (sim.rover.drag; Spirit's right front from sol 125, Cheng, Maimone and
Matthies 2005 sec. 4.2): the rover veers towards it, its encoder rolls little, the five
driven wheels slip more, and wheel odometry over the five driven wheels is what they say;
the balance's invariants (a symmetric pair does not yaw; no drag is the six-wheel model)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation.geometry import WHEEL_KEYS
from estimation.sapp.wheel_odometry import DriveKind, odometry_deltas
from sim.errors import InputError
from sim.rover import drive
from sim.rover.drag import ROLL_FRACTION, Drag
from sim.rover.geometry import MER_GEOMETRY as G
from sim.rover.slip import SlipModel, SlipParams, slip_curve
from sim.rover.truth import TruthTrajectory
from sim.world.terrain import GUSEV_SOIL, FlatTerrain, PlaneTerrain

LEVEL = FlatTerrain(soil=GUSEV_SOIL)


def _straight(
    terrain: FlatTerrain | PlaneTerrain, distance_m: float, drag: Drag | None, seed: int = 3
) -> tuple[TruthTrajectory, drive.DriveState]:
    start = drive.initial_state(terrain, 0.0)
    model = SlipModel(terrain.soil, np.random.default_rng(seed))
    return drive.drive_straight(terrain, start, distance_m, model, drag=drag)


@pytest.mark.parametrize("key", WHEEL_KEYS)
def test_a_dragged_wheel_veers_the_rover_towards_its_side(key: str) -> None:
    _, plain = _straight(LEVEL, 2.0, None)
    _, dragged = _straight(LEVEL, 2.0, Drag.of(key))
    assert plain.yaw_rad == 0.0  # level ground, no drag: straight on
    side = math.copysign(1.0, G.wheel_xy_b()[WHEEL_KEYS.index(key), 1])  # y right
    # heading increases turning right (clockwise from above): towards a right wheel
    assert side * dragged.yaw_rad > math.radians(2.0)


def test_the_dragged_wheel_rolls_little_and_the_others_as_commanded() -> None:
    traj, _ = _straight(LEVEL, 2.0, Drag.of("rf"))
    rolled_m = (traj.wheel_angle_rad[-1] - traj.wheel_angle_rad[0]) * G.wheel_radius_m
    driven = np.array([0, 1, 2, 4, 5])
    np.testing.assert_allclose(rolled_m[driven], 2.0, rtol=1e-12)
    ground_m = np.diff(traj.wheel_angle_rad[:, 0]) * G.wheel_radius_m * (1.0 - traj.slip[1:])
    expected = ROLL_FRACTION * float(np.sum(ground_m))  # 5 % of its ground travel
    assert rolled_m[3] == pytest.approx(expected, rel=1e-9)
    assert rolled_m[3] < 0.1 * rolled_m[0]


def test_the_driven_wheels_slip_more_carrying_the_drag() -> None:
    plain, _ = _straight(LEVEL, 2.0, None)
    dragged, _ = _straight(LEVEL, 2.0, Drag.of("rf"))
    # the same noise draws: the difference is the model's extra slip, at every step
    extra = dragged.slip[1:] - plain.slip[1:]
    assert np.all(extra > 0.02)
    covered = np.hypot(*(dragged.p_s[-1, :2] - dragged.p_s[0, :2]))
    assert covered < plain.p_s[-1, 0] - plain.p_s[0, 0]


def test_a_symmetric_pair_does_not_yaw_and_one_wheel_does() -> None:
    flat = np.zeros(3)
    slopes = np.tan(np.radians([-10.0, 0.0, 10.0]))
    extra, kappa = Drag((0, 3)).path_effect(GUSEV_SOIL, slopes, flat, SlipParams(), G)
    np.testing.assert_array_equal(kappa, 0.0)
    assert np.all(extra > 0.0)
    # mirror wheels yaw by opposite amounts with the same extra slip
    rf, lf = Drag((3,)), Drag((0,))
    e_rf, k_rf = rf.path_effect(GUSEV_SOIL, slopes, flat, SlipParams(), G)
    e_lf, k_lf = lf.path_effect(GUSEV_SOIL, slopes, flat, SlipParams(), G)
    np.testing.assert_allclose(k_rf, -k_lf, rtol=1e-12)
    np.testing.assert_allclose(e_rf, e_lf, rtol=1e-12)
    # the yaw is the fixed point of κ = (s_R - s_L) / B
    s_l, s_r = rf.side_slips(GUSEV_SOIL, slopes, flat, k_rf, SlipParams(), G)
    np.testing.assert_allclose(k_rf, (s_r - s_l) / G.track_m, rtol=1e-9)
    # with no lateral resistance (κ = 0 in the moment) the yaw would be larger
    s_l0, s_r0 = rf.side_slips(GUSEV_SOIL, slopes, flat, 0.0 * k_rf, SlipParams(), G)
    assert np.all((s_r0 - s_l0) / G.track_m > k_rf)
    # the body's slip is the six-wheel model's plus the extra
    six, _ = slip_curve(GUSEV_SOIL, np.arctan(slopes))
    np.testing.assert_allclose(0.5 * (s_l + s_r), six + e_rf, rtol=1e-12)


def test_a_turn_in_place_dragging_a_corner_turns_less() -> None:
    start = drive.initial_state(LEVEL, 0.0)
    ends = []
    for drag in (None, Drag.of("rr")):
        model = SlipModel(LEVEL.soil, np.random.default_rng(5))
        _, end = drive.turn_in_place(LEVEL, start, math.radians(30.0), model, drag=drag)
        ends.append(end.yaw_rad)
    assert 0.0 < ends[1] < ends[0] - math.radians(0.5)


def _odometry(terrain: PlaneTerrain, drag_wheel: str | None) -> tuple[float, float, float]:
    """Wheel odometry (eq. 5) on the truth's wheel angles of a 4 m drive dragging ``rf``,
    each step turned into the Site with the true attitude (the gyros' job, as SAPP does with
    its own): ``(distance it measures, its distance from the true end, the true path)`` (m)."""
    traj, _ = _straight(terrain, 4.0, Drag.of("rf"))
    steps = len(traj) - 1
    dp_b, _ = odometry_deltas(
        DriveKind.STRAIGHT,
        np.diff(traj.wheel_angle_rad, axis=0),
        np.zeros((steps, 6)),
        drag_wheel=drag_wheel,
    )
    p_s = np.sum(Rotation.from_quat(traj.q_s_b[1:]).apply(dp_b), axis=0)
    path = float(np.sum(np.linalg.norm(np.diff(traj.p_s, axis=0), axis=1)))
    return (
        float(np.sum(dp_b[:, 0])),
        float(np.linalg.norm(p_s - (traj.p_s[-1] - traj.p_s[0]))),
        path,
    )


def test_five_wheel_odometry_measures_what_the_driven_wheels_rolled() -> None:
    """Level ground: the five driven wheels say 4 m, the six-wheel average a sixth less of
    the dragged wheel's share; what is left is the driven wheels' slip."""
    level = PlaneTerrain(0.0, 0.0, soil=GUSEV_SOIL)
    five, err_five, path = _odometry(level, "rf")
    six, _, _ = _odometry(level, None)
    assert five == pytest.approx(4.0, abs=1e-12)
    traj, _ = _straight(level, 4.0, Drag.of("rf"))
    rolled_rf = (traj.wheel_angle_rad[-1, 3] - traj.wheel_angle_rad[0, 3]) * G.wheel_radius_m
    assert six == pytest.approx((5.0 * 4.0 + rolled_rf) / 6.0, abs=1e-12)
    slip = 1.0 - path / 4.0  # the body's, which the five wheels cannot see
    assert err_five == pytest.approx(slip * 4.0, rel=0.05)


def test_five_wheel_odometry_is_closer_than_six_downhill() -> None:
    """Where the driven wheels slip less than the six-wheel average's missing share (about
    16 %, halved), five-wheel odometry is the closer: downhill here. (On level Gusev soil the
    drag's own slip, ~8 %, about cancels the six-wheel average's shortfall: the two are alike.)"""
    down = PlaneTerrain(math.tan(math.radians(-8.0)), 0.0, soil=GUSEV_SOIL)
    _, five, path = _odometry(down, "rf")
    _, six, _ = _odometry(down, None)
    assert five < 0.5 * six
    assert five < 0.05 * path


def test_drag_wheels_are_checked() -> None:
    assert Drag.of(None, None) is None
    assert Drag.of("rf", "rf") == Drag((3,))
    with pytest.raises(InputError, match="drag_wheel"):
        Drag.of("RF")
    with pytest.raises(InputError, match="drag_wheel"):
        Drag((0, 1, 2))  # a whole side dragged: nothing left to steer it by
