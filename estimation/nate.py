"""The NATE core: SAPP's Navigation/Attitude Estimator state, without the camera modes.

Ali et al. 2005, "Attitude and Position Estimation on the Mars Exploration Rovers" (seed
000): Figure 1 (the NATE modes), sec. 2.1 (Attitude Quality Flag), 2.2.1 (Nadir Update,
eq. 1), 2.3 and 2.3.1 (Nadir Check), 2.4 (propagation never improves the flag; Fine drops
to Coarse after 15 min of gyro counter), 2.4.1 (Articulate: gyros with Mars rotation
subtracted, tilt corrections against the reference vertical), 2.4.2 (Mobility, and its
off-nominal wheel-odometry attitude submode), 2.5 (position, eqs. 5-7), sec. 1 / Table 1
(Site frames) and sec. 4 (the operators' "IMU integration time since the last Sungaze").
The math lives in ``nadir``, ``gyro_propagation``, ``wheel_odometry`` and ``site_frames``;
this module sequences it, one 8 Hz control cycle per ``Nate.step``.

Design. ``Nate.step(imu, encoders)`` takes only sensor data (``ImuSample``: delta angles,
delta velocities, dt, validity; ``EncoderSample``: wheel angles since power-on, steering
angles); commands are methods (``nadir_update``, ``nadir_check``, ``articulate``,
``mobility``, ``set_drive``, ``stop``, ``plant_site``, ``set_params``, ``load_attitude``).
A command not allowed in the current mode, or with an out-of-range parameter, raises
``ValueError`` with the reason and changes nothing (every check runs before any state is
touched). Documented choices (the paper leaves these to the ground):

- Commands are accepted in Idle only, except ``stop`` (Articulate, Mobility) and
  ``set_drive`` (Mobility). Nadir Update / Nadir Check end by themselves and return to Idle.
- In Idle and the acquisition modes the rover is stationary and the estimate is not
  propagated (the estimate changes only when an acquisition mode exits, sec. 2.4).
- The gyro counter counts seconds (the sum of the IMU ``dt`` of every Articulate or Mobility
  cycle, sec. 2.4); the IMU integration time counts the seconds the gyros were actually
  integrated, so the two differ only in Mobility's wheel-odometry submode. Both are reset
  only by a Fine attitude (Sungaze; here ``load_attitude(..., FINE)``, the seam for it).
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

Seams for the camera modes (next step, not here): ``NateMode`` already names Sunfind,
Sungaze and Suncheck; they will enter like Nadir Update (from Idle), be driven by camera
results rather than ``step``'s IMU data, and finish through ``load_attitude`` (Sunfind:
Coarse; Sungaze: Fine, which resets both counters) or by setting the flag alone (their
failures, and Suncheck).
The acquisition macros of sec. 2.2.4 (GetTiltAttitude, ...) also belong to that step.

>>> nate = Nate(lat_rad=math.radians(-14.57))
>>> nate.nadir_update()
>>> level = ImuSample(np.zeros(3), np.array([0.0, 0.0, -3.711 / 8]), 0.125)
>>> out = [nate.step(level) for _ in range(80)][-1]
>>> out.aqf.paper_name, out.mode.name, round(out.tilt_est_deg, 9)
('TiltOnly', 'IDLE', 0.0)
"""

from __future__ import annotations

import dataclasses
import enum
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.aqf import AttitudeQuality
from estimation.gyro_propagation import propagate_gyro
from estimation.ivp import mars_rotation_ll
from estimation.nadir import (
    AccelAverager,
    NadirCheckResult,
    NadirParams,
    NadirUpdateResult,
    check_average,
    nadir_check,
    nadir_update,
    tilt_from_specific_force_rad,
    tilt_of_estimate_rad,
)
from estimation.quaternion import quat_canonical, quat_conjugate, quat_from_rotvec, quat_multiply
from estimation.site_frames import SiteChain
from estimation.wheel_odometry import (
    N_WHEELS,
    DriveKind,
    arc_centre_b,
    odometry_step,
    propagate_heading,
    propagate_position,
)

FloatArray = NDArray[np.float64]

IDENTITY_Q = np.array([0.0, 0.0, 0.0, 1.0])
FINE_TO_COARSE_S = 15.0 * 60.0  # seed 000 sec. 2.4: "currently 15 minutes" of propagation


class NateMode(enum.Enum):
    """NATE modes (seed 000 Figure 1). The camera modes are named but not implemented yet."""

    IDLE = "Idle"
    NADIR_UPDATE = "NadirUpdate"
    NADIR_CHECK = "NadirCheck"
    ARTICULATE = "Articulate"
    MOBILITY = "Mobility"
    SUNFIND = "Sunfind"  # not implemented yet (camera)
    SUNGAZE = "Sungaze"  # not implemented yet (camera)
    SUNCHECK = "Suncheck"  # not implemented yet (camera)


@dataclass(frozen=True)
class NateParams:
    """Ground-settable NATE parameters; paper values as defaults where the paper gives one.

    ``fine_to_coarse_s``: gyro-counter tolerance after which Fine drops to Coarse (sec. 2.4,
    15 min). ``nadir``: Nadir Update / Check parameters (10 s window, sec. 2.2.1; the rest
    documented in ``estimation.nadir``). ``articulate_window_s``: length of the reference
    vertical and of each later accelerometer average in Articulate (documented choice: the
    Nadir Update window, 10 s; the paper says "regular accelerometer averages").
    """

    fine_to_coarse_s: float = FINE_TO_COARSE_S
    nadir: NadirParams = field(default_factory=NadirParams)
    articulate_window_s: float = 10.0  # documented choice, as the 10 s of sec. 2.2.1

    def __post_init__(self) -> None:
        for name in ("fine_to_coarse_s", "articulate_window_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}: must be positive and finite, got {value!r}")
        if not isinstance(self.nadir, NadirParams):
            raise ValueError(f"nadir: must be NadirParams, got {type(self.nadir).__name__}")


@dataclass(frozen=True)
class ImuSample:
    """One control cycle of IMU data: ``delta_angle_b`` (3,) rad and ``delta_velocity_b``
    (3,) m/s in body axes over ``dt_s`` (> 0) seconds; ``valid`` the driver's flag."""

    delta_angle_b: FloatArray
    delta_velocity_b: FloatArray
    dt_s: float
    valid: bool = True


@dataclass(frozen=True)
class EncoderSample:
    """Mobility sensors at the end of the cycle: ``wheel_angle_rad`` (6,) each wheel's
    rotation since power-on (LF, LM, LR, RF, RM, RR; forwards positive) and ``steer_rad``
    (6,) the steering angles in the same order (middle wheels 0; ``steer_six``)."""

    wheel_angle_rad: FloatArray
    steer_rad: FloatArray


@dataclass(frozen=True)
class DriveCommand:
    """What the driving software commands (sec. 2.5): ``kind`` and, for ``ARC``, the signed
    radius of the body origin's path ``radius_m`` (> 0 centre on the right, as
    ``wheel_odometry.arc_centre_b``)."""

    kind: DriveKind = DriveKind.STRAIGHT
    radius_m: float = 0.0


@dataclass(frozen=True)
class NateOutput:
    """NATE's telemetry after one control cycle.

    ``q_b_ll`` (4,) the estimate; ``tilt_est_deg`` the tilt of the estimate and
    ``tilt_accel_deg`` the tilt from this cycle's single accelerometer reading (NaN if the
    sample is unusable), degrees; ``p_s`` (3,) m in Site ``site_index``; ``aqf``; ``mode``
    (after the cycle); ``imu_integration_s`` s of gyro integration since the last Fine
    attitude (sec. 4); ``gyro_counter_s`` the gyro counter, s (sec. 2.4); ``completed``
    the result of a Nadir Update / Check that finished this cycle, else ``None``.
    """

    q_b_ll: FloatArray
    tilt_est_deg: float
    tilt_accel_deg: float
    p_s: FloatArray
    site_index: int
    aqf: AttitudeQuality
    mode: NateMode
    imu_integration_s: float
    gyro_counter_s: float
    completed: NadirUpdateResult | NadirCheckResult | None = None


def _vec(value: ArrayLike, name: str, n: int) -> FloatArray:
    try:
        out = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: must be numeric with shape ({n},)") from exc
    if out.shape != (n,) or not np.all(np.isfinite(out)):
        raise ValueError(f"{name}: must be finite with shape ({n},), got {out.shape}")
    return out


def _unit_q(value: ArrayLike, name: str) -> FloatArray:
    q = _vec(value, name, 4)
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > 1e-6:
        raise ValueError(f"{name}: must be a unit quaternion, norm {norm:g}")
    return quat_canonical(q / norm)


def _rotation_onto(u_b: FloatArray, v_b: FloatArray) -> FloatArray:
    """``δq^B`` turning unit ``u_b`` onto unit ``v_b`` about ``u_b × v_b`` (sec. 2.2.1, the
    form of eq. 1's correction); identity if parallel (opposite cannot occur for a relative
    tilt of a settled rover; it also returns identity rather than guess an axis)."""
    axis = np.cross(u_b, v_b)  # sec. 2.2.1: about n^B x g^B
    angle = math.atan2(float(np.linalg.norm(axis)), float(np.dot(u_b, v_b)))
    if float(np.linalg.norm(axis)) < 1e-15:
        return IDENTITY_Q.copy()
    return quat_from_rotvec(axis / np.linalg.norm(axis) * angle)


class Nate:
    """SAPP's NATE state machine without the camera modes (module docstring).

    ``lat_rad``: the site's planetographic latitude, for IVP's Mars rotation in LL.
    """

    def __init__(self, lat_rad: float, params: NateParams | None = None) -> None:
        self._omega_mars_ll = mars_rotation_ll(lat_rad)  # sec. 2.4.1, from IVP
        self._params = params if params is not None else NateParams()
        self._q_b_ll = IDENTITY_Q.copy()
        self._p_s = np.zeros(3)
        self._sites = SiteChain()
        self._aqf = AttitudeQuality.UNKNOWN  # sec. 2.1: "the initial value after landing"
        self._mode = NateMode.IDLE
        self._gyro_counter_s = 0.0
        self._imu_integration_s = 0.0
        self._averager: AccelAverager | None = None
        self._check_tolerance_rad = self._params.nadir.check_tolerance_rad
        self._ref_down_ll: FloatArray | None = None  # Articulate's reference vertical
        self._q_entry_b_ll = IDENTITY_Q.copy()  # estimate at Articulate entry
        self._drive = DriveCommand()
        self._use_gyros = True
        self._last_wheel_rad: FloatArray | None = None

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

    # ---- commands -----------------------------------------------------------------

    def _require(self, command: str, *allowed: NateMode) -> None:
        if self._mode not in allowed:
            names = ", ".join(m.value for m in allowed)
            raise ValueError(f"{command}: refused in mode {self._mode.value} (allowed: {names})")

    def nadir_update(self, window_s: float | None = None) -> None:
        """Start a Nadir Update (sec. 2.2.1) over ``window_s`` (default the parameter)."""
        self._require("nadir_update", NateMode.IDLE)
        nadir = self._nadir_params(window_s, None)
        self._averager = AccelAverager(nadir)
        self._mode = NateMode.NADIR_UPDATE

    def nadir_check(
        self, window_s: float | None = None, tolerance_deg: float | None = None
    ) -> None:
        """Start a Nadir Check (sec. 2.3.1); ``tolerance_deg`` in (0, 180) overrides the
        parameter's tolerance for this check."""
        self._require("nadir_check", NateMode.IDLE)
        nadir = self._nadir_params(window_s, tolerance_deg)
        self._averager = AccelAverager(nadir)
        self._check_tolerance_rad = nadir.check_tolerance_rad
        self._mode = NateMode.NADIR_CHECK

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
        cmd = self._check_drive(drive if drive is not None else DriveCommand())
        if not isinstance(use_gyros, bool):
            raise ValueError(f"use_gyros: must be a bool, got {use_gyros!r}")
        ref = None if wheel_angle_rad is None else _vec(wheel_angle_rad, "wheel_angle_rad", 6)
        self._drive, self._use_gyros, self._last_wheel_rad = cmd, use_gyros, ref
        self._mode = NateMode.MOBILITY

    def set_drive(self, drive: DriveCommand) -> None:
        """Change the commanded drive kind while in Mobility."""
        self._require("set_drive", NateMode.MOBILITY)
        self._drive = self._check_drive(drive)

    def stop(self) -> None:
        """Leave Articulate or Mobility for Idle."""
        self._require("stop", NateMode.ARTICULATE, NateMode.MOBILITY)
        self._averager, self._ref_down_ll = None, None
        self._mode = NateMode.IDLE

    def plant_site(self) -> int:
        """Plant a new Site here (sec. 1): position to the origin; returns the new index."""
        self._require("plant_site", NateMode.IDLE)
        new = self._sites.plant(self._p_s)
        self._p_s = np.zeros(3)
        return new.index

    def set_params(self, **changes: object) -> None:
        """Change parameters (Idle only), e.g. ``set_params(fine_to_coarse_s=600.0)``."""
        self._require("set_params", NateMode.IDLE)
        try:
            new = dataclasses.replace(self._params, **changes)  # type: ignore[arg-type]
        except TypeError as exc:
            raise ValueError(f"set_params: {exc}") from exc
        self._params = new
        self._check_tolerance_rad = new.nadir.check_tolerance_rad

    def load_attitude(self, q_b_ll: ArrayLike, aqf: AttitudeQuality) -> None:
        """Replace the estimate and flag (Idle only): the seam the camera modes will use
        (Sunfind: Coarse; Sungaze: Fine), and a ground override. A Fine attitude resets the
        gyro counter (sec. 2.2.3) and the IMU integration time (sec. 4)."""
        self._require("load_attitude", NateMode.IDLE)
        q = _unit_q(q_b_ll, "q_b_ll")
        if not isinstance(aqf, AttitudeQuality):
            raise ValueError(f"aqf: must be an AttitudeQuality, got {aqf!r}")
        self._q_b_ll, self._aqf = q, aqf
        if aqf is AttitudeQuality.FINE:
            self._gyro_counter_s = 0.0
            self._imu_integration_s = 0.0

    def _nadir_params(self, window_s: float | None, tolerance_deg: float | None) -> NadirParams:
        nadir = self._params.nadir
        if window_s is not None:
            if not (math.isfinite(window_s) and window_s > 0.0):
                raise ValueError(f"window_s: must be positive and finite, got {window_s!r}")
            nadir = dataclasses.replace(nadir, window_s=float(window_s))
        if tolerance_deg is not None:
            if not (math.isfinite(tolerance_deg) and 0.0 < tolerance_deg < 180.0):
                raise ValueError(f"tolerance_deg: must be in (0, 180), got {tolerance_deg!r}")
            nadir = dataclasses.replace(nadir, check_tolerance_rad=math.radians(tolerance_deg))
        return nadir

    def _articulate_averager(self) -> AccelAverager:
        p = dataclasses.replace(self._params.nadir, window_s=self._params.articulate_window_s)
        return AccelAverager(p)

    @staticmethod
    def _check_drive(drive: DriveCommand) -> DriveCommand:
        if not isinstance(drive, DriveCommand) or not isinstance(drive.kind, DriveKind):
            raise ValueError(f"drive: must be a DriveCommand, got {drive!r}")
        if not math.isfinite(drive.radius_m):
            raise ValueError(f"drive: radius_m must be finite, got {drive.radius_m!r}")
        if drive.kind is DriveKind.ARC and drive.radius_m == 0.0:
            raise ValueError("drive: an ARC needs a non-zero radius_m (use TURN_IN_PLACE)")
        return drive

    # ---- the control cycle --------------------------------------------------------

    def step(self, imu: ImuSample, encoders: EncoderSample | None = None) -> NateOutput:
        """One control cycle (8 Hz): feed the IMU sample (and in Mobility the encoders)."""
        d_theta_b = _vec(imu.delta_angle_b, "imu.delta_angle_b", 3)
        dv_b = np.array(imu.delta_velocity_b, dtype=np.float64)
        if dv_b.shape != (3,):
            raise ValueError(f"imu.delta_velocity_b: must have shape (3,), got {dv_b.shape}")
        dt = float(imu.dt_s)
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"imu.dt_s: must be positive and finite, got {imu.dt_s!r}")
        enc = None
        if encoders is not None:
            enc = (
                _vec(encoders.wheel_angle_rad, "encoders.wheel_angle_rad", N_WHEELS),
                _vec(encoders.steer_rad, "encoders.steer_rad", N_WHEELS),
            )

        completed: NadirUpdateResult | NadirCheckResult | None = None
        mode = self._mode
        if mode in (NateMode.NADIR_UPDATE, NateMode.NADIR_CHECK):
            completed = self._acquire(dv_b, dt, bool(imu.valid))
        elif mode is NateMode.ARTICULATE:
            self._propagate_gyros(d_theta_b, dt)
            self._articulate_tilt(dv_b, dt, bool(imu.valid))
            self._count(dt)
        elif mode is NateMode.MOBILITY:
            if self._use_gyros:
                self._propagate_gyros(d_theta_b, dt)  # sec. 2.5: attitude first ...
            if enc is not None:
                self._odometry(*enc)  # ... then position with the fresh attitude
            self._count(dt)

        tilt_accel = math.nan
        if imu.valid and np.all(np.isfinite(dv_b)) and float(np.linalg.norm(dv_b)) > 0.0:
            tilt_accel = math.degrees(tilt_from_specific_force_rad(dv_b / dt))
        return NateOutput(
            q_b_ll=self._q_b_ll.copy(),
            tilt_est_deg=math.degrees(tilt_of_estimate_rad(self._q_b_ll)),
            tilt_accel_deg=tilt_accel,
            p_s=self._p_s.copy(),
            site_index=self._sites.current.index,
            aqf=self._aqf,
            mode=self._mode,
            imu_integration_s=self._imu_integration_s,
            gyro_counter_s=self._gyro_counter_s,
            completed=completed,
        )

    def _acquire(
        self, dv_b: FloatArray, dt: float, valid: bool
    ) -> NadirUpdateResult | NadirCheckResult | None:
        averager = self._averager
        assert averager is not None
        averager.add(dv_b, dt, valid)
        if not averager.full:
            return None
        average = averager.average()
        result: NadirUpdateResult | NadirCheckResult
        if self._mode is NateMode.NADIR_UPDATE:
            result = nadir_update(self._q_b_ll, average, self._params.nadir)  # eq. (1)
            self._q_b_ll = result.q_b_ll  # unchanged on failure (sec. 2.2.1)
        else:
            nadir = dataclasses.replace(
                self._params.nadir, check_tolerance_rad=self._check_tolerance_rad
            )
            result = nadir_check(self._q_b_ll, average, self._aqf, nadir)  # sec. 2.3.1
        self._aqf = result.aqf
        self._averager = None
        self._check_tolerance_rad = self._params.nadir.check_tolerance_rad
        self._mode = NateMode.IDLE
        return result

    def _propagate_gyros(self, d_theta_b: FloatArray, dt: float) -> None:
        q = propagate_gyro(self._q_b_ll, d_theta_b[None, :], dt, self._omega_mars_ll)[-1]
        self._q_b_ll = quat_canonical(q)  # sec. 2.4.1
        self._imu_integration_s += dt

    def _count(self, dt: float) -> None:
        self._gyro_counter_s += dt  # sec. 2.4: incremented each Articulate/Mobility cycle
        if (
            self._aqf is AttitudeQuality.FINE
            and self._gyro_counter_s > self._params.fine_to_coarse_s
        ):
            self._aqf = AttitudeQuality.COARSE  # sec. 2.4: Fine drops to Coarse

    def _articulate_tilt(self, dv_b: FloatArray, dt: float, valid: bool) -> None:
        averager = self._averager
        assert averager is not None
        averager.add(dv_b, dt, valid)
        if not averager.full:
            return
        average = averager.average()
        self._averager = self._articulate_averager()
        if check_average(average, self._params.nadir) is not None:
            return  # sanity check failed (sec. 2.2.1): no correction from this window
        if self._ref_down_ll is None:  # sec. 2.4.1: the reference vertical, kept in LL
            R_ll_b_entry = Rotation.from_quat(quat_conjugate(self._q_entry_b_ll))
            self._ref_down_ll = R_ll_b_entry.apply(average.down_b)
            return
        R_b_ll = Rotation.from_quat(self._q_b_ll)
        ref_b = R_b_ll.apply(self._ref_down_ll)  # reference with the latest estimate
        dq_b = _rotation_onto(ref_b, average.down_b)  # relative tilt, sec. 2.4.1
        q = quat_multiply(dq_b, self._q_b_ll)  # eq. (1)'s form: δq^B ⊗ q
        self._q_b_ll = quat_canonical(q / np.linalg.norm(q))

    def _q_s_b(self) -> FloatArray:
        """``q_s_b`` for wheel odometry: the Site has LL's orientation, so conj(q_b_ll)."""
        return quat_conjugate(self._q_b_ll)

    def _odometry(self, wheel_rad: FloatArray, steer_rad: FloatArray) -> None:
        last, self._last_wheel_rad = self._last_wheel_rad, wheel_rad
        if last is None:
            return  # first reading: the reference only
        drive = self._drive
        centre = arc_centre_b(drive.radius_m) if drive.kind is DriveKind.ARC else None
        step = odometry_step(drive.kind, wheel_rad - last, steer_rad, centre)  # eqs. (5)-(7)
        q_s_b = self._q_s_b()
        if not self._use_gyros:  # sec. 2.4.2 off-nominal submode: attitude from odometry
            q_s_b = propagate_heading(q_s_b, step.delta_heading_rad)
            self._q_b_ll = quat_canonical(quat_conjugate(q_s_b))
        self._p_s = propagate_position(self._p_s, q_s_b, step.delta_p_b)  # sec. 2.5
