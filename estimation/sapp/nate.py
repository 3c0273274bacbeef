"""The NATE state machine: SAPP's Navigation/Attitude Estimator (Ali et al. 2005 Figure 1).

Ali et al. 2005, "Attitude and Position Estimation on the Mars Exploration Rovers":
Figure 1 (the NATE modes), sec. 2.1 (Attitude Quality Flag), 2.2.1 (Nadir Update,
eq. 1), 2.3 and 2.3.1 (Nadir Check), 2.4 (propagation never improves the flag; Fine drops
to Coarse after 15 min of gyro counter), 2.4.1 (Articulate: gyros with Mars rotation
subtracted, tilt corrections against the reference vertical), 2.4.2 (Mobility, and its
off-nominal wheel-odometry attitude submode), 2.5 (position, eqs. 5-7), sec. 1 / Table 1
(Site frames) and sec. 4 (the operators' "IMU integration time since the last Sungaze").
The math lives in ``nadir``, ``gyro_propagation``, ``wheel_odometry`` and ``site_frames``;
NATE sequences it, one 8 Hz control cycle per ``Nate.step``, in three modules:
``nate_io`` (the modes, ``NateParams``, the samples it takes and ``NateOutput``),
``nate_modes`` (the state, what each mode does on entry and per cycle, the flag rules, and
the checkpoint ``state()``/``load_state()``) and this one (the commands with their
refusals, the read-only properties and the control cycle's dispatch).

Design. ``Nate.step(imu, encoders, image)`` takes only sensor data (``ImuSample``: delta
angles, delta velocities, dt, validity; ``EncoderSample``: wheel angles since power-on,
steering angles; a Pancam frame when a camera mode asked for one); commands are methods
(``nadir_update``, ``nadir_check``, ``sunfind``, ``sungaze``, ``suncheck``, the acquisition
commands, ``gyrocompass``, ``articulate``, ``mobility``, ``set_drive``, ``stop``,
``plant_site``, ``set_param``, ``load_attitude``).
A command not allowed in the current mode, or with an out-of-range parameter, raises
``ValueError`` with the reason and changes nothing (every check runs before any state is
touched). Documented choices (the paper leaves these to the ground):

- Commands are accepted in Idle only, except ``stop`` (Articulate, Mobility) and
  ``set_drive`` (Mobility). The acquisition and check modes and gyrocompassing end by
  themselves and return to Idle.
- In Idle and the acquisition modes the rover is stationary and the estimate is not
  propagated (the estimate changes only when an acquisition mode exits, sec. 2.4).
- The gyro counter counts seconds (the sum of the IMU ``dt`` of every Articulate or Mobility
  cycle, sec. 2.4); the IMU integration time counts the seconds the gyros were actually
  integrated, so the two differ only in Mobility's wheel-odometry submode. Both are reset
  only by a Fine attitude (Sungaze, or a ground ``load_attitude(..., FINE)``).
- Articulate (sec. 2.4.1), simplest faithful form: gyro propagation every cycle; the first
  accelerometer window after entry is the reference vertical, stored in LL with the
  estimate at entry (``ref_ll = R_ll_b(q_entry) ref_b``: the mode "starts with the SAPP
  attitude estimate at the time Articulate mode is entered", and the rover is expected to
  be still while the reference is taken, so gyro drift over that window does not enter
  it); each following window's
  average ``g_b`` is compared with ``R_b_ll ref_ll`` (the reference in body with the latest
  estimate) and the estimate is turned by eq. (1)'s form ``δq^B ⊗ q`` with ``δq^B`` the
  rotation about ``(R_b_ll ref_ll) × g_b`` by the angle between them. That axis is normal to
  the reference vertical, so there is no rotation about it: yaw is left to the gyros. A
  window failing the sanity checks of sec. 2.2.1 is skipped (no correction, flag unchanged).
  The rover moving within a window blurs that window's average; this is not modelled.
- Mobility (sec. 2.4.2, 2.5): gyro propagation, then the odometry step for the commanded
  ``DriveCommand`` with the freshly propagated attitude. Wheel odometry (``wheel_odometry``)
  works with ``q_s_b``; the Site has LL orientation, so ``q_s_b = conj(q_b_ll)``, converted
  in ``_q_s_b`` only. The first encoder reading after entry only sets the reference unless
  ``mobility(..., wheel_angle_rad=...)`` gave one.

Camera modes (sec. 2.2.2, 2.2.3, 2.3.2; procedures in ``estimation.sapp.sun_modes``). Sunfind,
Sungaze and Suncheck enter from Idle like Nadir Update. While one runs, ``camera_request``
says where to point the mast and the earliest time for the image; the next ``step`` that
carries an ``image`` (the Pancam frame, pixels) answers it: NATE runs the sun finder
(``estimation.sapp.sunfind``) with the mast pointing it asked for and hands the result to the
procedure. NATE keeps its own clock (``t_s``, advanced by each sample's ``dt``) for IVP's
sun and Earth. The outcome is applied in ``_finish_camera`` only, by the flag rules:
Sunfind success Coarse (estimate updated, or not near the zenith), failure Unknown with the
estimate unchanged; Sungaze success Fine (both counters reset), failure Unknown and no
update; Suncheck pass leaves both alone, failure sets Unknown. A camera command while the
sun is below ``min_sun_elevation_rad`` (IVP) fails its sanity check: refused, nothing
changes. The Sungaze gravity variation first averages the accelerometers for one Nadir
window (8 Hz samples); if that average fails the sanity checks it proceeds sun-only.

Attitude Acquisition Machine (sec. 2.2.4): ``get_tilt_attitude`` (Nadir Update),
``get_coarse_attitude`` (Nadir Update, Sunfind), ``get_fine_attitude`` (Nadir Update,
Sunfind, Sungaze) run the primitives in order and abort at the first failure.
``suncheck_sungaze`` is the operators' practice of sec. 4 (a Suncheck, then a Sungaze) as
the one command sec. 5 wishes SAPP had. It runs Sungaze after a Suncheck that saw the sun,
whether or not it was within tolerance: in that practice the Suncheck points the camera
(it "leaves the camera pointed at the sun", sec. 2.3.2) and Sungaze "can determine the
full attitude so long as the sun is in the field of view" (sec. 4; it "starts with no
assumptions about the rover's attitude knowledge", sec. 2.2.3). A Suncheck that failed
but saw the sun is an event of its own (the AQF is Unknown until Sungaze ends); one that
saw no sun aborts the command (AQF Unknown, Sungaze not run). It is meant for an AQF of
Coarse or better, the attitude knowledge sec. 4 relies on "to point the cameras at the
sun"; it is not refused below that (a Suncheck that sees the sun is all Sungaze needs),
but from Unknown or TiltOnly the sun may be outside the image: GetFineAttitude is the
command for that. ``gyrocompass`` (sec. 5's other lesson,
``estimation.sapp.gyrocompass``) sums the gyro delta angles over a stationary span (IMU samples
of any length) and corrects the heading; the flag becomes Coarse only if the predicted
heading 3σ is within ``gyrocompass_coarse_3sigma_rad`` (default 8 deg, Pancam's half field:
a Coarse attitude must put the sun in a Suncheck image), and otherwise TiltOnly at best (a
Fine or Coarse flag no longer describes the new heading); a
refusal (too short, near a pole, or the measured horizontal rate off by more than
``gyrocompass_rate_tolerance`` of Mars' because the rover moved) leaves everything
unchanged. ``wait_hint_s`` tells the caller how long it may aggregate IMU data before NATE
needs the next cycle (0.125 s in the 8 Hz modes, until the image time in a camera mode).

Parameters are set by ``set_param("sunfind.image_spacing_s", 5.0)`` (dotted paths into
``NateParams``; SI units), Idle only, each value checked by its dataclass.

>>> nate = Nate(lat_rad=math.radians(-14.57), lon_east_rad=math.radians(175.47), t_s=1.3e8)
>>> nate.nadir_update()
>>> level = ImuSample(np.zeros(3), np.array([0.0, 0.0, -3.711 / 8]), 0.125)
>>> out = [nate.step(level) for _ in range(80)][-1]
>>> out.aqf.paper_name, out.mode.name, round(out.tilt_est_deg, 9)
('TiltOnly', 'IDLE', 0.0)
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.checks import finite_vector, is_real_number
from estimation.geometry import N_WHEELS
from estimation.ivp import earth_ll
from estimation.quaternion import quat_canonical
from estimation.sapp.aqf import AttitudeQuality
from estimation.sapp.hga_pointing import HgaCommand, point_hga
from estimation.sapp.mobility import cycle_tilts_deg
from estimation.sapp.nadir import (
    AccelAverager,
)
from estimation.sapp.nate_io import (
    CONTROL_DT_S,
    Completed,
    DriveCommand,
    EncoderSample,
    EncoderSeries,
    GyrocompassOutcome,
    ImuSample,
    ImuSeries,
    NateMode,
    NateOutput,
    NateParams,
    NateSeries,
    checked_drive,
    nadir_params_for,
    replace_param,
)
from estimation.sapp.nate_modes import NateProcedures
from estimation.sapp.site_frames import SiteChain
from estimation.sapp.sun_modes import (
    PancamRequest,
    SuncheckParams,
)

__all__ = [
    "CONTROL_DT_S",
    "DriveCommand",
    "EncoderSample",
    "EncoderSeries",
    "GyrocompassOutcome",
    "ImuSample",
    "ImuSeries",
    "Nate",
    "NateMode",
    "NateOutput",
    "NateParams",
    "NateSeries",
    "replace_param",
]

FloatArray = NDArray[np.float64]

_CAMERA_MODES = (NateMode.SUNFIND, NateMode.SUNGAZE, NateMode.SUNCHECK)
_8HZ_MODES = (NateMode.NADIR_UPDATE, NateMode.NADIR_CHECK, NateMode.ARTICULATE, NateMode.MOBILITY)


def _unit_q(value: ArrayLike, name: str) -> FloatArray:
    q = finite_vector(value, name, 4)
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > 1e-6:
        raise ValueError(f"{name}: must be a unit quaternion, norm {norm:g}")
    return quat_canonical(q / norm)


class Nate(NateProcedures):
    """SAPP's NATE state machine (module docstring).

    ``lat_rad``, ``lon_east_rad``: the site (planetographic latitude, east longitude) for
    IVP's sun, Earth and Mars rotation; ``t_s``: NATE's clock at start (TT seconds from
    J2000, IVP's time), advanced by every IMU sample's ``dt``.
    """

    # ---- read-only state ----------------------------------------------------------

    @property
    def params(self) -> NateParams:
        """Current parameters."""
        return self._params

    @property
    def mode(self) -> NateMode:
        """Current NATE mode."""
        return self._mode

    @property
    def aqf(self) -> AttitudeQuality:
        """Current Attitude Quality Flag."""
        return self._aqf

    @property
    def q_b_ll(self) -> FloatArray:
        """Current estimate ``q_b_ll`` (4,), a copy."""
        return self._q_b_ll.copy()

    @property
    def p_s(self) -> FloatArray:
        """Current position in the current Site, m (3,), a copy."""
        return self._p_s.copy()

    @property
    def t_s(self) -> float:
        """NATE's clock, s (IVP's time scale)."""
        return self._t_s

    @property
    def sites(self) -> SiteChain:
        """The Site chain (read it; plant Sites with ``plant_site``)."""
        return self._sites

    @property
    def gyro_counter_s(self) -> float:
        """Seconds of Articulate/Mobility cycles since the last Fine attitude (sec. 2.4)."""
        return self._gyro_counter_s

    @property
    def imu_integration_s(self) -> float:
        """Seconds of gyro integration since the last Fine attitude (sec. 4)."""
        return self._imu_integration_s

    @property
    def acquisition(self) -> str | None:
        """The acquisition command running (``GetFineAttitude``, ...), or ``None``."""
        return self._acquisition

    @property
    def camera_request(self) -> PancamRequest | None:
        """The Pancam image a camera mode is waiting for, or ``None``."""
        return None if self._procedure is None else self._procedure.request

    @property
    def mast(self) -> tuple[float, float] | None:
        """Mast ``(az_rad, el_rad)`` if a camera mode left it on the sun, else ``None``."""
        return self._mast

    @property
    def busy(self) -> bool:
        """True while a mode that ends by itself (acquisition, check, gyrocompass) runs."""
        return self._mode not in (NateMode.IDLE, NateMode.ARTICULATE, NateMode.MOBILITY)

    @property
    def wait_hint_s(self) -> float:
        """How long the caller may aggregate IMU data before the next ``step`` matters, s:
        one cycle in the 8 Hz modes, until the image time in a camera mode, the rest of
        the span when gyrocompassing, ``inf`` when Idle."""
        if self._mode in _8HZ_MODES or (self._mode is NateMode.SUNGAZE and self._procedure is None):
            return CONTROL_DT_S
        request = self.camera_request
        if request is not None:
            return max(request.not_before_t_s - self._t_s, 0.0)
        if self._mode is NateMode.GYROCOMPASS:
            return max(self._gyro_span_s - self._gyro_sum_s, 0.0)
        return math.inf

    # ---- IVP ------------------------------------------------------------------------

    def sun_elevation_rad(self, t_s: float | None = None) -> float:
        """IVP's sun elevation at ``t_s`` (default: now), rad."""
        s = self.sun_ll_at(self._t_s if t_s is None else t_s)
        return math.asin(max(-1.0, min(1.0, -float(s[2]))))

    def point_hga(self) -> HgaCommand:
        """Point the HGA at Earth with the current estimate and IVP (sec. 1)."""
        earth = earth_ll(self._t_s, self._lat_rad, self._lon_east_rad)
        return point_hga(self._q_b_ll, earth)

    # ---- commands -----------------------------------------------------------------

    def _require(self, command: str, *allowed: NateMode) -> None:
        if self._mode not in allowed:
            names = ", ".join(m.value for m in allowed)
            raise ValueError(f"{command}: refused in mode {self._mode.value} (allowed: {names})")

    def _require_sun(self, command: str) -> None:
        elev = self.sun_elevation_rad()
        limit = self._params.min_sun_elevation_rad
        if elev < limit:
            raise ValueError(
                f"{command}: refused, the sun is {math.degrees(elev):.1f} deg high, below the "
                f"{math.degrees(limit):.1f} deg minimum (min_sun_elevation_rad)"
            )

    def nadir_update(self, window_s: float | None = None) -> None:
        """Start a Nadir Update (sec. 2.2.1) over ``window_s`` (default the parameter)."""
        self._require("nadir_update", NateMode.IDLE)
        nadir = nadir_params_for(self._params.nadir, window_s, None)
        self._start_nadir_update(nadir)

    def nadir_check(
        self, window_s: float | None = None, tolerance_deg: float | None = None
    ) -> None:
        """Start a Nadir Check (sec. 2.3.1); ``tolerance_deg`` in (0, 180) overrides the
        parameter's tolerance for this check."""
        self._require("nadir_check", NateMode.IDLE)
        nadir = nadir_params_for(self._params.nadir, window_s, tolerance_deg)
        self._averager = AccelAverager(nadir)
        self._check_tolerance_rad = nadir.check_tolerance_rad
        self._mode = NateMode.NADIR_CHECK

    def sunfind(self) -> None:
        """Start a Sunfind (sec. 2.2.2): search, confirm, heading update."""
        self._require("sunfind", NateMode.IDLE)
        self._require_sun("sunfind")
        self._start_sunfind()

    def sungaze(self, use_gravity: bool | None = None) -> None:
        """Start a Sungaze (sec. 2.2.3) with the mast where it is (on the sun after a
        Sunfind or Suncheck; anywhere else it will see no sun and fail at the timer).
        ``use_gravity`` overrides the parameter for the gravity variation."""
        self._require("sungaze", NateMode.IDLE)
        if use_gravity is not None and not isinstance(use_gravity, bool):
            raise ValueError(f"use_gravity: must be a bool, got {use_gravity!r}")
        self._require_sun("sungaze")
        gravity = self._params.sungaze.use_gravity if use_gravity is None else use_gravity
        self._start_sungaze(gravity)

    def suncheck(self, tolerance_deg: float | None = None) -> None:
        """Start a Suncheck (sec. 2.3.2); ``tolerance_deg`` in (0, 180) overrides the
        parameter for this check."""
        self._require("suncheck", NateMode.IDLE)
        params = self._params.suncheck
        if tolerance_deg is not None:
            if not (is_real_number(tolerance_deg) and 0.0 < tolerance_deg < 180.0):
                raise ValueError(f"tolerance_deg: must be in (0, 180), got {tolerance_deg!r}")
            params = SuncheckParams(math.radians(tolerance_deg))
        self._require_sun("suncheck")
        self._start_suncheck(params)

    def get_tilt_attitude(self) -> None:
        """GetTiltAttitude (sec. 2.2.4): a Nadir Update."""
        self._require("get_tilt_attitude", NateMode.IDLE)
        self._acquire_sequence("GetTiltAttitude", [NateMode.NADIR_UPDATE])

    def get_coarse_attitude(self) -> None:
        """GetCoarseAttitude (sec. 2.2.4): Nadir Update, then Sunfind unless it failed."""
        self._require("get_coarse_attitude", NateMode.IDLE)
        self._require_sun("get_coarse_attitude")
        self._acquire_sequence("GetCoarseAttitude", [NateMode.NADIR_UPDATE, NateMode.SUNFIND])

    def get_fine_attitude(self) -> None:
        """GetFineAttitude (sec. 2.2.4): Nadir Update, Sunfind, Sungaze; abort on failure."""
        self._require("get_fine_attitude", NateMode.IDLE)
        self._require_sun("get_fine_attitude")
        steps = [NateMode.NADIR_UPDATE, NateMode.SUNFIND, NateMode.SUNGAZE]
        self._acquire_sequence("GetFineAttitude", steps)

    def suncheck_sungaze(self) -> None:
        """Suncheck then Sungaze as one command: sec. 4's practice, sec. 5's wish (module
        docstring: Sungaze follows a Suncheck that saw the sun, passed or not)."""
        self._require("suncheck_sungaze", NateMode.IDLE)
        self._require_sun("suncheck_sungaze")
        self._acquire_sequence("SuncheckSungaze", [NateMode.SUNCHECK, NateMode.SUNGAZE])

    def gyrocompass(self, duration_s: float | None = None) -> None:
        """Gyrocompass at rest over ``duration_s`` (default the parameter; sec. 5)."""
        self._require("gyrocompass", NateMode.IDLE)
        span = self._params.gyrocompass_duration_s if duration_s is None else duration_s
        if not (is_real_number(span) and math.isfinite(span) and span > 0.0):
            raise ValueError(f"duration_s: must be positive and finite, got {duration_s!r}")
        self._gyro_sum_b, self._gyro_sum_s, self._gyro_span_s = np.zeros(3), 0.0, float(span)
        self._mode = NateMode.GYROCOMPASS

    def articulate(self) -> None:
        """Enter Articulate (sec. 2.4.1); the first window is the reference vertical."""
        self._require("articulate", NateMode.IDLE)
        self._averager = self._articulate_averager()
        self._ref_down_ll = None
        self._q_entry_b_ll = self._q_b_ll.copy()
        self._mode = NateMode.ARTICULATE

    def mobility(
        self,
        drive: DriveCommand | None = None,
        use_gyros: bool = True,
        wheel_angle_rad: ArrayLike | None = None,
    ) -> None:
        """Enter Mobility (sec. 2.4.2). ``use_gyros=False`` is the off-nominal submode that
        propagates attitude from wheel odometry. ``wheel_angle_rad`` (6,) optionally gives
        the encoder reference at entry."""
        self._require("mobility", NateMode.IDLE)
        cmd = checked_drive(drive if drive is not None else DriveCommand())
        if not isinstance(use_gyros, bool):
            raise ValueError(f"use_gyros: must be a bool, got {use_gyros!r}")
        ref = (
            None
            if wheel_angle_rad is None
            else finite_vector(wheel_angle_rad, "wheel_angle_rad", 6)
        )
        self._drive, self._use_gyros, self._last_wheel_rad = cmd, use_gyros, ref
        self._mode = NateMode.MOBILITY

    def set_drive(self, drive: DriveCommand) -> None:
        """Change the commanded drive kind while in Mobility."""
        self._require("set_drive", NateMode.MOBILITY)
        self._drive = checked_drive(drive)

    def stop(self) -> None:
        """Leave Articulate or Mobility for Idle. Driving or articulating moves the mast's
        base, so the camera is no longer known to be on the sun."""
        self._require("stop", NateMode.ARTICULATE, NateMode.MOBILITY)
        self._averager, self._ref_down_ll = None, None
        self._mast = None
        self._mode = NateMode.IDLE

    def plant_site(self) -> int:
        """Plant a new Site here (sec. 1): position to the origin; returns the new index."""
        self._require("plant_site", NateMode.IDLE)
        new = self._sites.plant(self._p_s)
        self._p_s = np.zeros(3)
        return new.index

    def set_params(self, **changes: object) -> None:
        """Change top-level parameters (Idle only), e.g. ``set_params(fine_to_coarse_s=600.0)``."""
        self._require("set_params", NateMode.IDLE)
        try:
            new = dataclasses.replace(self._params, **changes)  # type: ignore[arg-type]
        except TypeError as exc:
            raise ValueError(f"set_params: {exc}") from exc
        self._params = new
        self._check_tolerance_rad = new.nadir.check_tolerance_rad

    def set_param(self, path: str, value: object) -> None:
        """Set one parameter by dotted path (Idle only), e.g. ``"sungaze.timer_s"``; SI
        units. The owning dataclass validates the value; a refusal changes nothing."""
        self._require("set_param", NateMode.IDLE)
        self._params = replace_param(self._params, path, value)
        self._check_tolerance_rad = self._params.nadir.check_tolerance_rad

    def load_attitude(self, q_b_ll: ArrayLike, aqf: AttitudeQuality) -> None:
        """Replace the estimate and flag (Idle only): a ground override. A Fine attitude
        resets the gyro counter (sec. 2.2.3) and the IMU integration time (sec. 4)."""
        self._require("load_attitude", NateMode.IDLE)
        q = _unit_q(q_b_ll, "q_b_ll")
        if not isinstance(aqf, AttitudeQuality):
            raise ValueError(f"aqf: must be an AttitudeQuality, got {aqf!r}")
        self._set_attitude(q, aqf)

    def visual_odometry_update(self, p_s: ArrayLike, q_b_ll: ArrayLike | None = None) -> None:
        """Adopt a visual odometry position in the current Site, and the attitude when
        given (Idle only, between drive steps: Cheng, Maimone and Matthies 2005 sec. 4, where VO
        corrected the pose SAPP propagated from the wheels and gyros). The flag and counters stay:
        VO measures the motion since the previous image pair, so an attitude it updates is
        no better known in absolute terms than the one it started from."""
        self._require("visual_odometry_update", NateMode.IDLE)
        p = np.asarray(p_s, dtype=np.float64)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"p_s: must be a finite 3-vector, got {p_s!r}")
        if q_b_ll is not None:
            self._q_b_ll = _unit_q(q_b_ll, "q_b_ll")
        self._p_s = p.copy()

    # ---- the control cycle --------------------------------------------------------

    def step(
        self,
        imu: ImuSample,
        encoders: EncoderSample | None = None,
        image: ArrayLike | None = None,
    ) -> NateOutput:
        """One control cycle (8 Hz): feed the IMU sample (and in Mobility the encoders).

        In a camera mode the IMU sample may span the wait until the image (``wait_hint_s``)
        and ``image`` is the Pancam frame (H, W) taken at the end of it, at the pointing
        ``camera_request`` asked for.
        """
        d_theta_b = finite_vector(imu.delta_angle_b, "imu.delta_angle_b", 3)
        dv_b = np.array(imu.delta_velocity_b, dtype=np.float64)
        if dv_b.shape != (3,):
            raise ValueError(f"imu.delta_velocity_b: must have shape (3,), got {dv_b.shape}")
        dt = float(imu.dt_s)
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"imu.dt_s: must be positive and finite, got {imu.dt_s!r}")
        enc = None
        if encoders is not None:
            enc = (
                finite_vector(encoders.wheel_angle_rad, "encoders.wheel_angle_rad", N_WHEELS),
                finite_vector(encoders.steer_rad, "encoders.steer_rad", N_WHEELS),
            )
        request = self.camera_request
        if image is not None and request is None:
            raise ValueError("image: no camera mode is waiting for an image")

        if (
            image is not None
            and request is not None
            and self._t_s + dt < request.not_before_t_s - 1e-6
        ):
            raise ValueError(
                f"image: taken at {self._t_s + dt:.3f} s, before the requested "
                f"{request.not_before_t_s:.3f} s"
            )
        return self._cycle(d_theta_b, dv_b, dt, bool(imu.valid), enc, image, request)

    def step_series(self, imu: ImuSeries, encoders: EncoderSeries | None = None) -> NateSeries:
        """``step`` through ``N`` cycles (``imu``; in Mobility the ``encoders`` of the same
        cycles), no images: a drive segment, an 8 Hz wait. The samples are checked once, by
        the series; in Mobility the cycles run at once (``estimation.sapp.mobility``)."""
        if encoders is not None and len(encoders) != len(imu):
            raise ValueError(f"encoders: {len(encoders)} rows for {len(imu)} IMU cycles")
        if self._mode is NateMode.MOBILITY:
            return self._mobility_series(imu, encoders)
        cycles = [
            self._cycle(
                imu.delta_angle_b[k],
                imu.delta_velocity_b[k],
                float(imu.dt_s[k]),
                bool(imu.valid[k]),
                None if encoders is None else (encoders.wheel_angle_rad[k], encoders.steer_rad[k]),
                None,
                None,
            )
            for k in range(len(imu))
        ]
        return NateSeries.of_outputs(cycles)

    def _cycle(
        self,
        d_theta_b: FloatArray,
        dv_b: FloatArray,
        dt: float,
        valid: bool,
        enc: tuple[FloatArray, FloatArray] | None,
        image: ArrayLike | None,
        request: PancamRequest | None,
    ) -> NateOutput:
        """One control cycle on checked samples (``step``)."""
        self._t_s += dt
        self._events = []
        completed: Completed | None = None
        mode = self._mode
        if mode in (NateMode.NADIR_UPDATE, NateMode.NADIR_CHECK):
            completed = self._acquire(dv_b, dt, valid)
        elif mode is NateMode.ARTICULATE:
            self._propagate_gyros(d_theta_b, dt, valid)
            self._articulate_tilt(dv_b, dt, valid)
            self._count(dt)
        elif mode is NateMode.MOBILITY:
            if self._use_gyros:
                self._propagate_gyros(d_theta_b, dt, valid)  # sec. 2.5: attitude ...
            if enc is not None:
                self._odometry(*enc)  # ... then position with the fresh attitude
            self._count(dt)
        elif mode is NateMode.GYROCOMPASS:
            completed = self._gyrocompass_step(d_theta_b, dt, valid)
        elif mode is NateMode.SUNGAZE and self._procedure is None:
            self._sungaze_gravity_window(dv_b, dt, valid)
        elif mode in _CAMERA_MODES and image is not None:
            assert request is not None and self._procedure is not None
            completed = self._camera_image(request, image)
        if completed is not None:
            self._after_primitive(completed)

        x, y, z, w = self._q_b_ll.tolist()
        f_x, f_y, f_z = dv_b.tolist()
        tilt_est, tilt_accel = cycle_tilts_deg((x, y, z, w), (f_x, f_y, f_z), dt, valid)
        return NateOutput(
            q_b_ll=self._q_b_ll.copy(),
            tilt_est_deg=tilt_est,
            tilt_accel_deg=tilt_accel,
            p_s=self._p_s.copy(),
            site_index=self._sites.current.index,
            aqf=self._aqf,
            mode=self._mode,
            imu_integration_s=self._imu_integration_s,
            gyro_counter_s=self._gyro_counter_s,
            completed=completed,
            t_s=self._t_s,
            acquisition=self._acquisition,
            camera_request=self.camera_request,
            events=tuple(self._events),
        )
