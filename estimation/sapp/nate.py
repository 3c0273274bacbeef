"""The NATE state machine: SAPP's Navigation/Attitude Estimator (Ali et al. 2005 Figure 1).

Ali et al. 2005, "Attitude and Position Estimation on the Mars Exploration Rovers" (seed
000): Figure 1 (the NATE modes), sec. 2.1 (Attitude Quality Flag), 2.2.1 (Nadir Update,
eq. 1), 2.3 and 2.3.1 (Nadir Check), 2.4 (propagation never improves the flag; Fine drops
to Coarse after 15 min of gyro counter), 2.4.1 (Articulate: gyros with Mars rotation
subtracted, tilt corrections against the reference vertical), 2.4.2 (Mobility, and its
off-nominal wheel-odometry attitude submode), 2.5 (position, eqs. 5-7), sec. 1 / Table 1
(Site frames) and sec. 4 (the operators' "IMU integration time since the last Sungaze").
The math lives in ``nadir``, ``gyro_propagation``, ``wheel_odometry`` and ``site_frames``;
this module sequences it, one 8 Hz control cycle per ``Nate.step``.

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
import enum
import math
import numbers
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.camera_model import PANCAM, R_b_pancam
from estimation.events import Event, Severity, failure_severity
from estimation.ivp import earth_ll, mars_rotation_ll, sun_ll
from estimation.quaternion import quat_canonical, quat_conjugate, quat_from_rotvec, quat_multiply
from estimation.sapp.aqf import AttitudeQuality
from estimation.sapp.gyro_propagation import propagate_gyro
from estimation.sapp.gyrocompass import GyrocompassParams, GyrocompassResult, gyrocompass
from estimation.sapp.hga_pointing import HgaCommand, point_hga
from estimation.sapp.nadir import (
    AccelAverager,
    NadirCheckOutcome,
    NadirCheckResult,
    NadirParams,
    NadirUpdateResult,
    check_average,
    nadir_check,
    nadir_update,
    tilt_from_specific_force_rad,
    tilt_of_estimate_rad,
)
from estimation.sapp.site_frames import SiteChain
from estimation.sapp.sun_modes import (
    PancamRequest,
    Suncheck,
    SuncheckParams,
    Sunfind,
    SunfindParams,
    Sungaze,
    SungazeParams,
    SunResult,
)
from estimation.sapp.sunfind import SunFinderParams, find_sun
from estimation.sapp.wheel_odometry import (
    N_WHEELS,
    DriveKind,
    arc_centre_b,
    odometry_step,
    propagate_heading,
    propagate_position,
)

FloatArray = NDArray[np.float64]

IDENTITY_Q = np.array([0.0, 0.0, 0.0, 1.0])
FINE_TO_COARSE_S = 15.0 * 60.0  # Ali et al. 2005 sec. 2.4: "currently 15 minutes" of propagation


class NateMode(enum.Enum):
    """NATE modes (Ali et al. 2005 Figure 1, plus sec. 5's gyrocompassing)."""

    IDLE = "Idle"
    NADIR_UPDATE = "NadirUpdate"
    NADIR_CHECK = "NadirCheck"
    ARTICULATE = "Articulate"
    MOBILITY = "Mobility"
    SUNFIND = "Sunfind"
    SUNGAZE = "Sungaze"
    SUNCHECK = "Suncheck"
    GYROCOMPASS = "Gyrocompass"


_CAMERA_MODES = (NateMode.SUNFIND, NateMode.SUNGAZE, NateMode.SUNCHECK)
_8HZ_MODES = (NateMode.NADIR_UPDATE, NateMode.NADIR_CHECK, NateMode.ARTICULATE, NateMode.MOBILITY)
CONTROL_DT_S = 0.125  # 8 Hz (Ali et al. 2005 sec. 2.4)
# A Nadir Check that fails drops the flag (error); one that aborts could not judge (warning).
_CHECK_SEVERITY: dict[NadirCheckOutcome, Severity] = {
    NadirCheckOutcome.PASSED: "info",
    NadirCheckOutcome.FAILED: "error",
    NadirCheckOutcome.ABORTED: "warning",
}


@dataclass(frozen=True)
class NateParams:
    """Ground-settable NATE parameters; paper values as defaults where the paper gives one.

    ``fine_to_coarse_s``: gyro-counter tolerance after which Fine drops to Coarse (sec. 2.4,
    15 min). ``nadir``: Nadir Update / Check parameters (10 s window, sec. 2.2.1; the rest
    documented in ``estimation.sapp.nadir``). ``articulate_window_s``: length of the reference
    vertical and of each later accelerometer average in Articulate (documented choice: the
    Nadir Update window, 10 s; the paper says "regular accelerometer averages").
    ``sunfind``, ``sungaze``, ``suncheck``: the camera modes (``estimation.sapp.sun_modes``).
    ``min_sun_elevation_rad``: the camera modes' sanity check (5 deg, documented choice:
    lower, the sun's image is dimmed and refracted by the long path through the dust).
    ``gyrocompass``: its error model and refusal limits; ``gyrocompass_duration_s`` the
    default span (30 min: ARW term 0.3 deg at Gusev, far under the bias term);
    ``gyrocompass_coarse_3sigma_rad`` and ``gyrocompass_rate_tolerance`` (module doc).
    """

    fine_to_coarse_s: float = FINE_TO_COARSE_S
    nadir: NadirParams = field(default_factory=NadirParams)
    articulate_window_s: float = 10.0  # documented choice, as the 10 s of sec. 2.2.1
    sunfind: SunfindParams = field(default_factory=SunfindParams)
    sungaze: SungazeParams = field(default_factory=SungazeParams)
    suncheck: SuncheckParams = field(default_factory=SuncheckParams)
    min_sun_elevation_rad: float = math.radians(5.0)
    gyrocompass: GyrocompassParams = field(default_factory=GyrocompassParams)
    gyrocompass_duration_s: float = 1800.0
    gyrocompass_coarse_3sigma_rad: float = math.radians(8.0)
    gyrocompass_rate_tolerance: float = 0.2  # fraction of Ω cos φ, documented choice
    finder: SunFinderParams = field(default_factory=SunFinderParams)

    def __post_init__(self) -> None:
        for name in (
            "fine_to_coarse_s",
            "articulate_window_s",
            "gyrocompass_duration_s",
            "gyrocompass_coarse_3sigma_rad",
            "gyrocompass_rate_tolerance",
        ):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}: must be positive and finite, got {value!r}")
        if not (
            isinstance(self.min_sun_elevation_rad, (int, float))
            and -0.5 * math.pi < self.min_sun_elevation_rad < 0.5 * math.pi
        ):
            value = self.min_sun_elevation_rad
            raise ValueError(f"min_sun_elevation_rad: must be in (-pi/2, pi/2), got {value!r}")
        for name, kind in (
            ("nadir", NadirParams),
            ("sunfind", SunfindParams),
            ("sungaze", SungazeParams),
            ("suncheck", SuncheckParams),
            ("gyrocompass", GyrocompassParams),
            ("finder", SunFinderParams),
        ):
            if not isinstance(getattr(self, name), kind):
                raise ValueError(f"{name}: must be {kind.__name__}")


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
class GyrocompassOutcome:
    """Gyrocompassing's end: the estimator result (``None`` if refused), the reason of a
    refusal, and whether the flag became Coarse."""

    result: GyrocompassResult | None
    refusal: str | None
    coarse: bool

    @property
    def success(self) -> bool:
        """Whether the heading was updated."""
        return self.result is not None


Completed = NadirUpdateResult | NadirCheckResult | SunResult | GyrocompassOutcome


@dataclass(frozen=True)
class NateOutput:
    """NATE's telemetry after one control cycle.

    ``q_b_ll`` (4,) the estimate; ``tilt_est_deg`` the tilt of the estimate and
    ``tilt_accel_deg`` the tilt from this cycle's single accelerometer reading (NaN if the
    sample is unusable), degrees; ``p_s`` (3,) m in Site ``site_index``; ``aqf``; ``mode``
    (after the cycle); ``imu_integration_s`` s of gyro integration since the last Fine
    attitude (sec. 4); ``gyro_counter_s`` the gyro counter, s (sec. 2.4); ``completed``
    the result of a mode that finished this cycle, else ``None``; ``t_s`` NATE's clock at
    the end of the cycle; ``acquisition`` the acquisition command running, if any;
    ``camera_request`` the image NATE waits for, if any; ``events`` what happened this
    cycle (``estimation.events``: words for the operators, a kind and a severity).
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
    completed: Completed | None = None
    t_s: float = math.nan
    acquisition: str | None = None
    camera_request: PancamRequest | None = None
    events: tuple[Event, ...] = ()


def _is_number(value: object) -> bool:
    """A real number that is not a bool (``True`` is not 1 deg)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


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


def replace_param(params: Any, path: str, value: object) -> Any:
    """``params`` (a parameter dataclass) with the field at dotted ``path`` (e.g.
    ``"sungaze.timer_s"``, ``"sunfind.search.elevation_tolerance_rad"``) set to ``value``;
    the dataclasses' own checks validate it. ``ValueError`` names the path.

    >>> replace_param(NateParams(), "sungaze.timer_s", 300.0).sungaze.timer_s
    300.0
    """
    if not isinstance(path, str) or not path:
        raise ValueError(f"set_param: the name must be a non-empty string, got {path!r}")
    return _replace_in(params, path, path.split("."), value)


def _replace_in(group: Any, path: str, names: list[str], value: object) -> Any:
    head, rest = names[0], names[1:]
    fields = sorted(f.name for f in dataclasses.fields(group))
    if head not in fields:
        raise ValueError(f"{path}: no such parameter (here: {', '.join(fields)})")
    current = getattr(group, head)
    if rest:
        if not dataclasses.is_dataclass(current):
            raise ValueError(f"{path}: {head} has no sub-parameters")
        new_value = _replace_in(current, path, rest, value)
    elif dataclasses.is_dataclass(current):
        raise ValueError(f"{path}: is a group; set one of its fields, e.g. {path}.<name>")
    else:
        new_value = _coerce(path, current, value)
    changes: dict[str, Any] = {head: new_value}
    try:
        return dataclasses.replace(group, **changes)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from exc


def _coerce(path: str, old: object, value: object) -> object:
    """``value`` as the type of the parameter's current value (bool, int or float)."""
    if isinstance(old, bool):
        if not isinstance(value, bool):
            raise ValueError(f"{path}: must be true or false, got {value!r}")
        return value
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{path}: must be a number, got {value!r}")
    try:
        number = float(value)
    except OverflowError:
        number = math.inf
    if not math.isfinite(number):
        raise ValueError(f"{path}: must be finite, got {value!r}")
    if isinstance(old, int):
        if number != int(number):
            raise ValueError(f"{path}: must be a whole number, got {value!r}")
        return int(number)
    return number


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
    """SAPP's NATE state machine (module docstring).

    ``lat_rad``, ``lon_east_rad``: the site (planetographic latitude, east longitude) for
    IVP's sun, Earth and Mars rotation; ``t_s``: NATE's clock at start (TT seconds from
    J2000, IVP's time), advanced by every IMU sample's ``dt``.
    """

    def __init__(
        self,
        lat_rad: float,
        lon_east_rad: float,
        t_s: float,
        params: NateParams | None = None,
    ) -> None:
        for name, value in (("lon_east_rad", lon_east_rad), ("t_s", t_s)):
            if not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise ValueError(f"{name}: must be finite, got {value!r}")
        self._lat_rad, self._lon_east_rad = float(lat_rad), float(lon_east_rad)
        self._omega_mars_ll = mars_rotation_ll(lat_rad)  # sec. 2.4.1, from IVP
        sun_ll(float(t_s), self._lat_rad, self._lon_east_rad)  # validates the site
        self._t_s = float(t_s)
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
        self._procedure: Sunfind | Sungaze | Suncheck | None = None
        self._mast: tuple[float, float] | None = None  # mast (az, el) if on the sun
        self._sungaze_gravity = False
        self._acquisition: str | None = None  # the Attitude Acquisition Machine's command
        self._pending: list[NateMode] = []  # its primitives still to run
        self._gyro_sum_b = np.zeros(3)  # gyrocompassing: delta angles, time covered
        self._gyro_sum_s = 0.0
        self._gyro_span_s = 0.0
        self._events: list[Event] = []

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

    def sun_ll_at(self, t_s: float) -> FloatArray:
        """IVP's sun in LL at ``t_s`` (unit (3,))."""
        out: FloatArray = sun_ll(t_s, self._lat_rad, self._lon_east_rad)
        return out

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
        nadir = self._nadir_params(window_s, None)
        self._start_nadir_update(nadir)

    def _start_nadir_update(self, nadir: NadirParams) -> None:
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

    def sunfind(self) -> None:
        """Start a Sunfind (sec. 2.2.2): search, confirm, heading update."""
        self._require("sunfind", NateMode.IDLE)
        self._require_sun("sunfind")
        self._start_sunfind()

    def _start_sunfind(self) -> None:
        self._procedure = Sunfind(self._q_b_ll, self._t_s, self.sun_ll_at, self._params.sunfind)
        self._mode = NateMode.SUNFIND

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

    def _start_sungaze(self, gravity: bool) -> None:
        self._mode = NateMode.SUNGAZE
        self._sungaze_gravity = gravity
        if gravity:  # first one accelerometer window, then the images
            self._averager = AccelAverager(self._params.nadir)
            self._procedure = None
        else:
            self._begin_sungaze_images(None)

    def _begin_sungaze_images(self, down_b: FloatArray | None) -> None:
        p = dataclasses.replace(self._params.sungaze, use_gravity=down_b is not None)
        mast = self._mast if self._mast is not None else (0.0, 0.0)  # stowed: looks ahead
        self._procedure = Sungaze(self._q_b_ll, self._t_s, mast, self.sun_ll_at, p, down_b)

    def suncheck(self, tolerance_deg: float | None = None) -> None:
        """Start a Suncheck (sec. 2.3.2); ``tolerance_deg`` in (0, 180) overrides the
        parameter for this check."""
        self._require("suncheck", NateMode.IDLE)
        params = self._params.suncheck
        if tolerance_deg is not None:
            if not (_is_number(tolerance_deg) and 0.0 < tolerance_deg < 180.0):
                raise ValueError(f"tolerance_deg: must be in (0, 180), got {tolerance_deg!r}")
            params = SuncheckParams(math.radians(tolerance_deg))
        self._require_sun("suncheck")
        self._start_suncheck(params)

    def _start_suncheck(self, params: SuncheckParams) -> None:
        self._procedure = Suncheck(self._q_b_ll, self._t_s, self.sun_ll_at, params)
        self._mode = NateMode.SUNCHECK

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

    def _acquire_sequence(self, name: str, steps: list[NateMode]) -> None:
        self._acquisition, self._pending = name, steps[1:]
        self._start_primitive(steps[0])

    def _start_primitive(self, mode: NateMode) -> None:
        if mode is NateMode.NADIR_UPDATE:
            self._start_nadir_update(self._params.nadir)
        elif mode is NateMode.SUNFIND:
            self._start_sunfind()
        elif mode is NateMode.SUNCHECK:
            self._start_suncheck(self._params.suncheck)
        elif mode is NateMode.SUNGAZE:
            self._start_sungaze(self._params.sungaze.use_gravity)
        else:  # pragma: no cover - the sequences above hold only these
            raise AssertionError(mode)

    def gyrocompass(self, duration_s: float | None = None) -> None:
        """Gyrocompass at rest over ``duration_s`` (default the parameter; sec. 5)."""
        self._require("gyrocompass", NateMode.IDLE)
        span = self._params.gyrocompass_duration_s if duration_s is None else duration_s
        if not (_is_number(span) and math.isfinite(span) and span > 0.0):
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

    def _set_attitude(self, q_b_ll: FloatArray, aqf: AttitudeQuality) -> None:
        """The one place an acquisition's result is adopted."""
        self._q_b_ll, self._aqf = q_b_ll, aqf
        if aqf is AttitudeQuality.FINE:
            self._gyro_counter_s = 0.0
            self._imu_integration_s = 0.0

    def _nadir_params(self, window_s: float | None, tolerance_deg: float | None) -> NadirParams:
        nadir = self._params.nadir
        if window_s is not None:
            if not (_is_number(window_s) and math.isfinite(window_s) and window_s > 0.0):
                raise ValueError(f"window_s: must be positive and finite, got {window_s!r}")
            nadir = dataclasses.replace(nadir, window_s=float(window_s))
            if window_s / CONTROL_DT_S < nadir.min_valid_samples:
                shortest = nadir.min_valid_samples * CONTROL_DT_S
                raise ValueError(
                    f"window_s: {window_s!r} s holds fewer than min_valid_samples "
                    f"({nadir.min_valid_samples}) 8 Hz samples; at least {shortest:g} s"
                )
        if tolerance_deg is not None:
            if not (_is_number(tolerance_deg) and 0.0 < tolerance_deg < 180.0):
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
        self._t_s += dt
        self._events = []
        completed: Completed | None = None
        mode = self._mode
        if mode in (NateMode.NADIR_UPDATE, NateMode.NADIR_CHECK):
            completed = self._acquire(dv_b, dt, bool(imu.valid))
        elif mode is NateMode.ARTICULATE:
            self._propagate_gyros(d_theta_b, dt, bool(imu.valid))
            self._articulate_tilt(dv_b, dt, bool(imu.valid))
            self._count(dt)
        elif mode is NateMode.MOBILITY:
            if self._use_gyros:
                self._propagate_gyros(d_theta_b, dt, bool(imu.valid))  # sec. 2.5: attitude ...
            if enc is not None:
                self._odometry(*enc)  # ... then position with the fresh attitude
            self._count(dt)
        elif mode is NateMode.GYROCOMPASS:
            completed = self._gyrocompass_step(d_theta_b, dt, bool(imu.valid))
        elif mode is NateMode.SUNGAZE and self._procedure is None:
            self._sungaze_gravity_window(dv_b, dt, bool(imu.valid))
        elif mode in _CAMERA_MODES and image is not None:
            assert request is not None and self._procedure is not None
            completed = self._camera_image(request, image)
        if completed is not None:
            self._after_primitive(completed)

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
            t_s=self._t_s,
            acquisition=self._acquisition,
            camera_request=self.camera_request,
            events=tuple(self._events),
        )

    def _after_primitive(self, completed: Completed) -> None:
        """The Attitude Acquisition Machine (sec. 2.2.4): next primitive or abort."""
        if self._acquisition is None:
            return
        proceed = completed.success
        suncheck_done = self._mode is NateMode.IDLE and self._pending == [NateMode.SUNGAZE]
        if self._acquisition == "SuncheckSungaze" and suncheck_done:
            assert isinstance(completed, SunResult)
            proceed = completed.sun_seen  # Sungaze needs only the sun in the field
            if proceed and not completed.success:
                text = (
                    f"SuncheckSungaze: Suncheck failed ({completed.outcome.value}): "
                    "Sungaze on the sun it saw"
                )
                self._events.append(Event(text, "acquisition", "warning"))  # degraded
        if proceed and self._pending:
            self._start_primitive(self._pending.pop(0))
            return
        verdict = "done" if proceed else "aborted"
        text = f"{self._acquisition} {verdict}: AQF {self._aqf.paper_name}"
        self._events.append(Event(text, "acquisition", "info" if proceed else "error"))
        self._acquisition, self._pending = None, []

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
            failure = result.failure
            verdict = "succeeded" if failure is None else f"failed: {failure.value}"
            self._events.append(
                Event(f"Nadir Update {verdict}", "nadir", failure_severity(failure is None))
            )
        else:
            nadir = dataclasses.replace(
                self._params.nadir, check_tolerance_rad=self._check_tolerance_rad
            )
            result = nadir_check(self._q_b_ll, average, self._aqf, nadir)  # sec. 2.3.1
            self._events.append(
                Event(
                    f"Nadir Check: {result.outcome.value}", "nadir", _CHECK_SEVERITY[result.outcome]
                )
            )
        self._aqf = result.aqf
        self._averager = None
        self._check_tolerance_rad = self._params.nadir.check_tolerance_rad
        self._mode = NateMode.IDLE
        return result

    def _sungaze_gravity_window(self, dv_b: FloatArray, dt: float, valid: bool) -> None:
        averager = self._averager
        assert averager is not None
        averager.add(dv_b, dt, valid)
        if not averager.full:
            return
        average = averager.average()
        self._averager = None
        failure = check_average(average, self._params.nadir)
        if failure is not None:
            text = f"Sungaze: gravity average unusable ({failure.value}), sun only"
            self._events.append(Event(text, "sungaze", "warning"))
            self._begin_sungaze_images(None)
        else:
            self._begin_sungaze_images(average.down_b)

    def _camera_image(self, request: PancamRequest, image: ArrayLike) -> SunResult | None:
        procedure = self._procedure
        assert procedure is not None
        R_b_cam = R_b_pancam(request.az_rad, request.el_rad)
        fix = find_sun(image, PANCAM, R_b_cam, self._params.finder)
        procedure.on_image(self._t_s, fix)
        if procedure.result is None:
            return None
        return self._finish_camera(procedure.result)

    def _finish_camera(self, result: SunResult) -> SunResult:
        """Apply a camera mode's outcome: the AQF rules of sec. 2.2.2, 2.2.3 and 2.3."""
        mode = self._mode
        if mode is NateMode.SUNFIND:
            if result.success:
                self._set_attitude(result.q_b_ll, AttitudeQuality.COARSE)
            else:
                self._aqf = AttitudeQuality.UNKNOWN  # estimate unchanged
            text = f"Sunfind: {result.outcome.value} ({result.n_images} images)"
            self._events.append(Event(text, "sunfind", failure_severity(result.success)))
        elif mode is NateMode.SUNGAZE:
            if result.success:
                self._set_attitude(result.q_b_ll, AttitudeQuality.FINE)  # resets counters
            else:
                self._aqf = AttitudeQuality.UNKNOWN  # no update
            text = (
                f"Sungaze: {result.outcome.value}, 3σ {math.degrees(result.three_sigma_rad):.2f} "
                f"deg after {result.n_images} images"
            )
            self._events.append(Event(text, "sungaze", failure_severity(result.success)))
        else:
            if not result.success:
                self._aqf = AttitudeQuality.UNKNOWN  # the estimate is never changed
            err = math.degrees(result.error_rad)
            text = f"Suncheck: {result.outcome.value} (error {err:.2f} deg)"
            self._events.append(Event(text, "suncheck", failure_severity(result.success)))
        self._mast = result.final_mast
        self._procedure = None
        self._mode = NateMode.IDLE
        return result

    def _gyrocompass_step(
        self, d_theta_b: FloatArray, dt: float, valid: bool
    ) -> GyrocompassOutcome | None:
        if valid:
            self._gyro_sum_b += d_theta_b
            self._gyro_sum_s += dt
        else:
            self._gyro_span_s += dt  # an invalid sample extends the span
        if self._gyro_sum_s < self._gyro_span_s * (1.0 - 1e-9):
            return None
        self._mode = NateMode.IDLE
        p = self._params
        try:
            result = gyrocompass(
                self._gyro_sum_b,
                self._gyro_sum_s,
                self._q_b_ll,
                self._lat_rad,
                params=p.gyrocompass,
            )
        except ValueError as exc:
            self._events.append(Event(f"Gyrocompass refused: {exc}", "gyrocompass", "error"))
            return GyrocompassOutcome(None, str(exc), False)
        mismatch = abs(result.horizontal_rate_rad_s / result.expected_horizontal_rate_rad_s - 1.0)
        if mismatch > p.gyrocompass_rate_tolerance:
            reason = (
                f"measured horizontal rate is {100 * mismatch:.0f} % off Mars' (limit "
                f"{100 * p.gyrocompass_rate_tolerance:.0f} %): the rover moved or a gyro failed"
            )
            self._events.append(Event(f"Gyrocompass refused: {reason}", "gyrocompass", "error"))
            return GyrocompassOutcome(None, reason, False)
        # The 3σ assumes a measured tilt (Nadir Update): without one, never Coarse.
        tilt_known = self._aqf >= AttitudeQuality.TILT_ONLY
        coarse = tilt_known and result.heading_3sigma_rad <= p.gyrocompass_coarse_3sigma_rad
        # The heading is now the gyrocompass's: Coarse if good enough, else TiltOnly at best.
        aqf = AttitudeQuality.COARSE if coarse else min(self._aqf, AttitudeQuality.TILT_ONLY)
        self._set_attitude(result.q_b_ll, aqf)
        text = (
            f"Gyrocompass: heading {math.degrees(result.heading_rad):.1f} deg, 3σ "
            f"{math.degrees(result.heading_3sigma_rad):.1f} deg, AQF {self._aqf.paper_name}"
        )
        self._events.append(Event(text, "gyrocompass"))
        return GyrocompassOutcome(result, None, coarse)

    def _propagate_gyros(self, d_theta_b: FloatArray, dt: float, valid: bool) -> None:
        if not valid:
            return  # the driver flagged the sample: not integrated (nor counted as IMU time)
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
