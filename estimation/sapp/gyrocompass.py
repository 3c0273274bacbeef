"""Gyrocompassing at rest: heading from the gyros' measurement of Mars' rotation.

Ali et al. 2005, "Attitude and Position Estimation on the Mars Exploration Rovers"
(Ali et al. 2005), sec. 5 (lessons learned): "it would have been comforting if the software had
the capability to perform gyrocompassing ... determining the Mars rotation vector from gyro
readings when the rover is stationary ... only a rough attitude estimate, it could be used
if the cameras failed". The paper gives no equations for it; this module writes the
standard method in the paper's frames and update forms (sec. 2.2.2, eqs. 2-4):

1. Mean measured rate over a stationary span of duration ``T``:
   ``ω^B = Σ Δθ^B / T``. At rest the body does not turn relative to LL, so the gyros see
   only Mars' spin, ``ω^B = R_b_ll ω^LL`` with ``ω^LL = Ω (cos φ, 0, -sin φ)``
   (``estimation.ivp.mars_rotation_ll``, the IVP's copy; sec. 2.4.1).             (G1)
2. Level it with the tilt-only estimate ``^Bq^LL`` from Nadir Update (sec. 2.2.1: roll and
   pitch right, heading unknown): ``ω̂^LL = R_b_ll(q̂)ᵀ ω^B``. The estimate differs from
   the truth by a turn ``δ`` about LL Down, ``R_b_ll = R_b_ll(q̂) R_z(δ)``, so
   ``ω̂^LL = R_z(δ) ω^LL`` and its horizontal part is ``Ω cos φ (cos δ, sin δ)``.   (G2)
3. ``δ = atan2(ω̂_E, ω̂_N)``: the horizontal part of the spin axis points North.      (G3)
4. Apply the heading adjustment about LL Down on the right, as eq. (4) with eq. (3)'s
   ``δq^LL = [0, 0, sin(δ/2), cos(δ/2)]``: ``^Bq_+^LL = ^Bq_-^LL ⊗ δq^LL``. A turn about
   LL Down leaves the body's nadir ``R_b_ll [0, 0, 1]`` unchanged: the tilt is kept.  (G4)

Error budget (first order; per-axis errors independent and isotropic, so a rate error of
``σ_ω`` per body axis is ``σ_ω`` along the level East axis too). The heading error is the
East rate error over the horizontal signal, plus the tilt coupling: an estimate tilted by
``ε_N`` about North turns the vertical component ``-Ω sin φ`` into East by ``ε_N Ω sin φ``::

    σ_ω = sqrt(σ_bias² + ARW² / T)                                                  (G5)
    σ_ψ = sqrt((σ_ω / (Ω cos φ))² + (tan φ · σ_tilt)²)                               (G6)

(independent terms add in quadrature; ``σ_bias + ARW/√T`` would be the conservative sum).
``σ_bias`` is the bias *averaged over the span* (turn-on plus whatever instability does not
average out). Defaults: LN-200 class, 1 deg/h bias and 0.1 deg/sqrt(h) ARW
(docs/REFERENCES.md, "Hardware"), tilt 7.9e-4 rad per axis (300 µg accelerometer
bias over 3.711 m/s², as ``estimation.sapp.nadir`` computes).

How good is it? At Gusev (14.57° S) ``Ω cos φ = 14.62 · 0.968 = 14.15 deg/h``, so a 1 deg/h
gyro bias alone gives ``1 / 14.15 rad = 4.0 deg`` of heading error (1 σ; 12 deg 3 σ), and no
averaging removes it: gyrocompassing is **Coarse-class at best, never Fine** (Ali et al. 2005's
HGA needs 2 deg 3 σ, sec. 1; Sungaze gives 1.5 deg 3 σ). Near the poles the horizontal
signal vanishes and the method fails: refused below ``min_horizontal_rate_rad_s``
(5 deg/h, |φ| > ~70°). A span so short that the ARW alone would exceed
``max_arw_heading_sigma_rad`` (1 deg; ~10 min at Gusev) is refused too. These two limits
are documented choices (the paper leaves thresholds to the ground, sec. 2).

Flight software: numpy and scipy only; bad arguments raise ``ValueError`` naming the
parameter. The result carries no Attitude Quality Flag: setting it (Coarse at best) is the
NATE state machine's decision.

>>> import math
>>> from estimation.ivp import mars_rotation_ll
>>> from estimation.quaternion import quat_from_rotvec
>>> lat = math.radians(-14.57)
>>> q_true = quat_from_rotvec([0.0, 0.0, math.radians(-30.0)])  # heading 30 deg (q_b_ll)
>>> w_b = Rotation.from_quat(q_true).apply(mars_rotation_ll(lat))
>>> res = gyrocompass(w_b * 3600.0, 3600.0, [0.0, 0.0, 0.0, 1.0], lat)
>>> round(math.degrees(res.heading_rad), 9), round(math.degrees(res.heading_sigma_rad), 2)
(30.0, 4.07)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.mars_constants import MARS_ROTATION_RATE_RAD_S
from estimation.quaternion import quat_canonical, quat_multiply

FloatArray = NDArray[np.float64]

DEG_PER_H_TO_RAD_S = math.pi / 180.0 / 3600.0
DEG_PER_SQRT_H_TO_RAD_PER_SQRT_S = math.pi / 180.0 / 60.0
LN200_GYRO_BIAS_RAD_S = 1.0 * DEG_PER_H_TO_RAD_S  # docs/REFERENCES.md "Hardware": ~1 deg/h
LN200_GYRO_ARW_RAD_PER_SQRT_S = 0.1 * DEG_PER_SQRT_H_TO_RAD_PER_SQRT_S  # docs/REFERENCES.md
NADIR_TILT_SIGMA_RAD = 300e-6 * 9.80665 / 3.711  # 300 ug accel bias / Mars g (docs/REFERENCES.md)


@dataclass(frozen=True)
class GyrocompassParams:
    """Error model (1 σ, per axis) and refusal limits; SI units (rad, s)."""

    gyro_bias_sigma_rad_s: float = LN200_GYRO_BIAS_RAD_S
    gyro_arw_rad_per_sqrt_s: float = LN200_GYRO_ARW_RAD_PER_SQRT_S
    tilt_sigma_rad: float = NADIR_TILT_SIGMA_RAD
    min_horizontal_rate_rad_s: float = 5.0 * DEG_PER_H_TO_RAD_S  # choice: |φ| <~ 70 deg
    max_arw_heading_sigma_rad: float = math.radians(1.0)  # choice: ARW term <= 1 deg

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name}: must be finite and non-negative, got {value!r}")
        if self.min_horizontal_rate_rad_s <= 0.0:
            raise ValueError("min_horizontal_rate_rad_s: must be positive")
        if self.max_arw_heading_sigma_rad <= 0.0:
            raise ValueError("max_arw_heading_sigma_rad: must be positive")


@dataclass(frozen=True)
class GyrocompassResult:
    """Outcome of gyrocompassing.

    ``q_b_ll`` (4,) the heading-corrected estimate (eq. 4 form, G4); ``heading_rad`` the
    azimuth of body x's horizontal projection, clockwise from North, in [0, 2π);
    ``delta_q_ll_angle_rad`` the angle ``δ`` of the correction about LL Down, applied on
    the right (eq. 4 form), in (-π, π]: it is minus the change of heading;
    ``delta_q_ll`` (4,) its quaternion (eq. 3 form); ``omega_b_rad_s`` (3,) the mean
    measured rate (G1); ``horizontal_rate_rad_s`` its measured horizontal magnitude, to
    compare with ``expected_horizontal_rate_rad_s = Ω cos φ`` (a consistency figure: a
    large mismatch means the rover moved or a gyro failed); ``heading_sigma_rad`` and
    ``heading_3sigma_rad`` the predicted error (G6).
    """

    q_b_ll: FloatArray
    heading_rad: float
    delta_q_ll_angle_rad: float
    delta_q_ll: FloatArray
    omega_b_rad_s: FloatArray
    horizontal_rate_rad_s: float
    expected_horizontal_rate_rad_s: float
    duration_s: float
    heading_sigma_rad: float
    heading_3sigma_rad: float


def _check_lat_omega(lat_rad: float, omega_mars_rad_s: float) -> None:
    if not (math.isfinite(lat_rad) and abs(lat_rad) <= 0.5 * math.pi):
        raise ValueError(f"lat_rad: must be in [-pi/2, pi/2], got {lat_rad!r}")
    if not (math.isfinite(omega_mars_rad_s) and omega_mars_rad_s > 0.0):
        raise ValueError(f"omega_mars_rad_s: must be positive and finite, got {omega_mars_rad_s!r}")


def heading_sigma_rad(
    lat_rad: float,
    duration_s: float,
    params: GyrocompassParams | None = None,
    omega_mars_rad_s: float = MARS_ROTATION_RATE_RAD_S,
) -> float:
    """Predicted 1-σ heading error (rad) of a ``duration_s`` span at ``lat_rad`` (G5, G6).

    No refusal here (the budget is defined wherever ``cos φ > 0``); ``inf`` at a pole.

    >>> round(math.degrees(heading_sigma_rad(math.radians(-14.57), 3600.0)), 2)
    4.07
    """
    p = params or GyrocompassParams()
    _check_lat_omega(lat_rad, omega_mars_rad_s)
    if not (math.isfinite(duration_s) and duration_s > 0.0):
        raise ValueError(f"duration_s: must be positive and finite, got {duration_s!r}")
    horizontal = omega_mars_rad_s * math.cos(lat_rad)
    if horizontal <= 0.0:
        return math.inf
    sigma_rate = math.hypot(
        p.gyro_bias_sigma_rad_s, p.gyro_arw_rad_per_sqrt_s / math.sqrt(duration_s)
    )  # G5
    return math.hypot(sigma_rate / horizontal, math.tan(lat_rad) * p.tilt_sigma_rad)  # G6


def min_duration_s(
    lat_rad: float,
    params: GyrocompassParams | None = None,
    omega_mars_rad_s: float = MARS_ROTATION_RATE_RAD_S,
) -> float:
    """Shortest span (s) whose ARW term ``ARW / (√T Ω cos φ)`` is within the limit.

    Zero for a noise-free gyro; ``inf`` at a pole.

    >>> round(min_duration_s(math.radians(-14.57)))
    590
    """
    p = params or GyrocompassParams()
    _check_lat_omega(lat_rad, omega_mars_rad_s)
    horizontal = omega_mars_rad_s * math.cos(lat_rad)
    if horizontal <= 0.0:
        return math.inf
    return (p.gyro_arw_rad_per_sqrt_s / (horizontal * p.max_arw_heading_sigma_rad)) ** 2


def gyrocompass(
    delta_angle_sum_b: ArrayLike,
    duration_s: float,
    q_b_ll: ArrayLike,
    lat_rad: float,
    omega_mars_rad_s: float = MARS_ROTATION_RATE_RAD_S,
    params: GyrocompassParams | None = None,
) -> GyrocompassResult:
    """Heading from gyro delta angles summed over a stationary span.

    ``delta_angle_sum_b`` (3,) rad, body axes; ``duration_s`` the span, s; ``q_b_ll`` (4,)
    ``[x, y, z, w]`` the tilt-only estimate (roll and pitch right, heading arbitrary);
    ``lat_rad`` the site's planetographic latitude; ``omega_mars_rad_s`` Mars' spin rate.
    Raises ``ValueError`` for bad arguments, near a pole (``lat_rad``: Ω cos φ below
    ``params.min_horizontal_rate_rad_s``) and for a span too short to beat the ARW
    (``duration_s``: below ``min_duration_s``).
    """
    p = params or GyrocompassParams()
    _check_lat_omega(lat_rad, omega_mars_rad_s)
    dtheta = np.asarray(delta_angle_sum_b, dtype=np.float64)
    if dtheta.shape != (3,) or not np.all(np.isfinite(dtheta)):
        raise ValueError(f"delta_angle_sum_b: must be a finite 3-vector, got shape {dtheta.shape}")
    if not (math.isfinite(duration_s) and duration_s > 0.0):
        raise ValueError(f"duration_s: must be positive and finite, got {duration_s!r}")
    q = np.asarray(q_b_ll, dtype=np.float64)
    if q.shape != (4,) or not np.all(np.isfinite(q)) or np.linalg.norm(q) < 1e-9:
        raise ValueError("q_b_ll: must be a finite non-zero quaternion [x, y, z, w]")
    q = q / np.linalg.norm(q)

    expected_horizontal = omega_mars_rad_s * math.cos(lat_rad)
    if expected_horizontal < p.min_horizontal_rate_rad_s:
        raise ValueError(
            f"lat_rad: too close to a pole: Mars' horizontal rate Ω cos φ = "
            f"{expected_horizontal / DEG_PER_H_TO_RAD_S:.3g} deg/h is below the "
            f"{p.min_horizontal_rate_rad_s / DEG_PER_H_TO_RAD_S:.3g} deg/h limit"
        )
    t_min = min_duration_s(lat_rad, p, omega_mars_rad_s)
    if duration_s < t_min:
        raise ValueError(
            f"duration_s: {duration_s:.6g} s is too short to beat the gyro ARW "
            f"(needs >= {t_min:.6g} s at this latitude)"
        )

    omega_b = dtheta / duration_s  # G1: mean measured rate
    omega_ll_hat = Rotation.from_quat(q).inv().apply(omega_b)  # G2: R_b_ll(q̂)^T ω^B
    horizontal = math.hypot(float(omega_ll_hat[0]), float(omega_ll_hat[1]))
    delta = math.atan2(float(omega_ll_hat[1]), float(omega_ll_hat[0]))  # G3
    dq_ll = np.array([0.0, 0.0, math.sin(0.5 * delta), math.cos(0.5 * delta)])  # eq. (3)
    q_new = quat_canonical(quat_multiply(q, dq_ll))  # eq. (4), G4
    q_new = q_new / np.linalg.norm(q_new)
    x_ll = Rotation.from_quat(q_new).inv().apply([1.0, 0.0, 0.0])  # body x in LL
    heading = math.atan2(float(x_ll[1]), float(x_ll[0])) % (2.0 * math.pi)
    if heading >= 2.0 * math.pi:  # (-1e-17) % 2π rounds to 2π itself
        heading = 0.0
    sigma = heading_sigma_rad(lat_rad, duration_s, p, omega_mars_rad_s)
    return GyrocompassResult(
        q_b_ll=q_new,
        heading_rad=heading,
        delta_q_ll_angle_rad=delta,
        delta_q_ll=dq_ll,
        omega_b_rad_s=omega_b,
        horizontal_rate_rad_s=horizontal,
        expected_horizontal_rate_rad_s=expected_horizontal,
        duration_s=float(duration_s),
        heading_sigma_rad=sigma,
        heading_3sigma_rad=3.0 * sigma,
    )


def gyrocompass_samples(
    delta_angle_b: ArrayLike,
    dt_s: ArrayLike,
    q_b_ll: ArrayLike,
    lat_rad: float,
    omega_mars_rad_s: float = MARS_ROTATION_RATE_RAD_S,
    params: GyrocompassParams | None = None,
) -> GyrocompassResult:
    """``gyrocompass`` on raw samples: ``delta_angle_b`` (N, 3) rad, ``dt_s`` (N,) or a
    scalar, s. At rest the samples' axes do not turn relative to LL, so their sum is the
    span's delta angle (G1).
    """
    dtheta = np.asarray(delta_angle_b, dtype=np.float64)
    if dtheta.ndim != 2 or dtheta.shape[0] < 1 or dtheta.shape[1] != 3:
        raise ValueError(f"delta_angle_b: must have shape (N, 3), got {dtheta.shape}")
    dt_in = np.asarray(dt_s, dtype=np.float64)
    if dt_in.shape not in ((), (dtheta.shape[0],)):
        raise ValueError(f"dt_s: must be a scalar or have shape ({dtheta.shape[0]},)")
    dt = np.broadcast_to(dt_in, (dtheta.shape[0],))
    if not (np.all(np.isfinite(dt)) and np.all(dt > 0.0)):
        raise ValueError("dt_s: must be positive and finite")
    return gyrocompass(
        dtheta.sum(axis=0), float(dt.sum()), q_b_ll, lat_rad, omega_mars_rad_s, params
    )
