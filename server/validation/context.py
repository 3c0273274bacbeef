"""The rover's side of sequence validation: a ``ValidationContext`` from ``sim``.

``sequences.validate`` predicts when each command starts and asks the context for Earth's
elevation there (HGA passes: at the start and end of each). One DE421 evaluation per
question made a 40,000-line upload cost minutes of CPU. Here the ephemeris is sampled
coarsely, and only what changes slowly is interpolated:

- ``sim.world.mars_frames.body_ll_truth`` is ``R_ll_mf (Rz(W) Q p + parallax, aberration)``:
  the light-time corrected position ``p`` of the body from Mars (J2000) and Mars' velocity
  come from DE421; ``Q`` is Mars' pole orientation (IAU: a tenth of a degree per century);
  ``W``, the prime meridian, turns 351 deg a day, exactly linearly (IAU 2009).
- So ``Q p`` and ``Q v`` are sampled every ``COARSE_S`` (a quarter sol), ``BLOCK`` samples
  (32 sols) per ephemeris call, computed when first needed and kept for the request; a
  question interpolates them linearly (the body's motion over a quarter sol curves by a
  few hundred km in 55 million: 1e-5 rad) and applies ``W``, the parallax and the
  aberration exactly, in plain Python (microseconds).

A sequence therefore costs one ephemeris call per 32 sols it reaches, however often it
asks: 40,000 HGA passes (406 sols) take 13 calls, and one HGA pass on each of the 17,600
sols the ephemeris covers ~550. tests/server/validation/test_validation_context.py checks
the elevations against ``body_ll_truth`` (within 0.05 deg over a sol at both landing sites)
and counts the calls. The context also carries the ephemeris' last instant, past which
``sequences.validate`` refuses a step instead of asking.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np
from scipy.spatial.transform import Rotation

from estimation.protection.keepout import KeepOutZone
from estimation.protection.limits import LIMITS, MobilityLimits, replace_limit
from estimation.sapp.nate import NateParams
from sequences.terrain_grid import TerrainGrid
from sequences.validate import AqfName, ValidationContext
from server.validation.comm_context import RoverLink, rover_link
from sim.world.ephemeris import C_KM_S, Body, astrometric_from_mars_j2000_km, coverage_t_s
from sim.world.ephemeris import mars_velocity_j2000_km_s as mars_velocity
from sim.world.mars_frames import R_ll_mf, R_mf_j2000, iau_mars_angles_rad, site_mf_m
from sim.world.marsclock import (
    SOL_S,
    get_mission,
    lmst_h_from_t_s,
    sol_number_t_s,
    t_s_for_sol_lmst,
)
from sim.world.sites import site

if TYPE_CHECKING:  # the validation process (server.validation.pool) imports no runtime
    from server.runtime import RoverRuntime
    from server.storage import Store
    from sim.loop.downlink import DownlinkDict

MIN_SUN_ELEVATION_RAD = NateParams().min_sun_elevation_rad  # NATE's default (5 deg)
COARSE_S = SOL_S / 4.0  # s between ephemeris samples
BLOCK = 128  # samples per ephemeris call: 32 sols

_Vec = tuple[float, float, float]


class SampledElevation:
    """Elevation (deg, positive up) of ``body`` ("earth" or "sun") above a site
    (planetographic ``lat_rad``, ``lon_east_rad``) at TT seconds ``t_s``: what
    ``elevation_rad(body_ll_truth(...))`` gives, from ephemeris samples (module docstring)
    taken in blocks from ``origin_t_s`` on. ``end_t_s`` is the last instant that may be
    asked (the ephemeris' end): no sample lies beyond it; a later ``t_s`` is a ValueError.
    """

    def __init__(
        self, body: Body, lat_rad: float, lon_east_rad: float, origin_t_s: float, end_t_s: float
    ) -> None:
        if not origin_t_s <= end_t_s:
            raise ValueError(f"origin_t_s: must be at most end_t_s, got {origin_t_s}")
        self._body = body
        self._origin, self._end = origin_t_s, end_t_s
        site_km = site_mf_m(lat_rad, lon_east_rad) / 1000.0
        self._site_km: _Vec = (float(site_km[0]), float(site_km[1]), float(site_km[2]))
        down = R_ll_mf(lat_rad, lon_east_rad)[2]
        self._down: _Vec = (float(down[0]), float(down[1]), float(down[2]))
        # block index -> (times, W unwrapped, Q p, Q v) at BLOCK + 1 samples
        self._blocks: dict[int, tuple[list[float], list[float], list[_Vec], list[_Vec]]] = {}

    @property
    def blocks_sampled(self) -> int:
        """How many blocks have been computed (each one call per ephemeris function)."""
        return len(self._blocks)

    def __call__(self, t_s: float) -> float:
        if not t_s <= self._end:
            raise ValueError(f"t_s: {t_s} is past the end of the samples ({self._end})")
        k = math.floor((t_s - self._origin) / (COARSE_S * BLOCK))
        times, w, qp, qv = self._blocks.get(k) or self._sample(k)
        i = max(0, min(int((t_s - times[0]) / COARSE_S), BLOCK - 1))
        t0, t1 = times[i], times[i + 1]
        f = (t_s - t0) / (t1 - t0) if t1 > t0 else 0.0
        angle = w[i] + f * (w[i + 1] - w[i])  # W is linear in t (IAU 2009)
        c, s = math.cos(angle), math.sin(angle)
        (a0, a1, a2), (b0, b1, b2) = qp[i], qp[i + 1]
        x, y, z = a0 + f * (b0 - a0), a1 + f * (b1 - a1), a2 + f * (b2 - a2)
        sx, sy, sz = self._site_km
        px, py, pz = c * x + s * y - sx, -s * x + c * y - sy, z - sz  # Rz(W) Q p - site
        (a0, a1, a2), (b0, b1, b2) = qv[i], qv[i + 1]
        x, y, z = a0 + f * (b0 - a0), a1 + f * (b1 - a1), a2 + f * (b2 - a2)
        vx, vy, vz = c * x + s * y, -s * x + c * y, z
        norm = math.sqrt(px * px + py * py + pz * pz)
        ux, uy, uz = px / norm + vx / C_KM_S, py / norm + vy / C_KM_S, pz / norm + vz / C_KM_S
        dx, dy, dz = self._down
        sin_elev = -(dx * ux + dy * uy + dz * uz) / math.sqrt(ux * ux + uy * uy + uz * uz)
        return math.degrees(math.asin(max(-1.0, min(1.0, sin_elev))))

    def _sample(self, k: int) -> tuple[list[float], list[float], list[_Vec], list[_Vec]]:
        start = self._origin + k * COARSE_S * BLOCK
        t = np.minimum(start + COARSE_S * np.arange(BLOCK + 1), self._end)
        w = iau_mars_angles_rad(t)[2]
        c, s = np.cos(w), np.sin(w)
        zero, one = np.zeros_like(c), np.ones_like(c)
        rz_t = np.stack(  # Rz(W) transposed: Q = Rz(W)^T R_mf_j2000
            [np.stack(r, axis=-1) for r in ([c, -s, zero], [s, c, zero], [zero, zero, one])],
            axis=-2,
        )
        q = rz_t @ R_mf_j2000(t)
        qp = (q @ astrometric_from_mars_j2000_km(self._body, t)[:, :, None])[:, :, 0]
        qv = (q @ mars_velocity(t)[:, :, None])[:, :, 0]
        block = (
            t.tolist(),
            np.unwrap(w).tolist(),
            [(float(a), float(b), float(c)) for a, b, c in qp],
            [(float(a), float(b), float(c)) for a, b, c in qv],
        )
        self._blocks[k] = block
        return block


def site_context(
    mission: str,
    lat_rad: float,
    lon_east_rad: float,
    start_t_s: float,
    aqf: AqfName = "Unknown",
    imu_integration_s: float = 0.0,
    articulating: bool = False,
    min_sun_elevation_rad: float = MIN_SUN_ELEVATION_RAD,
) -> ValidationContext:
    """A context for a rover of ``mission`` (its sol clock) at a site (planetographic
    latitude, East longitude, rad) from ``start_t_s`` (TT s since J2000), with Earth's and
    the sun's elevation sampled (``SampledElevation``) up to the end of DE421, and the
    lowest sun NATE's camera modes accept (``min_sun_elevation_rad``, NATE's parameter)."""
    lon_west_deg = get_mission(mission).lon_west_deg
    end_t_s = coverage_t_s()[1]
    origin = min(start_t_s, end_t_s)

    return ValidationContext(
        start_t_s=start_t_s,
        lmst_h=lambda t_s: float(lmst_h_from_t_s(t_s, lon_west_deg)),
        sol=lambda t_s: int(sol_number_t_s(mission, t_s)),
        t_s_for=lambda sol, lmst_h: t_s_for_sol_lmst(mission, sol, lmst_h),
        earth_elevation_deg=SampledElevation("earth", lat_rad, lon_east_rad, origin, end_t_s),
        aqf=aqf,
        imu_integration_s=imu_integration_s,
        articulating=articulating,
        ephemeris_end_t_s=end_t_s,
        sun_elevation_deg=SampledElevation("sun", lat_rad, lon_east_rad, origin, end_t_s),
        min_sun_elevation_deg=math.degrees(min_sun_elevation_rad),
    )


@dataclass(frozen=True)
class RoverSite:
    """What validation needs to know of a rover, as plain values: ``site_context``'s
    arguments. It pickles, so the validation process (``server.validation.pool``) builds
    the context itself."""

    mission: str
    lat_rad: float
    lon_east_rad: float
    start_t_s: float
    aqf: AqfName = "Unknown"
    imu_integration_s: float = 0.0
    articulating: bool = False
    min_sun_elevation_rad: float = MIN_SUN_ELEVATION_RAD
    p_s_est: tuple[float, float] | None = None
    heading_rad: float | None = None
    site_index: int = 0
    position_sigma_m: float = 0.0
    keepout_zones: tuple[KeepOutZone, ...] = ()
    mobility_fault: str | None = None
    comm: RoverLink | None = None  # the link across the light time; None: instant
    mobility_limits: MobilityLimits | None = None  # as the rover reports them; None: defaults
    terrain: TerrainGrid | None = None  # the ground's map around the rover; None: none yet

    def context(self) -> ValidationContext:
        """The ``ValidationContext`` of this site (``site_context``), with the drives'
        state (``sequences.drive_safety``) and the link's timing
        (``server.validation.comm_context``), its reported mobility limits and the ground's
        map around it."""
        base = site_context(
            self.mission,
            self.lat_rad,
            self.lon_east_rad,
            self.start_t_s,
            aqf=self.aqf,
            imu_integration_s=self.imu_integration_s,
            articulating=self.articulating,
            min_sun_elevation_rad=self.min_sun_elevation_rad,
        )
        return dataclasses.replace(
            base,
            p_s_est=self.p_s_est,
            heading_rad=self.heading_rad,
            site_index=self.site_index,
            position_sigma_m=self.position_sigma_m,
            keepout_zones=self.keepout_zones,
            mobility_fault=self.mobility_fault,
            comm=self.comm.timing() if self.comm is not None else None,
            mobility_limits=self.mobility_limits,
            terrain=self.terrain,
        )


def rover_site(runtime: RoverRuntime) -> RoverSite:
    """A rover's ``RoverSite`` as the ground knows it now: the landing site's coordinates,
    and from the rover's last downlink record, read under the runtime's lock together with
    the played-out clock so that both are of one moment, its AQF, IMU time and mode, and
    the NATE parameters it has reported setting (``reported``; NATE's defaults
    otherwise), its estimated pose and position uncertainty, and the keep-out zones and
    mobility fault its events report (``server.validation.reported``). Never from the live
    session, which may be a command ahead of the clock. Across the light time, its link
    (``server.validation.comm_context.rover_link``) of the same moment. The mobility limits
    it reports holding (its ``parameter`` events of ``mobility.<name>``), and the ground's
    map around its reported position (``server.validation.terrain``) when the rover has a
    ground map on this server (``server.terrain.feed.shared_feed``: its 3D views' or its
    pointing advisor's, with the pairs they have fused; none: no map, no tilt check)."""
    from server.terrain.feed import shared_feed  # the validation worker needs neither
    from server.validation.terrain import rover_terrain

    landing = site(runtime.spec.site)
    with runtime.lock:
        last = runtime.last_frame  # a played-out record is never changed: no copy needed
        t_s = float(runtime.t_s)
        params = dict(runtime.reported.params)
        zones = tuple(runtime.reported.zones.values())
        fault = runtime.reported.mobility_fault
        link = rover_link(runtime)
    pose = _reported_pose(last)
    feed = shared_feed(runtime)
    terrain = None
    if feed is not None and last is not None:
        p_m, p_s = last["p_mission_est"], last["p_s_est"]
        terrain = rover_terrain(feed.service, (float(p_m[0]), float(p_m[1])),
                                (float(p_s[0]), float(p_s[1])))  # fmt: skip
    return RoverSite(
        runtime.spec.mission,
        math.radians(landing.lat_deg),
        math.radians(landing.lon_east_deg),
        t_s,
        # the flag as the rover reported it (ValidationContext checks it is one of AQF_RANK)
        aqf=cast(AqfName, last["aqf"]) if last is not None else "Unknown",
        imu_integration_s=last["imu_integration_s"] if last is not None else 0.0,
        articulating=last is not None and last["nate_mode"] == "Articulate",
        min_sun_elevation_rad=float(params.get("min_sun_elevation_rad", MIN_SUN_ELEVATION_RAD)),
        p_s_est=pose[0],
        heading_rad=pose[1],
        site_index=int(last["site_index"]) if last is not None else 0,
        position_sigma_m=pose[2],
        keepout_zones=zones,
        mobility_fault=fault,
        comm=link,
        mobility_limits=reported_limits(params),
        terrain=terrain,
    )


def reported_limits(params: dict[str, float]) -> MobilityLimits | None:
    """The mobility limits from the parameters the rover reported setting (``mobility.``
    names; one the flight software would refuse is not in its table: skipped); ``None``
    when it reported none."""
    limits = LIMITS
    for name, value in params.items():
        if name.startswith("mobility."):
            with contextlib.suppress(ValueError):
                limits = replace_limit(limits, name.removeprefix("mobility."), value)
    return None if limits == LIMITS else limits


def _reported_pose(
    last: DownlinkDict | None,
) -> tuple[tuple[float, float] | None, float | None, float]:
    """The estimated position (North, East), heading and position 1σ a downlink reports."""
    if last is None:
        return None, None, 0.0
    p, q = last["p_s_est"], last["q_b_ll_est"]
    x_ll = Rotation.from_quat(q).inv().apply([1.0, 0.0, 0.0])  # body x in LL
    sigma = last.get("position_sigma_m")
    return (
        (float(p[0]), float(p[1])),
        math.atan2(float(x_ll[1]), float(x_ll[0])),
        float(sigma) if sigma is not None and math.isfinite(sigma) else 0.0,
    )


def validation_context(runtime: RoverRuntime) -> ValidationContext:
    """What validation needs to know of a rover, from its state now."""
    return rover_site(runtime).context()


def stored_rover_site(store: Store, rover: str, *, ground_map: bool = True) -> RoverSite | None:
    """A rover's ``RoverSite`` from its last checkpoint in ``store`` (``None`` if it has
    none): the state a server restarted on that database would resume, and validate
    against, with the last stored frame as the latest telemetry, as ``Server._resume``
    sets it. ``roverops validate --rover NAME`` reads it when no ``--server`` is given.
    With ``ground_map`` its ground map is rebuilt from the pairs stored (``server.terrain.
    feed``: the map a restarted server's 3D view would fuse), for the tilt check."""
    from server.runtime import ROVERS, RoverRuntime
    from server.terrain.feed import ground_feed

    spec = ROVERS[rover]
    saved = store.load_checkpoint(rover)
    if saved is None:
        return None
    runtime = RoverRuntime.restore(spec, saved[1])
    runtime.last_frame = store.last_frame(rover)
    runtime.note_reported(store.events(rover, -math.inf, runtime.t_s))
    if ground_map:
        ground_feed(runtime, store).catch_up()  # the rover's shared feed, until it is gone
    return rover_site(runtime)
