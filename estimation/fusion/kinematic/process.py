"""Process model of Balaram's kinematic EKF: state layout, ``f``, ``F`` and ``Q``.

Balaram 2000 sec. 2.2. The filter state is ``X = (θ, ω_p, x, v_p, ξ[, b])`` (sec. 3):

- ``θ`` (3) the small-angle attitude error of eq. 5, ``q_s_b = q0_s_b ⊗ [θ/2; 1]``: a
  rotation in *body* axes multiplying the reference quaternion on the right, re-absorbed
  into it after each step (eq. 21), so every Jacobian is taken at ``θ = 0``;
- ``ω_p`` (3) the perturbation angular velocity, body axes, rad/s (eq. 2);
- ``x`` (3) the body origin in the Site frame (the paper's inertial frame), m (eq. 1);
- ``v_p`` (3) the perturbation velocity, body axes, m/s (eq. 1);
- ``ξ`` (6) the contact angles on the wheels' equators, rad (eq. 8);
- ``b`` (1 or 3) the gyro bias, rad/s, only when estimated (eq. 9, optional as in the
  paper, which averages it out at stops instead).

Continuous model with the commanded body velocity ``v_c`` and rate ``ω_c`` as inputs
(``ω = ω_c + ω_p``, ``v = v_c + v_p``)::

    θ̇   = ω - ½ ω× θ                    (eq. 7, from eqs. 2, 3, 5)
    ω̇_p = A_ω ω_p + n_ω                 (eq. 2)
    ẋ   = R(q0)(I + θ×)(v_c + v_p)      (eq. 1, R(q) = R(q0 ⊗ δq(θ)) to first order in θ)
    v̇_p = A_v v_p + n_v                 (eq. 1)
    ξ̇   = A_ξ ξ + n_ξ                   (eq. 8)
    ḃ   = n_b                           (eq. 9)

The damping matrices are ``-I/τ`` and each noise density is set from the steady-state
standard deviation of its first-order Gauss-Markov process: ``q = 2 σ² / τ``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def skew(v: FloatArray) -> FloatArray:
    """``v×`` of eqs. 3 and 19: ``skew(a) @ b == cross(a, b)``."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def cross3(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a × b`` of two 3-vectors, ``np.cross``'s formula without its cost on single vectors."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


@dataclass(frozen=True)
class Layout:
    """Indices of the state blocks; ``n_bias`` is 0 (no bias state), 1 or 3."""

    n_bias: int = 0

    THETA = slice(0, 3)
    OMEGA_P = slice(3, 6)
    X = slice(6, 9)
    V_P = slice(9, 12)
    XI = slice(12, 18)
    UNCOUPLED_FROM = 12  # ξ and b: diagonal F and Q, uncoupled from the rest (eqs. 8-9)

    def __post_init__(self) -> None:
        if self.n_bias not in (0, 1, 3):
            raise ValueError(f"n_bias must be 0, 1 or 3, got {self.n_bias}")

    @property
    def bias(self) -> slice:
        return slice(18, 18 + self.n_bias)

    @property
    def n(self) -> int:
        return 18 + self.n_bias


@dataclass(frozen=True)
class ProcessParams:
    """Time constants (s) and steady-state 1σ of the Gauss-Markov states (units in names).

    Defaults are tuned for a MER-class rover at 3.75 cm/s and 2.1 deg/s on bumpy ground:
    the body rocks at up to a few deg/s and bobs at a few mm/s over ~1 s, and a contact
    point wanders by tens of degrees over a wheel's passage over a 0.2 m bump.
    """

    tau_omega_s: float = 1.0
    sigma_omega_rad_s: float = 0.02
    tau_v_s: float = 1.0
    sigma_v_m_s: float = 0.01
    tau_xi_s: float = 4.0
    sigma_xi_rad: float = 0.3
    bias_rw_rad_s_per_sqrt_s: float = 1e-6  # eq. 9 random walk (LN-200 class: ~0.2 deg/h/h)

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not (np.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be positive and finite, got {value}")


def dynamics(
    X: FloatArray, R0: FloatArray, v_c_b: FloatArray, omega_c_b: FloatArray, p: ProcessParams
) -> FloatArray:
    """``Ẋ = f(X)`` of the module docstring; ``R0 = R_s_b`` of the reference quaternion."""
    return dynamics_at(R0, v_c_b, omega_c_b, p)(X)


def dynamics_at(
    R0: FloatArray, v_c_b: FloatArray, omega_c_b: FloatArray, p: ProcessParams
) -> Callable[[FloatArray], FloatArray]:
    """``f`` of ``dynamics`` with its inputs fixed, as RK4's four calls over a step share
    them. Written out on plain floats: array operations on 3-vectors would cost more than
    the arithmetic."""
    c0, c1, c2 = omega_c_b.tolist()
    vc0, vc1, vc2 = v_c_b.tolist()
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R0.tolist()
    tau_w, tau_v, tau_xi = p.tau_omega_s, p.tau_v_s, p.tau_xi_s

    def f(X: FloatArray) -> FloatArray:
        t0, t1, t2, wp0, wp1, wp2, _, _, _, vp0, vp1, vp2, *rest = X.tolist()
        w0, w1, w2 = c0 + wp0, c1 + wp1, c2 + wp2
        v0, v1, v2 = vc0 + vp0, vc1 + vp1, vc2 + vp2
        # eq. 1: (I + θ×) v, then R0
        u0 = v0 + (t1 * v2 - t2 * v1)
        u1 = v1 + (t2 * v0 - t0 * v2)
        u2 = v2 + (t0 * v1 - t1 * v0)
        out = [
            w0 - 0.5 * (w1 * t2 - w2 * t1),  # eq. 7: ω - ½ ω×θ
            w1 - 0.5 * (w2 * t0 - w0 * t2),
            w2 - 0.5 * (w0 * t1 - w1 * t0),
            -wp0 / tau_w,  # eq. 2
            -wp1 / tau_w,
            -wp2 / tau_w,
            r00 * u0 + r01 * u1 + r02 * u2,  # eq. 1
            r10 * u0 + r11 * u1 + r12 * u2,
            r20 * u0 + r21 * u1 + r22 * u2,
            -vp0 / tau_v,  # eq. 1
            -vp1 / tau_v,
            -vp2 / tau_v,
        ]
        out += [-xi / tau_xi for xi in rest[:6]]  # eq. 8
        out += [0.0] * len(rest[6:])  # the bias: eq. 9
        return np.array(out)

    return f


def jacobian(
    X: FloatArray, R0: FloatArray, v_c_b: FloatArray, omega_c_b: FloatArray, p: ProcessParams
) -> FloatArray:
    """``F = ∂f/∂X`` at ``X`` (n, n). The contact angles and the bias are uncoupled from
    the rest and from each other: ``F`` is diagonal over ``UNCOUPLED_FROM`` on.

    The blocks that depend on ``X`` are written out on plain floats into a copy of the
    constant ones (``_constant_jacobian``).
    """
    F = _constant_jacobian(X.shape[0], p).copy()
    t0, t1, t2, wp0, wp1, wp2, _, _, _, vp0, vp1, vp2 = X[:12].tolist()
    c0, c1, c2 = omega_c_b.tolist()
    h0, h1, h2 = 0.5 * (c0 + wp0), 0.5 * (c1 + wp1), 0.5 * (c2 + wp2)
    vc0, vc1, vc2 = v_c_b.tolist()
    v0, v1, v2 = vc0 + vp0, vc1 + vp1, vc2 + vp2
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R0.tolist()
    F[0:3, 0:3] = [[0.0, h2, -h1], [-h2, 0.0, h0], [h1, -h0, 0.0]]  # eq. 7: -½ ω×
    # eq. 7: I + ½ θ× (-½ ω×θ = ½ θ×ω)
    F[0:3, 3:6] = [
        [1.0, -0.5 * t2, 0.5 * t1],
        [0.5 * t2, 1.0, -0.5 * t0],
        [-0.5 * t1, 0.5 * t0, 1.0],
    ]
    F[6:9, 0:3] = [  # eq. 1: -R0 v× (θ×v = -v×θ)
        [r01 * -v2 + r02 * v1, r00 * v2 + r02 * -v0, r00 * -v1 + r01 * v0],
        [r11 * -v2 + r12 * v1, r10 * v2 + r12 * -v0, r10 * -v1 + r11 * v0],
        [r21 * -v2 + r22 * v1, r20 * v2 + r22 * -v0, r20 * -v1 + r21 * v0],
    ]
    F[6:9, 9:12] = [  # eq. 1: R0 (I + θ×)
        [r00 + (r01 * t2 - r02 * t1), r01 + (r02 * t0 - r00 * t2), r02 + (r00 * t1 - r01 * t0)],
        [r10 + (r11 * t2 - r12 * t1), r11 + (r12 * t0 - r10 * t2), r12 + (r10 * t1 - r11 * t0)],
        [r20 + (r21 * t2 - r22 * t1), r21 + (r22 * t0 - r20 * t2), r22 + (r20 * t1 - r21 * t0)],
    ]
    return F


@functools.lru_cache(maxsize=8)
def _constant_jacobian(n: int, p: ProcessParams) -> FloatArray:
    """The blocks of ``F`` that do not depend on ``X`` (read-only; ``jacobian``)."""
    L = Layout(n - 18)
    F = np.zeros((n, n))
    F[L.OMEGA_P, L.OMEGA_P] = -np.eye(3) / p.tau_omega_s  # eq. 2
    F[L.V_P, L.V_P] = -np.eye(3) / p.tau_v_s  # eq. 1
    F[L.XI, L.XI] = -np.eye(6) / p.tau_xi_s  # eq. 8
    F.setflags(write=False)
    return F


def noise_density(layout: Layout, p: ProcessParams) -> FloatArray:
    """Spectral density ``Q`` of ``(n_ω, n_v, n_ξ, n_b)`` placed in the state (n, n)."""
    q = np.zeros(layout.n)
    q[layout.OMEGA_P] = 2.0 * p.sigma_omega_rad_s**2 / p.tau_omega_s
    q[layout.V_P] = 2.0 * p.sigma_v_m_s**2 / p.tau_v_s
    q[layout.XI] = 2.0 * p.sigma_xi_rad**2 / p.tau_xi_s
    q[layout.bias] = p.bias_rw_rad_s_per_sqrt_s**2
    return np.diag(q)
