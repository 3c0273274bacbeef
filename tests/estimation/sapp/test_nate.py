"""The NATE core (Ali et al. 2005 Figure 1, sec. 2.1-2.5) on the simulator's sensors: every AQF
transition of sec. 2.2.1, 2.3.1 and 2.4 one by one, a rover at rest in Articulate, a
straight drive in Mobility, Site planting and refused commands."""

import math
from collections.abc import Callable
from datetime import UTC, datetime

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation.sapp.aqf import AttitudeQuality as Aqf
from estimation.sapp.gyro_propagation import propagate_gyro
from estimation.sapp.nate import (
    DriveCommand,
    EncoderSample,
    EncoderSeries,
    ImuSample,
    ImuSeries,
    Nate,
    NateMode,
    NateOutput,
    NateSeries,
)
from estimation.sapp.wheel_odometry import DriveKind, steer_six
from sim.loop.rover_sim import RoverSim
from sim.sensors.imu import Ln200Imu, Ln200Params

LAT = math.radians(-14.57)
LON = math.radians(175.47)
T0 = 1.3e8  # s from J2000 (2004-02-13)
OMEGA_LL = np.array([7.0882181e-5 * math.cos(LAT), 0.0, -7.0882181e-5 * math.sin(LAT)])
Q_LL_B = Rotation.from_euler("ZYX", [37.0, 4.0, -6.0], degrees=True).as_quat()  # truth
Q_B_LL = Rotation.from_quat(Q_LL_B).inv().as_quat()
START = datetime(2004, 1, 10, 12, 0, tzinfo=UTC)


def _angle(q_a: np.ndarray, q_b: np.ndarray) -> float:
    return float((Rotation.from_quat(q_a).inv() * Rotation.from_quat(q_b)).magnitude())


def _tilt_err_rad(q_b_ll: np.ndarray) -> float:
    down_est = Rotation.from_quat(q_b_ll).apply([0.0, 0.0, 1.0])
    down_true = Rotation.from_quat(Q_B_LL).apply([0.0, 0.0, 1.0])
    return math.acos(min(1.0, float(down_est @ down_true)))


def _static(n: int, params: Ln200Params | None = None, seed: int = 0) -> list[ImuSample]:
    """``n`` 8 Hz samples of the LN-200 model for a rover at rest at attitude Q_LL_B."""
    imu = Ln200Imu(params or Ln200Params.noise_free(), np.random.default_rng(seed))
    s = imu.measure(np.arange(n + 1) * 0.125, np.tile(Q_LL_B, (n + 1, 1)), OMEGA_LL)
    return [
        ImuSample(s.delta_angle_b[k], s.delta_velocity_b[k], float(s.dt_s[k])) for k in range(n)
    ]


def _state(nate: Nate) -> tuple[object, ...]:
    return (
        nate.q_b_ll.tolist(),
        nate.aqf,
        nate.mode,
        nate.p_s.tolist(),
        nate.gyro_counter_s,
        nate.imu_integration_s,
        nate.params,
        len(nate.sites),
    )


# ---- Nadir Update (sec. 2.2.1) -----------------------------------------------------


def test_nadir_update_takes_unknown_to_tilt_only_with_the_true_tilt() -> None:
    nate = Nate(LAT, LON, T0)
    assert nate.aqf is Aqf.UNKNOWN and nate.mode is NateMode.IDLE  # after landing
    nate.nadir_update()
    samples = _static(80, Ln200Params(), seed=3)
    outs = [nate.step(s) for s in samples]
    assert outs[78].mode is NateMode.NADIR_UPDATE and outs[78].aqf is Aqf.UNKNOWN
    assert outs[78].q_b_ll.tolist() == [0.0, 0.0, 0.0, 1.0]  # not updated before the end
    assert outs[79].mode is NateMode.IDLE and outs[79].aqf is Aqf.TILT_ONLY
    # the true tilt acos(cos 4 cos 6) = 7.21 deg, to the 300 ug bias level (< 0.1 deg)
    true_tilt_deg = math.degrees(math.acos(math.cos(math.radians(4)) * math.cos(math.radians(6))))
    assert outs[79].tilt_est_deg == pytest.approx(true_tilt_deg, abs=0.1)
    assert math.degrees(_tilt_err_rad(outs[79].q_b_ll)) < 0.1
    assert outs[79].tilt_accel_deg == pytest.approx(true_tilt_deg, abs=0.2)
    assert outs[79].gyro_counter_s == 0.0  # acquisition is not propagation


@pytest.mark.parametrize("fault", ["gravity", "invalid"])
def test_failed_nadir_update_sets_unknown_and_keeps_the_estimate(fault: str) -> None:
    nate = Nate(LAT, LON, T0)
    nate.load_attitude(quat := Rotation.from_rotvec([0.02, -0.01, 0.3]).as_quat(), Aqf.COARSE)
    nate.nadir_update()
    for s in _static(80):
        if fault == "gravity":  # 5 % too much gravity: fails the 0.1 m/s^2 check
            s = ImuSample(s.delta_angle_b, 1.05 * s.delta_velocity_b, s.dt_s)
        else:  # every sample flagged invalid: too few samples
            s = ImuSample(s.delta_angle_b, s.delta_velocity_b, s.dt_s, valid=False)
        out = nate.step(s)
    assert out.mode is NateMode.IDLE and out.aqf is Aqf.UNKNOWN
    assert out.completed is not None and out.completed.failure is not None
    assert np.allclose(out.q_b_ll, quat) or np.allclose(out.q_b_ll, -quat)


# ---- Nadir Check (sec. 2.3.1) ------------------------------------------------------


def test_nadir_check_pass_keeps_the_flag_and_the_estimate() -> None:
    nate = Nate(LAT, LON, T0)
    nate.load_attitude(Q_B_LL, Aqf.COARSE)
    nate.nadir_check()
    outs = [nate.step(s) for s in _static(80, Ln200Params(), seed=5)]
    assert outs[-1].mode is NateMode.IDLE and outs[-1].aqf is Aqf.COARSE
    assert _angle(outs[-1].q_b_ll, Q_B_LL) == 0.0


def test_nadir_check_fail_sets_unknown_without_touching_the_estimate() -> None:
    off = (
        Rotation.from_rotvec([math.radians(2.0), 0.0, 0.0]) * Rotation.from_quat(Q_B_LL)
    ).as_quat()
    nate = Nate(LAT, LON, T0)
    nate.load_attitude(off, Aqf.FINE)  # 2 deg of tilt error > 1 deg tolerance
    nate.nadir_check()
    out = [nate.step(s) for s in _static(80)][-1]
    assert out.aqf is Aqf.UNKNOWN and out.mode is NateMode.IDLE
    assert _angle(out.q_b_ll, off) < 1e-12
    # with a 3 deg tolerance for this check only, the same estimate passes
    nate.load_attitude(off, Aqf.FINE)
    nate.nadir_check(tolerance_deg=3.0)
    assert [nate.step(s) for s in _static(80)][-1].aqf is Aqf.FINE


def test_nadir_check_sanity_failure_changes_nothing() -> None:
    nate = Nate(LAT, LON, T0)
    nate.load_attitude(Q_B_LL, Aqf.TILT_ONLY)
    nate.nadir_check()
    for s in _static(80):
        out = nate.step(ImuSample(s.delta_angle_b, 0.9 * s.delta_velocity_b, s.dt_s))
    assert out.completed is not None and out.completed.failure is not None
    assert out.aqf is Aqf.TILT_ONLY and _angle(out.q_b_ll, Q_B_LL) == 0.0


# ---- propagation and the gyro counter (sec. 2.4) ----------------------------------


def _rest_one(imu: Ln200Imu, dt_s: float) -> ImuSample:
    s = imu.measure_interval(dt_s, Q_LL_B, OMEGA_LL)
    return ImuSample(s.delta_angle_b[0], s.delta_velocity_b[0], dt_s)


@pytest.mark.parametrize("mode", ["articulate", "mobility"])
def test_fine_drops_to_coarse_after_15_min_of_gyro_counter_and_not_before(mode: str) -> None:
    imu = Ln200Imu(Ln200Params.noise_free(), np.random.default_rng(0))
    nate = Nate(LAT, LON, T0)
    nate.load_attitude(Q_B_LL, Aqf.FINE)
    getattr(nate, mode)()
    out = nate.step(_rest_one(imu, 899.875))
    out = nate.step(_rest_one(imu, 0.125))
    assert out.gyro_counter_s == 900.0 and out.aqf is Aqf.FINE  # "exceeds": not yet
    out = nate.step(_rest_one(imu, 0.125))
    assert out.gyro_counter_s == 900.125 and out.aqf is Aqf.COARSE
    assert out.imu_integration_s == 900.125
    nate.stop()
    out = nate.step(_rest_one(imu, 0.125))
    assert out.aqf is Aqf.COARSE and out.gyro_counter_s == 900.125  # Idle does not count
    # a new Fine attitude (the Sungaze seam) resets both counters
    nate.load_attitude(Q_B_LL, Aqf.FINE)
    assert nate.gyro_counter_s == 0.0 and nate.imu_integration_s == 0.0


@pytest.mark.parametrize("flag", [Aqf.UNKNOWN, Aqf.TILT_ONLY, Aqf.COARSE, Aqf.FINE])
@pytest.mark.parametrize("mode", ["articulate", "mobility"])
def test_propagation_never_improves_the_flag(flag: Aqf, mode: str) -> None:
    nate = Nate(LAT, LON, T0)
    nate.load_attitude(Q_B_LL, flag)
    getattr(nate, mode)()
    outs = [nate.step(s) for s in _static(200, Ln200Params(), seed=1)]
    assert all(o.aqf is flag for o in outs)  # 25 s, far below 15 min
    assert outs[-1].gyro_counter_s == pytest.approx(25.0)


def test_rover_at_rest_in_articulate_keeps_its_attitude() -> None:
    nate = Nate(LAT, LON, T0)
    nate.load_attitude(Q_B_LL, Aqf.FINE)
    nate.articulate()
    outs = [nate.step(s) for s in _static(400)]  # 50 s: reference + 4 tilt corrections
    assert outs[-1].mode is NateMode.ARTICULATE
    assert _angle(outs[-1].q_b_ll, Q_B_LL) < 1e-9
    assert outs[-1].aqf is Aqf.FINE


def test_articulate_tilt_corrections_remove_gyro_tilt_drift_but_not_yaw_drift() -> None:
    # A gyro with a 200 deg/h bias and nothing else: pure gyro propagation drifts.
    params = Ln200Params(200.0, 0.0, 0.0, 3600.0, 0.0, 0.0)
    samples = _static(480, params, seed=8)  # 60 s
    nate = Nate(LAT, LON, T0)
    nate.load_attitude(Q_B_LL, Aqf.COARSE)
    nate.articulate()
    out = [nate.step(s) for s in samples][-1]
    d_theta = np.array([s.delta_angle_b for s in samples])
    gyro_only = propagate_gyro(Q_B_LL, d_theta, 0.125, OMEGA_LL)[-1]
    # tilt: 7.8 deg of gyro-only drift; the correction at 60 s (the reference at 10 s, then
    # every 10 s) restores the entry tilt exactly, the rover being still
    assert _tilt_err_rad(gyro_only) > math.radians(5.0)
    assert _tilt_err_rad(out.q_b_ll) < 1e-6

    def heading_rad(q_b_ll: np.ndarray) -> float:
        x_ll = Rotation.from_quat(q_b_ll).inv().apply([1.0, 0.0, 0.0])
        return math.atan2(x_ll[1], x_ll[0])

    # yaw: the accelerometers do not touch it, it drifts like the gyro-only solution
    assert heading_rad(out.q_b_ll) == pytest.approx(heading_rad(gyro_only), abs=math.radians(0.3))


# ---- Mobility and Sites (sec. 2.4.2, 2.5) -----------------------------------------


def _drive(nate: Nate, sim: RoverSim, distance_m: float) -> np.ndarray:
    seg = sim.drive_straight(distance_m)
    wheel = sim.encoders.wheel_angle_rad(seg.encoders.wheel_counts)
    nate.mobility(DriveCommand(DriveKind.STRAIGHT), wheel_angle_rad=wheel[0])
    imu = seg.imu
    for k in range(len(imu)):
        enc = EncoderSample(wheel[k + 1], steer_six(seg.encoders.steer_rad[k + 1]))
        nate.step(ImuSample(imu.delta_angle_b[k], imu.delta_velocity_b[k], float(imu.dt_s[k])), enc)
    nate.stop()
    out: np.ndarray = seg.truth.p_s[-1] - seg.truth.p_s[0]
    return out


def test_straight_drive_on_flat_ends_at_the_commanded_distance_and_plant_site_resets() -> None:
    sim = RoverSim("flat", 0, START, imu_params=Ln200Params.noise_free(), slip=False)
    nate = Nate(sim.lat_rad, sim.lon_east_rad, sim.t_s)
    nate.load_attitude(Rotation.from_quat(sim.q_ll_b()).inv().as_quat(), Aqf.FINE)
    truth_delta = _drive(nate, sim, 3.0)
    p_s = nate.p_s
    assert float(np.linalg.norm(p_s[:2])) == pytest.approx(3.0, abs=0.005)
    assert np.allclose(p_s[:2], truth_delta[:2], atol=0.005)
    assert nate.aqf is Aqf.FINE and nate.gyro_counter_s == pytest.approx(3.0 / 0.0375, abs=0.2)
    # plant a Site: origin, index 1, and the old position is the new Site's mission offset
    assert nate.plant_site() == 1
    assert nate.p_s.tolist() == [0.0, 0.0, 0.0]
    assert np.allclose(nate.sites.to_mission(np.zeros(3), 1), p_s)
    out = nate.step(_static(1)[0])
    assert out.site_index == 1 and out.p_s.tolist() == [0.0, 0.0, 0.0]


def test_mobility_wheel_odometry_submode_turns_the_attitude_with_the_wheels() -> None:
    sim = RoverSim("flat", 1, START, imu_params=Ln200Params.noise_free(), slip=False)
    q0 = Rotation.from_quat(sim.q_ll_b()).inv().as_quat()
    nate = Nate(sim.lat_rad, sim.lon_east_rad, sim.t_s)
    nate.load_attitude(q0, Aqf.COARSE)
    seg = sim.turn_in_place(math.radians(30.0))
    wheel = sim.encoders.wheel_angle_rad(seg.encoders.wheel_counts)
    nate.mobility(DriveCommand(DriveKind.TURN_IN_PLACE), use_gyros=False, wheel_angle_rad=wheel[0])
    zero = np.zeros(3)  # faulty gyros: their data must not matter
    for k in range(len(seg.imu)):
        enc = EncoderSample(wheel[k + 1], steer_six(seg.encoders.steer_rad[k + 1]))
        out = nate.step(ImuSample(zero, seg.imu.delta_velocity_b[k], 0.125), enc)
    assert _angle(out.q_b_ll, Rotation.from_quat(sim.q_ll_b()).inv().as_quat()) < math.radians(1)
    assert _angle(out.q_b_ll, q0) == pytest.approx(math.radians(30.0), abs=math.radians(1))
    assert out.imu_integration_s == 0.0 and out.gyro_counter_s > 0.0


# ---- refused commands ----------------------------------------------------------


def test_refused_commands_leave_the_state_untouched() -> None:
    nate = Nate(LAT, LON, T0)
    nate.load_attitude(Q_B_LL, Aqf.COARSE)
    bad_idle: list[tuple[Callable[[], object], str]] = [
        (lambda: nate.nadir_update(window_s=-1.0), "window_s"),
        (lambda: nate.nadir_check(tolerance_deg=200.0), "tolerance_deg"),
        (lambda: nate.mobility(DriveCommand(DriveKind.ARC, 0.0)), "drive"),
        (lambda: nate.mobility(wheel_angle_rad=[0.0] * 5), "wheel_angle_rad"),
        (lambda: nate.set_params(fine_to_coarse_s=-5.0), "fine_to_coarse_s"),
        (lambda: nate.set_params(no_such=1.0), "set_params"),
        (lambda: nate.load_attitude([1.0, 1.0, 0.0, 0.0], Aqf.FINE), "q_b_ll"),
        (lambda: nate.stop(), "stop: refused in mode Idle"),
        (lambda: nate.set_drive(DriveCommand()), "set_drive: refused"),
    ]
    for command, reason in bad_idle:
        before = _state(nate)
        with pytest.raises(ValueError, match=reason):
            command()
        assert _state(nate) == before
    nate.mobility()
    nate.step(_static(1)[0])
    in_mobility: list[tuple[Callable[[], object], str]] = [
        (lambda: nate.articulate(), "articulate: refused in mode Mobility"),
        (lambda: nate.plant_site(), "plant_site: refused"),
        (lambda: nate.nadir_update(), "nadir_update: refused"),
        (lambda: nate.load_attitude(Q_B_LL, Aqf.FINE), "load_attitude: refused"),
        (lambda: nate.set_drive(DriveCommand(DriveKind.ARC, math.inf)), "radius_m"),
    ]
    for command, reason in in_mobility:
        before = _state(nate)
        with pytest.raises(ValueError, match=reason):
            command()
        assert _state(nate) == before
    nate.stop()
    nate.set_params(fine_to_coarse_s=600.0)
    assert nate.params.fine_to_coarse_s == 600.0


# ---- a segment's cycles at once (step_series) against cycle by cycle (step) -----------------


def _series_and_steps(
    drive: DriveCommand, make_segment: Callable[[RoverSim], object], use_gyros: bool,
    reference: bool, invalid: tuple[int, ...] = (), fine_to_coarse_s: float = 900.0,
) -> tuple[NateSeries, list[NateOutput], Nate, Nate]:  # fmt: skip
    """Two NATEs in Mobility through one gusev segment: one with ``step_series``, one with
    ``step`` per cycle (the reference)."""
    sim = RoverSim("gusev", 4, START)
    q0 = Rotation.from_quat(sim.q_ll_b()).inv().as_quat()
    seg = make_segment(sim)
    wheel = sim.encoders.wheel_angle_rad(seg.encoders.wheel_counts)  # type: ignore[attr-defined]
    steer = steer_six(seg.encoders.steer_rad)  # type: ignore[attr-defined]
    imu = seg.imu  # type: ignore[attr-defined]
    valid = np.ones(len(imu), dtype=bool)
    valid[list(invalid)] = False
    nates = []
    for _ in range(2):
        nate = Nate(sim.lat_rad, sim.lon_east_rad, sim.t_s)
        nate.set_params(fine_to_coarse_s=fine_to_coarse_s)
        nate.load_attitude(q0, Aqf.FINE)
        nate.mobility(drive, use_gyros=use_gyros, wheel_angle_rad=wheel[0] if reference else None)
        nates.append(nate)
    series = nates[0].step_series(
        ImuSeries(imu.delta_angle_b, imu.delta_velocity_b, imu.dt_s, valid),
        EncoderSeries(wheel[1:], steer[1:]),
    )
    steps = [
        nates[1].step(
            ImuSample(imu.delta_angle_b[k], imu.delta_velocity_b[k], float(imu.dt_s[k]), valid[k]),
            EncoderSample(wheel[k + 1], steer[k + 1]),
        )
        for k in range(len(imu))
    ]
    return series, steps, nates[0], nates[1]


@pytest.mark.parametrize(
    ("drive", "make_segment", "use_gyros", "reference", "invalid"),
    [
        (DriveCommand(DriveKind.STRAIGHT), lambda s: s.drive_straight(4.0), True, True, ()),
        (DriveCommand(DriveKind.STRAIGHT), lambda s: s.drive_straight(2.0), True, False, (3, 40)),
        (DriveCommand(DriveKind.ARC, 3.0), lambda s: s.drive_arc(3.0, 0.5), True, True, (7,)),
        (DriveCommand(DriveKind.ARC, -2.0), lambda s: s.drive_arc(-2.0, 0.4), False, True, ()),
        (DriveCommand(DriveKind.TURN_IN_PLACE), lambda s: s.turn_in_place(-0.6), False, False, ()),
        (DriveCommand(DriveKind.TURN_IN_PLACE), lambda s: s.turn_in_place(0.8), True, True, ()),
    ],
)
def test_a_segment_at_once_is_the_segment_cycle_by_cycle(
    drive: DriveCommand,
    make_segment: Callable[[RoverSim], object],
    use_gyros: bool,
    reference: bool,
    invalid: tuple[int, ...],
) -> None:
    series, steps, at_once, by_cycle = _series_and_steps(
        drive, make_segment, use_gyros, reference, invalid, fine_to_coarse_s=10.0
    )
    assert len(series) == len(steps) > 100
    for name in ("q_b_ll", "p_s", "t_s", "imu_integration_s", "gyro_counter_s", "tilt_est_deg"):
        expected = np.array([getattr(o, name) for o in steps])
        assert np.allclose(getattr(series, name), expected, rtol=0.0, atol=1e-12), name
    accel = np.array([o.tilt_accel_deg for o in steps])
    assert np.allclose(series.tilt_accel_deg, accel, rtol=0.0, atol=1e-12, equal_nan=True)
    assert np.isnan(series.tilt_accel_deg[list(invalid)]).all()
    # the flag drops from Fine to Coarse at the same cycle (10 s of gyro counter here)
    assert series.aqf == [o.aqf for o in steps] and Aqf.COARSE in series.aqf
    assert series.mode == [o.mode for o in steps] and series.events == [o.events for o in steps]
    last = series.output(len(steps) - 1)
    assert np.allclose(last.p_s, steps[-1].p_s, rtol=0.0, atol=1e-12)
    assert (last.aqf, last.mode, last.site_index, last.events) == (
        steps[-1].aqf, steps[-1].mode, steps[-1].site_index, steps[-1].events,
    )  # fmt: skip
    # and NATE's state after it is the same
    state_a, state_b = at_once.state(), by_cycle.state()
    for key in ("q_b_ll", "p_s", "last_wheel_rad"):
        assert np.allclose(state_a[key], state_b[key], rtol=0.0, atol=1e-12), key
    for key in ("t_s", "gyro_counter_s", "imu_integration_s"):
        assert state_a[key] == pytest.approx(state_b[key], abs=1e-9), key
    assert state_a["aqf"] == state_b["aqf"] and state_a["mode"] == state_b["mode"]


def test_step_series_outside_mobility_is_step_cycle_by_cycle() -> None:
    """Articulate (and any 8 Hz mode) runs ``step`` per cycle inside ``step_series``."""
    samples = _static(40, seed=3)
    a, b = Nate(LAT, LON, T0), Nate(LAT, LON, T0)
    for nate in (a, b):
        nate.load_attitude(np.array([0.0, 0.0, 0.0, 1.0]), Aqf.COARSE)
        nate.articulate()
    series = a.step_series(
        ImuSeries(
            [s.delta_angle_b for s in samples],
            [s.delta_velocity_b for s in samples],
            [s.dt_s for s in samples],
        )
    )
    steps = [b.step(s) for s in samples]
    assert np.array_equal(series.q_b_ll, [o.q_b_ll for o in steps])
    assert np.array_equal(series.t_s, [o.t_s for o in steps])
    assert series.aqf == [o.aqf for o in steps] and series.events == [o.events for o in steps]
    assert series.mode == [NateMode.ARTICULATE] * len(samples)


@pytest.mark.parametrize(
    ("imu", "message"),
    [
        (lambda: ImuSeries(np.full((3, 3), np.nan), np.zeros((3, 3)), np.full(3, 0.125)), "finite"),
        (lambda: ImuSeries(np.zeros((3, 2)), np.zeros((3, 3)), np.full(3, 0.125)), "shape"),
        (lambda: ImuSeries(np.zeros((3, 3)), np.zeros((2, 3)), np.full(3, 0.125)), "as many"),
        (lambda: ImuSeries(np.zeros((3, 3)), np.zeros((3, 3)), [0.125, 0.0, 0.125]), "dt_s"),
        (lambda: EncoderSeries(np.zeros((3, 6)), np.zeros((2, 6))), "as many"),
        (lambda: EncoderSeries([[np.inf] * 6], [[0.0] * 6]), "finite"),
    ],
)
def test_a_series_is_checked_once_at_the_boundary(imu: Callable[[], object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        imu()
