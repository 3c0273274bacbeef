"""A rehearsal's start: the true pose drawn around the report, the flight software on the report.

The ground knows where the rover says it is (``sim.rehearsal.inputs.ReportedStart``), not
where it is. One run draws its truth around the report:

- the position (mission frame, North and East) from a 2-D Gaussian about the reported
  estimate (0: exactly the estimate). The reported 1σ (``position_sigma_m``, times
  ``Priors.position_sigma_scale``) is the onboard uncertainty of
  ``estimation.protection.position_sigma``: its worst direction, along track, where wheel
  odometry errs by the fraction ``f`` of the distance ``D``; across track it errs by the
  heading's 1σ ``σ_ψ`` times ``D``. So the error is drawn with the reported 1σ along the
  reported heading (the last drive's track, for a drive that ended straight) and
  ``min(1, σ_ψ / f)`` of it across (``D ≈ σ / f``): a fifth for a Fine heading, the whole for
  a heading not known (isotropic). Measured on 24 executions of a 3 m drive on both sites, the
  true start error lay along track (Meridiani's sand: 0.09-0.15 m behind the estimate for a
  reported 0.093 m), which an isotropic draw spreads over both axes. Where the priors hold
  the site's measured odometry error (``Priors.odometry_error_by_site``: the rover behind its
  estimate by a share of σ, with a spread along and across), the draw is that instead;
- the heading from a Gaussian about the reported one with the 1σ the priors give the reported
  Attitude Quality Flag (``Priors.heading_sigma_rad``; Ali et al. 2005, sec. 2.1);
- the tilt from the terrain: the rover is settled on the sampled ground at that position and
  heading, as every ``RoverSim`` settles its rover (``sim.rover.drive.initial_state``). The
  report's tilt is a measurement (the accelerometers at rest, 0.045° 1σ: Ali et al. 2005,
  sec. 2.2.1), so the ground under the start is given the slope that makes the settled rover
  stand at the reported tilt (``level_start``: a plane added about the start, fading out a few
  metres away, ``sim.rehearsal.world.StartSlope``); else the flight software would start
  from a tilt the world denies, and carry the difference into its heading as it drives.

The flight software starts from the REPORT, not from the drawn truth (``load_reported``):
NATE with the reported attitude and flag (``Nate.load_attitude``), its position, Sites, IMU
integration time and gyro counter as reported (through NATE's own checkpoint interface,
``Nate.state``/``load_state``: the Site chain is rebuilt so that Site ``site_index``'s
origin is ``p_mission_est - p_s_est``), its parameters as reported (``SET_PARAM``'s paths);
mobility fault protection with the reported keep-out zones, position 1σ and latched fault;
the pointing knowledge from the flag. The IMU biases, mast bias and sensor noise are the
simulator's own draws from the run's seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.protection.halt import HALT_CHECKS, Halt
from estimation.protection.limits import LIMITS
from estimation.sapp.aqf import AttitudeQuality
from sim.loop.drives import set_vo_rig
from sim.loop.session import RoverSession
from sim.rehearsal.inputs import Priors, ReportedStart
from sim.rehearsal.world import SampledWorld, StartSlope
from sim.rover import drive

FloatArray = NDArray[np.float64]

_AQF_BY_NAME = {q.paper_name: q for q in AttitudeQuality}
# words of a halt's reason that name its check (estimation.protection.monitor's sentences)
_CHECK_WORDS = (
    ("keep-out", "keepout"),
    ("VO failed", "vo_fail"),
    ("slip", "slip"),
    ("tilt", "tilt"),
    ("rocker", "suspension"),
    ("bogie", "suspension"),
    ("LMST", "lmst"),
)


@dataclass(frozen=True)
class TrueStart:
    """A run's true start: ``p_mission_m`` (North, East; mission frame, m), ``yaw_rad``
    (heading, from North towards East)."""

    p_mission_m: tuple[float, float]
    yaw_rad: float


def heading_of(q_b_ll: NDArray[np.float64] | tuple[float, ...]) -> float:
    """The heading (rad, from North towards East) of an attitude ``q_b_ll`` [x, y, z, w]: the
    yaw of the body in Local Level (Z-Y-X angles), as the simulator's truth defines it."""
    yaw = Rotation.from_quat(np.asarray(q_b_ll, dtype=np.float64)).inv().as_euler("ZYX")[0]
    return float(yaw)


def sample_start(start: ReportedStart, priors: Priors, rng: np.random.Generator) -> TrueStart:
    """The true start drawn around ``start`` (module docstring). Draws three normals."""
    z = rng.standard_normal(3)
    sigma = start.position_sigma_m * priors.position_sigma_scale
    heading = heading_of(start.q_b_ll_est)
    heading_sigma = priors.heading_sigma_rad(start.aqf)
    fraction = float(
        start.params.get("mobility.odometry_sigma_fraction", LIMITS.odometry_sigma_fraction)
    )
    measured = priors.odometry_error(start.site)
    if measured is not None:  # the site's measured odometry error (Priors)
        mean, along, across = measured
        along_m = sigma * (mean + along * float(z[0]))
        across_m = sigma * across * float(z[1])
    else:  # the onboard budget
        across = sigma * min(1.0, heading_sigma / fraction) if fraction > 0.0 else sigma
        along_m, across_m = sigma * float(z[0]), across * float(z[1])
    north = start.p_mission_est[0] + along_m * math.cos(heading) - across_m * math.sin(heading)
    east = start.p_mission_est[1] + along_m * math.sin(heading) + across_m * math.cos(heading)
    yaw = heading + heading_sigma * float(z[2])
    yaw = math.remainder(yaw, 2.0 * math.pi)
    return TrueStart((float(north), float(east)), float(yaw))


def _gradient(z_down: FloatArray) -> FloatArray:
    """The ground's slope (dh/dx, dh/dy) under a body whose z axis (Down) is ``z_down``."""
    out: FloatArray = np.asarray(z_down[:2], dtype=np.float64) / float(z_down[2])
    return out


def level_start(
    world: SampledWorld, true: TrueStart, start: ReportedStart, iterations: int = 2
) -> SampledWorld:
    """``world`` with the slope under the true start that settles the rover at the reported
    tilt (module docstring)."""
    z_axis = np.array([0.0, 0.0, 1.0])
    wanted = _gradient(Rotation.from_quat(np.asarray(start.q_b_ll_est)).inv().apply(z_axis))
    x, y = true.p_mission_m
    added = np.zeros(2)
    out = world
    for _ in range(iterations):
        state = drive.initial_state(out.terrain(), start.t_s, x, y, true.yaw_rad)
        z_true = Rotation.from_quat(np.asarray(state.q_s_b).reshape(-1, 4)[0]).apply(z_axis)
        added = added + wanted - _gradient(z_true)
        out = world.with_start_slope(StartSlope((x, y), (float(added[0]), float(added[1]))))
    return out


def site_origins(start: ReportedStart) -> FloatArray:
    """The origins of Sites ``0..site_index`` in the mission frame, (n, 3): Site 0 at the
    mission origin, the current one at ``p_mission_est - p_s_est``; the report holds no
    other, so the Sites between take the current one's (a zone kept in one of them is
    placed as if in the current Site)."""
    origin = np.asarray(start.p_mission_est, dtype=np.float64) - np.asarray(start.p_s_est)
    origins = np.tile(origin, (start.site_index + 1, 1))
    if start.site_index > 0:
        origins[0] = 0.0
    return origins


def halt_of(reason: str) -> Halt:
    """A latched halt from the reason the rover reported (``Downlink.mobility_fault``)."""
    check = next((c for word, c in _CHECK_WORDS if word in reason), "timeout")
    assert check in HALT_CHECKS
    return Halt(check, reason)


def load_reported(session: RoverSession, start: ReportedStart) -> None:
    """Put the session's flight software in the reported state (module docstring). The
    session is fresh (NATE Idle). ``ValueError`` if a reported parameter is refused."""
    loop, nate = session.loop, session.nate
    aqf = _AQF_BY_NAME[start.aqf]
    for path, value in sorted(start.params.items()):
        if path.startswith("mobility."):
            loop.protection.set_limit(path.removeprefix("mobility."), value)
        elif path == "vo.rig":
            set_vo_rig(loop, int(value))
        else:
            nate.set_param(path, value)
    nate.load_attitude(np.asarray(start.q_b_ll_est, dtype=np.float64), aqf)
    state = nate.state()
    state["p_s"] = np.asarray(start.p_s_est, dtype=np.float64).copy()
    state["sites"] = {"origins_mission_m": site_origins(start)}
    state["imu_integration_s"] = float(start.imu_integration_s)
    state["gyro_counter_s"] = min(float(start.gyro_counter_s), float(start.imu_integration_s))
    nate.load_state(state)
    protection = loop.protection
    for zone in start.keepout_zones:
        protection.add_zone(zone)
    sigma = float(start.position_sigma_m)
    protection.uncertainty.load_state(
        {"sigma_m": sigma, "base_m": sigma, "heading_sigma_rad": 0.0, "distance_m": 0.0}
    )
    protection.fault = halt_of(start.mobility_fault) if start.mobility_fault else None
    # the pointing knowledge as the flag implies it, its IMU time counted from the last Fine
    loop.recorder.knowledge.update(aqf, 0.0)
