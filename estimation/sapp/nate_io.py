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
from numpy.typing import NDArray

from estimation.events import Event
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
