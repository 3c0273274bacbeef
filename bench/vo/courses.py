"""``roverops bench vo``: MER visual odometry (Cheng, Maimone and Matthies 2005)
measured on rendered Navcam pairs, with an OpenCV baseline beside it.

Every drive is a ``RoverSession`` ``vo=on`` drive (``sim.loop.session``): the flight software's
VO (``estimation.vo``) on 256 x 256 pairs (``sim.loop.vo_drive.VO_RIG``), SAPP's position replaced
on each converged step. The attitude starts Fine, loaded from the truth, so the position
error measured is VO's (and wheel odometry's), not a heading error's. A wrapper around the
flight VO (``RecordingVO``) keeps, for every pair, the truth pose, VO's outcome and the
baseline's (``bench.vo.baseline``: ORB, StereoSGBM, solvePnPRansac) on the same images.

- Rock course (Cheng, Maimone and Matthies 2005 sec. 3, Fig. 4): 2.45 m commanded straight over
rocks 8-20 cm tall
  (``sim.scenarios.vo_courses.find_rock_course``) in 35 cm steps, each step's slip drawn
  uniformly in 0-85 % (``SlipParams.slip_range``); the distance truly driven is shorter
  (about 1.4 m).
- Slope drive: 20 m commanded up and across a 20 deg slope of Gusev's hills
  (``find_slope_course``), MER's 0.75 m steps, slip 30-60 % per step.
- Convergence: 3 m drives at random places near the origin of ``gusev`` and ``meridiani``
  (the model's own slip), MER's steps; the fraction of steps that converged.
- Shadow: the same drives on ``gusev`` heading away from a 25-45 deg sun, the rover's own
  shadow drawn in the pairs (sec. 4.3's false positive).
- Sols 137/141 (sec. 4.3): the Gusev convergence drives and the rock course again, with the
  features' minimum separation too small (``MIN_SEPARATION_SMALL_PX``), against the same
  drives at the default separation.

Mobility fault protection is set not to stop these drives (``RELAXED_LIMITS``: the slip check
every 50 m, longer than any drive here, tilt and suspension limits at their largest;
``vo_fail=continue``): the bench measures VO over slipping drives on rough ground.

Errors. A drive's error is the distance between the estimated and the true displacement
from the first pair to the last (3D, Site frame), as a percentage of the distance truly
driven (the path length). VO's estimate is SAPP's own after the drive; wheel odometry's
and the baseline's are the same chain of steps with the wheel-odometry step (what SAPP
propagated) or the baseline's motion in place of VO's (a failed baseline step keeps the
wheel-odometry step, as VO's does). Accuracy statistics are the RMS over runs (and the
worst run). A step's update is false when its motion differs from the true motion between
its two pairs by more than 5 cm or 1 deg.

Timing: the median wall time of ``VisualOdometry.step`` on a new pair (features and
stereo of the new pair, tracking, RANSAC, ML), rendering excluded, at 1024 and 256 px, run
before the Monte Carlo so nothing else competes for the cores.
"""

from __future__ import annotations

import math
import os
import statistics
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from datetime import UTC, datetime, timedelta
from functools import partial
from itertools import pairwise
from multiprocessing import get_context
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from bench.result import bench_result
from bench.vo.baseline import OrbPnpBaseline
from estimation.protection.limits import SPECS
from estimation.sapp.aqf import AttitudeQuality
from estimation.vo.odometry import VisualOdometry, VoResult, VoStatus
from estimation.vo.params import VoParams
from estimation.vo.stereo_rig import NAVCAM, StereoRig
from sequences import commands as cmd
from sim.errors import InputError
from sim.loop.rover_sim import RoverSim
from sim.loop.session import RoverSession
from sim.loop.vo_drive import VO_MAST_AZ_RAD, VO_MAST_EL_RAD, VO_RIG, VoDriveOptions
from sim.scenarios.vo_courses import find_rock_course, find_slope_course
from sim.world.heightmap import HeightmapTerrain
from sim.world.mars_frames import elevation_rad, sun_ll_truth
from sim.world.marsclock import utc_to_t_s
from sim.world.sites import make_terrain, site

FloatArray = NDArray[np.float64]

ROCK_COURSE_M = 2.45  # Cheng, Maimone and Matthies 2005 sec. 3
ROCK_STEP_M = 0.35
ROCK_SLIP = (0.0, 0.85)
SLOPE_DEG = 20.0
SLOPE_COURSE_M = 20.0
SLOPE_SLIP = (0.3, 0.6)
CONVERGENCE_DRIVE_M = 3.0
CONVERGENCE_PLACE_M = 40.0
SUN_ELEVATION_DEG = (30.0, 65.0)  # VO was commanded in daylight, sun well up
SHADOW_SUN_ELEVATION_DEG = (25.0, 45.0)  # the mast's shadow 1.6-3.2 m ahead: in view
FALSE_UPDATE_M = 0.05
FALSE_UPDATE_DEG = 1.0
EPOCH = datetime(2004, 1, 10, tzinfo=UTC)
SPAN_DAYS = 700.0
TIMING_STEP_M = 0.5
SHADOW_DARKER = 0.9  # a pixel in the rover's shadow is at least 10 % darker
KINDS = ("rock", "slope", "convergence", "shadow")
# Sec. 4.3, sols 137/141: "the minimum separation between features was too small", so the
# features clustered on one small feature-rich patch. No separation at all (features on
# neighbouring pixels, the 1 px grid) is what reproduces false updates on these drives:
# a few pixels of separation already spread them enough (docs/BENCHMARKS.md)
MIN_SEPARATION_SMALL_PX = 1.01
_SMALL = {"min_separation_px": MIN_SEPARATION_SMALL_PX, "grid_cell_px": 1}
# MER's single tracking pass and no precision check, as flown on those sols
_MER_TRACKING = {"track_passes": 1, "max_sigma_m": 1.0, "max_sigma_rad": math.pi}
VO_VARIANTS: dict[str, dict[str, Any]] = {
    "default": {},
    "separation_small": _SMALL,
    "separation_small_mer": {**_SMALL, **_MER_TRACKING},
    "separation_default_mer": _MER_TRACKING,
}


@dataclass(frozen=True)
class DriveSpec:
    """One benchmark drive: ``kind`` (``KINDS``), where, the terrain/run seeds, and the
    VO rig's width (``RoverSession``'s ``vo_rig``)."""

    kind: str
    site_name: str
    seed: int
    index: int
    length_m: float
    vo_rig: int = 256
    vo_variant: str = "default"  # the VO's parameters (``VO_VARIANTS``)


@dataclass(frozen=True)
class PairRecord:
    """What one pair produced: the truth pose (Site, ``p_s`` m and ``R_s_b``), what SAPP
    gave VO (``R_s_b0`` estimate, the predicted ``p_b1_b0``), VO's status and motion,
    the baseline's motion, and both wall times (s)."""

    p_s_true: FloatArray
    R_s_b_true: FloatArray
    R_s_b0: FloatArray
    p_pred_b0: FloatArray
    status: VoStatus
    vo_motion: tuple[FloatArray, FloatArray] | None
    n_inliers: int
    baseline_motion: tuple[FloatArray, FloatArray] | None
    vo_s: float
    baseline_s: float


class RecordingVO(VisualOdometry):
    """The flight VO on ``rig``, recording each pair with the truth from ``sim`` and
    running the OpenCV baseline on the same images (a benchmark wrapper)."""

    def __init__(self, sim: RoverSim, rig: StereoRig = VO_RIG, variant: str = "default") -> None:
        params = replace(VoParams().for_width(rig.camera.width_px), **VO_VARIANTS[variant])
        super().__init__(rig, params)
        self.sim = sim
        self.baseline = OrbPnpBaseline(rig)
        self.pairs: list[PairRecord] = []

    def reset(self) -> None:
        super().reset()
        self.baseline.reset()

    def step(
        self,
        left: ArrayLike,
        right: ArrayLike,
        *,
        R_b0_b1_predicted: ArrayLike,
        p_b1_b0_predicted: ArrayLike,
        R_s_b0: ArrayLike,
        mast_az_rad: float,
        mast_el_rad: float,
        sun_b: ArrayLike | None = None,
    ) -> VoResult:
        start = time.perf_counter()
        result = super().step(
            left, right, R_b0_b1_predicted=R_b0_b1_predicted,
            p_b1_b0_predicted=p_b1_b0_predicted, R_s_b0=R_s_b0, mast_az_rad=mast_az_rad,
            mast_el_rad=mast_el_rad, sun_b=sun_b,
        )  # fmt: skip
        vo_s = time.perf_counter() - start
        start = time.perf_counter()
        base = self.baseline.step(left, right, mast_az_rad, mast_el_rad)
        baseline_s = time.perf_counter() - start
        state = self.sim.drive_state
        motion = result.motion
        self.pairs.append(
            PairRecord(
                p_s_true=state.p_s.copy(),
                R_s_b_true=Rotation.from_quat(state.q_s_b).as_matrix(),
                R_s_b0=np.asarray(R_s_b0, dtype=np.float64),
                p_pred_b0=np.asarray(p_b1_b0_predicted, dtype=np.float64),
                status=result.status,
                vo_motion=None if motion is None else (motion.R_b0_b1, motion.p_b1_b0),
                n_inliers=result.n_inliers,
                baseline_motion=base.motion,
                vo_s=vo_s,
                baseline_s=baseline_s,
            )
        )
        return result


def _sun_time(rng: np.random.Generator, site_name: str, elev_deg: tuple[float, float]) -> datetime:
    """A UTC time with the sun ``elev_deg[0]``-``elev_deg[1]`` high at the site."""
    s = site(site_name)
    lat, lon = math.radians(s.lat_deg), math.radians(s.lon_east_deg)
    while True:
        utc = EPOCH + timedelta(days=float(rng.uniform(0.0, SPAN_DAYS)))
        elev = math.degrees(float(elevation_rad(sun_ll_truth(utc_to_t_s(utc), lat, lon))))
        if elev_deg[0] <= elev <= elev_deg[1]:
            return utc


def _session(spec: DriveSpec, rng: np.random.Generator) -> tuple[RoverSession, dict[str, Any]]:
    """The session of a drive, placed and lit for its kind, with what placed it."""
    shadow = spec.kind == "shadow"
    utc = _sun_time(rng, spec.site_name, SHADOW_SUN_ELEVATION_DEG if shadow else SUN_ELEVATION_DEG)
    info: dict[str, Any] = {}
    if spec.kind in ("rock", "slope"):
        terrain = make_terrain(spec.site_name, spec.seed)
        assert isinstance(terrain, HeightmapTerrain)
        if spec.kind == "rock":  # the front wheels roll about the distance truly driven
            course = find_rock_course(terrain, rng, ROCK_COURSE_M * (1.0 - 0.5 * sum(ROCK_SLIP)))
        else:
            course = find_slope_course(terrain, rng, SLOPE_DEG, spec.length_m)
        x, y, yaw = course.x_m, course.y_m, course.yaw_rad
        info = {"rock_max_m": course.feature_m, "slope_deg": course.slope_deg,
                "rock_bumps": course.bumps}  # fmt: skip
    else:
        x, y = (float(v) for v in rng.uniform(-CONVERGENCE_PLACE_M, CONVERGENCE_PLACE_M, 2))
        yaw = float(rng.uniform(-math.pi, math.pi))
        if shadow:  # the sun behind the rover: its shadow falls ahead, where the mast looks
            s = site(spec.site_name)
            sun = sun_ll_truth(utc_to_t_s(utc), math.radians(s.lat_deg),
                               math.radians(s.lon_east_deg))  # fmt: skip
            yaw = math.atan2(float(sun[1]), float(sun[0])) + math.pi
    options = VoDriveOptions(
        step_max_m=ROCK_STEP_M if spec.kind == "rock" else cmd.VO_STEP_MAX_M, rover_shadow=shadow
    )
    make_vo = partial(RecordingVO, variant=spec.vo_variant)
    session = RoverSession(spec.site_name, spec.seed, utc, x_m=x, y_m=y, yaw_rad=yaw,
                           frame_every_s=3600.0, vo_options=options, vo_rig=spec.vo_rig,
                           visual_odometry=make_vo)  # fmt: skip
    slip_range = {"rock": ROCK_SLIP, "slope": SLOPE_SLIP}.get(spec.kind)
    if slip_range is not None:
        session.sim.slip.params = replace(session.sim.slip.params, slip_range=slip_range)
    session.nate.load_attitude(session.q_b_ll_true(), AttitudeQuality.FINE)
    if shadow:
        info["shadow_pixels_pct"] = shadow_pixels_pct(session.sim)
    return session, info


def shadow_pixels_pct(sim: RoverSim) -> float:
    """Percentage of the VO left image in the rover's own shadow now (noise-free renders
    with and without it)."""
    kwargs: dict[str, Any] = {"rig": VO_RIG, "noise": False}
    plain = sim.navcam_pair(VO_MAST_AZ_RAD, VO_MAST_EL_RAD, **kwargs).left
    shaded = sim.navcam_pair(VO_MAST_AZ_RAD, VO_MAST_EL_RAD, rover_shadow=True, **kwargs).left
    return 100.0 * float(np.mean(shaded < SHADOW_DARKER * plain))


def _true_motion(prev: PairRecord, cur: PairRecord) -> tuple[FloatArray, FloatArray]:
    R0 = prev.R_s_b_true
    return R0.T @ cur.R_s_b_true, R0.T @ (cur.p_s_true - prev.p_s_true)


def _motion_error(
    motion: tuple[FloatArray, FloatArray], truth: tuple[FloatArray, FloatArray]
) -> tuple[float, float]:
    """Position (m) and rotation (deg) differences of a step's motion from the truth."""
    angle = Rotation.from_matrix(motion[0] @ truth[0].T).magnitude()
    return float(np.linalg.norm(motion[1] - truth[1])), math.degrees(float(angle))


def _chain(pairs: list[PairRecord], which: str) -> FloatArray:
    """Displacement (Site, m) from the first pair to the last by the ``which`` motions
    (``vo``, ``baseline``, ``wheel``), each failed step replaced by wheel odometry's."""
    total = np.zeros(3)
    for cur in pairs[1:]:
        motion = {"vo": cur.vo_motion, "baseline": cur.baseline_motion}.get(which)
        total += cur.R_s_b0 @ (cur.p_pred_b0 if motion is None else motion[1])
    return total


# mobility fault protection's limits at their largest (estimation.protection.limits): no drive
# here reaches a slip check, and the reactive checks stop a drive only at the joints' stops
RELAXED_LIMITS = {
    "slip_check_m": SPECS["slip_check_m"].hi,
    "tilt_limit_rad": SPECS["tilt_limit_rad"].hi,
    "rocker_limit_rad": SPECS["rocker_limit_rad"].hi,
    "bogie_limit_rad": SPECS["bogie_limit_rad"].hi,
}


def drive_run(spec: DriveSpec) -> dict[str, Any]:
    """One benchmark drive (module docstring): errors, step outcomes and their accuracy."""
    rng = np.random.default_rng([spec.seed, spec.index, KINDS.index(spec.kind)])
    session, out = _session(spec, rng)
    recorder = session.vo
    assert isinstance(recorder, RecordingVO)
    p0_est = session.nate.p_s.copy()
    # VO is measured on the whole drive: mobility fault protection's slip check and VO-failure
    # halt (estimation.protection) would cut the slipping drives this bench exists for
    # (set in the rover's table directly: a SET_PARAM would take a control cycle and move
    # every figure off the ones measured before fault protection existed)
    for name, value in RELAXED_LIMITS.items():
        session.loop.protection.set_limit(name, value)
    report = session.execute(
        cmd.DriveStraight(distance_m=spec.length_m, vo=True, vo_fail="continue")
    )
    pairs = recorder.pairs
    steps = [(prev, cur) for prev, cur in pairwise(pairs) if cur.status is not VoStatus.INITIALISED]
    distance = float(report.details.get("distance_truth_m", math.nan))
    truth = pairs[-1].p_s_true - pairs[0].p_s_true
    whole = len(steps) == len(pairs) - 1  # one chain: no pair lost to a rendering error

    def err_pct(estimate: FloatArray) -> float:
        return 100.0 * float(np.linalg.norm(estimate - truth)) / distance

    vo_errors = [_motion_error(c.vo_motion, _true_motion(p, c)) for p, c in steps if c.vo_motion]
    base_errors = [
        _motion_error(c.baseline_motion, _true_motion(p, c)) for p, c in steps if c.baseline_motion
    ]
    out.update(
        kind=spec.kind, site=spec.site_name, seed=spec.seed, status=report.status,
        vo_variant=spec.vo_variant,
        distance_m=distance, length_m=spec.length_m,
        err_pct=err_pct(session.nate.p_s - p0_est),
        wheel_err_pct=err_pct(_chain(pairs, "wheel")) if whole else math.nan,
        baseline_err_pct=err_pct(_chain(pairs, "baseline")) if whole else math.nan,
        # SAPP's position against the chain of VO's own steps: the bookkeeping agrees
        vo_chain_gap_m=float(np.linalg.norm(_chain(pairs, "vo") - (session.nate.p_s - p0_est)))
        if whole else math.nan,
        steps=len(steps), vo_converged=len(vo_errors), baseline_converged=len(base_errors),
        vo_step_errors=vo_errors, baseline_step_errors=base_errors,
        vo_step_walls_s=[(c.vo_s, c.vo_motion is not None) for _, c in steps],
        failures=dict(Counter(c.status.value for _, c in steps if not c.vo_motion)),
        step_slip_max=max((1.0 - float(np.linalg.norm(c.p_s_true - p.p_s_true))
                           / float(np.linalg.norm(c.p_pred_b0)) for p, c in steps), default=0.0),
    )  # fmt: skip
    return out


def timing_run(width_px: int, seed: int, repeats: int) -> dict[str, Any]:
    """Median wall times (s) of one VO step and one baseline step on a Gusev pair after a
    0.5 m drive, and both steps' motion errors (cm, deg), at ``width_px``."""
    rng = np.random.default_rng([seed, width_px])
    utc = _sun_time(rng, "gusev", SUN_ELEVATION_DEG)
    sim = RoverSim("gusev", seed, utc, yaw_rad=float(rng.uniform(-math.pi, math.pi)))
    rig = NAVCAM.at_resolution(width_px)
    pair0, state0 = sim.navcam_pair(VO_MAST_AZ_RAD, VO_MAST_EL_RAD, rig=rig), sim.drive_state
    sim.drive_straight(TIMING_STEP_M)
    pair1, state1 = sim.navcam_pair(VO_MAST_AZ_RAD, VO_MAST_EL_RAD, rig=rig), sim.drive_state
    R_s_b0 = Rotation.from_quat(state0.q_s_b).as_matrix()
    predicted: dict[str, Any] = {
        "R_b0_b1_predicted": np.eye(3), "p_b1_b0_predicted": np.array([TIMING_STEP_M, 0.0, 0.0]),
        "R_s_b0": R_s_b0, "mast_az_rad": VO_MAST_AZ_RAD, "mast_el_rad": VO_MAST_EL_RAD,
    }  # fmt: skip
    truth = (
        R_s_b0.T @ Rotation.from_quat(state1.q_s_b).as_matrix(),
        R_s_b0.T @ (state1.p_s - state0.p_s),
    )
    vo, baseline = VisualOdometry(rig), OrbPnpBaseline(rig)
    vo_walls, base_walls = [], []
    for k in range(repeats + 1):  # the first repeat warms caches up and is not counted
        vo.reset()
        vo.step(pair0.left, pair0.right, **predicted)
        start = time.perf_counter()
        result = vo.step(pair1.left, pair1.right, **predicted)
        vo_walls += [time.perf_counter() - start] if k else []
        baseline.reset()
        baseline.step(pair0.left, pair0.right, VO_MAST_AZ_RAD, VO_MAST_EL_RAD)
        start = time.perf_counter()
        base = baseline.step(pair1.left, pair1.right, VO_MAST_AZ_RAD, VO_MAST_EL_RAD)
        base_walls += [time.perf_counter() - start] if k else []
    vo_motion = None if result.motion is None else (result.motion.R_b0_b1, result.motion.p_b1_b0)
    nan = (math.nan, math.nan)
    vo_err = _motion_error(vo_motion, truth) if vo_motion else nan
    base_err = _motion_error(base.motion, truth) if base.motion else nan
    return {
        "width_px": width_px, "vo_walls_s": vo_walls, "baseline_walls_s": base_walls,
        "vo_converged": vo_motion is not None, "vo_reason": result.reason,
        "vo_err_cm": 100.0 * vo_err[0], "vo_err_deg": vo_err[1],
        "baseline_err_cm": 100.0 * base_err[0], "baseline_err_deg": base_err[1],
    }  # fmt: skip


def _rms(values: list[float]) -> float:
    v = np.asarray([x for x in values if math.isfinite(x)], dtype=float)
    return float(np.sqrt(np.mean(v**2))) if v.size else math.nan


def _max(values: list[float]) -> float:
    v = [x for x in values if math.isfinite(x)]
    return max(v) if v else math.nan


def _false(errors: list[tuple[float, float]]) -> int:
    return sum(1 for m, d in errors if m > FALSE_UPDATE_M or d > FALSE_UPDATE_DEG)


def _pct(part: int, whole: int) -> float:
    return 100.0 * part / whole if whole else math.nan


def _accuracy_metrics(runs: list[dict[str, Any]], name: str) -> dict[str, Any]:
    """RMS and worst errors of a course's runs: VO, wheel odometry and the baseline."""
    return {
        f"{name}_err_pct": _rms([r["err_pct"] for r in runs]),
        f"{name}_err_max_pct": _max([r["err_pct"] for r in runs]),
        f"{name}_wheel_err_pct": _rms([r["wheel_err_pct"] for r in runs]),
        f"baseline_{name}_err_pct": _rms([r["baseline_err_pct"] for r in runs]),
        f"baseline_{name}_err_max_pct": _max([r["baseline_err_pct"] for r in runs]),
        f"{name}_runs": len(runs),
        f"{name}_distance_mean_m": float(np.mean([r["distance_m"] for r in runs])),
        f"{name}_step_slip_max_pct": 100.0 * max(r["step_slip_max"] for r in runs),
        f"{name}_vo_converged_pct": _pct(
            sum(r["vo_converged"] for r in runs), sum(r["steps"] for r in runs)
        ),
    }


def _step_metrics(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Convergence per site, false updates (all drives and the shadow drives), step errors."""
    out: dict[str, Any] = {}
    conv = [r for r in runs if r["kind"] == "convergence"]
    for site_name in sorted({r["site"] for r in conv}):
        mine = [r for r in conv if r["site"] == site_name]
        steps = sum(r["steps"] for r in mine)
        out[f"convergence_pct_{site_name}"] = _pct(sum(r["vo_converged"] for r in mine), steps)
        out[f"baseline_convergence_pct_{site_name}"] = _pct(
            sum(r["baseline_converged"] for r in mine), steps
        )
        out[f"convergence_steps_{site_name}"] = steps
        failures: Counter[str] = Counter()
        for r in mine:
            failures.update(r["failures"])
        out[f"convergence_failures_{site_name}"] = dict(failures)
    shadow = [r for r in runs if r["kind"] == "shadow"]
    vo_steps = [e for r in runs for e in r["vo_step_errors"]]
    base_steps = [e for r in runs for e in r["baseline_step_errors"]]
    out.update(
        false_update_count=_false(vo_steps),
        false_update_count_shadow=_false([e for r in shadow for e in r["vo_step_errors"]]),
        baseline_false_update_count=_false(base_steps),
        baseline_false_update_count_shadow=_false(
            [e for r in shadow for e in r["baseline_step_errors"]]
        ),
        accepted_steps=len(vo_steps),
        baseline_accepted_steps=len(base_steps),
        step_err_rms_cm=100.0 * _rms([m for m, _ in vo_steps]),
        step_err_max_cm=100.0 * _max([m for m, _ in vo_steps]),
        step_err_max_deg=_max([d for _, d in vo_steps]),
        baseline_step_err_rms_cm=100.0 * _rms([m for m, _ in base_steps]),
        shadow_runs=len(shadow),
        shadow_steps=sum(r["steps"] for r in shadow),
        shadow_convergence_pct=_pct(
            sum(r["vo_converged"] for r in shadow), sum(r["steps"] for r in shadow)
        ),
        shadow_pixels_pct_median=float(np.median([r["shadow_pixels_pct"] for r in shadow]))
        if shadow
        else math.nan,
        vo_chain_gap_max_m=_max([r["vo_chain_gap_m"] for r in runs]),
        drives_not_completed=sum(1 for r in runs if r["status"] != "completed"),
    )
    return out


def _timing_metrics(timings: list[dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for width in sorted({t["width_px"] for t in timings}):
        mine = [t for t in timings if t["width_px"] == width]
        out[f"vo_step_s_{width}"] = statistics.median(w for t in mine for w in t["vo_walls_s"])
        out[f"baseline_step_s_{width}"] = statistics.median(
            w for t in mine for w in t["baseline_walls_s"]
        )
        # a step that fails early (too few features tracked) is quicker: count them
        out[f"vo_step_converged_{width}"] = sum(1 for t in mine if t["vo_converged"])
        out[f"vo_step_timed_{width}"] = len(mine)
        converged = [w for t in mine if t["vo_converged"] for w in t["vo_walls_s"]]
        out[f"vo_step_converged_s_{width}"] = (
            statistics.median(converged) if converged else math.nan
        )
        out[f"vo_step_err_max_cm_{width}"] = _max([t["vo_err_cm"] for t in mine])
        out[f"baseline_step_err_max_cm_{width}"] = _max([t["baseline_err_cm"] for t in mine])
    return out


def _map(specs: list[DriveSpec], workers: int) -> list[dict[str, Any]]:
    if workers <= 1:
        return [drive_run(s) for s in specs]
    # spawn, not fork: the timing renders started numba's OpenMP threads in this process
    with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as pool:
        return list(pool.map(drive_run, specs))


def _separation_metrics(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """False updates on the Gusev convergence drives and the rock course (the same drives)
    for each ``VO_VARIANTS`` entry: sec. 4.3's small feature separation and the default, with
    MER's single tracking pass and with ours."""
    out: dict[str, Any] = {"min_separation_small_px": MIN_SEPARATION_SMALL_PX}
    names = {"separation_small_mer": "small", "separation_default_mer": "default",
             "separation_small": "small_multipass", "default": "default_multipass"}  # fmt: skip
    for variant, name in names.items():
        mine = [r for r in runs if r["vo_variant"] == variant and (r["kind"] == "rock" or (
            r["kind"] == "convergence" and r["site"] == "gusev"))]  # fmt: skip
        out[f"false_update_count_min_separation_{name}"] = _false(
            [e for r in mine for e in r["vo_step_errors"]]
        )
        for kind in ("convergence", "rock"):
            out[f"false_update_count_min_separation_{name}_{kind}"] = _false(
                [e for r in mine if r["kind"] == kind for e in r["vo_step_errors"]]
            )
        out[f"min_separation_{name}_accepted_steps"] = sum(r["vo_converged"] for r in mine)
        out[f"min_separation_{name}_steps"] = sum(r["steps"] for r in mine)
    return out


def bench_courses(
    n_rock: int = 24,
    n_slope: int = 16,
    n_convergence: int = 100,
    n_shadow: int = 12,
    timing_poses: int = 5,
    timing_repeats: int = 5,
    slope_course_m: float = SLOPE_COURSE_M,
    seed: int = 0,
    workers: int | None = None,
) -> dict[str, Any]:
    """Run the VO benchmark (module docstring); smaller counts make a quick version
    (``n_convergence`` drives per site; ``timing_poses`` x ``timing_repeats`` timed steps
    per resolution)."""
    counts = (("n_rock", n_rock), ("n_slope", n_slope), ("n_convergence", n_convergence),
              ("n_shadow", n_shadow), ("timing_poses", timing_poses),
              ("timing_repeats", timing_repeats))  # fmt: skip
    for name, value in counts:
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise InputError(name, f"must be a positive integer, got {value!r}")
    if not (math.isfinite(slope_course_m) and 1.0 <= slope_course_m <= cmd.MAX_DRIVE_M):
        raise InputError("slope_course_m", f"must be in [1, {cmd.MAX_DRIVE_M:g}] m")
    n_workers = workers if workers is not None else (os.cpu_count() or 1)

    timings = [timing_run(w, seed + k, timing_repeats) for w in (1024, 256)
               for k in range(timing_poses)]  # fmt: skip
    specs = (  # the longest drives first, for the pool's balance
        [DriveSpec("slope", "gusev", seed + k, k, slope_course_m) for k in range(n_slope)]
        + [DriveSpec("rock", "gusev", seed + k, k, ROCK_COURSE_M) for k in range(n_rock)]
        + [DriveSpec("convergence", s, seed + k, k, CONVERGENCE_DRIVE_M)
           for s in ("gusev", "meridiani") for k in range(n_convergence)]
        + [DriveSpec("shadow", "gusev", seed + k, k, CONVERGENCE_DRIVE_M) for k in range(n_shadow)]
    )  # fmt: skip
    # sec. 4.3's sols 137/141 setting, on the same Gusev convergence drives and rock course
    again = [
        s for s in specs if s.kind == "rock" or (s.kind, s.site_name) == ("convergence", "gusev")
    ]
    separation = [replace(s, vo_variant=v) for v in VO_VARIANTS if v != "default" for s in again]
    everything = _map(specs + separation, n_workers)
    runs = everything[: len(specs)]
    rock = [r for r in runs if r["kind"] == "rock"]
    slope = [r for r in runs if r["kind"] == "slope"]
    metrics: dict[str, Any] = {
        **_accuracy_metrics(rock, "rock_course"),
        "rock_course_rock_max_m": max(r["rock_max_m"] for r in rock),
        "rock_course_rock_max_min_m": min(r["rock_max_m"] for r in rock),
        **_accuracy_metrics(slope, "slope_drive"),
        "slope_drive_slope_mean_deg": float(np.mean([r["slope_deg"] for r in slope])),
        **_step_metrics(runs),
        **_separation_metrics(everything),
        **_timing_metrics(timings),
    }
    targets: dict[str, dict[str, float]] = {
        "rock_course_err_pct": {"le": 0.4},
        "rock_course_runs": {"ge": 16},
        "slope_drive_err_pct": {"le": 0.4},
        "slope_drive_runs": {"ge": 16},
        "convergence_pct_gusev": {"ge": 97.0},
        "convergence_pct_meridiani": {"ge": 80.0},
        "false_update_count": {"le": 0.0},
        "false_update_count_min_separation_small": {"ge": 1.0},
        "false_update_count_min_separation_default": {"le": 0.0},
        "false_update_count_shadow": {"le": 0.0},
        "vo_step_s_1024": {"le": 0.3},
        "vo_step_s_256": {"le": 0.05},
    }
    return bench_result("vo", metrics, targets)
