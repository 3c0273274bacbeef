"""Balaram's kinematic EKF for a rocker-bogie rover (Balaram 2000, sec. 3, eqs. 1-21).

State ``X = (θ, ω_p, x, v_p, ξ[, b])`` (``kinematic_process``) beside the reference
attitude quaternion ``q_s_b`` (the paper's ``q``: ``R(q) = R_s_b`` takes body
coordinates to the Site frame, the paper's inertial frame). One filter cycle follows the
paper's outline:

(i)   re-parameterise about ``q0 = q_s_b`` (eq. 5; ``θ = 0``),
(ii)  propagate ``X`` and ``P`` (continuous-discrete EKF, ``ekf_core.propagate``), then
      update with any of the measurements ``Y = (ω_m, s_m, t_m)``:
      ``update_gyro`` (eqs. 12-13), ``update_sun`` (eqs. 15-16), ``update_slip``
      (eqs. 17-20),
(iii) absorb ``θ`` into the quaternion, ``q_s_b ← q_s_b ⊗ [θ/2; 1]`` normalised, and set
      ``θ = 0`` (eq. 21).

We absorb after the propagation as well as after each update, so every measurement is
linearised at ``θ = 0`` about the predicted attitude: the same filter to first order
(``q0 ⊗ δq(θ⁻ + δθ) ≈ (q0 ⊗ δq(θ⁻)) ⊗ δq(δθ)`` for the few tenths of a degree a step
turns), with simpler Jacobians. The covariance of ``θ`` is kept unchanged through the
absorption (the reset Jacobian is ``I`` to first order). After every step the contact
angles are also held on the wheels' lower halves (``CONTACT_ANGLE_LIMIT_RAD``).

Timing: the gyro's delta angles and the encoders' increments are averages over an
interval; apply them at its middle (``propagate(dt/2)``, ``update_gyro``,
``update_slip``, ``propagate(dt/2)``), so the position integrates each interval's own
velocity and a drive's last interval is not lost.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.checks import finite_array
from estimation.fusion import ekf_core
from estimation.fusion.kinematic.attitude_sensors import (
    HEADING_GYRO,
    THREE_AXIS_GYRO,
    gyro_measurement,
    sun_measurement,
)
from estimation.fusion.kinematic.process import (
    Layout,
    ProcessParams,
    dynamics_at,
    jacobian,
    noise_density,
)
from estimation.fusion.kinematic.rover_kinematics import suspension
from estimation.fusion.kinematic.slip_constraint import (
    JointRates,
    deterministic_slip,
    slip_constraint,
    slip_constraint_d_psi_rate,
)
from estimation.geometry import FLIGHT_GEOMETRY, N_WHEELS, FlightGeometry
from estimation.quaternion import q_multiply, q_normalised

FloatArray = NDArray[np.float64]

# Initial 1σ: attitude 0.3 deg per axis (a sun-and-gravity fix at rest), rates 0.01 rad/s,
# position 1 mm, velocity 1 cm/s, contact angles 0.3 rad, gyro bias 2 deg/h.
DEFAULT_SIGMA0 = (0.005, 0.01, 0.001, 0.01, 0.3, 1e-5)

# A wheel touches the ground on its lower half, |ξ| < 90 deg. The slip constraint cannot
# tell: ξ + π with the body velocity reversed satisfies eqs. 17-20 as well (the contact on
# top of the wheel, the rover rolling backwards), and one update linearised at a contact
# angle of 40 deg on a rock can carry ξ past 90 deg into that mirror solution, where the
# filter then drives backwards. We hold ξ inside ±75 deg (a 13 cm wheel against a face of
# 75 deg; Gusev's rocks give at most ~60 deg), projecting the estimate after each step.
CONTACT_ANGLE_LIMIT_RAD = float(np.deg2rad(75.0))


@dataclass(frozen=True)
class SensorNoise:
    """1σ measurement noise (units in the names).

    ``gyro_rad_s``: rate noise of one 8 Hz sample (LN-200 ARW 0.1 deg/√h gives
    ~8e-5 rad/s; the default leaves room for the gyro's bias). ``sun_sm``: eq. 15's
    ``n_s`` in output units (0.2 deg of angle is 0.0022). Slip (eq. 17's ``n_i``, the
    paper's "un-correlated slip model"): rolling, lateral and normal slip velocities
    and turning slip; the lateral one carries the transverse slip that a six-wheeled
    rover on a curved surface cannot avoid. ``gamma_rate_rad_s`` and ``psi_rate_rad_s``:
    noise of the joint and drive rates, mapped into the slip covariance through the
    constraint's Jacobians (shared by all wheels, so it is correlated across them). The
    default joint figure is ~2.5 times the white-noise figure of 0.01 deg sensors through
    ``encoder_rates.interval_rates``, because overlapping windows correlate the rates
    from one interval to the next, which the filter does not model.
    """

    gyro_rad_s: float = 2e-4
    sun_sm: float = 0.0022
    slip_rolling_m_s: float = 0.001
    slip_lateral_m_s: float = 0.004
    slip_normal_m_s: float = 0.002
    slip_spin_rad_s: float = 0.01
    gamma_rate_rad_s: float = 0.002
    psi_rate_rad_s: float = 0.001

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not (np.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be positive and finite, got {value}")


# The defaults are the paper's compliant wheels (sec. 2.3.4: each wheel's controller gives
# way to the ground, so rolling slip is small and independent). A rover that drives each
# wheel at its commanded rate (MER, and the simulated rover: ``sim.rover.drive``) cannot do that
# on rocks: a wheel climbing or leaving a rock face has its centre moving at v / cos(ξ)
# while its rim turns at v, and it skids. Measured on Gusev through eq. 17 with the truth
# (10 m legs and an arc, with and without slip): rolling slip 4.4-5.1 mm/s RMS, correlated
# over ~20 samples at 8 Hz (2.5 s, one rock's passage). A white-noise model of a noise
# correlated over N samples must carry √N times its RMS (as the joint rates above):
# √20 x 4.4-5.1 mm/s = 2.0-2.3 cm/s. With the compliant 1 mm/s the filter explains each skid
# by tilting all six contact angles together (unobservable against the body's vertical
# velocity) and drifts in height by ~4 % of the distance.
RATE_CONTROLLED_WHEELS = SensorNoise(slip_rolling_m_s=0.02)


@dataclass(frozen=True)
class KinematicEstimate:
    """The filter's estimate (Site frame ``s``: N, E, Down; body ``b``: fwd, right, down).

    - ``q_s_b`` ``[x, y, z, w]``, body to Site (the paper's ``q``); ``q_b_s`` its inverse;
    - ``p_s`` (3,) body origin in the Site frame, m;
    - ``v_b`` (3,) and ``omega_b`` (3,): body velocity and angular rate relative to the
      Site frame, body axes (``v_c + v_p``, ``ω_c + ω_p``);
    - ``xi_rad`` (6,) contact angles, wheel order LF, LM, LR, RF, RM, RR;
    - ``gyro_bias_rad_s`` (0, 1 or 3,);
    - ``P`` (n, n) covariance of ``X``, the attitude block in body-frame small angles
      (error on the right: ``q_true = q_s_b ⊗ δq(θ)``), the position block in Site axes.
    """

    q_s_b: FloatArray
    p_s: FloatArray
    v_b: FloatArray
    omega_b: FloatArray
    xi_rad: FloatArray
    gyro_bias_rad_s: FloatArray
    P: FloatArray

    @property
    def q_b_s(self) -> FloatArray:
        out: FloatArray = np.concatenate([-self.q_s_b[:3], self.q_s_b[3:]])
        return out


@dataclass
class _Command:
    v_c_b: FloatArray = field(default_factory=lambda: np.zeros(3))
    omega_c_b: FloatArray = field(default_factory=lambda: np.zeros(3))


class KinematicEkf:
    """The kinematic estimator. ``gyro`` is ``"heading"`` (eq. 13, the paper's choice) or
    ``"3axis"`` (eq. 12 with ``B_g = I``); ``estimate_bias`` adds eq. 9's bias states.

    ``P0`` is the initial covariance of ``X`` (n, n); by default ``sigma0`` gives its
    diagonal blocks: attitude (rad), rates (rad/s), position (m), velocity (m/s), contact
    angles (rad), bias (rad/s).
    """

    def __init__(
        self,
        q_s_b: ArrayLike,
        p_s: ArrayLike,
        *,
        gyro: str = "heading",
        estimate_bias: bool = False,
        process: ProcessParams | None = None,
        noise: SensorNoise | None = None,
        geometry: FlightGeometry = FLIGHT_GEOMETRY,
        sigma0: tuple[float, float, float, float, float, float] = DEFAULT_SIGMA0,
        P0: ArrayLike | None = None,
    ) -> None:
        if gyro not in ("heading", "3axis"):
            raise ValueError(f"gyro must be 'heading' or '3axis', got {gyro!r}")
        q = finite_array(q_s_b, "q_s_b", (4,))
        if abs(float(np.linalg.norm(q)) - 1.0) > 1e-6:
            raise ValueError("q_s_b must be a unit quaternion")
        self.B_g = HEADING_GYRO if gyro == "heading" else THREE_AXIS_GYRO
        self.layout = Layout(self.B_g.shape[0] if estimate_bias else 0)
        self.process = process or ProcessParams()
        self.noise = noise or SensorNoise()
        self.geometry = geometry
        self.q_s_b = q
        L = self.layout
        self.X = np.zeros(L.n)
        self.X[L.X] = finite_array(p_s, "p_s", (3,))
        if P0 is None:
            s_att, s_rate, s_pos, s_vel, s_xi, s_bias = sigma0
            diag = np.zeros(L.n)
            diag[L.THETA], diag[L.OMEGA_P], diag[L.X] = s_att, s_rate, s_pos
            diag[L.V_P], diag[L.XI], diag[L.bias] = s_vel, s_xi, s_bias
            self.P = np.diag(diag**2)
        else:
            self.P = np.array(P0, dtype=float)
            if self.P.shape != (L.n, L.n) or not np.allclose(self.P, self.P.T):
                raise ValueError(f"P0 must be a symmetric ({L.n}, {L.n}) matrix")
        self._command = _Command()
        self._Q = noise_density(L, self.process)
        n = self.noise  # eq. 17's n_i of each wheel, uncorrelated
        per_wheel = [n.slip_rolling_m_s, n.slip_lateral_m_s, n.slip_normal_m_s, n.slip_spin_rad_s]
        self._R_slip = np.diag(np.tile(np.square(per_wheel), N_WHEELS))
        # the drive rates' noise through ∂t/∂ψ̇, which depends on the wheel radius alone
        d_psi = slip_constraint_d_psi_rate(geometry.wheel_radius_m)
        self._R_slip += n.psi_rate_rad_s**2 * d_psi @ d_psi.T
        self._R_gyro = self.noise.gyro_rad_s**2 * np.eye(self.B_g.shape[0])
        self._R_sun = self.noise.sun_sm**2 * np.eye(2)

    # ---- checkpoints (estimation.state) ---------------------------------------------

    def state(self) -> dict[str, Any]:
        """The filter's estimate and command as plain data; ``load_state`` puts it back on
        a filter built with the same arguments."""
        return {
            "q_s_b": self.q_s_b.copy(),
            "X": self.X.copy(),
            "P": self.P.copy(),
            "v_c_b": self._command.v_c_b.copy(),
            "omega_c_b": self._command.omega_c_b.copy(),
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state()``'s output."""
        n = self.layout.n
        self.q_s_b = finite_array(state["q_s_b"], "q_s_b", (4,)).copy()
        self.X = finite_array(state["X"], "X", (n,)).copy()
        P = np.array(state["P"], dtype=np.float64)
        if P.shape != (n, n):
            raise ValueError(f"P: must be ({n}, {n}), got {P.shape}")
        self.P = P
        self.set_command(np.array(state["v_c_b"]), np.array(state["omega_c_b"]))

    # ---- (i)-(iii) of sec. 3 --------------------------------------------------------

    def _absorb(self) -> None:
        """Eq. 21: ``q ← q ⊗ [θ/2; 1]`` (normalised), ``θ ← 0``."""
        t0, t1, t2 = self.X[self.layout.THETA].tolist()
        dq = q_normalised((0.5 * t0, 0.5 * t1, 0.5 * t2, 1.0))
        x, y, z, w = self.q_s_b.tolist()
        self.q_s_b = np.array(q_normalised(q_multiply((x, y, z, w), dq)))
        self.X[self.layout.THETA] = 0.0

    def _hold_contacts(self) -> None:
        """Project ``ξ`` onto the wheels' lower halves (``CONTACT_ANGLE_LIMIT_RAD``), away
        from the slip constraint's mirror solution; ``P`` is left as it is."""
        xi = self.X[self.layout.XI]
        np.clip(xi, -CONTACT_ANGLE_LIMIT_RAD, CONTACT_ANGLE_LIMIT_RAD, out=xi)

    def _R0(self) -> FloatArray:
        """``R(q_s_b)``, the rotation matrix of the reference quaternion (normalised, as
        ``scipy.spatial.transform.Rotation`` does: the constructor takes one of norm 1 to
        1e-6), on plain floats."""
        x0, y0, z0, w0 = self.q_s_b.tolist()
        x, y, z, w = q_normalised((x0, y0, z0, w0))
        xx, yy, zz, ww = x * x, y * y, z * z, w * w
        xy, xz, xw, yz, yw, zw = x * y, x * z, x * w, y * z, y * w, z * w
        return np.array(
            [
                [xx - yy - zz + ww, 2.0 * (xy - zw), 2.0 * (xz + yw)],
                [2.0 * (xy + zw), -xx + yy - zz + ww, 2.0 * (yz - xw)],
                [2.0 * (xz - yw), 2.0 * (yz + xw), -xx - yy + zz + ww],
            ]
        )

    def set_command(self, v_c_b: ArrayLike, omega_c_b: ArrayLike) -> None:
        """The prescribed body velocity (m/s) and rate (rad/s) of the controller (eqs. 1-2)."""
        self._command = _Command(
            finite_array(v_c_b, "v_c_b", (3,)), finite_array(omega_c_b, "omega_c_b", (3,))
        )

    def propagate(self, dt_s: float) -> None:
        """Propagate over ``dt_s`` (> 0) under the current command (eqs. 1, 2, 7, 8, 9)."""
        if not (np.isfinite(dt_s) and dt_s > 0.0):
            raise ValueError(f"dt_s must be positive and finite, got {dt_s}")
        R0, c, p = self._R0(), self._command, self.process
        f = dynamics_at(R0, c.v_c_b, c.omega_c_b, p)
        F = jacobian(self.X, R0, c.v_c_b, c.omega_c_b, p)
        self.X, self.P = ekf_core.propagate(
            self.X, self.P, f, F, self._Q, dt_s, n_coupled=Layout.UNCOUPLED_FROM
        )
        self._absorb()
        self._hold_contacts()

    def _update(self, residual: FloatArray, H: FloatArray, R: FloatArray) -> float:
        self.X, self.P, nis = ekf_core.update(self.X, self.P, residual, H, R)
        self._absorb()
        self._hold_contacts()
        return nis

    # ---- measurements (eqs. 12-20) ----------------------------------------------------

    def update_gyro(self, omega_m: ArrayLike, omega_frame_s: ArrayLike = (0.0, 0.0, 0.0)) -> float:
        """Gyro rate ``omega_m`` (1 value for the heading gyro, 3 for a 3-axis one), rad/s,
        body axes; ``omega_frame_s`` the Site frame's inertial rate (Mars rotation) in Site
        axes. Returns the normalised innovation squared."""
        m = self.B_g.shape[0]
        y = finite_array(np.atleast_1d(np.asarray(omega_m, dtype=float)), "omega_m", (m,))
        frame = finite_array(omega_frame_s, "omega_frame_s", (3,))
        h, H = gyro_measurement(self.X, self._R0(), self._command.omega_c_b, self.B_g, frame)
        return self._update(y - h, H, self._R_gyro)

    def update_sun(self, s_m: ArrayLike, sun_s: ArrayLike) -> float:
        """A WASS reading ``s_m`` (2,) of the Sun along the unit ``sun_s`` (Site frame)."""
        y = finite_array(s_m, "s_m", (2,))
        sun = finite_array(sun_s, "sun_s", (3,))
        if abs(math.hypot(*sun.tolist()) - 1.0) > 1e-6:
            raise ValueError("sun_s must be a unit vector")
        h, H = sun_measurement(self.X, self._R0(), sun)
        return self._update(y - h, H, self._R_sun)

    def update_slip(self, joints: JointRates) -> float:
        """The 24 slip constraints (eqs. 17-20) with the encoders' ``joints``; the measured
        value is the deterministic slip of the current command (sec. 2.3.4)."""
        L, c, n = self.layout, self._command, self.noise
        susp = suspension(joints.gamma_rad, self.geometry)
        v_b = c.v_c_b + self.X[L.V_P]
        omega_b = c.omega_c_b + self.X[L.OMEGA_P]
        J = slip_constraint(v_b, omega_b, self.X[L.XI], joints, self.geometry, susp)
        t_m = deterministic_slip(
            c.v_c_b, c.omega_c_b, joints.sigma_rad, joints.sigma_rate_rad_s, self.geometry
        )
        H = np.zeros((J.slip.shape[0], L.n))
        H[:, L.V_P], H[:, L.OMEGA_P], H[:, L.XI] = J.d_v, J.d_omega, J.d_xi
        R = self._R_slip + n.gamma_rate_rad_s**2 * J.d_gamma_rate @ J.d_gamma_rate.T  # shared
        return self._update(t_m - J.slip, H, R)

    # ---- output --------------------------------------------------------------------

    def estimate(self) -> KinematicEstimate:
        L, c = self.layout, self._command
        return KinematicEstimate(
            q_s_b=self.q_s_b.copy(),
            p_s=self.X[L.X].copy(),
            v_b=c.v_c_b + self.X[L.V_P],
            omega_b=c.omega_c_b + self.X[L.OMEGA_P],
            xi_rad=self.X[L.XI].copy(),
            gyro_bias_rad_s=self.X[L.bias].copy(),
            P=self.P.copy(),
        )
