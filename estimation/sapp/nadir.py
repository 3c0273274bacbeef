"""Nadir Update and Nadir Check: roll and pitch from the averaged accelerometers.

Ali et al. 2005, "Attitude and Position Estimation on the Mars Exploration Rovers"
(Ali et al. 2005): sec. 2.2.1 (Nadir Update, eq. 1), sec. 2.3 and 2.3.1 (Nadir Check), and the
Attitude Quality Flag consequences of sec. 2.1 (``estimation.sapp.aqf``).

Averaging (sec. 2.2.1). The IMU gives 8 Hz delta velocities ``dv_b`` over ``dt``; at rest
they measure the specific force ``f_b = dv_b / dt``, which points *up* (3.711 m/s^2 along
``-z`` for a level rover). ``AccelAverager`` keeps ``sum(dv_b) / sum(dt)`` (the time-weighted
mean specific force) over the valid samples of a window (10 s, the paper's "typically 10
seconds"). A sample is dropped if the driver flags it invalid, if ``dv_b`` or ``dt`` is not
finite, if ``dt <= 0``, or if its magnitude ``|f_b|`` differs from the known gravity by more
than ``sample_gate_m_s2`` (1.0 m/s^2 default, a documented choice: some 700 sigmas of the
LN-200's 8 Hz white noise, 1.4e-3 m/s^2, so it only removes gross faults such as a stuck
or saturated channel or a bump). A consequence, unlike the paper's order of checks: a
gravity reading off by more than the gate on every sample fails as "too few samples", not
as a gravity-magnitude failure; the outcome (estimate unchanged, AQF Unknown) is the same.
The measured down direction is ``g_b = -f_b / |f_b|``.

Sanity checks (sec. 2.2.1, repeated by 2.3.1), defaults are documented choices since the
paper leaves every threshold to the ground (sec. 2, "almost all numerical values ... are
parameters"):

- ``min_valid_samples = 40``: half the 80 samples of a 10 s window at 8 Hz. With 40 samples
  the white-noise nadir error is 1.4e-3 / sqrt(40) / 3.711 = 6e-5 rad (0.003 deg), still far
  below the 300 ug accelerometer-bias term (7.9e-4 rad, 0.045 deg per axis, 1 sigma), so
  losing half the window costs no accuracy; losing more points at an IMU fault.
- ``gravity_tolerance_m_s2 = 0.1`` (2.7 %): the bias moves ``|f|`` by under 0.01 m/s^2
  (3 sigma); Mars' surface gravity itself varies by about 1 % with latitude and about
  1 % over +-20 km of elevation (``2 g h / R``, approximate), which a fixed 3.711 must absorb.

Tilt correction (eq. 1). With ``n_b = R_b_ll [0, 0, 1]`` the Down axis predicted by the
current estimate and ``g_b`` the measured one, ``δq^B`` rotates by the angle between them
about ``n_b x g_b``, so that ``R(δq^B) n_b = g_b``, and ``^Bq^LL_+ = δq^B ⊗ ^Bq^LL_-``.

What "leaving the yaw unchanged" means, precisely: the same correction written in LL,
``^Bq^LL_+ = ^Bq^LL_- ⊗ δq^LL`` with ``δq^LL = conj(^Bq^LL_-) ⊗ δq^B ⊗ ^Bq^LL_-``, is a
rotation about the LL image of ``n_b x g_b``; the estimate maps ``n_b`` to LL Down, so that
axis is horizontal. The correction has *exactly zero* component about LL Down (zero twist
in a swing-twist split about Down): no rotation about the vertical is applied. It does not
keep the Euler yaw (the azimuth of body x) exactly: for a level prior estimate it changes
by ``atan2(sin a cos t, cos a) - a`` (``t`` the correction angle, ``a`` the angle between
the horizontal axis and body x), at most ``atan((1 - cos t) / (2 sqrt(cos t)))``, about
``t^2 / 4`` (0.0077 rad for ``t`` = 10 deg), and
zero for a pure roll or pure pitch correction; for a tilted prior a first-order term of
about ``t sin(tilt)`` adds to it (tests/estimation/sapp/test_nadir.py measures both).

If ``n_b`` and ``g_b`` coincide, ``δq^B`` is the identity; if they are opposite (an
upside-down estimate) the paper's axis is undefined and this module turns by 180 deg about
the body axis ``n_b x e_k``, ``e_k`` the body axis least aligned with ``n_b`` (still a
horizontal axis in LL, so still no twist about Down).

Flight software: numpy and scipy only; bad arguments raise ``ValueError``.

>>> avg = average_accelerometer(np.tile([0.0, 0.0, -3.711 / 8], (80, 1)), np.full(80, 0.125))
>>> res = nadir_update(quat_from_rotvec([0.1, 0.0, 0.0]), avg)
>>> res.aqf.paper_name, round(math.degrees(tilt_of_estimate_rad(res.q_b_ll)), 12)
('TiltOnly', 0.0)
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.checks import angle_between_rad, unit_quaternion, unit_vector
from estimation.mars_constants import MARS_GRAVITY_M_S2
from estimation.quaternion import Vec3, quat_canonical, quat_from_rotvec, quat_multiply
from estimation.sapp.aqf import AttitudeQuality
from estimation.state import load_params, params_state

FloatArray = NDArray[np.float64]

DOWN_LL = np.array([0.0, 0.0, 1.0])  # LL z is Down (docs/CONVENTIONS.md)
IDENTITY_Q = np.array([0.0, 0.0, 0.0, 1.0])
_WINDOW_REL_TOL = 1e-9  # a window of 80 x 0.1 s that sums to 7.9999999999 s is full


@dataclass(frozen=True)
class NadirParams:
    """Ground-settable parameters of Nadir Update and Nadir Check (sources: module doc)."""

    window_s: float = 10.0  # Ali et al. 2005 sec. 2.2.1, "typically 10 seconds"
    min_valid_samples: int = 40  # documented choice: half of 10 s at 8 Hz
    gravity_m_s2: float = MARS_GRAVITY_M_S2  # known Mars gravity, NASA fact sheet
    gravity_tolerance_m_s2: float = 0.1  # documented choice (module doc)
    sample_gate_m_s2: float = 1.0  # documented choice: per-sample | |f| - g | gate
    # Nadir Check tolerance, documented choice: 2/3 of the 1.5 deg (3 sigma) level of a
    # Fine attitude (Ali et al. 2005 sec. 2.2.3), over 20x the bias-limited nadir error.
    check_tolerance_rad: float = math.radians(1.0)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.window_s) and self.window_s > 0.0):
            raise ValueError(f"window_s: must be positive and finite, got {self.window_s}")
        if self.min_valid_samples < 1:
            raise ValueError(f"min_valid_samples: must be >= 1, got {self.min_valid_samples}")
        for name in ("gravity_m_s2", "gravity_tolerance_m_s2", "sample_gate_m_s2"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}: must be positive and finite, got {value}")
        if not 0.0 < self.check_tolerance_rad < math.pi:
            raise ValueError(
                f"check_tolerance_rad: must be in (0, pi), got {self.check_tolerance_rad}"
            )


@dataclass(frozen=True)
class AccelAverage:
    """Averaged accelerometers: ``f_b_m_s2`` (3,) the mean specific force in body axes,
    m/s^2 (NaN if no sample was valid); ``n_valid`` and ``n_rejected`` samples;
    ``elapsed_s`` the time the window covered (valid or not)."""

    f_b_m_s2: FloatArray
    n_valid: int
    n_rejected: int
    elapsed_s: float

    @property
    def gravity_m_s2(self) -> float:
        """Measured gravity magnitude ``|f_b|``, m/s^2 (NaN if no sample was valid)."""
        return float(np.linalg.norm(self.f_b_m_s2))

    @property
    def down_b(self) -> FloatArray:
        """Measured Down (nadir) unit vector in body axes, ``-f_b / |f_b|``, (3,)."""
        out: FloatArray = -self.f_b_m_s2 / self.gravity_m_s2
        return out


class AccelAverager:
    """Running average of accelerometer samples over one window (Ali et al. 2005 sec. 2.2.1).

    Feed 8 Hz samples with ``add`` until ``full``; ``average()`` gives the result at any
    time. A sample is consumed while the time already covered is below ``window_s`` (so the
    last one may end a fraction of a sample past it); later samples are left unconsumed.
    """

    def __init__(self, params: NadirParams | None = None) -> None:
        self._p = params if params is not None else NadirParams()
        self._sum_dv_b = np.zeros(3)
        self._sum_dt_s = 0.0
        self._n_valid = 0
        self._n_rejected = 0
        self._elapsed_s = 0.0

    @property
    def full(self) -> bool:
        """True once the window's time has been covered."""
        return self._elapsed_s >= self._p.window_s * (1.0 - _WINDOW_REL_TOL)

    def add(
        self, delta_velocity_b: ArrayLike, dt_s: ArrayLike, valid: ArrayLike | None = None
    ) -> int:
        """Offer samples; returns how many were consumed (the rest fall past the window).

        ``delta_velocity_b`` (N, 3) or (3,), m/s, body axes; ``dt_s`` (N,) or scalar, s;
        ``valid`` (N,) or scalar bool, the driver's validity flags (default all valid).
        """
        dv = np.asarray(delta_velocity_b, dtype=np.float64)
        single = dv.ndim == 1
        dv = np.atleast_2d(dv)
        if dv.ndim != 2 or dv.shape[1] != 3:
            raise ValueError(f"delta_velocity_b: must have shape (N, 3) or (3,), got {dv.shape}")
        n = dv.shape[0]
        dt = np.asarray(dt_s, dtype=np.float64).reshape(-1)
        if dt.shape != (n,):
            raise ValueError(
                f"dt_s: must have shape ({n},)" + (" or be a scalar" if single else "")
            )
        ok_driver = np.ones(n, dtype=bool) if valid is None else np.asarray(valid).reshape(-1)
        if ok_driver.shape != (n,) or ok_driver.dtype != np.bool_:
            raise ValueError(f"valid: must be a bool array of shape ({n},)")

        # Time covered: a sample without a usable dt takes none.
        time_ok = np.isfinite(dt) & (dt > 0.0)
        dt_time = np.where(time_ok, dt, 0.0)
        before_s = self._elapsed_s + np.cumsum(dt_time) - dt_time
        n_take = int(np.count_nonzero(before_s < self._p.window_s * (1.0 - _WINDOW_REL_TOL)))
        dv, dt, dt_time, ok_driver = dv[:n_take], dt[:n_take], dt_time[:n_take], ok_driver[:n_take]
        time_ok = time_ok[:n_take]

        ok = ok_driver & time_ok & np.all(np.isfinite(dv), axis=1)
        f_norm = np.full(n_take, np.inf)
        f_norm[ok] = np.linalg.norm(dv[ok], axis=1) / dt[ok]  # |f_b| = |dv_b| / dt
        ok &= np.abs(f_norm - self._p.gravity_m_s2) <= self._p.sample_gate_m_s2

        self._sum_dv_b += dv[ok].sum(axis=0)
        self._sum_dt_s += float(dt[ok].sum())
        self._n_valid += int(np.count_nonzero(ok))
        self._n_rejected += n_take - int(np.count_nonzero(ok))
        self._elapsed_s += float(dt_time.sum())
        return n_take

    def add_sample(self, delta_velocity_b: Vec3, dt_s: float, valid: bool) -> bool:
        """``add`` for one sample on plain floats (``dt_s`` positive and finite, checked by
        the caller): NATE's 8 Hz cycle. Returns whether it was consumed."""
        before_s = (self._elapsed_s + dt_s) - dt_s  # as add's running sum computes it
        if not before_s < self._p.window_s * (1.0 - _WINDOW_REL_TOL):
            return False
        x, y, z = delta_velocity_b
        ok = valid and math.isfinite(x) and math.isfinite(y) and math.isfinite(z)
        if ok:  # |f_b| = |dv_b| / dt within the gate of gravity
            f_norm = math.sqrt(x * x + y * y + z * z) / dt_s
            ok = abs(f_norm - self._p.gravity_m_s2) <= self._p.sample_gate_m_s2
        if ok:
            self._sum_dv_b += (x, y, z)
            self._sum_dt_s += dt_s
            self._n_valid += 1
        else:
            self._n_rejected += 1
        self._elapsed_s += dt_s
        return True

    def average(self) -> AccelAverage:
        """The average so far: ``f_b = sum(dv_b) / sum(dt)`` over the valid samples."""
        f_b = self._sum_dv_b / self._sum_dt_s if self._n_valid else np.full(3, np.nan)
        return AccelAverage(f_b, self._n_valid, self._n_rejected, self._elapsed_s)

    def state(self) -> dict[str, Any]:
        """The window so far and its parameters, as plain data (``estimation.state``)."""
        return {
            "params": params_state(self._p),
            "sum_dv_b": self._sum_dv_b.copy(),
            "sum_dt_s": self._sum_dt_s,
            "n_valid": self._n_valid,
            "n_rejected": self._n_rejected,
            "elapsed_s": self._elapsed_s,
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state()``'s output onto this averager."""
        self._p = load_params(self._p, state["params"])
        self._sum_dv_b = np.array(state["sum_dv_b"], dtype=np.float64)
        self._sum_dt_s = float(state["sum_dt_s"])
        self._n_valid = int(state["n_valid"])
        self._n_rejected = int(state["n_rejected"])
        self._elapsed_s = float(state["elapsed_s"])


def average_accelerometer(
    delta_velocity_b: ArrayLike,
    dt_s: ArrayLike,
    valid: ArrayLike | None = None,
    params: NadirParams | None = None,
) -> AccelAverage:
    """One window's average of a batch of samples (shapes as ``AccelAverager.add``)."""
    averager = AccelAverager(params)
    averager.add(delta_velocity_b, dt_s, valid)
    return averager.average()


class NadirFailure(enum.Enum):
    """Why a sanity check failed (Ali et al. 2005 sec. 2.2.1 and 2.3.1)."""

    TOO_FEW_SAMPLES = "too few valid accelerometer samples"
    GRAVITY_MAGNITUDE = "measured gravity magnitude differs from Mars gravity"


def check_average(average: AccelAverage, params: NadirParams | None = None) -> NadirFailure | None:
    """The two sanity checks of sec. 2.2.1 / 2.3.1; ``None`` if both pass."""
    p = params if params is not None else NadirParams()
    if average.n_valid < p.min_valid_samples:
        return NadirFailure.TOO_FEW_SAMPLES
    if not abs(average.gravity_m_s2 - p.gravity_m_s2) <= p.gravity_tolerance_m_s2:
        return NadirFailure.GRAVITY_MAGNITUDE
    return None


def nadir_in_body(q_b_ll: ArrayLike) -> FloatArray:
    """Expected nadir ``n_b = R_b_ll [0, 0, 1]``, unit (3,), from the estimate ``q_b_ll``."""
    out: FloatArray = Rotation.from_quat(unit_quaternion(q_b_ll)).apply(DOWN_LL)
    return out


def tilt_of_estimate_rad(q_b_ll: ArrayLike) -> float:
    """Tilt of an attitude: the angle between body z and LL Down, rad (telemetry
    ``tilt_est_deg``).

    >>> round(math.degrees(tilt_of_estimate_rad(quat_from_rotvec([0.0, 0.2, 0.0]))), 6)
    11.459156
    """
    x, y, _, _ = unit_quaternion(q_b_ll)
    # Body z in LL is R_ll_b [0, 0, 1]; its Down component is 1 - 2(x² + y²) for a unit
    # quaternion, so the angle is 2 asin(sqrt(x² + y²)): closed form, cheap at 8 Hz.
    return 2.0 * math.asin(min(1.0, math.sqrt(float(x * x + y * y))))


def tilt_from_specific_force_rad(f_b_m_s2: ArrayLike) -> float:
    """Tilt measured by one accelerometer reading at rest: the angle between body z and
    the measured Down ``-f_b``, rad (telemetry ``tilt_accel_deg``). ``f_b_m_s2`` (3,) is the
    specific force in body axes (``dv_b / dt``), any non-zero magnitude.

    >>> tilt_from_specific_force_rad([0.0, 0.0, -3.711])
    0.0
    """
    fx, fy, fz = unit_vector(f_b_m_s2, "f_b_m_s2")
    return math.atan2(math.hypot(float(fx), float(fy)), -float(fz))  # angle(-f_b, z)


def tilt_correction(q_b_ll: ArrayLike, down_b: ArrayLike) -> tuple[FloatArray, float]:
    """``(δq^B, angle_rad)`` turning the estimate's nadir onto the measured ``down_b``.

    ``δq^B`` rotates by the angle between ``n_b`` (``nadir_in_body(q_b_ll)``) and
    ``down_b`` (3,, any non-zero length) about ``n_b x down_b`` (sec. 2.2.1), so that
    ``R(δq^B) n_b = down_b / |down_b|``; to be applied by eq. (1). Identity if collinear;
    180 deg about a horizontal axis if opposite (module doc).
    """
    n_b = nadir_in_body(q_b_ll)
    g_b = unit_vector(down_b, "down_b")
    axis_b = np.cross(n_b, g_b)  # sec. 2.2.1: rotate along n^B x g^B
    angle = angle_between_rad(n_b, g_b)  # sec. 2.2.1: by the angle between n^B and g^B
    sin_angle = float(np.linalg.norm(axis_b))
    if angle > 0.5 * math.pi and sin_angle < 1e-12:  # opposite: an axis normal to n_b
        e_k = np.zeros(3)
        e_k[int(np.argmin(np.abs(n_b)))] = 1.0
        axis_b = np.cross(n_b, e_k)
    elif sin_angle == 0.0:  # collinear: no update (sec. 2.2.1)
        return IDENTITY_Q.copy(), 0.0
    dq_b = quat_from_rotvec(axis_b / np.linalg.norm(axis_b) * angle)
    return dq_b, angle


@dataclass(frozen=True)
class NadirUpdateResult:
    """Outcome of a Nadir Update (sec. 2.2.1).

    Success (``failure is None``): ``q_b_ll`` the new estimate (eq. 1), ``aqf`` TiltOnly.
    Failure: ``q_b_ll`` the unchanged input estimate, ``aqf`` Unknown, ``failure`` the
    reason, ``delta_q_b`` the identity. ``correction_rad`` is the angle of ``δq^B``.
    """

    q_b_ll: FloatArray
    aqf: AttitudeQuality
    failure: NadirFailure | None
    delta_q_b: FloatArray
    correction_rad: float
    average: AccelAverage = field(repr=False)

    @property
    def success(self) -> bool:
        """True if the estimate was updated."""
        return self.failure is None


def nadir_update(
    q_b_ll: ArrayLike, average: AccelAverage, params: NadirParams | None = None
) -> NadirUpdateResult:
    """Nadir Update (sec. 2.2.1, eq. 1) of the estimate ``q_b_ll`` (4,) from one window's
    ``average`` (``AccelAverager``/``average_accelerometer``)."""
    q_minus = unit_quaternion(q_b_ll)
    failure = check_average(average, params)
    if failure is not None:  # sec. 2.2.1: estimate unchanged, flag Unknown
        return NadirUpdateResult(
            q_minus, AttitudeQuality.UNKNOWN, failure, IDENTITY_Q.copy(), 0.0, average
        )
    dq_b, angle = tilt_correction(q_minus, average.down_b)
    q_plus = quat_multiply(dq_b, q_minus)  # eq. (1): q+ = δq^B ⊗ q-
    q_plus = quat_canonical(q_plus / np.linalg.norm(q_plus))
    return NadirUpdateResult(q_plus, AttitudeQuality.TILT_ONLY, None, dq_b, angle, average)


class NadirCheckOutcome(enum.Enum):
    """Nadir Check outcome (sec. 2.3, 2.3.1)."""

    PASSED = "passed"  # nadir within tolerance: flag unchanged
    FAILED = "failed"  # nadir outside tolerance: flag Unknown
    ABORTED = "aborted"  # sanity check failed: flag unchanged


@dataclass(frozen=True)
class NadirCheckResult:
    """Outcome of a Nadir Check; the estimate is never changed (sec. 2.3).

    ``aqf`` is the flag afterwards; ``nadir_error_rad`` the angle between measured and
    expected nadir (NaN if aborted); ``failure`` the sanity check that aborted it.
    """

    outcome: NadirCheckOutcome
    aqf: AttitudeQuality
    failure: NadirFailure | None
    nadir_error_rad: float
    average: AccelAverage = field(repr=False)

    @property
    def success(self) -> bool:
        """True if the check passed."""
        return self.outcome is NadirCheckOutcome.PASSED


def nadir_check(
    q_b_ll: ArrayLike,
    average: AccelAverage,
    aqf: AttitudeQuality,
    params: NadirParams | None = None,
) -> NadirCheckResult:
    """Nadir Check (sec. 2.3.1) of the estimate ``q_b_ll`` (4,) with flag ``aqf``."""
    p = params if params is not None else NadirParams()
    n_b = nadir_in_body(q_b_ll)
    failure = check_average(average, p)
    if failure is not None:  # sec. 2.3.1: abort without changing the flag
        return NadirCheckResult(NadirCheckOutcome.ABORTED, aqf, failure, math.nan, average)
    error = angle_between_rad(n_b, average.down_b)  # sec. 2.3.1: angle between the nadirs
    if error < p.check_tolerance_rad:
        return NadirCheckResult(NadirCheckOutcome.PASSED, aqf, None, error, average)
    return NadirCheckResult(NadirCheckOutcome.FAILED, AttitudeQuality.UNKNOWN, None, error, average)
