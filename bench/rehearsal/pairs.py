"""The calibration pairs of ``roverops bench rehearsal``: a rehearsal from what the ground
knows, then the execution it predicts, on the site's true world.

An execution is a real ``RoverSession`` (the server's rover model, on the site's true world
for the pair's terrain seed) placed at a random point and heading near the landing, in
daylight (the Sun 30-65 deg up, as VO was commanded). It acquires a Fine attitude with
``GET_FINE_ATTITUDE`` (Ali et al. 2005, sec. 2.2.4: the heading error it leaves is the
flight software's own), then drives a little (``DRIVE_STRAIGHT`` of 1-3 m without VO and
a turn in place), so that its estimate carries an error and its position 1σ has grown
(``estimation.protection``). Then the ground's view of it is taken, and nothing else:

- the start: ``ReportedStart.from_downlink`` of the last telemetry frame that came down
  (its estimate, AQF, IMU time, position 1σ; no keep-out zone or parameter was set);
- the map: the ground map ``server.terrain`` builds for a rover placed there (the orbital
  product around the landing, ``GroundMapService``), cut to ``MAP_HALF_M`` around the
  reported position;
- the sequence: one drive of 2-6 m, ``DRIVE_STRAIGHT`` or ``DRIVE_ARC``, with ``vo=on`` on
  every other pair.

The rehearsal (``RUNS_PER_PAIR`` runs of ``sim.rehearsal.run.run_once``, a campaign on the
bench's Dask cluster) sees only those inputs. The execution then runs the sequence's steps
in the same session, as the runtime would, and its true end position in the mission frame
(the truth's body origin less the first Site's origin, ``RoverSession.mission_origin_world``,
as ``sim.scoring`` computes it) is set against the rehearsal's predicted end: a Gaussian fit
to the runs' true ends, its 50 % and 95 % ellipses (chi-square with 2 degrees of freedom,
``server.rehearsal.risk``).

The pairs alternate Gusev and Meridiani, VO on and off, straight and arc; their terrain and
run seeds differ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sequences import commands as cmd
from sequences.language import parse
from server.rehearsal.gather import crop_map
from server.rehearsal.risk import gaussian_fit, inside_ellipse, mahalanobis2
from server.terrain.feed import GROUND_HALF_M
from server.terrain.service import GroundMapService
from sim.loop.session import RoverSession
from sim.rehearsal.inputs import GroundMapData, RehearsalInputs, ReportedStart
from sim.rehearsal.outcome import RunOutcome
from sim.world.mars_frames import elevation_rad, sun_ll_truth
from sim.world.marsclock import utc_to_t_s
from sim.world.sites import site

FloatArray = NDArray[np.float64]

SITES = (("gusev", "spirit"), ("meridiani", "opportunity"))  # (site, mission)
RUNS_PER_PAIR = 40
SEQUENCE_M = (2.0, 6.0)  # the rehearsed drive's length
PRE_DRIVE_M = (1.0, 3.0)  # the drive before the report: estimate error, position 1σ
PRE_TURN_DEG = 30.0  # ... and a turn in place of up to this much either way
PLACE_M = 20.0  # the rover starts within this of the landing (North and East)
ARC_RADIUS_M = (4.0, 12.0)  # |radius| of the arcs
MAP_HALF_M = 20.0  # the ground map sent to the rehearsal: this far around the report
SUN_ELEVATION_DEG = (30.0, 65.0)  # daylight, the Sun well up (VO was commanded so)
EPOCH = datetime(2004, 1, 10, tzinfo=UTC)
SPAN_DAYS = 700.0
BENCH_SEED = 25  # the bench's own stream (issue 25)
FRAME_EVERY_S = 60.0  # the execution's frames: one a minute, and at every event
P_50, P_95 = 0.50, 0.95


@dataclass(frozen=True)
class PairSpec:
    """One pair: ``index`` (its seeds), the site and mission, the terrain ``seed``, the
    drive (``straight`` or ``arc``), its length and whether it runs VO."""

    index: int
    site_name: str
    mission: str
    seed: int
    kind: str
    length_m: float
    vo: bool

    def sequence_text(self, rng: np.random.Generator) -> str:
        """The rehearsed sequence: one drive (module docstring)."""
        vo = " vo=on" if self.vo else ""
        if self.kind == "straight":
            drive = f"DRIVE_STRAIGHT distance_m={self.length_m:.2f}{vo}"
        else:
            radius = float(rng.uniform(*ARC_RADIUS_M)) * (1.0 if rng.random() < 0.5 else -1.0)
            angle_deg = math.degrees(self.length_m / abs(radius))
            drive = f"DRIVE_ARC radius_m={radius:.2f} angle_deg={angle_deg:.2f}{vo}"
        return f"SEQUENCE calibration_{self.index}\n{drive}\n"


def pair_specs(n: int, lengths_m: tuple[float, float] = SEQUENCE_M) -> list[PairSpec]:
    """``n`` pairs (module docstring): sites, VO and drive kinds alternating, lengths drawn
    in ``lengths_m``."""
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"pairs: must be a positive integer, got {n!r}")
    rng = np.random.default_rng([BENCH_SEED, n])
    specs = []
    for k in range(n):
        site_name, mission = SITES[k % 2]
        specs.append(
            PairSpec(
                index=k,
                site_name=site_name,
                mission=mission,
                seed=1000 + k,
                kind=("straight", "arc")[(k // 4) % 2],
                length_m=float(rng.uniform(*lengths_m)),
                vo=k % 4 in (0, 3),  # each site with VO and without, every 4 pairs
            )
        )
    return specs


def sun_time(rng: np.random.Generator, site_name: str) -> datetime:
    """A UTC time with the Sun ``SUN_ELEVATION_DEG`` high at the site."""
    s = site(site_name)
    lat, lon = math.radians(s.lat_deg), math.radians(s.lon_east_deg)
    lo, hi = SUN_ELEVATION_DEG
    while True:
        utc = EPOCH + timedelta(days=float(rng.uniform(0.0, SPAN_DAYS)))
        elev = math.degrees(float(elevation_rad(sun_ll_truth(utc_to_t_s(utc), lat, lon))))
        if lo <= elev <= hi:
            return utc


def map_data(service: GroundMapService, north_m: float, east_m: float) -> GroundMapData:
    """The ground's map cut to ``MAP_HALF_M`` around (``north_m``, ``east_m``), mission
    frame, as the plain data a rehearsal takes (the server's own cut,
    ``server.rehearsal.gather.crop_map``)."""
    return crop_map(service.ground_map(), north_m, east_m, MAP_HALF_M)


def true_mission_ne(session: RoverSession) -> tuple[float, float]:
    """The truth's body origin in the mission frame (North, East), as ``sim.scoring``."""
    p = session.sim.drive_state.p_s - session.mission_origin_world
    return float(p[0]), float(p[1])


@dataclass
class Execution:
    """A pair's execution: the session after its pre-drive, the inputs the ground gives
    the rehearsal, and (once ``run``) the statuses and the true end."""

    spec: PairSpec
    session: RoverSession
    inputs: RehearsalInputs
    true_start_ne: tuple[float, float]
    statuses: list[str] = field(default_factory=list)
    true_end_ne: tuple[float, float] | None = None

    def run(self) -> None:
        """The sequence's steps in the session, in order; a refused or halted step stops
        it, as the runtime stops a sequence."""
        for step in parse(self.inputs.sequence_text).steps:
            report = self.session.execute(step.command, label=step.command.describe())
            self.statuses.append(report.status)
            if report.status in ("refused", "halted"):
                break
        self.true_end_ne = true_mission_ne(self.session)


def prepare(spec: PairSpec) -> Execution:
    """The execution's session up to the report, and the rehearsal's inputs from it."""
    rng = np.random.default_rng([BENCH_SEED, spec.index])
    x_m, y_m = (float(v) for v in rng.uniform(-PLACE_M, PLACE_M, 2))
    session = RoverSession(
        spec.site_name, spec.seed, sun_time(rng, spec.site_name), x_m=x_m, y_m=y_m,
        yaw_rad=float(rng.uniform(-math.pi, math.pi)), frame_every_s=FRAME_EVERY_S,
    )  # fmt: skip
    session.execute(cmd.GetFineAttitude())
    session.execute(cmd.DriveStraight(distance_m=float(rng.uniform(*PRE_DRIVE_M))))
    session.execute(cmd.TurnInPlace(angle_deg=float(rng.uniform(-PRE_TURN_DEG, PRE_TURN_DEG))))
    frame = session.take_frames()[-1][0]  # the last frame that came down
    start = ReportedStart.from_downlink(frame, spec.site_name, spec.mission)
    start_n, start_e = session.sim.start_xy_m  # the landing the mission localised
    service = GroundMapService(spec.site_name, spec.seed, start_n, start_e, half_m=GROUND_HALF_M)
    gmap = map_data(service, start.p_mission_est[0], start.p_mission_est[1])
    inputs = RehearsalInputs(start=start, ground_map=gmap, sequence_text=spec.sequence_text(rng))
    return Execution(spec, session, inputs, true_mission_ne(session))


def end_points(outcomes: list[RunOutcome]) -> list[tuple[float, float]]:
    """Each run's true end (mission frame): where its last step that ran ended."""
    ends = []
    for outcome in outcomes:
        ran = [s for s in outcome.steps if s.status != "not_run"]
        if ran and all(math.isfinite(v) for v in ran[-1].p_mission_true_m):
            ends.append(ran[-1].p_mission_true_m)
    return ends


def coverage(outcomes: list[RunOutcome], true_end_ne: tuple[float, float]) -> dict[str, Any]:
    """Whether the executed true end lies inside the rehearsal's 50 % and 95 % ellipses,
    with its squared Mahalanobis distance and the fit's spread."""
    ends = end_points(outcomes)
    fit = gaussian_fit(ends)
    if fit is None:
        return {"runs": len(ends), "in_50": False, "in_95": False, "fitted": False}
    mean, cov = fit
    d = np.asarray(true_end_ne) - mean
    return {
        "runs": len(ends),
        "fitted": True,
        "in_50": bool(inside_ellipse(true_end_ne, mean, cov, P_50)),
        "in_95": bool(inside_ellipse(true_end_ne, mean, cov, P_95)),
        "mahalanobis2": mahalanobis2(true_end_ne, mean, cov),
        "sigma_major_m": float(math.sqrt(max(np.linalg.eigvalsh(cov)))),
        "miss_m": float(np.hypot(*d)),
    }
