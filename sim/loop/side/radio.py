"""The radio + terrain-matching EKF beside SAPP in a rover session (the fusion issue,
item 3; Jiang, Li et al. 2014, ``estimation.fusion.radio.ekf``).

``RadioEkfRunner`` runs the filter on what this rover has, with Jiang, Li et al. 2014's sensor set
in its case 4 configuration (a HiRISE-class 0.25 m landmark map, 1 m radio ranging):

- **Drives**, in Jiang, Li et al. 2014's 1 s steps (the last one of a segment shorter):
  - eq. 2 with the IMU's specific force over the step, its 8 Hz samples rotated to LL by
    SAPP's attitude, summed, and turned into body axes at the step's start;
  - eq. 1 with SAPP's attitude: the paper takes the attitude as known, and SAPP is this
    rover's attitude;
  - eq. 4 with the yaw rate of SAPP's gyro-propagated attitude over the step (at 3.75 cm/s
    it weighs little: the acceleration uncertainty in its prediction, ``Q``'s velocity
    part over the speed squared, dwarfs the gyro's noise);
  - a range to the relay orbiter (``sim.sensors.orbiter``) whenever it is above the 10°
    mask (eqs. 7-9);
  - two landmarks of the orbital map seen by Navcam (eqs. 10-11, ``sim.sensors.landmarks``).

  When the wheels stop at the end of a segment, a zero-velocity update: the driving
  software knows the rover is parked.
- **At rest** the state is held (the rover does not move). Every 10 s of a relay pass
  brings a range. Each pass starts with the overflight predict, the orbiter's state as
  the ground would upload it for the pass, propagated onboard (two-body,
  ``estimation.fusion.radio.beacon``).

What is taken as exact, as Jiang, Li et al. 2014 takes it: the orbiter's state (the upload is the
true two-body state, so the ranges carry only their 1 m noise; a real predict has
along-track errors that would bias them), the maps' tie to the site (the rover's start is
its true placement in the map, and the elevation model is the true rock-free ground), and
the identity of each matched landmark. The figures are therefore those of a rover whose
maps and ephemerides are good: the mission-frame error leaves out any map-tie error.

The filter estimates position only (latitude, longitude, North and East velocity); its
frames carry its position and error and no attitude of its own. It starts at the first
drive, from SAPP's mission position placed at the rover's start in the site's map, with
Jiang, Li et al. 2014's 10 m ``P0``. The mission frame's origin is the rover's start: the placement
(``x_m``, ``y_m``) the session was given, at the map's height there. The onboard map gives
the heights: the orbital elevation model (``sim.sensors.landmarks.OrbitalDem``, 1 m posts) plus the
body's nominal height above the ground.
Noise: the filter's Q (``SESSION_TUNING``) is ten times smaller than the one matched to
Jiang, Li et al. 2014's scenario (``sim.scenarios.radio.SCENARIO_TUNING``): this rover's LN-200 has
a tenth of the paper's gyro noise and SAPP's Fine attitude leaks less gravity into eq. 2.
Over six courses on Gusev and Meridiani it gave 0.20 m RMS against 0.24 m, half the
step-to-step jitter, and a final NEES of 1.7 over the 2 horizontal states. The sensors draw
from generators seeded from the session's seed.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.fusion.radio.beacon import OrbitingBeacon
from estimation.fusion.radio.ekf import RadioEkf, RadioEkfTuning
from sim.loop.rover_sim import RoverSim, Segment
from sim.loop.side.kinematic import DriveInputs, SideEstimate
from sim.rover.geometry import MER_GEOMETRY
from sim.scenarios.radio import metres_per_radian
from sim.sensors.landmarks import (
    NAVCAM_FOCAL_PX,
    NAVCAM_OFFSET_B_M,
    PIXEL_SIGMA_PX,
    LandmarkTiles,
    OrbitalDem,
    choose_pair,
    matching_band,
    matching_geometry,
    navcam_pixels,
)
from sim.sensors.orbiter import ORBIT_EPOCH, KeplerOrbit, RelayOrbiter
from sim.world.mars_frames import mf_from_site_m
from sim.world.marsclock import utc_to_t_s

FloatArray = NDArray[np.float64]

MAP_RESOLUTION_M = 0.25  # Jiang, Li et al. 2014 Table 1, cases 3-4: HiRISE
RADIO_SIGMA_M = 1.0  # Jiang, Li et al. 2014 Table 1, cases 2 and 4
STEP_S = 1.0  # Jiang, Li et al. 2014 sec. 5
REST_RANGE_EVERY_S = 10.0  # ranges while parked: the pass's geometry changes slowly
NEW_PASS_GAP_S = 600.0  # an orbiter unseen this long comes back on a new pass
ZUPT_SIGMA_M_S = 1.0e-3  # a parked rover's velocity: the wheels' creep, at most
SESSION_TUNING = RadioEkfTuning(q_position_m2_per_s=1.0e-4, q_velocity_m2_s2_per_s=1.0e-3)


class RadioEkfRunner:
    """The radio + terrain-matching EKF beside SAPP (module docstring)."""

    name = "radio_ekf"

    def __init__(self, sim: RoverSim, seed: int, x_m: float, y_m: float) -> None:
        self.lat_rad, self.lon_east_rad = sim.lat_rad, sim.lon_east_rad
        self.m_per_lat, self.m_per_lon = metres_per_radian(sim.lat_rad)
        self.body_height_m = MER_GEOMETRY.body_height_m
        self.spacing_m, _, _ = matching_geometry(MAP_RESOLUTION_M)
        # the orbital maps onboard, both cut from the site's terrain
        self.dem = OrbitalDem(sim.terrain)
        self.landmarks = LandmarkTiles(sim.terrain, MAP_RESOLUTION_M, seed, self.spacing_m)
        self.orbiter = RelayOrbiter(KeplerOrbit(epoch_t_s=utc_to_t_s(ORBIT_EPOCH)))
        self.rng = np.random.default_rng([seed, 7004])
        start_ne = np.array([x_m, y_m])
        self.start_s = np.array([x_m, y_m, -self._height_m(start_ne)])
        self.ekf: RadioEkf | None = None
        self.beacon: OrbitingBeacon | None = None
        self.last_seen_t_s = -math.inf  # the orbiter's last range
        self.rest_t_s = sim.t_s  # ranges at rest are taken up to here

    # ---- the map and the frames ------------------------------------------------------

    def _height_m(self, ne_m: FloatArray) -> float:
        """Height (m) of the body origin at North/East ``ne_m`` by the onboard map, over the
        Site origin and so over the ellipsoid (eq. 5's ``h``: the origin is on it)."""
        return self.dem.height_m(float(ne_m[0]), float(ne_m[1])) + self.body_height_m

    def _ne_from_state(self, x: FloatArray) -> FloatArray:
        return np.array(
            [(x[0] - self.lat_rad) * self.m_per_lat, (x[1] - self.lon_east_rad) * self.m_per_lon]
        )

    def _p_mission(self) -> FloatArray:
        assert self.ekf is not None
        ne = self._ne_from_state(self.ekf.estimate()[0])
        p_s = np.array([ne[0], ne[1], -self._height_m(ne)])
        out: FloatArray = p_s - self.start_s
        return out

    def estimate_now(self) -> tuple[FloatArray, FloatArray | None] | None:
        """``(p_mission, None)`` now (position only), or ``None`` before the first drive."""
        if self.ekf is None:
            return None
        return self._p_mission(), None

    # ---- radio -----------------------------------------------------------------------

    def _estimated_height_m(self) -> float:
        assert self.ekf is not None
        return self._height_m(self._ne_from_state(self.ekf.estimate()[0]))

    def _range_update(self, t_s: FloatArray, p_s_true: FloatArray) -> None:
        """Ranges at the instants ``t_s`` (n,) from the rover's truth ``p_s_true`` (n, 3),
        those the orbiter is above the mask for."""
        assert self.ekf is not None
        lat, lon = self.lat_rad, self.lon_east_rad
        rover_mf = mf_from_site_m(p_s_true, lat, lon)
        ranges, visible = self.orbiter.ranges(t_s, rover_mf, lat, lon, RADIO_SIGMA_M, self.rng)
        for t, r in zip(t_s[visible], ranges[visible], strict=True):
            if self.beacon is None or t - self.last_seen_t_s > NEW_PASS_GAP_S:
                r0, v0 = self.orbiter.state_j2000(float(t))  # the pass's overflight predict
                self.beacon = OrbitingBeacon(r0, v0, float(t))
            self.last_seen_t_s = float(t)
            height = self._estimated_height_m()
            self.ekf.update_range(
                float(r), self.beacon.position_mf_m(float(t)), height, RADIO_SIGMA_M
            )

    def rest_until(self, t_s: float, p_s_true: FloatArray) -> None:
        """Ranges every ``REST_RANGE_EVERY_S`` (on a TT grid) up to ``t_s`` while parked at
        ``p_s_true``; the state is held."""
        first = math.floor(self.rest_t_s / REST_RANGE_EVERY_S) + 1
        last = math.floor(t_s / REST_RANGE_EVERY_S)
        self.rest_t_s = max(self.rest_t_s, t_s)
        if self.ekf is None or last < first:
            return
        grid = REST_RANGE_EVERY_S * np.arange(first, last + 1, dtype=np.float64)
        self._range_update(grid, np.tile(p_s_true, (grid.size, 1)))

    # ---- checkpoint ------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        """The generator, the filter and the pass's beacon (``None`` before they start),
        as plain data; the maps are caches, rebuilt from the seed."""
        beacon = self.beacon
        return {
            "rng": self.rng.bit_generator.state,
            "ekf": None if self.ekf is None else self.ekf.state(),
            "beacon": None
            if beacon is None
            else {"state_j2000": beacon.state_j2000(), "t_s": beacon.t_s},
            "last_seen_t_s": self.last_seen_t_s,
            "rest_t_s": self.rest_t_s,
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state`` (``state()``) onto a runner built for the same session."""
        self.rng.bit_generator.state = state["rng"]
        self.ekf = None
        if state["ekf"] is not None:
            self._start(np.zeros(3))
            assert self.ekf is not None
            self.ekf.load_state(state["ekf"])
        beacon = state["beacon"]
        self.beacon = None
        if beacon is not None:
            rv = np.array(beacon["state_j2000"], dtype=np.float64)
            self.beacon = OrbitingBeacon(rv[:3], rv[3:], float(beacon["t_s"]))
        self.last_seen_t_s = float(state["last_seen_t_s"])
        self.rest_t_s = float(state["rest_t_s"])

    # ---- driving ---------------------------------------------------------------------

    def _start(self, p_mission: FloatArray) -> None:
        ne = self.start_s[:2] + p_mission[:2]
        lat = self.lat_rad + ne[0] / self.m_per_lat
        lon = self.lon_east_rad + ne[1] / self.m_per_lon
        self.ekf = RadioEkf(lat, lon, 0.0, 0.0, self._height_m(ne), SESSION_TUNING)

    def drive(self, seg: Segment, inputs: DriveInputs) -> SideEstimate:
        """Run the filter through ``seg`` in 1 s steps (module docstring). Returns the
        estimate at each sample of the segment, held between steps (its first = before
        moving)."""
        truth = seg.truth
        t = truth.t_s
        self.rest_until(float(t[0]), truth.p_s[0])
        if self.ekf is None:
            self._start(inputs.start[0])
        ekf = self.ekf
        assert ekf is not None
        R_ll_b = Rotation.from_quat(inputs.sapp_q_b_ll).inv()
        euler = R_ll_b.as_euler("ZYX")[:, ::-1]  # eq. 1's (roll, pitch, yaw)
        dv_ll = R_ll_b[:-1].apply(seg.imu.delta_velocity_b)
        R_s_b = Rotation.from_quat(truth.q_s_b).as_matrix()
        p = np.empty((t.size, 3))
        p[0] = self._p_mission()
        per_step = max(1, round(STEP_S / float(np.median(seg.imu.dt_s))))
        bounds = [*range(0, t.size - 1, per_step), t.size - 1]
        height = self._estimated_height_m()
        for i0, i1 in itertools.pairwise(bounds):
            dt = float(t[i1] - t[i0])
            force_b = R_ll_b[i0].inv().apply(dv_ll[i0:i1].sum(axis=0) / dt)
            ekf.propagate(dt, force_b, euler[i0], height)
            yaw_change = math.remainder(float(euler[i1, 2] - euler[i0, 2]), 2.0 * math.pi)
            ekf.update_yaw_rate(yaw_change / dt)
            height = self._estimated_height_m()  # looked up once a step
            self._range_update(t[i1 : i1 + 1], truth.p_s[i1 : i1 + 1])
            self._sight_landmarks(truth.p_s[i1], R_s_b[i1], euler[i1], height)
            p[i0 + 1 : i1] = p[i0]
            p[i1] = self._p_mission()
        ekf.update_velocity(np.zeros(2), ZUPT_SIGMA_M_S)  # the wheels have stopped
        p[-1] = self._p_mission()
        self.rest_t_s = float(t[-1])
        return SideEstimate(p, None)

    def _sight_landmarks(
        self, p_s_true: FloatArray, R_s_b_true: FloatArray, euler: FloatArray, height_m: float
    ) -> None:
        """Two landmarks imaged from the truth pose (``sim.sensors.landmarks``), matched to the
        map."""
        assert self.ekf is not None
        near_m, far_m = matching_band(MAP_RESOLUTION_M, self.ekf.horizontal_sigma_m())
        landmarks = self.landmarks.around(p_s_true, far_m)
        yaw_true = math.atan2(R_s_b_true[1, 0], R_s_b_true[0, 0])  # to centre them: pointing only
        pair = choose_pair(p_s_true, yaw_true, landmarks.true_s_m, self.rng, near_m, far_m)
        if pair is None:
            return
        ids, pans = pair
        pixels = navcam_pixels(
            p_s_true, R_s_b_true, pans, landmarks.true_s_m[ids], PIXEL_SIGMA_PX, self.rng
        )
        self.ekf.update_landmarks(
            pixels,
            landmarks.map_mf_m(self.lat_rad, self.lon_east_rad)[ids],
            pans,
            euler,
            height_m,
            NAVCAM_OFFSET_B_M,
            NAVCAM_FOCAL_PX,
            PIXEL_SIGMA_PX,
            MAP_RESOLUTION_M,
        )
