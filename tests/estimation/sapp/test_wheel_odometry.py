"""Wheel odometry (Ali et al. 2005 §2.5, eqs. 5-7) against hand-computed arcs, exact circles and
sim; with a dragged wheel, the five driven wheels' average."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation.geometry import (
    FLIGHT_GEOMETRY,
    WHEEL_KEYS,
    FlightGeometry,
    driven_wheels,
    wheel_index,
)
from estimation.sapp import wheel_odometry as wo
from estimation.sapp.nate import DriveCommand, Nate, NateMode
from estimation.sapp.nate_io import EncoderSample, ImuSample
from estimation.sapp.wheel_odometry import DriveKind
from tests.estimation.sapp.test_nate import LAT, LON, T0

XY = FLIGHT_GEOMETRY.wheel_xy_b()
RADIUS = FLIGHT_GEOMETRY.wheel_radius_m
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


def _tangent_steer(centre: np.ndarray) -> np.ndarray:
    """Steering that rolls each wheel forwards round ``centre`` for a right turn (ψ > 0).

    The tangent ẑ × r = (-r_y, r_x) for r from the centre to the wheel; σ = its azimuth.
    """
    r = XY - centre
    out: np.ndarray = np.arctan2(r[:, 0], -r[:, 1])
    return out


def _arc_inputs(centre: np.ndarray, psi: float) -> tuple[np.ndarray, np.ndarray]:
    """Wheel rotations (rad) and steering for a rotation ``psi`` about ``centre``, no slip."""
    r_norm = np.hypot(*(XY - centre).T)
    steer = _tangent_steer(centre) if psi >= 0 else _tangent_steer(centre) + math.pi
    # A left turn rolls each wheel the other way round: flip its direction, keep a_i > 0.
    steer = np.angle(np.exp(1j * steer))
    return r_norm * abs(psi) / RADIUS, steer


def test_default_geometry_matches_the_simulator() -> None:
    from sim.rover.geometry import MER_GEOMETRY

    np.testing.assert_array_equal(XY, MER_GEOMETRY.wheel_xy_b())
    assert MER_GEOMETRY.wheel_radius_m == RADIUS


def test_eq5_all_wheels_straight_is_the_mean_arc() -> None:
    a = np.array([0.01, 0.02, 0.03, 0.04, 0.05, 0.06])  # hand: sum 0.21, /6 = 0.035
    np.testing.assert_allclose(wo.straight_step(a, np.zeros(6)), [0.035, 0.0, 0.0], atol=1e-15)


def test_eq5_all_wheels_at_30_deg() -> None:
    a = np.full(6, 0.012)
    dp = wo.straight_step(a, np.full(6, math.radians(30.0)))
    # hand: 0.012 (cos 30°, sin 30°) = (0.0103923048, 0.006); y is right: a crab to the right
    np.testing.assert_allclose(dp, [0.012 * math.sqrt(3) / 2, 0.006, 0.0], atol=1e-15)


def test_straight_step_converts_encoder_angles_with_the_wheel_radius() -> None:
    s = wo.odometry_step(DriveKind.STRAIGHT, np.full(6, 0.5), np.zeros(6))
    np.testing.assert_allclose(s.delta_p_b, [0.065, 0.0, 0.0], atol=1e-15)  # 0.5 rad × 0.13 m
    assert s.delta_heading_rad == 0.0


def test_quarter_circle_in_one_step_by_hand() -> None:
    # C = (0, 3): |r| LF = LR = sqrt(0.7² + 3.6²) = sqrt(13.45), LM = 3.6,
    # RF = RR = sqrt(0.7² + 2.4²) = 2.5, RM = 2.4; each wheel rolls |r_i| π/2.
    r_hand = np.array([math.sqrt(13.45), 3.6, math.sqrt(13.45), 2.5, 2.4, 2.5])
    steer = np.array([math.atan2(x, 3.0 - y) for x, y in XY])  # as sim.rover.drive: atan(x/(R-y))
    a = r_hand * math.pi / 2
    c = wo.arc_centre_b(3.0)
    dp, psi_ave, psi, used = wo.arc_step(a, steer, c)
    np.testing.assert_allclose(psi, np.full(6, math.pi / 2), rtol=1e-14)
    assert used.all()
    assert psi_ave == pytest.approx(math.pi / 2, rel=1e-14)
    # eq. 7 is first order: ψR = 3π/2 ahead, 0 across, not the chord (3, 3).
    np.testing.assert_allclose(dp, [3 * math.pi / 2, 0.0, 0.0], atol=1e-14)


def test_left_turn_has_negative_heading_and_still_moves_forward() -> None:
    c = wo.arc_centre_b(-3.0)
    rot, steer = _arc_inputs(c, -0.01)
    s = wo.odometry_step(DriveKind.ARC, rot, steer, c)
    assert s.delta_heading_rad == pytest.approx(-0.01, rel=1e-12)
    np.testing.assert_allclose(s.delta_p_b, [0.03, 0.0, 0.0], atol=1e-14)  # ψ C_y = 0.03 m
    # mirror of the right turn: same forward step, opposite heading change
    r2, s2 = _arc_inputs(wo.arc_centre_b(3.0), 0.01)
    right = wo.odometry_step(DriveKind.ARC, r2, s2, wo.arc_centre_b(3.0))
    np.testing.assert_allclose(right.delta_p_b, s.delta_p_b, atol=1e-15)
    # mirror image in the body x axis: left wheels steer as the right ones did, negated
    np.testing.assert_allclose(steer, -s2[[3, 4, 5, 0, 1, 2]], atol=1e-15)


def test_eq7_small_step_is_first_order_in_psi() -> None:
    # The exact motion of the origin rotated by ψ about C = (0, R): (R sin ψ, R(1 - cos ψ)).
    R, psi = 3.0, 1e-3
    rot, steer = _arc_inputs(wo.arc_centre_b(R), psi)
    dp = wo.odometry_step(DriveKind.ARC, rot, steer, wo.arc_centre_b(R)).delta_p_b
    exact = np.array([R * math.sin(psi), R * (1 - math.cos(psi)), 0.0])
    err = float(np.linalg.norm(dp - exact))
    assert err == pytest.approx(R * psi**2 / 2, rel=1e-3)  # leading term, 1.5 µm


def test_integrating_small_steps_reproduces_the_circle_within_the_closed_form_bound() -> None:
    """Eq. 7 steps rotated by the end-of-step attitude: each step has length ψR at heading
    kψ where the exact chord 2R sin(ψ/2) is at (k - 1/2)ψ. The integrated path is the exact
    one scaled by s = (ψ/2)/sin(ψ/2) and rotated by ψ/2, so the end error is exactly
    |D| |s e^{iψ/2} - 1| ≈ |D| ψ/2 with D the exact displacement."""
    R, total = 3.0, math.pi / 2
    c = wo.arc_centre_b(R)
    errors = {}
    for n in (250, 1000):  # 1000 steps of 4.7 mm: 8 Hz at 3.75 cm/s
        psi = total / n
        rot, steer = _arc_inputs(c, psi)
        p, q = np.zeros(3), IDENTITY
        for _ in range(n):
            step = wo.odometry_step(DriveKind.ARC, rot, steer, c)
            q = wo.propagate_heading(q, step.delta_heading_rad)
            p = wo.propagate_position(p, q, step.delta_p_b)
        exact = np.array([R * math.sin(total), R * (1 - math.cos(total)), 0.0])  # (3, 3)
        s = (psi / 2) / math.sin(psi / 2)
        bound = float(np.linalg.norm(exact)) * abs(s * np.exp(0.5j * psi) - 1)
        err = float(np.linalg.norm(p - exact))
        assert err == pytest.approx(bound, rel=1e-6)
        heading = Rotation.from_quat(q).as_euler("ZYX")[0]
        assert heading == pytest.approx(total, abs=1e-12)
        errors[n] = err
    assert errors[1000] < 3.4e-3  # measured 3.33 mm over the 4.71 m arc
    assert errors[250] / errors[1000] == pytest.approx(4.0, rel=1e-3)  # first order


def test_eq7_off_axis_centres_against_the_exact_rotation() -> None:
    # Pivot about the right front wheel, C = (0.7, 0.6): by hand ẑ × (O - C) = (0.6, -0.7),
    # so ψ = 0.1 gives (0.06, -0.07). (MER's middle wheels cannot steer for this: the test
    # steers all six tangent to check the equations, not the rover.)
    c = XY[3].copy()
    rot, steer = _arc_inputs(c, 0.1)
    s = wo.odometry_step(DriveKind.ARC, rot, steer, c)
    np.testing.assert_allclose(s.delta_p_b, [0.06, -0.07, 0.0], atol=1e-15)
    # Random centres, both senses: within the second-order term |C| ψ²/2 of the exact
    # rotation (Rz(ψ) - I)(O - C) of the origin about C.
    rng = np.random.default_rng(7)
    for _ in range(20):
        c = rng.uniform(-5.0, 5.0, 2)
        psi = float(rng.choice([-1.0, 1.0]) * rng.uniform(1e-4, 1e-2))
        rot, steer = _arc_inputs(c, psi)
        s = wo.odometry_step(DriveKind.ARC, rot, steer, c)
        assert s.delta_heading_rad == pytest.approx(psi, rel=1e-12)
        origin_from_c = np.array([-c[0], -c[1], 0.0])
        exact = Rotation.from_rotvec([0.0, 0.0, psi]).apply(origin_from_c) - origin_from_c
        err = float(np.linalg.norm(s.delta_p_b - exact))
        assert err <= float(np.linalg.norm(c)) * psi**2 / 2 * (1 + 1e-2)


def test_eq6_as_published_for_a_wheel_steered_off_its_tangent() -> None:
    # The paper's ψ_i = a_i / |r_i| keeps only the sense from the steering: a front wheel
    # steered 40° off its tangent still counts a_i / |r_i| (no scrub correction).
    c = wo.arc_centre_b(3.0)
    rot, steer = _arc_inputs(c, 0.02)
    steer[0] += math.radians(40.0)
    s = wo.odometry_step(DriveKind.ARC, rot, steer, c)
    np.testing.assert_allclose(s.psi_rad, np.full(6, 0.02), rtol=1e-12)
    steer[0] += math.radians(100.0)  # now 140° off: rolling forwards goes round backwards
    s = wo.odometry_step(DriveKind.ARC, rot, steer, c)
    assert s.psi_rad[0] == pytest.approx(-0.02, rel=1e-12)


def test_wheel_at_the_arc_centre_is_excluded() -> None:
    c = XY[4].copy()  # pivot about the right middle wheel (0, 0.6)
    rot, steer = _arc_inputs(c, 0.1)
    results = []
    for scrub_rad in (0.0, 0.4):  # whatever the pivot wheel reads must not matter
        rot[4] = scrub_rad
        results.append(wo.odometry_step(DriveKind.ARC, rot, steer, c))
    for s in results:
        np.testing.assert_array_equal(s.used, [True, True, True, True, False, True])
        assert math.isnan(s.psi_rad[4])
        assert s.delta_heading_rad == pytest.approx(0.1, rel=1e-12)
        np.testing.assert_allclose(s.delta_p_b, [0.06, 0.0, 0.0], atol=1e-15)  # ψ C_y


def test_turn_in_place_with_the_simulator_steering_convention() -> None:
    # sim.rover.drive.turn_in_place keeps |σ| < 90°: the right wheels face forward, roll backward.
    sigma = np.arctan(-XY[:, 0] / XY[:, 1])
    lever = -XY[:, 1] * np.cos(sigma) + XY[:, 0] * np.sin(sigma)  # signed roll per radian
    psi = 0.05
    s = wo.odometry_step(DriveKind.TURN_IN_PLACE, lever * psi / RADIUS, sigma)
    assert (lever[3:] < 0).all()  # the right wheels really roll backwards on a right turn
    np.testing.assert_allclose(s.psi_rad, np.full(6, psi), rtol=1e-12)
    np.testing.assert_allclose(s.delta_p_b, np.zeros(3), atol=1e-15)
    assert s.delta_heading_rad == pytest.approx(psi, rel=1e-12)


def test_site_rotation_uses_the_given_attitude() -> None:
    # heading East (90° yaw about Down): body x is Site y (East), body y (right) is South.
    q_s_b = Rotation.from_euler("z", 90, degrees=True).as_quat()
    p = wo.propagate_position([1.0, 2.0, 0.0], q_s_b, [0.3, 0.1, 0.0])
    np.testing.assert_allclose(p, [1.0 - 0.1, 2.0 + 0.3, 0.0], atol=1e-15)
    rng = np.random.default_rng(5)
    q = Rotation.random(random_state=rng).as_quat()
    dp = rng.normal(size=3)
    np.testing.assert_allclose(
        wo.propagate_position(np.zeros(3), q, dp), Rotation.from_quat(q).apply(dp), atol=1e-14
    )


def test_heading_propagation_turns_about_body_down() -> None:
    q = Rotation.from_euler("ZYX", [0.3, 0.1, -0.2]).as_quat()  # tilted rover
    out = wo.propagate_heading(q, 0.25)
    expect = Rotation.from_quat(q) * Rotation.from_rotvec([0.0, 0.0, 0.25])
    assert (Rotation.from_quat(out).inv() * expect).magnitude() < 1e-14


def test_odometry_follows_a_simulated_arc_within_the_bound() -> None:
    """sim.drive_arc on flat ground, no slip: encoders, steering and the truth attitude
    (a perfect gyro) in, position out; the error stays under |D| ψ_step / 2."""
    from sim.rover.drive import drive_arc, initial_state
    from sim.rover.slip import SlipModel
    from sim.world.terrain import FlatTerrain

    flat = FlatTerrain()
    R, total = -3.0, math.pi / 2  # a left turn
    traj, _ = drive_arc(flat, initial_state(flat, 0.0), R, total, SlipModel.ideal(flat.soil))
    c = wo.arc_centre_b(R)
    p = traj.p_s[0].copy()
    for k in range(1, len(traj)):
        rot = traj.wheel_angle_rad[k] - traj.wheel_angle_rad[k - 1]
        steer = wo.steer_six(traj.steer_rad[k])
        step = wo.odometry_step(DriveKind.ARC, rot, steer, c)
        p = wo.propagate_position(p, traj.q_s_b[k], step.delta_p_b)
    err = float(np.linalg.norm((p - traj.p_s[-1])[:2]))
    d = float(np.linalg.norm((traj.p_s[-1] - traj.p_s[0])[:2]))
    psi_step = 0.0375 * 0.125 / abs(R)  # 3.75 cm/s at 8 Hz
    assert 0.5 * d * psi_step * 0.9 < err < 0.5 * d * psi_step * 1.01  # measured 3.3 mm


def test_classification_and_centre() -> None:
    assert wo.is_straight(np.zeros(6))
    assert wo.is_straight(np.full(6, 0.3))  # a crab: all parallel
    assert not wo.is_straight(_tangent_steer(wo.arc_centre_b(3.0)))
    assert wo.is_straight(np.array([0.0, 0.0, 0.0, 0.01, 0.0, 0.0]), tol_rad=0.02)
    np.testing.assert_array_equal(wo.arc_centre_b(0.0), [0.0, 0.0])
    np.testing.assert_array_equal(wo.steer_six([1, 2, 3, 4]), [1, 0, 2, 3, 0, 4])


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: wo.straight_step([0.1] * 5, [0.0] * 6), "arc_m"),
        (lambda: wo.straight_step([0.1] * 6, [0.0, np.nan, 0, 0, 0, 0]), "steer_rad"),
        (lambda: wo.arc_lengths_m(np.full((2, 6), 0.1)), "wheel_rotation_rad"),
        (lambda: wo.arc_step([0.1] * 6, [0.0] * 6, [0.0, np.inf]), "centre_b"),
        (lambda: wo.arc_step([0.1] * 6, [0.0] * 6, [0, 3], centre_tol_m=0.0), "centre_tol_m"),
        (lambda: wo.odometry_step(DriveKind.ARC, [0.1] * 6, [0.0] * 6), "centre_b"),
        (lambda: wo.odometry_step("arc", [0.1] * 6, [0.0] * 6), "kind"),  # type: ignore[arg-type]
        (lambda: wo.propagate_position([0, 0, 0], [0, 0, 0, 2], [1, 0, 0]), "q_s_b"),
        (lambda: wo.propagate_position([0, 0], IDENTITY, [1, 0, 0]), "p_s"),
        (lambda: wo.propagate_heading(IDENTITY, math.nan), "delta_heading_rad"),
        (lambda: wo.arc_centre_b(math.inf), "radius_m"),
        (lambda: wo.steer_six([0.0] * 6), "steer_corner_rad"),
        (lambda: wo.is_straight([0.0] * 6, tol_rad=-1.0), "tol_rad"),
        (lambda: FlightGeometry(track_m=0.0), "track_m"),
        (lambda: wo.straight_step(["a"] * 6, [0.0] * 6), "arc_m"),
    ],
)
def test_bad_input_raises_value_error_naming_the_parameter(call: object, name: str) -> None:
    with pytest.raises(ValueError, match=f"^{name}:"):
        call()  # type: ignore[operator]


@pytest.mark.parametrize(
    ("kind", "radius_m"),
    [
        (DriveKind.STRAIGHT, 0.0),
        (DriveKind.ARC, 2.5),
        (DriveKind.ARC, -1.2),
        (DriveKind.TURN_IN_PLACE, 0.0),
    ],
)
def test_many_cycles_at_once_are_the_cycles_one_by_one(kind: DriveKind, radius_m: float) -> None:
    rng = np.random.default_rng(16)
    rotation = rng.normal(0.02, 0.01, (200, 6))
    steer = wo.steer_six(rng.uniform(-0.8, 0.8, (200, 4)))  # rows at once, as steer_six does one
    centre = wo.arc_centre_b(radius_m) if kind is DriveKind.ARC else None
    dp_b, heading = wo.odometry_deltas(kind, rotation, steer, centre)
    for k in range(200):
        one = wo.odometry_step(kind, rotation[k], steer[k], centre)
        assert np.allclose(dp_b[k], one.delta_p_b, rtol=0.0, atol=1e-15)
        assert heading[k] == pytest.approx(one.delta_heading_rad, abs=1e-15)
    assert np.array_equal(steer[7], wo.steer_six(steer[7][[0, 2, 3, 5]]))


# ---- a dragged wheel (the drive command's drag_wheel; Spirit's right front from sol 125,
# Cheng, Maimone and Matthies 2005 sec. 4.2): the five driven wheels are averaged
def test_eq5_with_a_dragged_wheel_is_the_mean_of_the_five_driven() -> None:
    a = np.array([0.010, 0.011, 0.012, 0.001, 0.013, 0.014])  # rf dragged: rolls little
    step = wo.odometry_step(DriveKind.STRAIGHT, a / 0.13, np.zeros(6), drag_wheel="rf")
    assert step.delta_p_b[0] == pytest.approx(np.mean(a[[0, 1, 2, 4, 5]]), abs=1e-15)
    assert step.used.tolist() == [True, True, True, False, True, True]
    six = wo.odometry_step(DriveKind.STRAIGHT, a / 0.13, np.zeros(6))
    assert six.delta_p_b[0] == pytest.approx(np.mean(a), abs=1e-15)


def test_eq6_leaves_the_dragged_wheel_out_of_psi_ave() -> None:
    centre = wo.arc_centre_b(3.0)
    r = wo.FLIGHT_GEOMETRY.wheel_xy_b() - centre
    steer = np.zeros(6)
    steer[[0, 2, 3, 5]] = np.arctan2(r[[0, 2, 3, 5], 0], -r[[0, 2, 3, 5], 1])  # tangent
    psi = 0.01
    a = psi * np.hypot(r[:, 0], r[:, 1])
    a[1] = 0.0  # lm dragged: no roll to speak of
    step = wo.odometry_step(DriveKind.ARC, a / 0.13, steer, centre, drag_wheel="lm")
    assert step.delta_heading_rad == pytest.approx(psi, rel=1e-12)
    assert np.isnan(step.psi_rad[1]) and not step.used[1]


@pytest.mark.parametrize("kind", [DriveKind.STRAIGHT, DriveKind.ARC, DriveKind.TURN_IN_PLACE])
@pytest.mark.parametrize("wheel", ["lf", "rm"])
def test_many_cycles_at_once_with_a_dragged_wheel(kind: DriveKind, wheel: str) -> None:
    rng = np.random.default_rng(22)
    rotation = rng.normal(0.02, 0.01, (50, 6))
    steer = wo.steer_six(rng.uniform(-0.5, 0.5, (50, 4)))
    centre = wo.arc_centre_b(-2.0) if kind is DriveKind.ARC else None
    dp_b, heading = wo.odometry_deltas(kind, rotation, steer, centre, drag_wheel=wheel)
    for k in range(50):
        one = wo.odometry_step(kind, rotation[k], steer[k], centre, drag_wheel=wheel)
        assert np.allclose(dp_b[k], one.delta_p_b, rtol=0.0, atol=1e-15)
        assert heading[k] == pytest.approx(one.delta_heading_rad, abs=1e-15)


def test_wheel_names_and_bad_ones() -> None:
    assert [wheel_index(k) for k in WHEEL_KEYS] == list(range(6))
    assert driven_wheels(None).all()
    with pytest.raises(ValueError, match=r"^drag_wheel: must be one of"):
        wo.odometry_step(DriveKind.STRAIGHT, np.zeros(6), np.zeros(6), drag_wheel="front")
    with pytest.raises(ValueError, match=r"^drive\.drag_wheel: must be one of"):
        Nate(LAT, LON, T0).mobility(DriveCommand(drag_wheel="RF"))


def test_nate_odometry_uses_the_commands_driven_wheels_and_keeps_them_in_a_checkpoint() -> None:
    nate = Nate(LAT, LON, T0)
    nate.mobility(DriveCommand(DriveKind.STRAIGHT, drag_wheel="rr"), wheel_angle_rad=np.zeros(6))
    restored = Nate(LAT, LON, T0)
    assert nate.state()["drive_drag_wheel"] == "rr"
    restored.load_state(nate.state())
    wheels = np.full(6, 1.0)
    wheels[5] = 0.05  # the dragged wheel barely turns
    imu = ImuSample(np.zeros(3), np.array([0.0, 0.0, -3.711 * 0.125]), 0.125, True)
    for n in (nate, restored):
        n.step(imu, EncoderSample(wheels, np.zeros(6)))
        assert n.mode is NateMode.MOBILITY
        assert n.p_s[0] == pytest.approx(0.13, rel=1e-4)  # 1 rad of the five driven wheels
    np.testing.assert_array_equal(restored.p_s, nate.p_s)
