"""Radio + terrain-matching EKF for a Mars rover (Jiang, Li et al. 2014, sec. 4).

State ``X = [L, λ, v_N, v_E]``: planetographic latitude and East longitude of the body
origin (rad), North and East velocity (m/s) (sec. 4.1; models in ``radio_models``).

- Time update (eqs. 26-27): the state by RK4 through eq. 2 (``ekf_core.rk4``) with the
  accelerometers' specific force, rotated by eq. 1, held over the step; the covariance by
  ``Φ = I + F Δt`` (eq. 19, ``F`` of eq. 22 at the previous state) and
  ``P = Φ P Φ^T + Q`` (eq. 27).
- Measurement updates (eqs. 28-30, Joseph form, ``ekf_core.joseph_update``), one sensor at a time
  (the paper stacks them in eq. 13; with uncorrelated noises, eq. 18, sequential updates
  are the same filter): gyro yaw rate (eq. 4), range to an orbiting beacon (eqs. 7-9), and
  the pixels of matched landmarks (eqs. 10-11).

Noise settings (``RadioEkfTuning``) default to the paper's sec. 5: ``P0 = diag(10² I, I)``,
``Q = diag(25 I, 4 I)`` per 1 s step and ``R`` with 9e-8 (rad/s)² for the gyro. The paper
writes ``P0`` and ``Q`` for a latitude/longitude state without units; we read their
position entries as metres North and East (10 m, 5 m per step; in radians they would be
absurd) and convert them to the state's radians. The range variance is the case's radio
accuracy squared, the pixel variance ``(1e-3 f)²`` (the paper's 1e-6 in focal-length units).
The map's matching error (its resolution, 1σ per axis) enters each landmark's pixel
covariance through the Jacobian with respect to the landmark position; the acceleration
uncertainty implied by ``Q`` enters the yaw-rate prediction the same way.

Flight software: no truth, numpy only; bad input raises ``ValueError`` naming it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.checks import finite_array
from estimation.fusion.ekf_core import joseph_update, rk4
from estimation.fusion.radio import models as rm

FloatArray = NDArray[np.float64]

STATE_NAMES = ("lat_rad", "lon_east_rad", "v_north_m_s", "v_east_m_s")
# A landmark predicted beyond this many focal lengths off axis (or behind the camera, where
# eq. 10 flips sign) is out of view for the current estimate: it is left out of the update.
MAX_PREDICTED_FOCAL_LENGTHS = 2.0


@dataclass(frozen=True)
class RadioEkfTuning:
    """Filter noise settings (1σ or variances, units in the names). Defaults: Jiang, Li et al. 2014
    sec. 5."""

    p0_position_m: float = 10.0  # P0 = diag(10² I, I)
    p0_velocity_m_s: float = 1.0
    q_position_m2_per_s: float = 25.0  # Q = diag(25 I, 4 I) per 1 s step
    q_velocity_m2_s2_per_s: float = 4.0
    gyro_yaw_rate_var_rad2_s2: float = 9.0e-8  # R_k's gyro entry
    min_speed_for_yaw_m_s: float = 0.01  # below it the heading of v, so eq. 4, is undefined

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}: must be positive and finite, got {value!r}")


def _scalar(name: str, value: float, low: float = -math.inf, high: float = math.inf) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating):
        raise ValueError(f"{name}: must be a number, got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and low <= v <= high):
        raise ValueError(f"{name}: must be finite and in [{low}, {high}], got {value!r}")
    return v


def _height(height_m: float) -> float:
    return _scalar("height_m", height_m, -2.0e4, 3.0e4)  # Hellas floor to Olympus Mons


def _euler(euler_rad: ArrayLike) -> FloatArray:
    e = finite_array(euler_rad, "euler_rad", (3,))
    return rm.R_ll_b_from_euler(float(e[0]), float(e[1]), float(e[2]))


class RadioEkf:
    """The filter. ``estimate()`` returns ``(x, P)``: ``x`` = ``STATE_NAMES`` (4,), ``P`` (4, 4)
    in the same units (rad², rad·m/s, (m/s)²).

    ``lat_rad`` planetographic, ``lon_east_rad`` East: the initial estimate (eq. 24), with
    the covariance of ``tuning.p0_*`` (eq. 25) at ``height_m`` above the ellipsoid.
    """

    def __init__(
        self,
        lat_rad: float,
        lon_east_rad: float,
        v_north_m_s: float,
        v_east_m_s: float,
        height_m: float = 0.0,
        tuning: RadioEkfTuning | None = None,
    ) -> None:
        lat = _scalar("lat_rad", lat_rad, -1.5, 1.5)  # 86°: the east scale 1/cos L stays sane
        lon = _scalar("lon_east_rad", lon_east_rad)
        vn = _scalar("v_north_m_s", v_north_m_s, -10.0, 10.0)
        ve = _scalar("v_east_m_s", v_east_m_s, -10.0, 10.0)
        h = _height(height_m)
        self.tuning = tuning or RadioEkfTuning()
        self._x = np.array([lat, lon, vn, ve])
        p0_m2 = self.tuning.p0_position_m**2
        self._P = self._metres_to_state(p0_m2, self.tuning.p0_velocity_m_s**2, h)
        self._accel_ne = np.zeros(2)
        self._dt_s = 1.0

    def state(self) -> dict[str, Any]:
        """The estimate and the last step's acceleration as plain data (``load_state`` puts
        it back on a filter built with the same arguments)."""
        return {
            "x": self._x.copy(),
            "P": self._P.copy(),
            "accel_ne": self._accel_ne.copy(),
            "dt_s": self._dt_s,
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state()``'s output."""
        self._x = finite_array(state["x"], "x", (4,)).copy()
        self._P = finite_array(state["P"], "P", (4, 4)).copy()
        self._accel_ne = finite_array(state["accel_ne"], "accel_ne", (2,)).copy()
        self._dt_s = float(state["dt_s"])

    def _metres_to_state(self, pos_var_m2: float, vel_var: float, height_m: float) -> FloatArray:
        """``diag(σ²_N, σ²_E, σ²_vN, σ²_vE)`` with the positions converted from m² to rad²."""
        M, N, _, _ = rm.radii_of_curvature_m(float(self._x[0]))
        east = (N + height_m) * math.cos(float(self._x[0]))
        return np.diag([pos_var_m2 / (M + height_m) ** 2, pos_var_m2 / east**2, vel_var, vel_var])

    def estimate(self) -> tuple[FloatArray, FloatArray]:
        """Copies of the state (4,) and covariance (4, 4)."""
        return self._x.copy(), self._P.copy()

    def horizontal_sigma_m(self, height_m: float = 0.0) -> float:
        """The horizontal position uncertainty (m, 1σ: the root of the sum of the North and
        East variances, √2 times a per-axis σ when they are equal) at ``height_m`` above the
        ellipsoid."""
        h = _height(height_m)
        M, N, _, _ = rm.radii_of_curvature_m(float(self._x[0]))
        east_m_per_rad = (N + h) * math.cos(float(self._x[0]))
        return math.sqrt(self._P[0, 0] * (M + h) ** 2 + self._P[1, 1] * east_m_per_rad**2)

    # ---- time update ---------------------------------------------------------------------

    def propagate(
        self,
        dt_s: float,
        specific_force_b: ArrayLike,
        euler_rad: ArrayLike,
        height_m: float,
        accel_bias_b: ArrayLike = (0.0, 0.0, 0.0),
    ) -> None:
        """Eqs. 26-27 over ``dt_s`` (s, in (0, 60]).

        ``specific_force_b`` (3,): the accelerometers' mean reading over the step, body axes
        at its start (m/s²); ``euler_rad`` (3,): ``(roll, pitch, yaw)`` of eq. 1 then (rad);
        ``accel_bias_b`` (3,): the known accelerometer bias ``b_a`` (m/s², default none).
        """
        dt = _scalar("dt_s", dt_s, 1e-6, 60.0)
        f_b = finite_array(specific_force_b, "specific_force_b", (3,))
        b_a = finite_array(accel_bias_b, "accel_bias_b", (3,))
        h = _height(height_m)
        a_ne = rm.horizontal_accel_ne(f_b, b_a, _euler(euler_rad))  # eqs. 1-2
        F = rm.dynamics_jacobian(self._x, h)  # eq. 22, at X_{k-1}
        self._x = rk4(lambda x: rm.dynamics(x, a_ne, h), self._x, dt)  # eq. 26
        Phi = np.eye(4) + F * dt  # eq. 19
        Q = self._metres_to_state(
            self.tuning.q_position_m2_per_s * dt, self.tuning.q_velocity_m2_s2_per_s * dt, h
        )
        self._P = Phi @ self._P @ Phi.T + Q  # eq. 27
        self._accel_ne, self._dt_s = a_ne, dt

    # ---- measurement updates -------------------------------------------------------------

    def update_yaw_rate(self, yaw_rate_rad_s: float) -> bool:
        """Eq. 4: the gyro's yaw rate about LL Down relative to the surface (rad/s, Mars'
        rotation removed), against the turn rate of the velocity with the last step's
        acceleration. Skipped (returns False) below ``tuning.min_speed_for_yaw_m_s``.

        Its variance is the gyro's plus the acceleration's (``Q``'s velocity part per
        second) carried through ``∂ω/∂a = (-v_E, v_N) / |v|²``.
        """
        y = _scalar("yaw_rate_rad_s", yaw_rate_rad_s, -10.0, 10.0)
        speed = float(np.hypot(self._x[2], self._x[3]))
        if speed < self.tuning.min_speed_for_yaw_m_s:
            return False
        predicted, H = rm.yaw_rate(self._x, self._accel_ne)
        accel_var = self.tuning.q_velocity_m2_s2_per_s / self._dt_s
        R = np.array([[self.tuning.gyro_yaw_rate_var_rad2_s2 + accel_var / speed**2]])
        self._x, self._P = joseph_update(self._x, self._P, np.array([y - predicted]), H, R)
        return True

    def update_velocity(self, v_ne_m_s: ArrayLike, sigma_m_s: float) -> FloatArray:
        """A direct North/East velocity measurement (m/s, 1σ ``sigma_m_s`` per axis). Not in
        Jiang, Li et al. 2014: the rover uses it as a zero-velocity update when its wheels have
        stopped (the driving software knows), so a parked rover's velocity stays known.
        Returns the innovation (2,)."""
        v = finite_array(v_ne_m_s, "v_ne_m_s", (2,))
        sigma = _scalar("sigma_m_s", sigma_m_s, 1e-9, 10.0)
        H = np.hstack([np.zeros((2, 2)), np.eye(2)])
        innovation: FloatArray = v - self._x[2:]
        R = sigma**2 * np.eye(2)
        self._x, self._P = joseph_update(self._x, self._P, innovation, H, R)
        return innovation

    def update_range(
        self, range_m: float, beacon_mf_m: ArrayLike, height_m: float, sigma_m: float
    ) -> float:
        """Eqs. 7-9: a range (m) to the beacon at ``beacon_mf_m`` (Mars-fixed, m) with noise
        ``sigma_m`` (1σ). Returns the innovation (m)."""
        y = _scalar("range_m", range_m, 0.0, 1.0e8)
        beacon = finite_array(beacon_mf_m, "beacon_mf_m", (3,))
        sigma = _scalar("sigma_m", sigma_m, 1e-6, 1e5)
        predicted, H = rm.beacon_range(self._x, _height(height_m), beacon)
        innovation = np.array([y - predicted])
        self._x, self._P = joseph_update(self._x, self._P, innovation, H, np.array([[sigma**2]]))
        return float(innovation[0])

    def update_landmarks(
        self,
        pixels_px: ArrayLike,
        landmarks_mf_m: ArrayLike,
        pan_rad: ArrayLike,
        euler_rad: ArrayLike,
        height_m: float,
        camera_offset_b_m: ArrayLike,
        focal_px: float,
        pixel_sigma_px: float,
        landmark_sigma_m: float,
    ) -> FloatArray:
        """Eqs. 10-11 for ``n`` matched landmarks at once (the paper uses two).

        ``pixels_px`` (n, 2): ``(u, v)`` relative to the principal point; ``landmarks_mf_m``
        (n, 3): their map positions, Mars-fixed (m); ``pan_rad`` (n,): the mast pan of each
        image (rad, right of body x); ``euler_rad``: the rover's eq. 1 attitude;
        ``camera_offset_b_m`` (3,): optical centre from the body origin, body axes (m);
        ``landmark_sigma_m``: the map's matching error, 1σ per axis (m). Returns the
        innovations (n, 2) in pixels, NaN for a landmark left out because the estimate
        puts it behind the camera or over two focal lengths off axis.
        """
        pixels = np.asarray(pixels_px, dtype=np.float64)
        if pixels.ndim != 2 or pixels.shape[0] < 1:
            raise ValueError(f"pixels_px: must have shape (n, 2), got {pixels.shape}")
        n = pixels.shape[0]
        pixels = finite_array(pixels, "pixels_px", (n, 2))
        landmarks = finite_array(landmarks_mf_m, "landmarks_mf_m", (n, 3))
        pans = finite_array(pan_rad, "pan_rad", (n,))
        R_ll_b = _euler(euler_rad)
        h = _height(height_m)
        offset_ll = R_ll_b @ finite_array(camera_offset_b_m, "camera_offset_b_m", (3,))
        f = _scalar("focal_px", focal_px, 1.0, 1.0e6)
        pix_var = _scalar("pixel_sigma_px", pixel_sigma_px, 1e-6, 1e4) ** 2
        map_var = _scalar("landmark_sigma_m", landmark_sigma_m, 0.0, 1e4) ** 2
        H = np.zeros((2 * n, 4))
        R = np.zeros((2 * n, 2 * n))
        innovation = np.full(2 * n, np.nan)
        for i in range(n):
            R_cam_ll = rm.R_cam_b(float(pans[i])) @ R_ll_b.T
            predicted, H_i, d_pix_d_landmark, depth_m = rm.landmark_pixels(
                self._x, h, landmarks[i], R_cam_ll, offset_ll, f
            )
            if depth_m <= 0.0 or not np.all(np.abs(predicted) <= MAX_PREDICTED_FOCAL_LENGTHS * f):
                continue  # the estimate puts it out of view (or behind): no linear model
            rows = slice(2 * i, 2 * i + 2)
            H[rows] = H_i
            innovation[rows] = pixels[i] - predicted  # eq. 29's y - h(x)
            R[rows, rows] = pix_var * np.eye(2) + map_var * d_pix_d_landmark @ d_pix_d_landmark.T
        used = np.isfinite(innovation)
        if np.any(used):
            self._x, self._P = joseph_update(
                self._x, self._P, innovation[used], H[used], R[np.ix_(used, used)]
            )
        return innovation.reshape(n, 2)
