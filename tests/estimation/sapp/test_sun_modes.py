"""Sunfind, Sungaze and Suncheck as procedures (Ali et al. 2005 sec. 2.2.2, 2.2.3, 2.3.2), no
images.

The procedures are fed synthetic ``SunFix`` results made from a known true attitude: a
"sky" answers each ``PancamRequest`` with the true body sun if the Pancam pinhole model
(``estimation.camera_model``) puts it on the detector at the requested mast pointing, and
``None`` otherwise. References from outside the code under test: scipy ``Rotation`` for
attitudes and angles, hand-derived cone geometry (chord ``2 asin(cos e sin(Δψ/2))``), and
IVP's sun at Gusev (14.57 S, 175.47 E) at t = 1.35054e8 s, 44.6 deg up.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.camera_model import PANCAM, R_b_pancam
from estimation.ivp import sun_ll as ivp_sun_ll
from estimation.sapp.sun_modes import (
    PancamRequest,
    Suncheck,
    SuncheckParams,
    Sunfind,
    SunfindParams,
    Sungaze,
    SungazeParams,
    SunOutcome,
    SunResult,
)
from estimation.sapp.sunfind import SunFix

F = NDArray[np.float64]
LAT = math.radians(-14.57)
LON = math.radians(175.47)
T0 = 1.35054e8  # s TT from J2000: IVP puts the sun 44.6 deg up, azimuth 63 deg, at Gusev
DOWN = np.array([0.0, 0.0, 1.0])
HALF_FIELD = math.radians(8.0)  # Pancam: 16 deg square field (Bell et al. 2003)
CORNER = math.atan(math.sqrt(2.0) * math.tan(HALF_FIELD))  # 11.3 deg to a corner
FOOTPRINT = math.radians(6.0)  # Sunfind's usable radius: 3/4 of the half field
# Truth: yaw 37 deg, pitch 4 deg, roll -6 deg (NED, intrinsic ZYX) as q_b_ll.
Q_TRUE = Rotation.from_euler("ZYX", [37.0, 4.0, -6.0], degrees=True).inv().as_quat()


def sun_ll(t_s: float) -> F:
    out: F = ivp_sun_ll(t_s, LAT, LON)
    return out


def elevation(v_ll: F) -> float:
    return math.asin(-float(v_ll[2]) / float(np.linalg.norm(v_ll)))


def angle(q1: F, q2: F) -> float:
    """Rotation angle between two attitudes, rad (scipy)."""
    return float((Rotation.from_quat(q1) * Rotation.from_quat(q2).inv()).magnitude())


def heading(q_b_ll: F) -> float:
    """Azimuth of body x in LL, rad."""
    x_ll = Rotation.from_quat(q_b_ll).inv().apply([1.0, 0.0, 0.0])
    return math.atan2(x_ll[1], x_ll[0])


def wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


def with_heading_error(q_b_ll: F, err_deg: float) -> F:
    """The estimate of a rover believed turned ``err_deg`` clockwise: same tilt,
    ``R_ll_b_est = Rz(err) R_ll_b``, i.e. ``R_b_ll_est = R_b_ll Rz(-err)``."""
    rz = Rotation.from_rotvec([0.0, 0.0, -math.radians(err_deg)])
    out: F = (Rotation.from_quat(q_b_ll) * rz).as_quat()
    return out


def fix(sun_b: F) -> SunFix:
    return SunFix(
        sun_b=np.asarray(sun_b, dtype=float),
        centroid_uv_px=np.zeros(2),
        area_px=400,
        peak_dn=3000.0,
        background_dn=100.0,
        noise_dn=1.5,
    )


def boresight_b(req: PancamRequest) -> F:
    out: F = R_b_pancam(req.az_rad, req.el_rad)[:, 2]
    return out


def in_field(req: PancamRequest, d_b: F) -> bool:
    """Does body direction ``d_b`` land on the Pancam detector at the request's pointing?"""
    u, v = PANCAM.project(R_b_pancam(req.az_rad, req.el_rad).T @ d_b)
    return bool(PANCAM.in_image(u, v))


Answer = Callable[[PancamRequest, float], SunFix | None]


def sky(q_true: F, sun: Callable[[float], F] = sun_ll) -> Answer:
    """Exact fixes of the true sun when it is in the field."""

    def answer(req: PancamRequest, t_s: float) -> SunFix | None:
        sun_b = Rotation.from_quat(q_true).apply(sun(t_s))
        return fix(sun_b) if in_field(req, sun_b) else None

    return answer


def no_sun(req: PancamRequest, t_s: float) -> None:
    return None


Log = list[tuple[PancamRequest, float, SunFix | None]]


def run(proc: Sunfind | Sungaze | Suncheck, answer: Answer) -> tuple[SunResult, Log]:
    """Answer every request at its earliest time until the procedure finishes."""
    log: Log = []
    while proc.request is not None:
        req = proc.request
        t = req.not_before_t_s
        f = answer(req, t)
        log.append((req, t, f))
        proc.on_image(t, f)
        assert len(log) < 1000
    assert proc.result is not None
    return proc.result, log


def cone_distance(elev_rad: float, dpsi_rad: float) -> float:
    """Angle between two directions at elevation ``elev_rad`` ``dpsi_rad`` apart in azimuth
    (chord of the circle of radius cos e)."""
    return 2.0 * math.asin(math.cos(elev_rad) * abs(math.sin(0.5 * dpsi_rad)))


# ---- Sunfind (sec. 2.2.2) ---------------------------------------------------------------


def test_the_reference_time_has_the_sun_30_to_60_deg_up() -> None:
    assert math.radians(30.0) < elevation(sun_ll(T0)) < math.radians(60.0)


@pytest.mark.parametrize("err_deg", [0.0, 90.0, 179.0])
def test_sunfind_finds_the_sun_and_corrects_the_heading(err_deg: float) -> None:
    q_est = with_heading_error(Q_TRUE, err_deg)
    proc = Sunfind(q_est, T0, sun_ll, SunfindParams())
    result, log = run(proc, sky(Q_TRUE))
    assert result.outcome is SunOutcome.SUCCESS and result.success and result.sun_seen
    if err_deg != 0.0:
        assert result.updated
    # eq. 4 with exact fixes: the truth, heading and tilt
    assert math.degrees(abs(wrap(heading(result.q_b_ll) - heading(Q_TRUE)))) < 0.01
    assert math.degrees(angle(result.q_b_ll, Q_TRUE)) < 0.01
    # images: the search up to the first guess that sees the sun, then two confirming ones
    assert result.n_images == len(log)
    purposes = [req.purpose for req, _, _ in log]
    k = len(log) - 3
    assert purposes == [f"search {i}" for i in range(k + 1)] + ["confirm 1", "confirm 2"]
    assert all(f is None for _, _, f in log[:k]) and all(f is not None for _, _, f in log[k:])
    # guess i is turned i Δξ: it sees the truth when i Δξ = err. The first guess that
    # sees it holds it at most a corner away; every earlier one was more than the
    # inscribed half field away (otherwise the sun was fully in view and was missed).
    e, step = elevation(sun_ll(T0)), 2.0 * math.pi / proc.plan.n_guesses
    err = math.radians(err_deg)
    assert cone_distance(e, k * step - err) <= CORNER
    assert all(cone_distance(e, i * step - err) > HALF_FIELD for i in range(k))
    if err_deg == 0.0:
        assert len(log) == 3
    # image times: 10 s apart in the search, the second confirmation 60 s after the first
    times = [t for _, t, _ in log]
    assert np.allclose(np.diff(times), [10.0] * (len(log) - 2) + [60.0])
    # the mast is left on the sun of the last image
    assert result.final_mast is not None
    mast_dir = R_b_pancam(*result.final_mast)[:, 2]
    sun_b_last = Rotation.from_quat(Q_TRUE).apply(sun_ll(times[-1]))
    assert math.degrees(math.acos(min(1.0, float(mast_dir @ sun_b_last)))) < 1e-6


def test_sunfind_without_a_sun_searches_the_whole_plane_and_changes_nothing() -> None:
    q_est = with_heading_error(Q_TRUE, 40.0)
    proc = Sunfind(q_est, T0, sun_ll, SunfindParams())
    n = proc.plan.n_guesses
    result, log = run(proc, no_sun)
    assert result.outcome is SunOutcome.PLANE_SEARCHED
    assert not result.success and not result.updated and not result.sun_seen
    assert result.n_images == n == len(log) and result.final_mast is None
    assert np.array_equal(result.q_b_ll, q_est) or np.array_equal(result.q_b_ll, -q_est)
    # The aims, taken to LL with the estimate (whose tilt is right), lie on the sun's
    # elevation cone at azimuth offsets i * 360/N from IVP's sun at each image time ...
    R_ll_b_est = Rotation.from_quat(q_est).inv()
    e0 = elevation(sun_ll(T0))
    offsets = []
    for i, (req, t, _) in enumerate(log):
        aim_ll = R_ll_b_est.apply(boresight_b(req))
        s = sun_ll(t)
        assert elevation(aim_ll) == pytest.approx(elevation(s), abs=1e-9)
        off = wrap(math.atan2(aim_ll[1], aim_ll[0]) - math.atan2(s[1], s[0]))
        assert abs(wrap(off - 2.0 * math.pi * i / n)) < 1e-9
        offsets.append(off % (2.0 * math.pi))
    # ... and every point of the cone is within the 6 deg footprint of some aim
    dense = np.radians(np.arange(0.0, 360.0, 0.05))
    worst = max(min(cone_distance(e0, float(a) - o) for o in offsets) for a in dense)
    assert worst <= FOOTPRINT
    # a finished procedure takes no more images
    with pytest.raises(ValueError, match="finished"):
        proc.on_image(log[-1][1] + 10.0, None)


def test_sunfind_rejects_a_false_sun_at_the_wrong_elevation_and_resumes() -> None:
    q_est = with_heading_error(Q_TRUE, 90.0)
    honest = sky(Q_TRUE)
    R_b_ll = Rotation.from_quat(Q_TRUE)

    def answer(req: PancamRequest, t_s: float) -> SunFix | None:
        if req.purpose == "search 0":  # a bright artefact 5 deg above the aim
            aim_ll = R_b_ll.inv().apply(boresight_b(req))
            az, el = math.atan2(aim_ll[1], aim_ll[0]), elevation(aim_ll) + math.radians(5.0)
            false_ll = [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), -math.sin(el)]
            false_b = R_b_ll.apply(false_ll)
            assert in_field(req, false_b)
            return fix(false_b)
        return honest(req, t_s)

    result, log = run(Sunfind(q_est, T0, sun_ll, SunfindParams()), answer)
    _, reference = run(Sunfind(q_est, T0, sun_ll, SunfindParams()), honest)
    assert log[1][0].purpose == "search 1"  # rejected: the search went on at the next guess
    assert [r.purpose for r, _, _ in log] == [r.purpose for r, _, _ in reference]
    assert result.outcome is SunOutcome.SUCCESS
    assert math.degrees(angle(result.q_b_ll, Q_TRUE)) < 0.01


def test_sunfind_rejects_a_fixed_false_sun_at_the_right_elevation_by_its_motion() -> None:
    q_est = with_heading_error(Q_TRUE, 90.0)
    honest = sky(Q_TRUE)
    fixed: dict[str, F] = {}

    def answer(req: PancamRequest, t_s: float) -> SunFix | None:
        true_fix = honest(req, t_s)
        if true_fix is not None:
            return true_fix
        if req.purpose == "search 0":
            fixed["b"] = boresight_b(req)  # on the cone: the right elevation, not moving
        if "b" in fixed and in_field(req, fixed["b"]):
            return fix(fixed["b"])
        return None

    result, log = run(Sunfind(q_est, T0, sun_ll, SunfindParams()), answer)
    purposes = [r.purpose for r, _, _ in log]
    assert purposes[:4] == ["search 0", "confirm 1", "confirm 2", "search 1"]
    assert all(np.array_equal(f.sun_b, fixed["b"]) for _, _, f in log[:3] if f is not None)
    # the sun moves 0.25 deg/min; the check's 0.05 deg tolerance tells it from a fixed spot
    t1, t2 = log[1][1], log[2][1]
    moved = math.acos(min(1.0, float(sun_ll(t1) @ sun_ll(t2))))
    assert math.degrees(moved) > 0.1
    assert result.outcome is SunOutcome.SUCCESS and result.sun_seen
    assert math.degrees(angle(result.q_b_ll, Q_TRUE)) < 0.01


def lose_first_confirmation(honest: Answer) -> Answer:
    """The sky, except that the first confirming image misses the sun (a dust devil)."""
    lost: list[float] = []

    def answer(req: PancamRequest, t_s: float) -> SunFix | None:
        if req.purpose == "confirm 1" and not lost:
            lost.append(t_s)
            return None
        return honest(req, t_s)

    return answer


def test_sunfind_resumes_the_search_when_a_confirming_image_loses_the_sun() -> None:
    # 90 deg off: the sun lies between guesses 5 and 6 (81.8 and 98.2 deg), 5.8 deg from
    # either aim, so the guess after the lost candidate sees it again.
    q_est = with_heading_error(Q_TRUE, 90.0)
    answer = lose_first_confirmation(sky(Q_TRUE))
    result, log = run(Sunfind(q_est, T0, sun_ll, SunfindParams()), answer)
    purposes = [r.purpose for r, _, _ in log]
    assert purposes == [f"search {i}" for i in range(6)] + ["confirm 1"] + [
        "search 6",
        "confirm 1",
        "confirm 2",
    ]
    assert result.outcome is SunOutcome.SUCCESS and result.n_images == len(log)
    assert math.degrees(angle(result.q_b_ll, Q_TRUE)) < 0.01


def test_sunfind_does_not_revisit_a_guess_whose_candidate_was_lost() -> None:
    # Sec. 2.2.2: "the search phase continues from the point it left off". With the sun
    # seen only at guess 0, losing it in the first confirmation leaves it unfound.
    q_est = with_heading_error(Q_TRUE, 0.0)
    proc = Sunfind(q_est, T0, sun_ll, SunfindParams())
    result, log = run(proc, lose_first_confirmation(sky(Q_TRUE)))
    purposes = [r.purpose for r, _, _ in log]
    n = proc.plan.n_guesses
    assert purposes == ["search 0", "confirm 1"] + [f"search {i}" for i in range(1, n)]
    assert result.outcome is SunOutcome.PLANE_SEARCHED and not result.success
    assert result.sun_seen and angle(result.q_b_ll, q_est) < 1e-12


def test_sunfind_near_the_zenith_succeeds_without_updating() -> None:
    def zenith_sun(t_s: float) -> F:  # 88 deg up, turning slowly in azimuth
        az, el = 0.3 + 2e-4 * (t_s - T0), math.radians(88.0)
        return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), -math.sin(el)])

    q_est = with_heading_error(Q_TRUE, 90.0)
    proc = Sunfind(q_est, T0, zenith_sun, SunfindParams())
    assert proc.plan.n_guesses == 1  # the cone fits in one image
    result, log = run(proc, sky(Q_TRUE, zenith_sun))
    assert result.outcome is SunOutcome.NEAR_ZENITH
    assert result.success and not result.updated and result.sun_seen
    assert [r.purpose for r, _, _ in log] == ["search 0", "confirm 1", "confirm 2"]
    assert angle(result.q_b_ll, q_est) < 1e-12  # the 90 deg heading error is left alone
    assert result.final_mast is not None


# ---- Sungaze (sec. 2.2.3) ---------------------------------------------------------------

THETA = np.radians(2.0) * np.array([0.6, -0.48, 0.64])  # a 2 deg 3-axis error (|u| = 1)
Q_EST_SMALL = (Rotation.from_rotvec(THETA) * Rotation.from_quat(Q_TRUE)).as_quat()


def mast_on_estimated_sun(q_est: F, t_s: float) -> tuple[float, float]:
    d = Rotation.from_quat(q_est).apply(sun_ll(t_s))
    return math.atan2(d[1], d[0]), math.atan2(-d[2], math.hypot(d[0], d[1]))


def run_sungaze(
    params: SungazeParams, answer: Answer, down_b: F | None = None
) -> tuple[SunResult, Log, list[float]]:
    proc = Sungaze(Q_EST_SMALL, T0, mast_on_estimated_sun(Q_EST_SMALL, T0), sun_ll, params, down_b)
    log: Log = []
    sigmas: list[float] = []
    while proc.request is not None:
        req = proc.request
        f = answer(req, req.not_before_t_s)
        log.append((req, req.not_before_t_s, f))
        proc.on_image(req.not_before_t_s, f)
        sigmas.append(proc.three_sigma_rad)
    assert proc.result is not None
    return proc.result, log, sigmas


def test_sungaze_converges_to_the_truth_with_a_shrinking_3_sigma() -> None:
    assert math.degrees(angle(Q_EST_SMALL, Q_TRUE)) == pytest.approx(2.0)
    result, log, sigmas = run_sungaze(SungazeParams(), sky(Q_TRUE))
    assert result.outcome is SunOutcome.CONVERGED and result.success and result.updated
    assert all(f is not None for _, _, f in log)  # the sun stays in the field
    assert math.degrees(angle(result.q_b_ll, Q_TRUE)) < 0.05
    # one sun vector leaves the roll about it unknown; then every image shrinks the 3σ
    assert sigmas[0] == math.inf
    assert all(b < a for a, b in itertools.pairwise(sigmas[1:]))
    # early stop at the first image with 3σ <= 1.5 deg
    assert sigmas[-1] <= math.radians(1.5) < sigmas[-2]
    assert result.three_sigma_rad == sigmas[-1] and result.n_images == len(log)
    # the mast never moves; images every 20 s
    assert len({(r.az_rad, r.el_rad) for r, _, _ in log}) == 1
    assert np.allclose(np.diff([t for _, t, _ in log]), 20.0)
    assert result.final_mast == (log[0][0].az_rad, log[0][0].el_rad)


def test_sungaze_without_early_stop_runs_to_the_ten_minute_timer() -> None:
    result, log, sigmas = run_sungaze(SungazeParams(early_stop=False), sky(Q_TRUE))
    assert result.outcome is SunOutcome.TIMER_CONVERGED and result.success
    assert len(log) == result.n_images == 31  # t = 0, 20, ..., 600 s
    assert log[-1][1] - log[0][1] == pytest.approx(600.0)
    assert all(b < a for a, b in itertools.pairwise(sigmas[1:]))
    assert math.degrees(angle(result.q_b_ll, Q_TRUE)) < 0.05


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sungaze_noisy_fixes_stay_within_the_reported_3_sigma(seed: int) -> None:
    rng = np.random.default_rng(seed)
    sigma = SungazeParams().sun_sigma_rad
    honest = sky(Q_TRUE)

    def noisy(req: PancamRequest, t_s: float) -> SunFix | None:
        f = honest(req, t_s)
        if f is None:
            return None
        s = f.sun_b
        e1 = np.cross(s, [0.0, 0.0, 1.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(s, e1)
        rotvec = sigma * (rng.standard_normal() * e1 + rng.standard_normal() * e2)
        return fix(Rotation.from_rotvec(rotvec).apply(s))

    for params in (SungazeParams(), SungazeParams(early_stop=False)):
        result, _, _ = run_sungaze(params, noisy)
        assert result.success
        err = angle(result.q_b_ll, Q_TRUE)
        assert err <= result.three_sigma_rad
        assert err < angle(Q_EST_SMALL, Q_TRUE)  # and it did improve on 2 deg


def test_sungaze_without_a_sun_does_not_converge_and_changes_nothing() -> None:
    result, log, _ = run_sungaze(SungazeParams(), no_sun)
    assert result.outcome is SunOutcome.NOT_CONVERGED
    assert not result.success and not result.updated and not result.sun_seen
    assert len(log) == result.n_images == 31
    assert result.final_mast is None and result.three_sigma_rad == math.inf
    assert angle(result.q_b_ll, Q_EST_SMALL) < 1e-12


def test_sungaze_gravity_variation_converges_after_the_first_image() -> None:
    down_b = Rotation.from_quat(Q_TRUE).apply(DOWN)  # the accelerometers' true down
    result, log, _ = run_sungaze(SungazeParams(use_gravity=True), sky(Q_TRUE), down_b)
    assert result.outcome is SunOutcome.CONVERGED and result.n_images == len(log) == 1
    assert 0.0 < result.three_sigma_rad <= math.radians(1.5)
    assert math.degrees(angle(result.q_b_ll, Q_TRUE)) < 0.05
    with pytest.raises(ValueError, match="down_b"):
        Sungaze(Q_EST_SMALL, T0, (0.0, 0.5), sun_ll, SungazeParams(use_gravity=True))


# ---- Suncheck (sec. 2.3.2) --------------------------------------------------------------


def test_suncheck_passes_within_tolerance_and_leaves_the_mast_on_the_sun() -> None:
    q_est = (
        Rotation.from_rotvec(np.radians([0.5, 0.5, 0.5])) * Rotation.from_quat(Q_TRUE)
    ).as_quat()
    proc = Suncheck(q_est, T0, sun_ll, SuncheckParams())
    req = proc.request
    assert req is not None
    predicted_b = Rotation.from_quat(q_est).apply(sun_ll(T0))
    assert np.allclose(boresight_b(req), predicted_b, atol=1e-12)  # aimed with the estimate
    result, _ = run(proc, sky(Q_TRUE))
    true_b = Rotation.from_quat(Q_TRUE).apply(sun_ll(T0))
    expected_err = math.acos(min(1.0, float(true_b @ predicted_b)))
    assert result.outcome is SunOutcome.PASSED and result.success and not result.updated
    assert result.error_rad == pytest.approx(expected_err, abs=1e-12)
    assert result.n_images == 1 and result.sun_seen
    assert angle(result.q_b_ll, q_est) < 1e-12
    assert result.final_mast is not None
    assert np.allclose(R_b_pancam(*result.final_mast)[:, 2], true_b, atol=1e-12)


def test_suncheck_fails_out_of_tolerance_without_changing_the_estimate() -> None:
    q_est = with_heading_error(Q_TRUE, 4.0)
    result, _ = run(Suncheck(q_est, T0, sun_ll, SuncheckParams()), sky(Q_TRUE))
    # a 4 deg heading error moves a sun at elevation e by 2 asin(cos e sin 2 deg)
    expected = cone_distance(elevation(sun_ll(T0)), math.radians(4.0))
    assert result.outcome is SunOutcome.OUT_OF_TOLERANCE and not result.success
    assert result.error_rad == pytest.approx(expected, abs=1e-9)
    assert result.sun_seen and result.final_mast is not None and not result.updated
    assert angle(result.q_b_ll, q_est) < 1e-12
    # the same error with a 3 deg tolerance passes
    loose = SuncheckParams(tolerance_rad=math.radians(3.0))
    assert run(Suncheck(q_est, T0, sun_ll, loose), sky(Q_TRUE))[0].success


def test_suncheck_without_a_sun_fails() -> None:
    q_est = with_heading_error(Q_TRUE, 30.0)
    result, log = run(Suncheck(q_est, T0, sun_ll, SuncheckParams()), sky(Q_TRUE))
    assert log[0][2] is None  # 30 deg off: not in the field
    assert result.outcome is SunOutcome.NO_SUN and not result.success and not result.sun_seen
    assert result.final_mast is None and angle(result.q_b_ll, q_est) < 1e-12
    assert math.isnan(result.error_rad)


# ---- parameters -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("make", "name"),
    [
        (lambda: SunfindParams(image_spacing_s=0.0), "image_spacing_s"),
        (lambda: SunfindParams(confirm_spacing_s=math.nan), "confirm_spacing_s"),
        (lambda: SungazeParams(timer_s=-1.0), "timer_s"),
        (lambda: SungazeParams(interval_s=700.0), "interval_s"),
        (lambda: SungazeParams(early_stop=1), "early_stop"),
        (lambda: SungazeParams(use_gravity="yes"), "use_gravity"),
        (lambda: SungazeParams(sun_sigma_rad=math.inf), "sun_sigma_rad"),
        (lambda: SuncheckParams(tolerance_rad=math.pi), "tolerance_rad"),
        (lambda: SuncheckParams(tolerance_rad=0.0), "tolerance_rad"),
    ],
)
def test_bad_procedure_parameters_are_refused(make: Callable[[], object], name: str) -> None:
    with pytest.raises(ValueError, match=name):
        make()
