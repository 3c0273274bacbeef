"""``convergence_pct_meridiani_advised``: Meridiani's convergence drives pointed as the ground's
advisor recommends (Cheng, Maimone and Matthies 2005, sec. 4.1 and 5: on Meridiani's fine
sand Opportunity's drivers pointed the Navcams at texture).

The drives are ``bench.vo.courses``' Meridiani convergence drives, the same ones (the same
place, heading, time and seeds: ``courses._session`` with the same generator): 3 m in MER's
0.75 m steps, ``vo=on``. Before each, the ground advises its pointing
(``server.terrain.advisor``) from what it has:

- its map (``ground_map``): the orbital product (``sim.world.orbital_map``: the DEM at 1 m
  posts, tied to the mission frame at the rover's start), and the texture the rover's first
  pair shows: a Navcam pair taken where the rover stands with MER's pointing (ahead, 35 deg
  down), its stereo features (the flight detector's, ``estimation.vo``) placed on the map
  through their pixels' rays, counted per 1 m cell of the ground the image covers;
- the rover's reported pose (SAPP's estimate), the Sun from the onboard ephemeris (IVP) at
  the rover's clock.

The drive then runs with ``vo_az_deg``/``vo_el_deg`` set to the recommendation (MER's
pointing if the advisor recommends none). Steps are scored as ``courses`` scores them: the
fraction converged, and a converged step is false when its motion differs from the true
motion between its two pairs by more than 5 cm or 1 deg.
"""

from __future__ import annotations

import math
import os
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from itertools import pairwise
from multiprocessing import get_context
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from bench.vo.courses import (
    KINDS,
    RELAXED_LIMITS,
    DriveSpec,
    RecordingVO,
    _false,
    _motion_error,
    _session,
    _true_motion,
)
from estimation.ivp import sun_ll
from estimation.vo.odometry import VisualOdometry, VoStatus
from sequences import commands as cmd
from server.terrain.advisor import (
    BODY_HEIGHT_M,
    AdviceParams,
    PlannedDrive,
    advise,
    footprint_area_m2,
    ground_of_pixels,
)
from server.terrain.ground_map import GroundMap
from sim.errors import InputError
from sim.loop.rover_sim import RoverSim
from sim.loop.session import RoverSession
from sim.loop.vo_drive import VO_MAST_AZ_RAD, VO_MAST_EL_RAD, VO_RIG
from sim.world.orbital_map import orbital_product

SITE = "meridiani"
DRIVE_M = 3.0  # courses.CONVERGENCE_DRIVE_M
MAP_HALF_M = 15.0
MAP_CELL_M = 1.0  # the orbital DEM's posts; texture counted per cell
FIRST_PAIR_SEED = 7025  # the first pair's noise: its own stream, the drive's images unchanged


def ground_map(session: RoverSession, seed: int, site_name: str = SITE) -> GroundMap:
    """The ground's map of a drive's start (module docstring), mission frame: the orbital
    product of ``site_name`` (terrain ``seed``) and the texture of a first pair."""
    sim: RoverSim = session.sim
    start_s = session.mission_origin_world  # where the ground tied the DEM: the start
    product = orbital_product(
        site_name, seed, float(start_s[0]), float(start_s[1]), MAP_HALF_M + 3.0
    )
    n = int(2 * MAP_HALF_M / MAP_CELL_M) + 1
    p_m = session.nate.p_s.copy()
    north = p_m[0] - MAP_HALF_M + MAP_CELL_M * np.arange(n)
    east = p_m[1] - MAP_HALF_M + MAP_CELL_M * np.arange(n)
    nn, ee = np.meshgrid(north, east, indexing="ij")
    dem = product.height_at(nn + start_s[0], ee + start_s[1])
    datum = float(product.height_at(np.array([start_s[0]]), np.array([start_s[1]]))[0])
    height = dem - datum - BODY_HEIGHT_M  # the body origin is at mission z = 0 at the start
    sigma = np.full((n, n), product.sigma_m)
    bare = GroundMap(float(north[0]), float(east[0]), MAP_CELL_M, height, sigma,
                     np.full((n, n), np.nan), np.full((n, n), np.nan),
                     np.zeros((n, n), dtype=bool))  # fmt: skip
    # the first pair: its stereo features, placed on the map, per cell of the imaged ground
    pair = sim.navcam_pair(VO_MAST_AZ_RAD, VO_MAST_EL_RAD, rig=VO_RIG,
                           rng=np.random.default_rng([seed, FIRST_PAIR_SEED]))  # fmt: skip
    vo = VisualOdometry(VO_RIG)
    first = vo.step(pair.left, pair.right, R_b0_b1_predicted=np.eye(3),
                    p_b1_b0_predicted=np.zeros(3), R_s_b0=np.eye(3),
                    mast_az_rad=VO_MAST_AZ_RAD, mast_el_rad=VO_MAST_EL_RAD)  # fmt: skip
    R_m_b = Rotation.from_quat(session.nate.q_b_ll).inv().as_matrix()
    cam = VO_RIG.camera
    grid = (np.arange(32) + 0.5) * cam.width_px / 32 - 0.5
    uu, vv = np.meshgrid(grid, grid)
    lattice = np.column_stack([uu.ravel(), vv.ravel()])
    _, seen = ground_of_pixels(bare, p_m, R_m_b, VO_MAST_AZ_RAD, VO_MAST_EL_RAD, lattice)
    _, found = ground_of_pixels(bare, p_m, R_m_b, VO_MAST_AZ_RAD, VO_MAST_EL_RAD,
                                first.features.features_uv_px)  # fmt: skip
    # the pair's density: its stereo features over the ground its image covers (the
    # lattice's rays within range stand for equal parts of the image; their ground areas
    # follow from the rays' ranges and grazing angles, as the advisor computes them)
    area_m2 = footprint_area_m2(bare, p_m, R_m_b, VO_MAST_AZ_RAD, VO_MAST_EL_RAD)
    i, j = bare.cell_of(seen[:, 0], seen[:, 1])
    ii, jj = np.rint(i).astype(int), np.rint(j).astype(int)
    inside = (ii >= 0) & (ii < n) & (jj >= 0) & (jj < n)
    imaged = np.zeros((n, n), dtype=bool)
    imaged[ii[inside], jj[inside]] = True
    density = len(found) / max(area_m2, 1e-6)
    texture = np.where(imaged, density, np.nan)
    return GroundMap(bare.north0_m, bare.east0_m, MAP_CELL_M, height, sigma,
                     np.full((n, n), np.nan), texture, imaged)  # fmt: skip


def advised_run(spec: DriveSpec, params: AdviceParams | None = None) -> dict[str, Any]:
    """One of ``courses``' convergence drives, pointed as the advisor recommends."""
    rng = np.random.default_rng([spec.seed, spec.index, KINDS.index(spec.kind)])
    session, _ = _session(spec, rng)
    recorder = session.vo
    assert isinstance(recorder, RecordingVO)
    for name, value in RELAXED_LIMITS.items():
        session.loop.protection.set_limit(name, value)
    gmap = ground_map(session, spec.seed)
    sim = session.sim
    sun = sun_ll(sim.t_s, sim.lat_rad, sim.lon_east_rad)
    drive = PlannedDrive("straight", distance_m=spec.length_m)
    advice = advise(gmap, session.nate.p_s, session.nate.q_b_ll, drive, sun / np.linalg.norm(sun),
                    params)  # fmt: skip
    best = advice.recommended
    az, el = (best.az_deg, best.el_deg) if best else (0.0, math.degrees(VO_MAST_EL_RAD))
    session.execute(cmd.DriveStraight(distance_m=spec.length_m, vo=True, vo_fail="continue",
                                      vo_az_deg=az, vo_el_deg=el))  # fmt: skip
    pairs = recorder.pairs
    steps = [(p, c) for p, c in pairwise(pairs) if c.status is not VoStatus.INITIALISED]
    errors = [_motion_error(c.vo_motion, _true_motion(p, c)) for p, c in steps if c.vo_motion]
    return {
        "seed": spec.seed, "az_deg": az, "el_deg": el, "advised": best is not None,
        "steps": len(steps), "converged": len(errors), "step_errors": errors,
        "failures": dict(Counter(c.status.value for _, c in steps if not c.vo_motion)),
        "features_min": best.features_min if best else 0.0,
    }  # fmt: skip


def _map(specs: list[DriveSpec], workers: int) -> list[dict[str, Any]]:
    if workers <= 1:
        return [advised_run(s) for s in specs]
    with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as pool:
        return list(pool.map(advised_run, specs))


def meridiani_advised(
    n_drives: int = 100, seed: int = 0, workers: int | None = None
) -> dict[str, Any]:
    """``convergence_pct_meridiani_advised`` over ``n_drives`` of ``courses``' Meridiani
    convergence drives (100: its 400 steps; a few for a quick check), with what explains it:
    the steps, the false updates among the converged, the failures and the pointings."""
    if isinstance(n_drives, bool) or not isinstance(n_drives, int) or n_drives < 1:
        raise InputError("n_drives", f"must be a positive integer, got {n_drives!r}")
    specs = [DriveSpec("convergence", SITE, seed + k, k, DRIVE_M) for k in range(n_drives)]
    runs = _map(specs, workers if workers is not None else (os.cpu_count() or 1))
    steps = sum(r["steps"] for r in runs)
    failures: Counter[str] = Counter()
    for r in runs:
        failures.update(r["failures"])
    errors = [e for r in runs for e in r["step_errors"]]
    return {
        "convergence_pct_meridiani_advised": 100.0 * sum(r["converged"] for r in runs) / steps,
        "convergence_steps_meridiani_advised": steps,
        "false_update_count_meridiani_advised": _false(errors),
        "convergence_failures_meridiani_advised": dict(failures),
        "advised_pointings_deg": dict(Counter(f"{r['az_deg']:g}/{r['el_deg']:g}" for r in runs)),
        "advised_drives_without_advice": sum(1 for r in runs if not r["advised"]),
    }
