"""The ground's terrain map scored against the truth: ``ground_map_height_err_m_p95`` and
``ground_map_sigma_coverage_pct`` (issue 24's deliverable 3).

Drives: short ``vo=on`` drives (MER's 0.75 m steps, one step per command) at seeded places
near the origin of ``gusev`` and ``meridiani``, the sun 30-65° up. Every Navcam pair the VO
took at a stop is what comes down: its two images converted to 8 bits (the 12-bit DN scaled
by 255/4095 and rounded), the commanded mast pointing, and the pose SAPP estimated at that
stop (``p_mission`` from NATE's Site position, ``q_b_ll``) with the onboard position 1σ
(``estimation.protection.position_sigma``): what the ground has, never the truth. They go
to a ``server.terrain.service.GroundMapService`` started from the orbital product around the
rover's start (``sim.world.orbital_map``).

Scoring (the bench may read the truth): the truth terrain's elevation at each cell's centre,
in the mission frame (``session.mission_origin_world``), against the map's height.

- Cells scored: those the stereo measured (``GroundMap.imaged``) from a camera within
  ``SCORE_RANGE_M`` = 5 m horizontally of the cell's centre (``GroundMapService.nearest_m``):
  "cells within 5 m of imaged stereo" read as cells the rover measured by stereo at 5 m
  range or nearer.
- ``ground_map_height_err_m_p95``: the 95th percentile of ``|map - truth|`` over those cells
  (all drives pooled).
- ``ground_map_sigma_coverage_pct``: the percentage of those cells with ``|map - truth| <= 2σ``,
  σ the map's reported ``sigma_m`` (2σ: 95.4 % for a Gaussian error of that σ).
- ``ground_map_cells_scored``, ``ground_map_imaged_cells`` (all stereo cells, any range),
  ``ground_map_pairs``, ``ground_map_drives``; per site the p95, the coverage, the median
  error (a bias) and the median σ.
- ``ground_map_disparity_z68``: on one extra pair per drive, rendered where the rover starts,
  the 68th percentile of the refined disparity's error (against the rendered depth) over its
  σ (``server.terrain.stereo.disparity_sigma_px``): 1 if that σ is right.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.protection.limits import SPECS
from estimation.sapp.aqf import AttitudeQuality
from estimation.vo.odometry import VisualOdometry, VoResult
from estimation.vo.params import VoParams
from estimation.vo.stereo_rig import StereoRig
from sequences import commands as cmd
from server.terrain.service import DownlinkedPair, GroundMapService
from server.terrain.stereo import (
    disparity_px,
    disparity_sigma_px,
    refine_disparity,
    window_px_for,
)
from sim.loop.rover_sim import RoverSim
from sim.loop.session import RoverSession
from sim.loop.vo_drive import VO_MAST_AZ_RAD, VO_MAST_EL_RAD, VO_RIG
from sim.world.mars_frames import elevation_rad, sun_ll_truth
from sim.world.marsclock import utc_to_t_s
from sim.world.sites import site

FloatArray = NDArray[np.float64]

SCORE_RANGE_M = 5.0
SITES = ("gusev", "meridiani")
STEP_M = 0.75  # MER's VO step (sequences.commands.VO_STEP_MAX_M)
PLACE_M = 30.0
SUN_ELEVATION_DEG = (30.0, 65.0)
EPOCH = datetime(2004, 1, 10, tzinfo=UTC)
DN_MAX = 4095.0
MAP_HALF_M = 40.0
RELAXED_LIMITS = {
    "slip_check_m": SPECS["slip_check_m"].hi,
    "tilt_limit_rad": SPECS["tilt_limit_rad"].hi,
    "rocker_limit_rad": SPECS["rocker_limit_rad"].hi,
    "bogie_limit_rad": SPECS["bogie_limit_rad"].hi,
}


def to_u8(dn: ArrayLike) -> NDArray[np.uint8]:
    """A 12-bit DN image as the 8-bit image that comes down (scaled by 255/4095, rounded)."""
    return np.clip(np.rint(np.asarray(dn, dtype=np.float64) * (255.0 / DN_MAX)), 0, 255).astype(
        np.uint8
    )


Kept = tuple[NDArray[np.uint8], NDArray[np.uint8], float, float]


class KeepingVO(VisualOdometry):
    """The flight VO on ``VO_RIG``, keeping the last pair it was given (a bench wrapper)."""

    def __init__(self, sim: RoverSim, rig: StereoRig = VO_RIG) -> None:
        super().__init__(rig, VoParams().for_width(rig.camera.width_px))
        self.first: Kept | None = None
        self.last: Kept | None = None

    def step(self, left: ArrayLike, right: ArrayLike, **kwargs: Any) -> VoResult:
        self.last = (to_u8(left), to_u8(right), kwargs["mast_az_rad"], kwargs["mast_el_rad"])
        if self.first is None:
            self.first = self.last
        return super().step(left, right, **kwargs)


@dataclass(frozen=True)
class DriveScore:
    """One drive's cells: the errors (m) and reported σ (m) of the scored cells; and the
    disparity errors of a pair at its start over their σ (``disparity_z``)."""

    site_name: str
    errors_m: FloatArray
    sigma_m: FloatArray
    pairs: int
    imaged_cells: int
    disparity_z: FloatArray


def disparity_z(session: RoverSession) -> FloatArray:
    """|refined disparity - the rendered depth's| / its σ (``server.terrain.stereo``), over
    the pixels kept, for a VO pair taken where the rover stands."""
    pair = session.sim.navcam_pair(VO_MAST_AZ_RAD, VO_MAST_EL_RAD, rig=VO_RIG)
    left, right = to_u8(pair.left), to_u8(pair.right)
    window = window_px_for(VO_RIG.camera.width_px)
    d = refine_disparity(left, right, disparity_px(left, right, VO_RIG), window)
    truth = VO_RIG.camera.f_px * VO_RIG.baseline_m / pair.depth_left_m.astype(np.float64)
    ok = np.isfinite(d) & np.isfinite(truth)
    out: FloatArray = np.abs(d[ok] - truth[ok]) / disparity_sigma_px(left, window)[ok]
    return out


def _sun_time(rng: np.random.Generator, site_name: str) -> datetime:
    s = site(site_name)
    lat, lon = math.radians(s.lat_deg), math.radians(s.lon_east_deg)
    while True:
        utc = EPOCH + timedelta(days=float(rng.uniform(0.0, 700.0)))
        elev = math.degrees(float(elevation_rad(sun_ll_truth(utc_to_t_s(utc), lat, lon))))
        if SUN_ELEVATION_DEG[0] <= elev <= SUN_ELEVATION_DEG[1]:
            return utc


Pose = tuple[FloatArray, FloatArray, float]


def _pose(session: RoverSession) -> Pose:
    """What the rover reports of its pose now: ``p_mission``, ``q_b_ll`` and the onboard
    position 1σ (the ground's; no truth)."""
    nate = session.nate
    p_mission = nate.sites.to_mission(nate.p_s, nate.sites.current.index)
    sigma = float(session.loop.protection.uncertainty.sigma_m)
    return np.asarray(p_mission, dtype=np.float64), nate.q_b_ll.copy(), sigma


def _downlinked(kept: Kept | None, pose: Pose) -> DownlinkedPair:
    """A kept VO pair with the pose the rover reported where it took it."""
    assert kept is not None
    left, right, az, el = kept
    p_mission, q_b_ll, sigma = pose
    return DownlinkedPair(left, right, left.shape[1], az, el, p_mission, q_b_ll, sigma)


def drive_score(site_name: str, seed: int, steps: int) -> DriveScore:
    """Drive ``steps`` VO steps at a seeded place of ``site_name``, fuse every pair into a
    ground map, score its cells (module docstring)."""
    rng = np.random.default_rng([seed, SITES.index(site_name), 24])
    utc = _sun_time(rng, site_name)
    x, y = (float(v) for v in rng.uniform(-PLACE_M, PLACE_M, 2))
    yaw = float(rng.uniform(-math.pi, math.pi))
    session = RoverSession(site_name, seed, utc, x_m=x, y_m=y, yaw_rad=yaw,
                           frame_every_s=3600.0, visual_odometry=KeepingVO)  # fmt: skip
    session.nate.load_attitude(session.q_b_ll_true(), AttitudeQuality.FINE)
    z = disparity_z(session)
    for name, value in RELAXED_LIMITS.items():
        session.loop.protection.set_limit(name, value)
    vo = session.vo
    assert isinstance(vo, KeepingVO)
    # the ground's map: the orbital product around where the mission localised the landing
    start_n, start_e = session.sim.start_xy_m
    service = GroundMapService(site_name, seed, start_n, start_e, half_m=MAP_HALF_M)
    start_pose = _pose(session)  # where the pair before the first step is taken
    for k in range(steps):
        session.execute(cmd.DriveStraight(distance_m=STEP_M, vo=True, vo_fail="continue"))
        if k == 0:
            service.add(_downlinked(vo.first, start_pose))
        service.add(_downlinked(vo.last, _pose(session)))
    pairs = steps + 1
    ground = service.ground_map()
    score = service.nearest_m <= SCORE_RANGE_M
    score &= ground.imaged
    i, j = np.nonzero(score)
    north = ground.north0_m + i * ground.cell_m
    east = ground.east0_m + j * ground.cell_m
    o = session.mission_origin_world
    truth = np.asarray(session.sim.terrain.height_m(north + o[0], east + o[1])) + o[2]
    return DriveScore(site_name, ground.height_m[i, j] - truth, ground.sigma_m[i, j], pairs,
                      int(np.count_nonzero(ground.imaged)), z)  # fmt: skip


def ground_map_metrics(drives_per_site: int = 2, steps: int = 4, seed0: int = 0) -> dict[str, Any]:
    """The bench's figures (module docstring) over ``drives_per_site`` drives of ``steps``
    steps on each of ``SITES``, terrain seeds ``seed0``, ``seed0 + 1``, ..."""
    scores = [drive_score(name, seed0 + d, steps) for name in SITES for d in range(drives_per_site)]
    err = np.concatenate([s.errors_m for s in scores])
    sig = np.concatenate([s.sigma_m for s in scores])
    out: dict[str, Any] = {
        "ground_map_height_err_m_p95": float(np.percentile(np.abs(err), 95))
        if err.size
        else math.nan,
        "ground_map_sigma_coverage_pct": 100.0 * float(np.mean(np.abs(err) <= 2.0 * sig))
        if err.size
        else math.nan,
        "ground_map_cells_scored": int(err.size),
        "ground_map_pairs": int(sum(s.pairs for s in scores)),
        "ground_map_drives": len(scores),
        "ground_map_disparity_z68": float(
            np.percentile(np.concatenate([s.disparity_z for s in scores]), 68)
        ),
        "ground_map_imaged_cells": int(sum(s.imaged_cells for s in scores)),
    }
    for name in SITES:
        e = np.concatenate([s.errors_m for s in scores if s.site_name == name])
        g = np.concatenate([s.sigma_m for s in scores if s.site_name == name])
        out[f"ground_map_height_err_m_p95_{name}"] = float(np.percentile(np.abs(e), 95))
        out[f"ground_map_sigma_coverage_pct_{name}"] = 100.0 * float(np.mean(np.abs(e) <= 2 * g))
        out[f"ground_map_height_err_m_median_{name}"] = float(np.median(e))
        out[f"ground_map_sigma_m_median_{name}"] = float(np.median(g))
    return out
