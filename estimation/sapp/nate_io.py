"""NATE's interface: its modes, parameters, the sensor samples it takes and what it gives.

Ali et al. 2005, "Attitude and Position Estimation on the Mars Exploration Rovers": Figure 1
(the modes), sec. 2.4 (the 8 Hz control cycle, Fine to Coarse after 15 min of gyro counter),
sec. 2.5 (the drive commands wheel odometry needs). The state machine that uses them is
``estimation.sapp.nate``; the parameters are documented there and in the modules that own
each group (``nadir``, ``sun_modes``, ``gyrocompass``, ``sunfind``). ``replace_param`` is the
ground's ``SET_PARAM``: a dotted path into ``NateParams``, checked by the dataclasses.
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

from estimation.checks import is_real_number
from estimation.events import Event
from estimation.geometry import wheel_index
from estimation.sapp.aqf import AttitudeQuality
from estimation.sapp.gyrocompass import GyrocompassParams, GyrocompassResult
from estimation.sapp.nadir import (
    NadirCheckResult,
    NadirParams,
    NadirUpdateResult,
)
from estimation.sapp.sun_modes import (
    PancamRequest,
    SuncheckParams,
    SunfindParams,
    SungazeParams,
    SunResult,
)
from estimation.sapp.sunfind import SunFinderParams
from estimation.sapp.wheel_odometry import (
    DriveKind,
)

FloatArray = NDArray[np.float64]

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


CONTROL_DT_S = 0.125  # 8 Hz (Ali et al. 2005 sec. 2.4)


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
    ``wheel_odometry.arc_centre_b``); ``drag_wheel`` the wheel the command leaves undriven
    and drags (``estimation.geometry.WHEEL_KEYS``; None: all six driven), which wheel
    odometry then leaves out (Cheng, Maimone and Matthies 2005 sec. 4.2: Spirit's right
    front wheel from sol 125)."""

    kind: DriveKind = DriveKind.STRAIGHT
    radius_m: float = 0.0
    drag_wheel: str | None = None


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


def nadir_params_for(
    nadir: NadirParams, window_s: float | None, tolerance_deg: float | None
) -> NadirParams:
    """``nadir`` with a command's window (s; it must hold ``min_valid_samples`` 8 Hz
    samples) and Nadir Check tolerance (deg, in (0, 180)) when given; ``ValueError``."""
    if window_s is not None:
        if not (is_real_number(window_s) and math.isfinite(window_s) and window_s > 0.0):
            raise ValueError(f"window_s: must be positive and finite, got {window_s!r}")
        nadir = dataclasses.replace(nadir, window_s=float(window_s))
        if window_s / CONTROL_DT_S < nadir.min_valid_samples:
            shortest = nadir.min_valid_samples * CONTROL_DT_S
            raise ValueError(
                f"window_s: {window_s!r} s holds fewer than min_valid_samples "
                f"({nadir.min_valid_samples}) 8 Hz samples; at least {shortest:g} s"
            )
    if tolerance_deg is not None:
        if not (is_real_number(tolerance_deg) and 0.0 < tolerance_deg < 180.0):
            raise ValueError(f"tolerance_deg: must be in (0, 180), got {tolerance_deg!r}")
        nadir = dataclasses.replace(nadir, check_tolerance_rad=math.radians(tolerance_deg))
    return nadir


def checked_drive(drive: DriveCommand) -> DriveCommand:
    """``drive`` if it is a well-formed ``DriveCommand``; ``ValueError`` otherwise."""
    if not isinstance(drive, DriveCommand) or not isinstance(drive.kind, DriveKind):
        raise ValueError(f"drive: must be a DriveCommand, got {drive!r}")
    if not math.isfinite(drive.radius_m):
        raise ValueError(f"drive: radius_m must be finite, got {drive.radius_m!r}")
    if drive.kind is DriveKind.ARC and drive.radius_m == 0.0:
        raise ValueError("drive: an ARC needs a non-zero radius_m (use TURN_IN_PLACE)")
    if drive.drag_wheel is not None:
        wheel_index(drive.drag_wheel, "drive.drag_wheel")
    return drive


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


# ---- many control cycles at once: checked once, at the boundary ---------------------------


class ImuSeries:
    """``N`` consecutive control cycles of IMU data, checked once here rather than per cycle:
    ``delta_angle_b`` (N, 3) rad (finite), ``delta_velocity_b`` (N, 3) m/s (a non-finite row
    is an unusable reading, as in ``ImuSample``), ``dt_s`` (N,) s (positive, finite) and the
    driver's ``valid`` flags (N,), all valid by default."""

    def __init__(
        self,
        delta_angle_b: ArrayLike,
        delta_velocity_b: ArrayLike,
        dt_s: ArrayLike,
        valid: ArrayLike | None = None,
    ) -> None:
        self.delta_angle_b = _rows("imu.delta_angle_b", delta_angle_b, 3, finite=True)
        n = len(self.delta_angle_b)
        self.delta_velocity_b = _rows("imu.delta_velocity_b", delta_velocity_b, 3, finite=False)
        self.dt_s = np.asarray(dt_s, dtype=np.float64)
        if self.delta_velocity_b.shape[0] != n or self.dt_s.shape != (n,):
            raise ValueError(f"imu: {n} delta angles need as many delta velocities and dt_s")
        if not (np.all(np.isfinite(self.dt_s)) and np.all(self.dt_s > 0.0)):
            raise ValueError("imu.dt_s: must be positive and finite")
        self.valid = np.ones(n, dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
        if self.valid.shape != (n,):
            raise ValueError(f"imu.valid: must have shape ({n},), got {self.valid.shape}")

    def __len__(self) -> int:
        return len(self.dt_s)

    def sample(self, k: int) -> ImuSample:
        """Cycle ``k`` as one ``ImuSample``."""
        return ImuSample(
            self.delta_angle_b[k],
            self.delta_velocity_b[k],
            float(self.dt_s[k]),
            bool(self.valid[k]),
        )


class EncoderSeries:
    """The mobility sensors at the end of each of ``N`` cycles, checked once: finite
    ``wheel_angle_rad`` and ``steer_rad``, (N, 6) each (``EncoderSample``'s rows)."""

    def __init__(self, wheel_angle_rad: ArrayLike, steer_rad: ArrayLike) -> None:
        self.wheel_angle_rad = _rows("encoders.wheel_angle_rad", wheel_angle_rad, 6, finite=True)
        self.steer_rad = _rows("encoders.steer_rad", steer_rad, 6, finite=True)
        if self.steer_rad.shape != self.wheel_angle_rad.shape:
            raise ValueError("encoders: as many steering rows as wheel rows")

    def __len__(self) -> int:
        return len(self.wheel_angle_rad)

    def sample(self, k: int) -> EncoderSample:
        """Cycle ``k`` as one ``EncoderSample``."""
        return EncoderSample(self.wheel_angle_rad[k], self.steer_rad[k])


def _rows(name: str, value: ArrayLike, width: int, finite: bool) -> FloatArray:
    try:
        out = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: must be numeric with shape (N, {width})") from exc
    if out.ndim != 2 or out.shape[1] != width:
        raise ValueError(f"{name}: must have shape (N, {width}), got {out.shape}")
    if finite and not np.all(np.isfinite(out)):
        raise ValueError(f"{name}: must be finite")
    return out


@dataclass
class NateSeries:
    """NATE's outputs over ``N`` cycles, as arrays (the ``NateOutput`` fields cycle by
    cycle, row ``k`` after cycle ``k``): what a drive segment's frames are built from
    without a ``NateOutput`` per cycle. ``output(k)`` is cycle ``k``'s ``NateOutput``."""

    t_s: FloatArray
    q_b_ll: FloatArray
    p_s: FloatArray
    tilt_est_deg: FloatArray
    tilt_accel_deg: FloatArray
    imu_integration_s: FloatArray
    gyro_counter_s: FloatArray
    aqf: list[AttitudeQuality]
    mode: list[NateMode]
    site_index: list[int]
    completed: list[Completed | None]
    acquisition: list[str | None]
    camera_request: list[PancamRequest | None]
    events: list[tuple[Event, ...]]

    def __len__(self) -> int:
        return len(self.t_s)

    def output(self, k: int) -> NateOutput:
        """Cycle ``k`` as a ``NateOutput``."""
        return NateOutput(
            q_b_ll=self.q_b_ll[k].copy(),
            tilt_est_deg=float(self.tilt_est_deg[k]),
            tilt_accel_deg=float(self.tilt_accel_deg[k]),
            p_s=self.p_s[k].copy(),
            site_index=self.site_index[k],
            aqf=self.aqf[k],
            mode=self.mode[k],
            imu_integration_s=float(self.imu_integration_s[k]),
            gyro_counter_s=float(self.gyro_counter_s[k]),
            completed=self.completed[k],
            t_s=float(self.t_s[k]),
            acquisition=self.acquisition[k],
            camera_request=self.camera_request[k],
            events=self.events[k],
        )

    @classmethod
    def of_outputs(cls, outputs: list[NateOutput]) -> NateSeries:
        """The series of cycle-by-cycle outputs."""
        return cls(
            t_s=np.array([o.t_s for o in outputs], dtype=np.float64),
            q_b_ll=np.array([o.q_b_ll for o in outputs], dtype=np.float64).reshape(-1, 4),
            p_s=np.array([o.p_s for o in outputs], dtype=np.float64).reshape(-1, 3),
            tilt_est_deg=np.array([o.tilt_est_deg for o in outputs], dtype=np.float64),
            tilt_accel_deg=np.array([o.tilt_accel_deg for o in outputs], dtype=np.float64),
            imu_integration_s=np.array([o.imu_integration_s for o in outputs], dtype=np.float64),
            gyro_counter_s=np.array([o.gyro_counter_s for o in outputs], dtype=np.float64),
            aqf=[o.aqf for o in outputs],
            mode=[o.mode for o in outputs],
            site_index=[o.site_index for o in outputs],
            completed=[o.completed for o in outputs],
            acquisition=[o.acquisition for o in outputs],
            camera_request=[o.camera_request for o in outputs],
            events=[o.events for o in outputs],
        )
