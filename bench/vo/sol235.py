"""Sol 235 (Cheng, Maimone and Matthies 2005, sec. 4.3), reproduced and prevented.

"During that sol the NAVCAMs were pointed at two small and widely separated rocks.
Although features were found on those rocks, many more features were found on the largest
shape in the image: the rover's shadow. So even though forward drive progress was made, the
onboard estimator assumed that the shadow (having more distinct features spread throughout
the image) better reflected actual motion, and therefore produced an incorrect estimate."

The scene (``sim.scenarios.scene_builder``), at Meridiani: level, nearly featureless fine
sand (``FAINT_SAND``: a faint mottling, no grains) and two small rocks (``ROCKS``: 12 cm,
1.6 m apart) where the Navcams look (ahead, 35 deg down); the Sun low
(``SUN_ELEVATION_DEG``) behind the rover, so that its shadow -- deck, mast and its head,
antennas, the suspension's links and the wheels (``sim.rover.geometry``'s shape table) --
lies across the view, drawn in the pairs. Each drive is a ``RoverSession`` ``vo=on`` drive
of ``DRIVE_M`` in ``STEP_M`` steps,
the attitude loaded Fine from the truth as in ``bench.vo.courses``, mobility fault
protection relaxed as there. A converged step is false when its motion differs from the true
motion between its two pairs by more than 5 cm or 1 deg (``courses``' scoring).

Prevention (``false_update_count_sol235``): the flight software's shadow mask
(``estimation.vo.shadow_mask``): before tracking, VO drops the features whose points lie in
the rover's shadow or within 10 cm of its edge, from the Sun's direction the flight software
knows (SAPP's attitude and IVP) and the flight copy of the rover's shape. Argued in
docs/BENCHMARKS.md: the mask needs no terrain model (each feature's own stereo point is
tested), costs nothing when the shadow is out of view, and cannot add a false feature; the
advisor's pointing prevents it too where the ground has a choice of view (it keeps the
shadow out of the image), but a driver may have to look at the shadow's side, and the mask
holds there as well (``false_update_count_sol235_advised`` is the advisor alone).
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from itertools import pairwise
from multiprocessing import get_context
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from bench.vo.courses import FALSE_UPDATE_DEG, FALSE_UPDATE_M, RELAXED_LIMITS
from estimation.ivp import sun_ll
from estimation.sapp.aqf import AttitudeQuality
from estimation.vo.odometry import VisualOdometry, VoResult, VoStatus
from sequences import commands as cmd
from sim.errors import InputError
from sim.loop.rover_sim import RoverSim
from sim.loop.session import RoverSession
from sim.loop.vo_drive import VO_RIG, VoDriveOptions
from sim.scenarios.scene_builder import TEXTURED, AlbedoPatch, RockSpec, build_scene, install_scene
from sim.world.albedo import AlbedoStyle
from sim.world.mars_frames import elevation_rad, sun_ll_truth
from sim.world.marsclock import utc_to_t_s
from sim.world.sites import site
from sim.world.soil_patches import Circle

FloatArray = NDArray[np.float64]

SITE = "meridiani"
DRIVE_M = 3.0
SUN_ELEVATION_DEG = (8.0, 14.0)  # late afternoon: the shadow long, across the whole view
STEP_M = 0.2  # short steps (sol 235's are not given): the shadow's corners stay in search
# nearly featureless fine sand: Meridiani's plains at their smoothest (its mean albedo), with
# a faint low-contrast mottling and no grains (sim.world.sites.MERIDIANI_ALBEDO has 8 %)
FAINT_SAND = AlbedoStyle(mean=0.13, contrast=0.01, beta=0.15)
SCENE_RADIUS_M = 60.0
ROCKS = ((2.4, -0.8, 0.12), (2.6, 0.8, 0.12))  # ahead (m), right (m), diameter (m)
EPOCH = datetime(2004, 1, 25, tzinfo=UTC)  # Opportunity's landing
SPAN_DAYS = 400.0
MODES = ("unprevented", "mask", "advised")


@dataclass(frozen=True)
class Sol235Spec:
    """One drive: its seed and how it is run (``MODES``)."""

    seed: int
    mode: str


class ShadowVO(VisualOdometry):
    """The flight VO recording each pair's truth pose and outcome; with ``mask`` it gives
    the VO front the Sun in the body frame from what the flight software knows (NATE's
    attitude, IVP's Sun at the rover's clock): the shadow mask's input."""

    def __init__(self, sim: RoverSim, rig: Any = VO_RIG) -> None:
        super().__init__(rig)
        self.sim = sim
        self.session: RoverSession | None = None
        self.mask = False
        self.records: list[tuple[FloatArray, FloatArray, VoResult]] = []

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
        if self.mask and self.session is not None:
            nate, sim = self.session.nate, self.sim
            sun = sun_ll(sim.t_s, sim.lat_rad, sim.lon_east_rad)
            sun_b = Rotation.from_quat(nate.q_b_ll).apply(sun / np.linalg.norm(sun))
        result = super().step(
            left, right, R_b0_b1_predicted=R_b0_b1_predicted,
            p_b1_b0_predicted=p_b1_b0_predicted, R_s_b0=R_s_b0, mast_az_rad=mast_az_rad,
            mast_el_rad=mast_el_rad, sun_b=sun_b,
        )  # fmt: skip
        state = self.sim.drive_state
        self.records.append((state.p_s.copy(), Rotation.from_quat(state.q_s_b).as_matrix(), result))
        return result


def _low_sun(rng: np.random.Generator) -> tuple[datetime, FloatArray]:
    s = site(SITE)
    lat, lon = math.radians(s.lat_deg), math.radians(s.lon_east_deg)
    while True:
        utc = EPOCH + timedelta(days=float(rng.uniform(0.0, SPAN_DAYS)))
        sun = sun_ll_truth(utc_to_t_s(utc), lat, lon)
        elev = math.degrees(float(elevation_rad(sun)))
        if SUN_ELEVATION_DEG[0] <= elev <= SUN_ELEVATION_DEG[1]:
            return utc, sun


def sol235_run(spec: Sol235Spec) -> dict[str, Any]:
    """One drive of the scene (module docstring); its steps and the false ones."""
    if spec.mode not in MODES:
        raise InputError("mode", f"must be one of {', '.join(MODES)}, got {spec.mode!r}")
    rng = np.random.default_rng([spec.seed, 235])
    utc, sun = _low_sun(rng)
    yaw = math.atan2(float(sun[1]), float(sun[0])) + math.pi  # the Sun behind the rover
    options = VoDriveOptions(step_max_m=STEP_M, rover_shadow=True)
    session = RoverSession(SITE, spec.seed, utc, yaw_rad=yaw, frame_every_s=3600.0,
                           vo_options=options, visual_odometry=ShadowVO)  # fmt: skip
    fwd = np.array([math.cos(yaw), math.sin(yaw)])
    right = np.array([-fwd[1], fwd[0]])
    rocks = []
    for ahead, side, d in ROCKS:
        north, east = ahead * fwd + side * right
        rocks.append(RockSpec(float(north), float(east), d))
    sand = AlbedoPatch(Circle(0.0, 0.0, SCENE_RADIUS_M), TEXTURED, style=FAINT_SAND, seed=spec.seed)
    install_scene(session.sim, build_scene("flat", spec.seed, rocks, [sand]))
    vo = session.vo
    assert isinstance(vo, ShadowVO)
    vo.session, vo.mask = session, spec.mode == "mask"
    session.nate.load_attitude(session.q_b_ll_true(), AttitudeQuality.FINE)
    for name, value in RELAXED_LIMITS.items():
        session.loop.protection.set_limit(name, value)
    pointing: dict[str, float] = {}
    if spec.mode == "advised":
        pointing = _advised_pointing(session, spec.seed)
    session.execute(cmd.DriveStraight(distance_m=DRIVE_M, vo=True, vo_fail="continue",
                                      vo_az_deg=pointing.get("vo_az_deg"),
                                      vo_el_deg=pointing.get("vo_el_deg")))  # fmt: skip
    steps = [(a, b) for a, b in pairwise(vo.records) if b[2].status is not VoStatus.INITIALISED]
    errors = []
    for (p0, R0, _), (p1, R1, result) in steps:
        if result.motion is None:
            continue
        dp = float(np.linalg.norm(result.motion.p_b1_b0 - R0.T @ (p1 - p0)))
        angle = Rotation.from_matrix(result.motion.R_b0_b1 @ (R0.T @ R1).T).magnitude()
        errors.append((dp, math.degrees(float(angle))))
    false = sum(1 for m, d in errors if m > FALSE_UPDATE_M or d > FALSE_UPDATE_DEG)
    return {"seed": spec.seed, "mode": spec.mode, "steps": len(steps), "converged": len(errors),
            "false": false, "errors": errors, **pointing}  # fmt: skip


def _advised_pointing(session: RoverSession, seed: int) -> dict[str, float]:
    """The advisor's pointing from the ground's map (``bench.vo.advised.ground_map``)."""
    from bench.vo.advised import ground_map
    from server.terrain.advisor import PlannedDrive, advise

    sim = session.sim
    sun = sun_ll(sim.t_s, sim.lat_rad, sim.lon_east_rad)
    gmap = ground_map(session, seed, SITE)
    drive = PlannedDrive("straight", distance_m=DRIVE_M)
    advice = advise(gmap, session.nate.p_s, session.nate.q_b_ll, drive, sun / np.linalg.norm(sun))
    best = advice.recommended
    return {} if best is None else {"vo_az_deg": best.az_deg, "vo_el_deg": best.el_deg}


def _map(specs: list[Sol235Spec], workers: int) -> list[dict[str, Any]]:
    if workers <= 1:
        return [sol235_run(s) for s in specs]
    with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as pool:
        return list(pool.map(sol235_run, specs))


def bench_sol235(n_drives: int = 12, seed: int = 0, workers: int | None = None) -> dict[str, Any]:
    """``false_update_count_sol235_unprevented`` (> 0: reproduced), ``false_update_count_sol235``
    (the shadow mask: 0) and ``false_update_count_sol235_advised`` over ``n_drives`` drives of
    the scene each, with their step counts."""
    if isinstance(n_drives, bool) or not isinstance(n_drives, int) or n_drives < 1:
        raise InputError("n_drives", f"must be a positive integer, got {n_drives!r}")
    specs = [Sol235Spec(seed + k, mode) for mode in MODES for k in range(n_drives)]
    runs = _map(specs, workers if workers is not None else (os.cpu_count() or 1))
    out: dict[str, Any] = {}
    for mode in MODES:
        mine = [r for r in runs if r["mode"] == mode]
        suffix = "" if mode == "mask" else f"_{mode}"
        out[f"false_update_count_sol235{suffix}"] = sum(r["false"] for r in mine)
        out[f"sol235_steps{suffix}"] = sum(r["steps"] for r in mine)
        out[f"sol235_converged{suffix}"] = sum(r["converged"] for r in mine)
    return out
