"""Drive primitives: exact distances and arcs without slip, Ackermann steering, turns in
place, slip on slopes, continuity across heightmap tiles, input validation."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from sim.errors import InputError
from sim.rover import drive
from sim.rover.geometry import MER_GEOMETRY, STEERED_INDEX
from sim.rover.slip import SlipModel, slip_curve
from sim.rover.truth import CONTROL_DT_S, TruthTrajectory
from sim.world.sites import make_terrain
from sim.world.terrain import MERIDIANI_SAND, Eq22Terrain, FlatTerrain, PlaneTerrain

FloatArray = NDArray[np.float64]
G = MER_GEOMETRY
R_WHEEL = G.wheel_radius_m


def ideal(terrain: object) -> SlipModel:
    return SlipModel.ideal(terrain.soil)  # type: ignore[attr-defined]


def corner_axles_b(steer: FloatArray) -> FloatArray:
    """Axle directions (x, y, 0) of the four corner wheels in the body frame for ``steer``."""
    return np.column_stack([-np.sin(steer), np.cos(steer), np.zeros_like(steer)])


def flat3(xy: FloatArray) -> FloatArray:
    """Body-plane points (x, y) as (x, y, 0)."""
    return np.column_stack([xy, np.zeros(len(xy))])


def test_no_slip_straight_covers_exactly_the_commanded_distance() -> None:
    flat = FlatTerrain()
    distance = 1.234
    for yaw in (0.0, np.pi / 2, -2.0):
        start = drive.initial_state(flat, 100.0, 1.0, -2.0, yaw)
        traj, end = drive.drive_straight(flat, start, distance, ideal(flat))
        moved = traj.p_s[-1, :2] - traj.p_s[0, :2]
        assert np.linalg.norm(moved) == pytest.approx(distance, abs=1e-9)
        np.testing.assert_allclose(moved / distance, [math.cos(yaw), math.sin(yaw)], atol=1e-9)
        np.testing.assert_allclose(traj.wheel_angle_rad[-1], distance / R_WHEEL, atol=1e-9)
        # 8 Hz samples from the start, the last one at rest after the motion ends.
        steps = math.ceil(distance / (drive.DEFAULT_SPEED_M_S * CONTROL_DT_S))
        np.testing.assert_allclose(traj.t_s, 100.0 + np.arange(steps + 1) * CONTROL_DT_S)
        step_len = np.linalg.norm(np.diff(traj.p_s, axis=0), axis=1)
        assert np.all(step_len <= drive.DEFAULT_SPEED_M_S * CONTROL_DT_S + 1e-12)
        np.testing.assert_allclose(traj.slip, 0.0)
        assert end.unsettled_poses == 0 and end.t_s == traj.t_s[-1]
        np.testing.assert_allclose(end.p_s, traj.p_s[-1])


def test_heading_east_moves_east_and_the_body_points_east() -> None:
    flat = FlatTerrain()
    traj, _ = drive.drive_straight(
        flat, drive.initial_state(flat, 0.0, 0.0, 0.0, np.pi / 2), 0.5, ideal(flat)
    )
    assert traj.p_s[-1, 1] == pytest.approx(0.5, abs=1e-9)
    forward = Rotation.from_quat(traj.q_s_b).apply([1.0, 0.0, 0.0])
    np.testing.assert_allclose(forward, np.tile([0.0, 1.0, 0.0], (len(traj), 1)), atol=1e-9)


@pytest.mark.parametrize("radius", [2.5, -4.0, 0.6])
def test_arc_ends_on_its_circle_at_the_commanded_angle(radius: float) -> None:
    flat = FlatTerrain()
    yaw0, angle = 0.3, math.radians(75.0)
    start = drive.initial_state(flat, 0.0, 2.0, 1.0, yaw0)
    traj, end = drive.drive_arc(flat, start, radius, angle, ideal(flat))
    # Centre at |R| to the right of the heading for R > 0, to the left for R < 0.
    right = np.array([-math.sin(yaw0), math.cos(yaw0)])
    centre = np.array([2.0, 1.0]) + radius * right
    dist = np.linalg.norm(traj.p_s[:, :2] - centre, axis=1)
    np.testing.assert_allclose(dist, abs(radius), atol=1e-9)  # every sample on the circle
    turned = end.yaw_rad - yaw0
    assert turned == pytest.approx(math.copysign(angle, radius), abs=1e-9)
    a0, a1 = (np.arctan2(*(p - centre)[::-1]) for p in (traj.p_s[0, :2], traj.p_s[-1, :2]))
    assert abs(math.remainder(a1 - a0, 2 * math.pi)) == pytest.approx(angle, abs=1e-9)
    # Ackermann: every corner wheel's axle line passes through the turn centre.
    centre_b = np.array([0.0, radius])
    wheels = G.wheel_xy_b()[list(STEERED_INDEX)]
    axles = corner_axles_b(traj.steer_rad[0])
    cross = np.cross(axles, flat3(centre_b - wheels))
    np.testing.assert_allclose(cross, 0.0, atol=1e-12)
    # Each wheel turns in proportion to its distance from the centre.
    lever = np.linalg.norm(G.wheel_xy_b() - centre_b, axis=1)
    np.testing.assert_allclose(traj.wheel_angle_rad[-1], lever * angle / R_WHEEL, rtol=1e-12)


def test_full_turn_in_place_on_eq22_returns_to_the_start() -> None:
    terrain = Eq22Terrain()
    start = drive.initial_state(terrain, 0.0, 0.3, 0.2, 0.5)
    traj, end = drive.turn_in_place(terrain, start, 2.0 * math.pi, ideal(terrain))
    assert end.yaw_rad - start.yaw_rad == pytest.approx(2.0 * math.pi, abs=1e-9)
    np.testing.assert_allclose(traj.p_s[:, :2], np.tile([0.3, 0.2], (len(traj), 1)), atol=1e-12)
    duration = 2.0 * math.pi / drive.DEFAULT_TURN_RATE_RAD_S  # 2.1 °/s: 171.4 s
    assert traj.t_s[-1] - traj.t_s[0] == pytest.approx(duration, abs=CONTROL_DT_S)
    # Back where it started: the same settled attitude and suspension.
    assert end.unsettled_poses == 0
    np.testing.assert_allclose(end.p_s, start.p_s, atol=2e-4)
    angle = (Rotation.from_quat(end.q_s_b) * Rotation.from_quat(start.q_s_b).inv()).magnitude()
    assert angle < 1e-3
    # The body really rode the bumps while turning.
    assert np.ptp(traj.p_s[:, 2]) > 0.005
    # Each corner wheel rolls tangent to its circle about the body origin.
    wheels = G.wheel_xy_b()[list(STEERED_INDEX)]
    axles = corner_axles_b(traj.steer_rad[0])
    np.testing.assert_allclose(np.cross(axles, flat3(-wheels)), 0.0, atol=1e-12)


def test_no_slip_on_a_slope_advances_by_the_cosine() -> None:
    slope = math.radians(20.0)
    plane = PlaneTerrain(math.tan(slope), 0.0)
    traj, end = drive.drive_straight(plane, drive.initial_state(plane, 0.0), 2.0, ideal(plane))
    assert end.p_s[0] - traj.p_s[0, 0] == pytest.approx(2.0 * math.cos(slope), abs=1e-9)
    assert end.p_s[2] - traj.p_s[0, 2] == pytest.approx(-2.0 * math.sin(slope), abs=1e-6)


def test_slip_on_a_steep_uphill_shortens_the_drive() -> None:
    slope = math.radians(18.0)
    plane = PlaneTerrain(math.tan(slope), 0.0, soil=MERIDIANI_SAND)
    distance = 3.0
    start = drive.initial_state(plane, 0.0)
    up, _ = drive.drive_straight(
        plane, start, distance, SlipModel(plane.soil, np.random.default_rng(1))
    )
    down_start = drive.initial_state(plane, 0.0, 0.0, 0.0, math.pi)
    down, _ = drive.drive_straight(
        plane, down_start, distance, SlipModel(plane.soil, np.random.default_rng(1))
    )
    ideal_run = distance * math.cos(slope)
    covered_up = up.p_s[-1, 0] - up.p_s[0, 0]
    covered_down = down.p_s[0, 0] - down.p_s[-1, 0]
    s_expected = float(slip_curve(plane.soil, slope)[0])
    assert 0.1 < s_expected < 0.5
    assert covered_up < ideal_run * (1.0 - 0.5 * s_expected)
    # The covered distance is what the slip allows (slip is on the undeformed radius, Wong
    # ch. 2, so sinkage adds no shortfall of its own; noise: ~2 % slip).
    predicted = ideal_run * (1.0 - s_expected)
    assert covered_up == pytest.approx(predicted, rel=0.05)
    assert np.mean(up.slip[1:]) == pytest.approx(s_expected, abs=0.05)
    assert covered_down > covered_up  # downhill the wheels skid: no shortfall from slope
    # The wheels still turned the commanded amount (MER's odometry ends the drive).
    np.testing.assert_allclose(up.wheel_angle_rad[-1], distance / R_WHEEL, atol=1e-9)


def test_drive_across_gusev_tile_edges_is_continuous() -> None:
    terrain = make_terrain("gusev", 1)
    tile = terrain.tile_size_m  # type: ignore[attr-defined]
    # Start 0.7 m short of a tile corner, heading across it diagonally (North-East).
    start = drive.initial_state(terrain, 0.0, tile - 0.7, tile - 0.7, math.pi / 4)
    slip = SlipModel(terrain.soil, np.random.default_rng(2))
    traj, end = drive.drive_straight(terrain, start, 2.0, slip)
    assert end.unsettled_poses == 0
    crossed = (traj.p_s[:, 0] > tile) & (traj.p_s[:, 1] > tile)
    assert crossed[-1] and not crossed[0]
    step = np.linalg.norm(np.diff(traj.p_s, axis=0), axis=1)
    assert np.max(step) < 1.5 * drive.DEFAULT_SPEED_M_S * CONTROL_DT_S  # no jumps
    turn = Rotation.from_quat(traj.q_s_b[1:]) * Rotation.from_quat(traj.q_s_b[:-1]).inv()
    assert np.max(np.degrees(turn.magnitude())) < 2.0
    # Joints move fast only where a wheel climbs a rock edge; nothing jumps.
    assert np.max(np.abs(np.diff(traj.rocker_rad))) < math.radians(5.0)
    assert np.max(np.abs(np.diff(traj.bogie_rad, axis=0))) < math.radians(15.0)
    # Where the body crosses each tile edge the step is an ordinary one.
    for axis in (0, 1):
        k = int(np.flatnonzero(traj.p_s[:, axis] > tile)[0])
        assert step[k - 1] < 1.2 * np.median(step)


def test_primitives_chain_and_repeat_bit_for_bit() -> None:
    terrain = Eq22Terrain()

    def run() -> list[FloatArray]:
        slip = SlipModel(MERIDIANI_SAND, np.random.default_rng(11))
        state = drive.initial_state(terrain, 5.0, -0.5, 0.0, 0.2)
        out = []
        steps: list[Callable[[drive.DriveState], tuple[TruthTrajectory, drive.DriveState]]] = [
            lambda s: drive.drive_straight(terrain, s, 0.3, slip),
            lambda s: drive.turn_in_place(terrain, s, -0.4, slip),
            lambda s: drive.drive_arc(terrain, s, -1.5, 0.3, slip),
        ]
        for step in steps:
            traj, new = step(state)
            assert traj.t_s[0] == state.t_s  # each starts where the previous ended
            np.testing.assert_allclose(traj.p_s[0, :2], state.p_s[:2], atol=1e-12)
            np.testing.assert_allclose(traj.wheel_angle_rad[0], state.wheel_angle_rad)
            out += [traj.p_s, traj.q_s_b, traj.wheel_angle_rad, traj.slip]
            state = new
        return out

    for a, b in zip(run(), run(), strict=True):
        assert np.array_equal(a, b)


def test_bad_commands_name_their_parameter() -> None:
    flat = FlatTerrain()
    start, slip = drive.initial_state(flat, 0.0), ideal(flat)
    cases: list[tuple[str, Callable[[], object]]] = [
        ("distance_m", lambda: drive.drive_straight(flat, start, 0.0, slip)),
        ("distance_m", lambda: drive.drive_straight(flat, start, -1.0, slip)),
        ("distance_m", lambda: drive.drive_straight(flat, start, float("nan"), slip)),
        ("distance_m", lambda: drive.drive_straight(flat, start, 1001.0, slip)),
        ("speed_m_s", lambda: drive.drive_straight(flat, start, 1.0, slip, speed_m_s=0.0)),
        ("radius_m", lambda: drive.drive_arc(flat, start, 0.5, 0.1, slip)),
        ("radius_m", lambda: drive.drive_arc(flat, start, float("inf"), 0.1, slip)),
        ("angle_rad", lambda: drive.drive_arc(flat, start, 2.0, -0.1, slip)),
        ("angle_rad", lambda: drive.drive_arc(flat, start, 600.0, 2.0, slip)),
        ("angle_rad", lambda: drive.turn_in_place(flat, start, 0.0, slip)),
        ("angle_rad", lambda: drive.turn_in_place(flat, start, 50.0, slip)),
        ("rate_rad_s", lambda: drive.turn_in_place(flat, start, 1.0, slip, rate_rad_s=-1.0)),
        ("x_m", lambda: drive.initial_state(flat, 0.0, float("nan"))),
    ]
    for name, call in cases:
        with pytest.raises(InputError) as err:
            call()
        assert err.value.parameter == name
