"""``roverops bench sapp``: SAPP against MER's requirements, Monte Carlo over seeds, sites
and times (Ali et al. 2005; the figures of docs/REFERENCES.md).

Every run is a ``RoverSession``: the flight software in the loop on the simulated rover,
judged against the simulator's truth.

- Acquisition runs (``n_runs``, default 200): a rover at a random place on ``gusev``,
  ``meridiani`` or ``eq22`` (so a random tilt), random heading (the estimate starts at
  North, so the initial heading error is uniform over 0-180 deg), at a random time with
  the sun 15-75 deg high, runs GetFineAttitude. Measured: the tilt error after Nadir
  Update, Sunfind's success and heading error, Sungaze's attitude error against its
  reported 3σ. The same run is repeated with the Sungaze gravity variation. Each run's wall
  time too: ``acquisition_run_wall_s_median``, the cost of one GetFineAttitude in the loop.
- Odometry runs: 100 m of mixed straight, arc and turn-in-place driving after
  GetFineAttitude, on ``flat`` without slip and on ``gusev`` with slip; the horizontal
  position error at the end, as a percentage of the distance really driven.
- HGA runs: GetFineAttitude, then IMU propagation at rest until the Earth-pointing error
  passes 2 deg or ``hga_max_h`` hours, in two modes: Mobility's gyro-only propagation (how
  IMU time builds up in drives, sec. 2.4.2: the headline figure) and Articulate's (gyros
  plus accelerometer tilt corrections, sec. 2.4.1: only the heading drifts).

3σ figures of a vector error are ``3 x`` the RMS of its worst axis (body axes for the
attitude; the two horizontal body axes for the tilt), the per-axis reading of MER's
"1.5 deg 3σ". Beside it: ``3 x`` the RMS of the total angle (``_3rms_total_deg``, stricter
by up to √3) and the 99.7th percentile of the total angle. Accuracy statistics are over
the runs whose mode succeeded; the success rates have their own targets.
"""

from __future__ import annotations

import math
import os
import time
from concurrent.futures import ProcessPoolExecutor
from datetime import UTC, datetime, timedelta
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from bench.result import bench_result
from estimation.ivp import earth_ll
from estimation.sapp.sun_modes import SunResult
from sequences import commands as cmd
from sim.errors import InputError
from sim.loop.downlink import Downlink
from sim.loop.session import RoverSession
from sim.scoring.truth import Truth
from sim.world.mars_frames import earth_ll_truth, elevation_rad, sun_ll_truth
from sim.world.marsclock import utc_to_t_s
from sim.world.sites import site

ACQUISITION_SITES = ("gusev", "meridiani", "eq22")
SUN_ELEVATION_DEG = (15.0, 75.0)
EPOCH = datetime(2004, 1, 10, tzinfo=UTC)
SPAN_DAYS = 700.0
PLACEMENT_M = 30.0
# 100 m of mixed driving: straight, arc, turn in place (lengths of the arcs in metres:
# 5 m x 90 deg = 7.85, 8 m x 60 deg = 8.38).
ODOMETRY_COURSE: tuple[cmd.Command, ...] = (
    cmd.DriveStraight(20.0),
    cmd.DriveArc(5.0, 90.0),
    cmd.DriveStraight(15.0),
    cmd.TurnInPlace(90.0),
    cmd.DriveStraight(20.0),
    cmd.DriveArc(-8.0, 60.0),
    cmd.DriveStraight(15.0),
    cmd.TurnInPlace(-45.0),
    cmd.DriveStraight(13.77),
)


def _random_start(rng: np.random.Generator, site_name: str) -> tuple[datetime, float]:
    """A UTC time with the sun in ``SUN_ELEVATION_DEG`` at the site, and its elevation."""
    s = site(site_name)
    lat, lon = math.radians(s.lat_deg), math.radians(s.lon_east_deg)
    while True:
        utc = EPOCH + timedelta(days=float(rng.uniform(0.0, SPAN_DAYS)))
        elev = math.degrees(float(elevation_rad(sun_ll_truth(utc_to_t_s(utc), lat, lon))))
        if SUN_ELEVATION_DEG[0] <= elev <= SUN_ELEVATION_DEG[1]:
            return utc, elev


def _attitude_error_b(q_b_ll_est: Any, q_b_ll_true: Any) -> np.ndarray:
    """Rotation vector of ``R_est R_trueᵀ``: the error in body axes, rad (3,)."""
    out: np.ndarray = (
        Rotation.from_quat(q_b_ll_est) * Rotation.from_quat(q_b_ll_true).inv()
    ).as_rotvec()
    return out


def _tilt_error_b(q_b_ll_est: Any, q_b_ll_true: Any) -> np.ndarray:
    """Small-angle tilt error in body axes (x, y components), rad."""
    down_est = Rotation.from_quat(q_b_ll_est).apply([0.0, 0.0, 1.0])
    down_true = Rotation.from_quat(q_b_ll_true).apply([0.0, 0.0, 1.0])
    out: np.ndarray = np.cross(down_true, down_est)[:2]
    return out


def _heading_deg(q_b_ll: Any) -> float:
    """Heading of body x (its horizontal projection), deg clockwise from North."""
    x_ll = Rotation.from_quat(q_b_ll).inv().apply([1.0, 0.0, 0.0])
    return math.degrees(math.atan2(float(x_ll[1]), float(x_ll[0])))


def _heading_error_deg(q_b_ll_est: Any, q_b_ll_true: Any) -> float:
    """Absolute heading difference, deg in [0, 180]."""
    d = (_heading_deg(q_b_ll_est) - _heading_deg(q_b_ll_true) + 180.0) % 360.0 - 180.0
    return abs(d)


def _frame_with(session: RoverSession, prefix: str) -> tuple[Downlink, Truth] | None:
    """The first frame (downlink and truth) whose downlink has an event starting ``prefix``."""
    for d, t in zip(session.downlinks, session.truths, strict=True):
        if any(e.text.startswith(prefix) for e in d.events):
            return d, t
    return None


def acquisition_run(index: int, seed: int, gravity: bool) -> dict[str, Any]:
    """One GetFineAttitude run (module docstring); ``gravity`` selects the variation.
    ``wall_s``: the run's wall time, set-up included."""
    t0 = time.perf_counter()
    rng = np.random.default_rng([seed, index])
    site_name = ACQUISITION_SITES[index % len(ACQUISITION_SITES)]
    utc, sun_elev = _random_start(rng, site_name)
    yaw = float(rng.uniform(-math.pi, math.pi))
    x, y = rng.uniform(-PLACEMENT_M, PLACEMENT_M, 2)
    session = RoverSession(
        site_name, seed * 100_000 + index, utc, yaw_rad=yaw, x_m=float(x), y_m=float(y),
        frame_every_s=3600.0,
    )  # fmt: skip
    if gravity:
        session.nate.set_param("sungaze.use_gravity", True)
    q_true = session.q_b_ll_true()
    tilt_true = math.degrees(2.0 * math.asin(min(1.0, math.hypot(q_true[0], q_true[1]))))
    heading_err0 = abs(math.degrees(float(_attitude_error_b(session.nate.q_b_ll, q_true)[2])))
    report = session.execute(cmd.GetFineAttitude())
    out: dict[str, Any] = {
        "site": site_name,
        "sun_elev_deg": sun_elev,
        "tilt_true_deg": tilt_true,
        "initial_heading_err_deg": min(heading_err0, 360.0 - heading_err0),
        "status": report.status,
    }
    nadir = _frame_with(session, "Nadir Update succeeded")
    if nadir is not None:
        out["nadir_tilt_err_b_rad"] = _tilt_error_b(
            nadir[0].q_b_ll_est, nadir[1].q_b_ll_true
        ).tolist()
    sunfind = _frame_with(session, "Sunfind:")
    sun_results = [r for r in report.results if isinstance(r, SunResult)]
    out["sunfind_ok"] = bool(sun_results and sun_results[0].success)
    if sunfind is not None and out["sunfind_ok"]:
        out["sunfind_heading_err_deg"] = _heading_error_deg(
            sunfind[0].q_b_ll_est, sunfind[1].q_b_ll_true
        )
        out["sunfind_images"] = sun_results[0].n_images
    if len(sun_results) == 2:
        gaze = sun_results[1]
        out["sungaze_ok"] = gaze.success
        out["sungaze_images"] = gaze.n_images
        out["sungaze_reported_3sigma_deg"] = math.degrees(gaze.three_sigma_rad)
        out["sungaze_err_b_rad"] = _attitude_error_b(
            session.nate.q_b_ll, session.q_b_ll_true()
        ).tolist()
    out["wall_s"] = time.perf_counter() - t0
    return out


def odometry_run(site_name: str, seed: int, slip: bool) -> dict[str, Any]:
    """GetFineAttitude then the 100 m course; position error as % of the distance."""
    rng = np.random.default_rng([seed, 7])
    utc, _ = _random_start(rng, "gusev")
    session = RoverSession(
        site_name, seed, utc, slip=slip, yaw_rad=float(rng.uniform(-math.pi, math.pi)),
        frame_every_s=600.0,
    )  # fmt: skip
    fine = session.execute(cmd.GetFineAttitude())
    distance = sum(r.details.get("distance_truth_m", 0.0) for r in session.run(ODOMETRY_COURSE))
    last, scored = session.downlinks[-1], session.truths[-1]
    err = float(np.linalg.norm(np.subtract(last.p_mission_est, scored.p_mission_true)[:2]))
    return {
        "site": site_name,
        "slip": slip,
        "fine_ok": fine.status == "completed",
        "distance_m": distance,
        "err_m": err,
        "err_pct": 100 * err / distance,
    }


def earth_pointing_error_deg(session: RoverSession) -> float:
    """Angle between where the estimate and IVP put Earth and where it is (body frame):
    the HGA error of a gimbal that can reach any direction."""
    sim, nate = session.sim, session.nate
    est_b = Rotation.from_quat(nate.q_b_ll).apply(earth_ll(sim.t_s, sim.lat_rad, sim.lon_east_rad))
    true_b = Rotation.from_quat(session.q_b_ll_true()).apply(
        earth_ll_truth(sim.t_s, sim.lat_rad, sim.lon_east_rad)
    )
    return math.degrees(
        math.atan2(float(np.linalg.norm(np.cross(est_b, true_b))), float(est_b @ true_b))
    )


def hga_run(seed: int, max_h: float, mode: str, step_s: float = 1000.0) -> dict[str, Any]:
    """GetFineAttitude, then propagation at rest in ``mode`` (``"mobility"``: gyros only,
    no wheel motion; ``"articulate"``: with tilt corrections); the Earth-pointing error
    over IMU time."""
    rng = np.random.default_rng([seed, 11])
    utc, _ = _random_start(rng, "gusev")
    session = RoverSession(
        "gusev", seed, utc, yaw_rad=float(rng.uniform(-math.pi, math.pi)), frame_every_s=3600.0
    )
    fine = session.execute(cmd.GetFineAttitude())
    if mode == "articulate":
        session.execute(cmd.ArticulateStart())
    else:  # a rover standing in Mobility: gyro-only propagation, as during drives
        session.nate.mobility()
    t0_imu = session.nate.imu_integration_s
    curve = [(0.0, earth_pointing_error_deg(session))]
    at_10000 = math.nan
    lost_h = math.nan
    while curve[-1][0] < max_h * 3600.0:
        session.execute(cmd.Wait(step_s))
        t = session.nate.imu_integration_s - t0_imu
        err = earth_pointing_error_deg(session)
        curve.append((t, err))
        if abs(t - 10_000.0) < 1.0:
            at_10000 = err
        if err > 2.0 and math.isnan(lost_h):
            prev_t, prev_err = curve[-2]
            lost_h = (prev_t + (2.0 - prev_err) / (err - prev_err) * (t - prev_t)) / 3600.0
        if not math.isnan(lost_h) and t >= 10_000.0:
            break
    return {
        "seed": seed,
        "mode": mode,
        "fine_ok": fine.status == "completed",
        "err_after_10000s_deg": at_10000,
        "margin_gone_h": lost_h,
        "curve": curve,
    }


def _three_sigma_deg(vectors: list[list[float]]) -> float:
    v = np.asarray(vectors, dtype=float)
    return float(3.0 * math.degrees(float(np.sqrt(np.mean(v**2, axis=0)).max())))


def _three_rms_total_deg(vectors: list[list[float]]) -> float:
    v = np.asarray(vectors, dtype=float)
    return float(3.0 * math.degrees(float(np.sqrt(np.mean(np.sum(v**2, axis=1))))))


def _p997_deg(vectors: list[list[float]]) -> float:
    v = np.asarray(vectors, dtype=float)
    return float(np.degrees(np.quantile(np.linalg.norm(v, axis=1), 0.997)))


def _pool_map(fn: Any, args: list[tuple[Any, ...]], workers: int) -> list[Any]:
    if workers <= 1:
        return [fn(*a) for a in args]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        return list(pool.map(fn, *zip(*args, strict=True)))


def _acquisition_metrics(runs: list[dict[str, Any]], prefix: str) -> dict[str, Any]:
    gaze = [r for r in runs if r.get("sungaze_ok")]
    errors = [r["sungaze_err_b_rad"] for r in gaze]
    reported = [r["sungaze_reported_3sigma_deg"] for r in gaze]
    true_3s = _three_sigma_deg(errors) if errors else math.nan
    return {
        f"{prefix}_err_3sigma_deg": true_3s,
        f"{prefix}_err_3rms_total_deg": _three_rms_total_deg(errors) if errors else math.nan,
        f"{prefix}_err_p997_deg": _p997_deg(errors) if errors else math.nan,
        f"{prefix}_err_max_deg": float(np.degrees(max(np.linalg.norm(e) for e in errors)))
        if errors
        else math.nan,
        f"{prefix}_reported_3sigma_mean_deg": float(np.mean(reported)) if reported else math.nan,
        f"{prefix}_converged_pct": 100.0
        * len(gaze)
        / max(1, sum(1 for r in runs if r["sunfind_ok"])),
        f"{prefix}_images_median": float(np.median([r["sungaze_images"] for r in gaze]))
        if gaze
        else math.nan,
    }


def bench_sapp(
    n_runs: int = 200,
    n_odometry: int = 3,
    n_hga: int = 4,
    hga_max_h: float = 8.0,
    seed: int = 0,
    workers: int | None = None,
) -> dict[str, Any]:
    """Run the SAPP benchmark (module docstring); smaller counts make a quick version."""
    for name, value in (("n_runs", n_runs), ("n_odometry", n_odometry), ("n_hga", n_hga)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise InputError(name, f"must be a positive integer, got {value!r}")
    if not (math.isfinite(hga_max_h) and 10_000.0 / 3600.0 <= hga_max_h <= 48.0):
        raise InputError("hga_max_h", "must be in [2.78, 48] h (at least 10,000 s)")
    n_workers = workers if workers is not None else (os.cpu_count() or 1)

    basic = _pool_map(acquisition_run, [(i, seed, False) for i in range(n_runs)], n_workers)
    gravity = _pool_map(acquisition_run, [(i, seed, True) for i in range(n_runs)], n_workers)
    odometry = _pool_map(
        odometry_run,
        [("flat", seed + k, False) for k in range(n_odometry)]
        + [("gusev", seed + k, True) for k in range(n_odometry)],
        n_workers,
    )
    hga = _pool_map(
        hga_run,
        [(seed + k, hga_max_h, mode) for mode in ("mobility", "articulate") for k in range(n_hga)],
        n_workers,
    )
    hga_mob = [r for r in hga if r["mode"] == "mobility"]
    hga_art = [r for r in hga if r["mode"] == "articulate"]

    nadir = [r["nadir_tilt_err_b_rad"] for r in basic if "nadir_tilt_err_b_rad" in r]
    sunfind_ok = [r for r in basic if r["sunfind_ok"]]
    flat = [r["err_pct"] for r in odometry if r["site"] == "flat"]
    gusev = [r["err_pct"] for r in odometry if r["site"] == "gusev"]
    metrics: dict[str, Any] = {
        "runs": n_runs,
        **_acquisition_metrics(basic, "sungaze"),
        **_acquisition_metrics(gravity, "sungaze_gravity"),
        "sunfind_success_pct": 100.0 * len(sunfind_ok) / n_runs,
        "sunfind_heading_err_max_deg": max(r["sunfind_heading_err_deg"] for r in sunfind_ok)
        if sunfind_ok
        else math.nan,
        "sunfind_images_median": float(np.median([r["sunfind_images"] for r in sunfind_ok]))
        if sunfind_ok
        else math.nan,
        "initial_heading_err_max_deg": max(r["initial_heading_err_deg"] for r in basic),
        "nadir_tilt_err_deg": _three_sigma_deg(nadir) if nadir else math.nan,
        "nadir_tilt_err_3rms_total_deg": _three_rms_total_deg(nadir) if nadir else math.nan,
        "nadir_success_pct": 100.0 * len(nadir) / n_runs,
        "tilt_true_median_deg": float(np.median([r["tilt_true_deg"] for r in basic])),
        "tilt_true_max_deg": max(r["tilt_true_deg"] for r in basic),
        "sun_elev_min_deg": min(r["sun_elev_deg"] for r in basic),
        "sun_elev_max_deg": max(r["sun_elev_deg"] for r in basic),
        "acquisition_run_wall_s_median": float(np.median([r["wall_s"] for r in basic])),
        "odometry_err_pct_of_distance": max(flat),
        "odometry_err_pct_of_distance_gusev_slip": max(gusev),
        "odometry_runs_per_site": n_odometry,
        "fine_failed_in_odometry_or_hga_runs": sum(1 for r in odometry + hga if not r["fine_ok"]),
        # Mobility (gyros only, as in drives): the headline; Articulate beside it
        "hga_err_after_10000s_deg": max(r["err_after_10000s_deg"] for r in hga_mob),
        "hga_err_after_10000s_each_deg": [r["err_after_10000s_deg"] for r in hga_mob],
        # hours of propagation until the 2 deg margin was gone; null: not within hga_max_h
        "hga_margin_gone_h_each": [r["margin_gone_h"] for r in hga_mob],
        "hga_err_after_10000s_articulate_deg": max(r["err_after_10000s_deg"] for r in hga_art),
        "hga_err_after_10000s_articulate_each_deg": [r["err_after_10000s_deg"] for r in hga_art],
        "hga_margin_gone_h_articulate_each": [r["margin_gone_h"] for r in hga_art],
        "hga_max_h": hga_max_h,
        "hga_runs": n_hga,
    }
    targets = {
        "sungaze_err_3sigma_deg": {"le": 1.5},
        "sunfind_success_pct": {"ge": 99.0},
        "sungaze_converged_pct": {"ge": 99.0},
        "nadir_tilt_err_deg": {"le": 0.1},
        # Half of the 0.68 s measured on the reference machine before issue 16's changes
        # (one GetFineAttitude run, the median of acquisition runs 0-7, seed 0).
        "acquisition_run_wall_s_median": {"le": 0.34},
        "odometry_err_pct_of_distance": {"le": 2.0},
    }
    return bench_result("sapp", metrics, targets)
