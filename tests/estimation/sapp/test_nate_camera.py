"""NATE's camera modes on real Pancam images (Ali et al. 2005 sec. 2.2.2, 2.2.3, 2.2.4, 2.3.2, 5).

The simulated rover (``sim.loop.rover_sim.RoverSim``) renders the Pancam sun frame at the mast
pointing NATE asks for, from the truth, as ``sim.loop.session`` does; NATE runs the sun finder
on it. One test per Attitude Quality Flag transition of the camera modes and of the
Attitude Acquisition Machine, then gyrocompassing (parameters and refused commands:
tests/estimation/sapp/test_nate_params.py).
Truth comes from the simulator (``RoverSim.q_ll_b``) and angles from scipy ``Rotation``.
Gusev, 2004-04-14 16:30 UTC: the sun is 47 deg up; at 04:00 UTC it is 51 deg down.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.camera_model import R_b_pancam
from estimation.sapp.aqf import AttitudeQuality as Aqf
from estimation.sapp.gyrocompass import DEG_PER_H_TO_RAD_S
from estimation.sapp.nadir import NadirUpdateResult
from estimation.sapp.nate import (
    CONTROL_DT_S,
    GyrocompassOutcome,
    ImuSample,
    Nate,
    NateMode,
    NateOutput,
)
from estimation.sapp.sun_modes import SunOutcome, SunResult
from sim.loop.rover_sim import RoverSim
from sim.sensors.imu import ImuSamples, Ln200Params

F = NDArray[np.float64]
DAY = datetime(2004, 4, 14, 16, 30, tzinfo=UTC)  # sun 47 deg up at Gusev
NIGHT = datetime(2004, 4, 14, 4, 0, tzinfo=UTC)  # sun 51 deg below the horizon
SEED = 3  # a rover tilted 7 deg on the Gusev terrain


def rover(
    start: datetime = DAY, imu: Ln200Params | None = None, seed: int = SEED
) -> tuple[RoverSim, Nate]:
    sim = RoverSim("gusev", seed, start, imu_params=imu)
    return sim, Nate(sim.lat_rad, sim.lon_east_rad, sim.t_s)


def q_true(sim: RoverSim) -> F:
    out: F = Rotation.from_quat(sim.q_ll_b()).inv().as_quat()
    return out


def angle_deg(q1: F, q2: F) -> float:
    return math.degrees((Rotation.from_quat(q1) * Rotation.from_quat(q2).inv()).magnitude())


def heading_deg(q_b_ll: F) -> float:
    x_ll = Rotation.from_quat(q_b_ll).inv().apply([1.0, 0.0, 0.0])
    return math.degrees(math.atan2(x_ll[1], x_ll[0]))


def heading_error_deg(q_b_ll: F, q_ref: F) -> float:
    d = heading_deg(q_b_ll) - heading_deg(q_ref)
    return abs((d + 180.0) % 360.0 - 180.0)


def turned(q_b_ll: F, err_deg: float) -> F:
    """Same tilt, heading believed ``err_deg`` further clockwise (``q ⊗ Rz(-err)``)."""
    out: F = (
        Rotation.from_quat(q_b_ll) * Rotation.from_rotvec([0, 0, -math.radians(err_deg)])
    ).as_quat()
    return out


def tipped_towards_sun(sim: RoverSim, q_b_ll: F, tip_deg: float) -> F:
    """An estimate whose zenith is tipped ``tip_deg`` towards the sun (a wrong tilt)."""
    s = sim.sun_ll()
    axis = np.cross([0.0, 0.0, -1.0], s)  # turning the zenith towards the sun
    rot = Rotation.from_rotvec(axis / np.linalg.norm(axis) * math.radians(tip_deg))
    # R_b_ll_est = R_b_ll_true R_p: the estimate's zenith in true LL is R_p zenith
    out: F = (Rotation.from_quat(q_b_ll) * rot).as_quat()
    return out


def imu(samples: ImuSamples, k: int = 0, valid: bool = True) -> ImuSample:
    return ImuSample(
        samples.delta_angle_b[k], samples.delta_velocity_b[k], float(samples.dt_s[k]), valid
    )


def run(nate: Nate, sim: RoverSim, valid: bool = True) -> list[NateOutput]:
    """Feed NATE until its mode ends by itself, as ``sim.loop.session`` does: 8 Hz samples in
    the 8 Hz modes (flagged ``valid``), a jump to the image time and the rendered Pancam
    frame in the camera modes, one jump over a gyrocompassing span."""
    outs: list[NateOutput] = []
    while nate.busy:
        req, hint = nate.camera_request, nate.wait_hint_s
        if req is not None:
            samples = sim.rest(max(hint, CONTROL_DT_S))
            image = sim.pancam_sun_image(req.az_rad, req.el_rad).image
            outs.append(nate.step(imu(samples), image=image))
        elif hint <= CONTROL_DT_S:
            outs.append(nate.step(imu(sim.rest_cycles(CONTROL_DT_S), valid=valid)))
        else:
            outs.append(nate.step(imu(sim.rest(hint))))
        assert len(outs) < 5000
    return outs


def completed(outs: list[NateOutput]) -> list[object]:
    return [o.completed for o in outs if o.completed is not None]


def events(outs: list[NateOutput]) -> list[str]:
    return [e.text for o in outs for e in o.events]


def state(nate: Nate) -> tuple[object, ...]:
    return (
        nate.q_b_ll.tolist(),
        nate.aqf,
        nate.mode,
        nate.params,
        nate.mast,
        nate.acquisition,
        nate.camera_request,
        nate.t_s,
        nate.gyro_counter_s,
        nate.imu_integration_s,
    )


def mast_on_sun_deg(nate: Nate, sim: RoverSim) -> float:
    assert nate.mast is not None
    boresight = R_b_pancam(*nate.mast)[:, 2]
    sun_b = Rotation.from_quat(q_true(sim)).apply(sim.sun_ll())
    return math.degrees(math.acos(min(1.0, float(boresight @ sun_b))))


def articulate_a_while(nate: Nate, sim: RoverSim, seconds: float) -> None:
    nate.articulate()
    samples = sim.rest_cycles(seconds)
    for k in range(len(samples)):
        nate.step(imu(samples, k))
    nate.stop()


# ---- Sunfind (sec. 2.2.2) ---------------------------------------------------------------


def test_sunfind_success_sets_coarse_and_corrects_a_120_deg_heading_error() -> None:
    sim, nate = rover()
    truth = q_true(sim)
    assert math.degrees(math.acos(float(Rotation.from_quat(truth).apply([0, 0, 1])[2]))) > 5.0
    nate.load_attitude(turned(truth, 120.0), Aqf.TILT_ONLY)
    nate.sunfind()
    assert nate.mode is NateMode.SUNFIND and nate.camera_request is not None
    outs = run(nate, sim)
    (result,) = completed(outs)
    assert isinstance(result, SunResult) and result.outcome is SunOutcome.SUCCESS
    assert nate.aqf is Aqf.COARSE and nate.mode is NateMode.IDLE
    assert nate.camera_request is None and nate.wait_hint_s == math.inf
    assert heading_error_deg(nate.q_b_ll, truth) < 0.3  # from 120 deg
    assert angle_deg(nate.q_b_ll, truth) < 0.3
    assert mast_on_sun_deg(nate, sim) < 1.0  # left on the sun for a Sungaze
    assert result.n_images == len(outs) > 3  # it had to search
    assert nate.gyro_counter_s == 0.0 and nate.imu_integration_s == 0.0


def test_sunfind_failure_sets_unknown_and_keeps_the_estimate() -> None:
    sim, nate = rover()
    # The tilt is 20 deg wrong towards the sun: the searched cone passes 20 deg from the
    # sun, outside every image (a Pancam corner is 11.3 deg off the boresight).
    q0 = tipped_towards_sun(sim, q_true(sim), 20.0)
    nate.load_attitude(q0, Aqf.TILT_ONLY)
    before = nate.q_b_ll
    nate.sunfind()
    outs = run(nate, sim)
    (result,) = completed(outs)
    assert isinstance(result, SunResult) and result.outcome is SunOutcome.PLANE_SEARCHED
    assert result.n_images == len(outs) >= 20
    assert nate.aqf is Aqf.UNKNOWN and nate.mode is NateMode.IDLE
    assert nate.q_b_ll.tolist() == before.tolist()
    assert nate.mast is None


# ---- Sungaze (sec. 2.2.3) ---------------------------------------------------------------


def test_sungaze_success_sets_fine_and_resets_both_counters() -> None:
    sim, nate = rover()
    nate.load_attitude(turned(q_true(sim), 30.0), Aqf.TILT_ONLY)
    articulate_a_while(nate, sim, 3.0)  # some gyro integration to be reset
    assert nate.gyro_counter_s == pytest.approx(3.0) and nate.imu_integration_s > 0.0
    nate.sunfind()
    run(nate, sim)
    assert nate.aqf is Aqf.COARSE and nate.gyro_counter_s == pytest.approx(3.0)  # not reset
    nate.sungaze()
    outs = run(nate, sim)
    (result,) = completed(outs)
    assert isinstance(result, SunResult) and result.outcome is SunOutcome.CONVERGED
    assert result.three_sigma_rad <= math.radians(1.5)
    assert nate.aqf is Aqf.FINE and nate.mode is NateMode.IDLE
    assert nate.gyro_counter_s == 0.0 and nate.imu_integration_s == 0.0
    assert angle_deg(nate.q_b_ll, q_true(sim)) < 0.5  # well inside 1.5 deg 3σ
    assert mast_on_sun_deg(nate, sim) < 8.0


def test_sungaze_with_the_mast_off_the_sun_fails_to_unknown_without_update() -> None:
    sim, nate = rover()
    q0 = q_true(sim)
    nate.load_attitude(q0, Aqf.COARSE)
    assert nate.mast is None  # stowed: looks ahead at the horizon, the sun is 47 deg up
    t0 = nate.t_s
    nate.sungaze()
    outs = run(nate, sim)
    (result,) = completed(outs)
    assert isinstance(result, SunResult) and result.outcome is SunOutcome.NOT_CONVERGED
    # images every 20 s until the next one would fall after the ten-minute timer
    assert result.n_images == len(outs) >= 30
    # the timer runs from the first image (taken one control cycle after the command)
    assert result.n_images == 31
    assert outs[-1].t_s - outs[0].t_s <= 600.0 < outs[-1].t_s - outs[0].t_s + 20.0
    assert outs[0].t_s - t0 == pytest.approx(0.125)
    assert nate.aqf is Aqf.UNKNOWN and nate.mode is NateMode.IDLE
    assert nate.q_b_ll.tolist() == q0.tolist() or angle_deg(nate.q_b_ll, q0) == 0.0
    assert nate.mast is None


def test_sungaze_gravity_variation_averages_the_accelerometers_then_converges_at_once() -> None:
    sim, nate = rover()
    nate.load_attitude(turned(q_true(sim), 10.0), Aqf.TILT_ONLY)
    nate.sunfind()
    run(nate, sim)
    nate.sungaze(use_gravity=True)
    assert nate.camera_request is None and nate.wait_hint_s == CONTROL_DT_S  # 8 Hz window
    outs = run(nate, sim)
    assert len(outs) == 81  # a 10 s window at 8 Hz, then one image
    assert outs[78].camera_request is None and outs[79].camera_request is not None
    (result,) = completed(outs)
    assert isinstance(result, SunResult) and result.n_images == 1
    assert nate.aqf is Aqf.FINE and angle_deg(nate.q_b_ll, q_true(sim)) < 0.5


# ---- Suncheck (sec. 2.3.2) --------------------------------------------------------------


def test_suncheck_pass_keeps_the_flag_and_the_estimate() -> None:
    sim, nate = rover()
    q0 = q_true(sim)
    nate.load_attitude(q0, Aqf.FINE)
    nate.suncheck()
    outs = run(nate, sim)
    (result,) = completed(outs)
    assert isinstance(result, SunResult) and result.outcome is SunOutcome.PASSED
    assert math.degrees(result.error_rad) < 0.5  # mast bias and centroid only
    assert nate.aqf is Aqf.FINE and nate.q_b_ll.tolist() == q0.tolist()
    assert len(outs) == 1 and mast_on_sun_deg(nate, sim) < 0.5


@pytest.mark.parametrize(
    ("err_deg", "outcome"), [(4.0, SunOutcome.OUT_OF_TOLERANCE), (40.0, SunOutcome.NO_SUN)]
)
def test_suncheck_fail_sets_unknown_and_keeps_the_estimate(
    err_deg: float, outcome: SunOutcome
) -> None:
    sim, nate = rover()
    q0 = turned(q_true(sim), err_deg)
    nate.load_attitude(q0, Aqf.FINE)
    nate.suncheck()
    outs = run(nate, sim)
    (result,) = completed(outs)
    assert isinstance(result, SunResult) and result.outcome is outcome
    assert nate.aqf is Aqf.UNKNOWN and nate.mode is NateMode.IDLE
    assert angle_deg(nate.q_b_ll, q0) == 0.0
    assert (nate.mast is not None) == (outcome is SunOutcome.OUT_OF_TOLERANCE)


# ---- the sun's sanity check ---------------------------------------------------------------


@pytest.mark.parametrize(
    "command",
    [
        "sunfind",
        "sungaze",
        "suncheck",
        "get_coarse_attitude",
        "get_fine_attitude",
        "suncheck_sungaze",
    ],
)
def test_camera_commands_at_night_are_refused_and_change_nothing(command: str) -> None:
    sim, nate = rover(NIGHT)
    assert math.degrees(nate.sun_elevation_rad()) < -40.0
    nate.load_attitude(q_true(sim), Aqf.COARSE)
    before = state(nate)
    with pytest.raises(ValueError, match=r"below the 5\.0 deg minimum"):
        getattr(nate, command)()
    assert state(nate) == before
    nate.get_tilt_attitude()  # the accelerometers need no sun
    assert nate.mode is NateMode.NADIR_UPDATE


# ---- the Attitude Acquisition Machine (sec. 2.2.4) ------------------------------------------


def test_get_coarse_attitude_aborts_without_sunfind_when_nadir_update_fails() -> None:
    sim, nate = rover()
    q0 = turned(q_true(sim), 25.0)
    nate.load_attitude(q0, Aqf.COARSE)
    nate.get_coarse_attitude()
    assert nate.acquisition == "GetCoarseAttitude"
    outs = run(nate, sim, valid=False)  # every IMU sample flagged invalid by the driver
    assert [o.mode for o in outs[:-1]] == [NateMode.NADIR_UPDATE] * (len(outs) - 1)
    (result,) = completed(outs)
    assert isinstance(result, NadirUpdateResult) and not result.success
    assert all(o.camera_request is None for o in outs)  # no Sunfind image asked for
    assert nate.mode is NateMode.IDLE and nate.acquisition is None
    assert nate.aqf is Aqf.UNKNOWN and nate.q_b_ll.tolist() == q0.tolist()
    assert events(outs)[-1] == "GetCoarseAttitude aborted: AQF Unknown"
    assert not any("Sunfind" in e for e in events(outs))


def test_get_coarse_attitude_runs_nadir_update_then_sunfind() -> None:
    sim, nate = rover()
    q0 = Rotation.from_euler("ZYX", [150.0, 0.0, 0.0], degrees=True).inv().as_quat()  # level
    nate.load_attitude(q0, Aqf.UNKNOWN)
    nate.get_coarse_attitude()
    outs = run(nate, sim)
    modes = [o.mode for o in outs]
    assert NateMode.NADIR_UPDATE in modes and NateMode.SUNGAZE not in modes
    assert [type(c) for c in completed(outs)] == [NadirUpdateResult, SunResult]
    assert nate.aqf is Aqf.COARSE and heading_error_deg(nate.q_b_ll, q_true(sim)) < 0.5


def test_get_fine_attitude_never_starts_sungaze_after_a_failed_sunfind() -> None:
    sim, nate = rover()
    nate.set_param("finder.min_snr", 1e9)  # a sun finder that never sees the sun
    q0 = turned(q_true(sim), 60.0)
    nate.load_attitude(q0, Aqf.COARSE)
    nate.get_fine_attitude()
    outs = run(nate, sim)
    modes = {o.mode for o in outs}
    assert NateMode.SUNGAZE not in modes and NateMode.SUNFIND in modes
    nadir, sunfind = completed(outs)
    assert isinstance(nadir, NadirUpdateResult) and nadir.success
    assert isinstance(sunfind, SunResult) and sunfind.outcome is SunOutcome.PLANE_SEARCHED
    assert nate.aqf is Aqf.UNKNOWN and nate.acquisition is None and nate.mode is NateMode.IDLE
    # the estimate is Nadir Update's (its tilt from the accelerometers), Sunfind left it
    assert nate.q_b_ll.tolist() == nadir.q_b_ll.tolist()
    assert events(outs)[-1] == "GetFineAttitude aborted: AQF Unknown"


def test_get_fine_attitude_reaches_fine() -> None:
    sim, nate = rover()
    nate.load_attitude(np.array([0.0, 0.0, 0.0, 1.0]), Aqf.UNKNOWN)  # nothing known
    nate.get_fine_attitude()
    outs = run(nate, sim)
    results = completed(outs)
    assert [type(c) for c in results] == [NadirUpdateResult, SunResult, SunResult]
    assert nate.aqf is Aqf.FINE and nate.acquisition is None
    assert angle_deg(nate.q_b_ll, q_true(sim)) < 0.5
    assert events(outs)[-1] == "GetFineAttitude done: AQF Fine"


def test_suncheck_sungaze_runs_sungaze_after_an_out_of_tolerance_suncheck() -> None:
    sim, nate = rover()
    nate.load_attitude(turned(q_true(sim), 4.0), Aqf.FINE)
    nate.suncheck_sungaze()
    outs = run(nate, sim)
    check, gaze = completed(outs)
    assert isinstance(check, SunResult) and check.outcome is SunOutcome.OUT_OF_TOLERANCE
    assert math.degrees(check.error_rad) > 2.0  # the default tolerance
    assert isinstance(gaze, SunResult) and gaze.outcome is SunOutcome.CONVERGED
    flags = [o.aqf for o in outs]
    assert Aqf.UNKNOWN in flags  # the failed check's verdict, before Sungaze
    assert nate.aqf is Aqf.FINE and angle_deg(nate.q_b_ll, q_true(sim)) < 0.5
    assert events(outs)[-1] == "SuncheckSungaze done: AQF Fine"
    # the failed Suncheck is an event of its own, before Sungaze starts (issue 14, item 9)
    said = "SuncheckSungaze: Suncheck failed (sun out of tolerance): Sungaze on the sun it saw"
    assert said in events(outs)
    assert events(outs).index(said) < events(outs).index("SuncheckSungaze done: AQF Fine")


def test_suncheck_sungaze_from_unknown_runs_when_the_sun_is_in_the_image() -> None:
    """Ali et al. 2005 sec. 4: Sungaze needs only the sun in the field of view, so NATE
    does not refuse the command below Coarse (the validator warns instead); from Unknown
    it reaches Fine when the Suncheck's image holds the sun, and says the Suncheck failed."""
    sim, nate = rover()
    nate.load_attitude(turned(q_true(sim), 4.0), Aqf.UNKNOWN)
    nate.suncheck_sungaze()
    outs = run(nate, sim)
    check, gaze = completed(outs)
    assert isinstance(check, SunResult) and not check.success and check.sun_seen
    assert isinstance(gaze, SunResult) and gaze.success
    assert nate.aqf is Aqf.FINE
    assert any(e.startswith("SuncheckSungaze: Suncheck failed") for e in events(outs))


def test_suncheck_sungaze_after_a_passed_suncheck_names_no_failure() -> None:
    sim, nate = rover()
    nate.load_attitude(turned(q_true(sim), 0.5), Aqf.COARSE)
    nate.suncheck_sungaze()
    outs = run(nate, sim)
    check, _ = completed(outs)
    assert isinstance(check, SunResult) and check.success
    assert not any("Suncheck failed" in e for e in events(outs))
    assert nate.aqf is Aqf.FINE


def test_suncheck_sungaze_aborts_when_the_suncheck_sees_no_sun() -> None:
    sim, nate = rover()
    q0 = turned(q_true(sim), 40.0)
    nate.load_attitude(q0, Aqf.FINE)
    nate.suncheck_sungaze()
    outs = run(nate, sim)
    (check,) = completed(outs)
    assert isinstance(check, SunResult) and check.outcome is SunOutcome.NO_SUN
    assert NateMode.SUNGAZE not in {o.mode for o in outs}
    assert nate.aqf is Aqf.UNKNOWN and angle_deg(nate.q_b_ll, q0) == 0.0


# ---- gyrocompassing (sec. 5) ------------------------------------------------------------


def test_gyrocompass_with_the_ln200_corrects_the_heading_but_stays_tilt_only() -> None:
    sim, nate = rover()  # the default LN-200 error model
    truth = q_true(sim)
    nate.load_attitude(turned(truth, 60.0), Aqf.TILT_ONLY)
    nate.gyrocompass()
    assert nate.wait_hint_s == 1800.0
    outs = run(nate, sim)
    (out,) = completed(outs)
    assert isinstance(out, GyrocompassOutcome) and out.result is not None and not out.coarse
    three_sigma_deg = math.degrees(out.result.heading_3sigma_rad)
    assert three_sigma_deg > 8.0  # a 1 deg/h bias: 12 deg, Coarse is out of reach
    assert heading_error_deg(nate.q_b_ll, truth) < three_sigma_deg
    assert nate.aqf is Aqf.TILT_ONLY
    # the tilt is kept: the nadirs of estimate and truth agree
    n_est = Rotation.from_quat(nate.q_b_ll).apply([0.0, 0.0, 1.0])
    n_true = Rotation.from_quat(truth).apply([0.0, 0.0, 1.0])
    assert math.degrees(math.acos(min(1.0, float(n_est @ n_true)))) < 1e-6


def test_gyrocompass_with_a_perfect_gyro_and_tight_parameters_becomes_coarse() -> None:
    sim, nate = rover(imu=Ln200Params.noise_free())
    truth = q_true(sim)
    nate.load_attitude(turned(truth, 60.0), Aqf.TILT_ONLY)
    nate.set_param("gyrocompass.gyro_bias_sigma_rad_s", 0.05 * DEG_PER_H_TO_RAD_S)
    nate.set_param("gyrocompass.gyro_arw_rad_per_sqrt_s", 0.0)
    nate.gyrocompass(duration_s=1200.0)
    (out,) = completed(run(nate, sim))
    assert isinstance(out, GyrocompassOutcome) and out.result is not None and out.coarse
    assert math.degrees(out.result.heading_3sigma_rad) < 8.0
    assert nate.aqf is Aqf.COARSE
    assert heading_error_deg(nate.q_b_ll, truth) < 0.05
