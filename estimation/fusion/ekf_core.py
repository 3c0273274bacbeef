"""The continuous-discrete extended Kalman filter, model-agnostic (Balaram 2000, sec. 3;
Jiang, Li et al. 2014, eqs. 26-30): the one RK4 and the one Joseph-form update of both filters.

Balaram's step (ii) is "the standard continuous-discrete EKF algorithm" (Gelb, *Applied
Optimal Estimation*, 1974, p. 188, Balaram 2000 ref. 12): between measurements the state
follows ``Ẋ = f(X)`` and the covariance ``Ṗ = F P + P Fᵀ + Q``; at a measurement
``Y = h(X) + n`` the state and covariance are updated with the gain ``K``.

- ``propagate``: the mean by fourth-order Runge-Kutta on ``f``; the covariance by the
  exact discretisation of the linearised model over the step with ``F`` and the spectral
  density ``Q`` held (Van Loan 1978, "Computing integrals involving the matrix
  exponential"): ``Φ = exp(F dt)``, ``Q_d = ∫ Φ(s) Q Φ(s)ᵀ ds``, ``P⁺ = Φ P Φᵀ + Q_d``.
- ``update``: ``K = P Hᵀ (H P Hᵀ + R)⁻¹``, ``X⁺ = X + K (Y - h(X))`` and the Joseph form
  ``P⁺ = (I - K H) P (I - K H)ᵀ + K R Kᵀ``, symmetric and positive by construction.
- The radio filter (``estimation.fusion.radio``) uses the same pieces as Jiang, Li et al.
  2014 write them: ``rk4`` is the "four-order Runge-Kutta algorithm" of its sec. 5 for the
  dynamics (eq. 26), and ``joseph_update`` its eqs. 28-30. The Joseph form keeps ``P⁺``
  symmetric and positive semi-definite for any gain, which matters when the state mixes
  radians of latitude (~1e-6) with metres per second; it equals the textbook ``(I - K H) P``
  for the optimal gain. The two updates differ only in how they solve for the gain: the
  kinematic filter by Cholesky (it also needs ``S⁻¹`` for the NIS), the radio filter by LU,
  as each always has (a checkpointed run replays bit for bit).

On a linear model these are exactly the linear Kalman filter's equations (the test in
``tests/estimation/fusion/test_kinematic_ekf_core.py``).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import cast

import numpy as np
from numpy.typing import NDArray
from scipy.linalg.lapack import dpotrf, dpotrs

FloatArray = NDArray[np.float64]
Dynamics = Callable[[FloatArray], FloatArray]


def _check_square(name: str, M: FloatArray, n: int) -> None:
    if M.shape != (n, n) or not np.isfinite(M).all():
        raise ValueError(f"{name} must be a finite ({n}, {n}) matrix, got shape {M.shape}")


def expm_taylor(M: FloatArray, order: int = 12) -> FloatArray:
    """``exp(M)`` by scaling and squaring a Taylor series (||M / 2^s|| <= 1/2, order 12:
    truncation below 1e-14 relative). The filter's ``F dt`` is small, so this takes a few
    squarings; on the 36 x 36 Van Loan matrix it is ~50 times faster than
    ``scipy.linalg.expm`` here.

    The polynomial is evaluated as Paterson and Stockmeyer 1973 do: the powers
    ``I, A, ..., A^(p-1)`` with ``p = ⌈√order⌉``, each block of ``p`` coefficients applied
    to them at once, and Horner's rule in ``A^p``: 6 matrix products for order 12 instead
    of 11, and a handful of array operations in all.

    >>> bool(abs(expm_taylor(np.array([[1.0]]))[0, 0] - np.e) < 1e-13)
    True
    """
    n = M.shape[0]
    norm = float(np.abs(M).sum(axis=1).max())
    squarings = max(0, int(np.ceil(np.log2(norm / 0.5)))) if norm > 0.5 else 0
    A = M / 2.0**squarings if squarings else M
    p = max(1, math.isqrt(order - 1) + 1) if order > 1 else 1
    powers = [np.eye(n), A]
    while len(powers) <= p:
        powers.append(powers[-1] @ A)
    blocks = _taylor_blocks(order, p) @ np.stack(powers[:p]).reshape(p, n * n)
    E: FloatArray = blocks[-1].reshape(n, n)
    for block in blocks[-2::-1]:
        E = block.reshape(n, n) + powers[p] @ E
    for _ in range(squarings):
        E = E @ E
    return E


@functools.lru_cache(maxsize=8)
def _taylor_blocks(order: int, p: int) -> FloatArray:
    """The Taylor coefficients ``1/k!``, ``k = 0..order``, in rows of ``p`` (Paterson and
    Stockmeyer's blocks, ``expm_taylor``)."""
    out = np.zeros((order // p + 1, p))
    for k in range(order + 1):
        out[k // p, k % p] = 1.0 / math.factorial(k)
    out.setflags(write=False)
    return out


def discretise_diagonal(f: FloatArray, q: FloatArray, dt_s: float) -> tuple[FloatArray, FloatArray]:
    """``discretise`` of uncoupled states: ``F = diag(f)``, ``Q = diag(q)``; returns the
    diagonals ``(φ, q_d)``: ``φ = e^(f dt)`` and the scalar Van Loan integral
    ``q_d = ∫ e^(2 f s) q ds = q (e^(2 f dt) - 1) / (2 f)`` (``q dt`` where ``f = 0``).

    >>> phi, qd = discretise_diagonal(np.array([-1.0, 0.0]), np.array([2.0, 3.0]), 1.0)
    >>> bool(abs(qd[0] - (1.0 - np.exp(-2.0))) < 1e-15), float(qd[1])
    (True, 3.0)
    """
    two_f_dt = 2.0 * f * dt_s
    moving = f != 0.0
    safe = np.where(moving, two_f_dt, 1.0)
    qd: FloatArray = q * dt_s * np.where(moving, np.expm1(safe) / safe, 1.0)
    return np.exp(f * dt_s), qd


def discretise(F: FloatArray, Q: FloatArray, dt_s: float) -> tuple[FloatArray, FloatArray]:
    """``(Φ, Q_d)`` of ``Ẋ = F X + w``, ``E[w wᵀ] = Q δ(t)``, over ``dt_s`` (Van Loan).

    >>> Phi, Qd = discretise(np.array([[-1.0]]), np.array([[2.0]]), 1.0)
    >>> bool(abs(Qd[0, 0] - (1.0 - np.exp(-2.0))) < 1e-12)  # OU: σ² (1 - e^(-2 dt))
    True
    """
    n = F.shape[0]
    _check_square("F", F, n)
    _check_square("Q", Q, n)
    if not (np.isfinite(dt_s) and dt_s >= 0.0):
        raise ValueError(f"dt_s must be finite and >= 0, got {dt_s}")
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -F
    M[:n, n:] = Q
    M[n:, n:] = F.T
    E = expm_taylor(M * dt_s)
    Phi = E[n:, n:].T
    Qd = Phi @ E[:n, n:]
    return Phi, 0.5 * (Qd + Qd.T)


def rk4(f: Dynamics, x: FloatArray, dt_s: float, substeps: int = 1) -> FloatArray:
    """``x(t + dt)`` of ``ẋ = f(x)`` by classical Runge-Kutta in ``substeps`` equal steps
    (local error ``O(dt⁵)``). ``x`` any shape, ``f`` returns the same shape; ``dt_s`` may be
    negative (backwards) but must be finite, else ``ValueError`` naming ``dt_s``.

    >>> x1 = rk4(lambda x: -x, np.array([1.0]), 0.1)
    >>> round(float(x1[0]), 8), round(float(np.exp(-0.1)), 8)
    (0.9048375, 0.90483742)
    """
    if not np.isfinite(dt_s):
        raise ValueError(f"dt_s: must be finite, got {dt_s!r}")
    h = dt_s / substeps
    for _ in range(substeps):
        k1 = f(x)
        k2 = f(x + 0.5 * h * k1)
        k3 = f(x + 0.5 * h * k2)
        k4 = f(x + h * k3)
        x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return x


def propagate(
    x: FloatArray,
    P: FloatArray,
    f: Dynamics,
    F: FloatArray,
    Q: FloatArray,
    dt_s: float,
    n_coupled: int | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Propagate mean and covariance over ``dt_s`` (``F`` the Jacobian of ``f`` at ``x``).

    ``n_coupled``: when the states from that index on are uncoupled (``F`` and ``Q``
    diagonal there and zero between them and the rest; the caller's model says so), their
    part of the discretisation is ``discretise_diagonal``'s closed form and only the first
    ``n_coupled`` states go through the matrix exponential: the same ``Φ`` and ``Q_d`` to
    rounding, at a fraction of the cost.
    """
    _check_square("P", P, x.shape[0])
    if n_coupled is None:
        Phi, Qd = discretise(F, Q, dt_s)
    else:
        Phi, Qd = _discretise_split(F, Q, dt_s, n_coupled)
    P_next = Phi @ P @ Phi.T + Qd
    return rk4(f, x, dt_s), 0.5 * (P_next + P_next.T)


def _discretise_split(
    F: FloatArray, Q: FloatArray, dt_s: float, n_coupled: int
) -> tuple[FloatArray, FloatArray]:
    """``discretise`` of ``F = diag(F_c, diag(f))``, ``Q = diag(Q_c, diag(q))`` with the
    coupled block ``F_c`` (``n_coupled`` square) by Van Loan and the rest in closed form."""
    n, c = F.shape[0], n_coupled
    Phi_c, Qd_c = discretise(F[:c, :c], Q[:c, :c], dt_s)
    diagonal = np.arange(c, n)
    f, q = F[diagonal, diagonal], Q[diagonal, diagonal]
    # a filter's uncoupled states keep their F, Q and step: computed once for them
    phi, qd = _discretise_diagonal_once(f.tobytes(), q.tobytes(), dt_s)
    Phi = np.zeros((n, n))
    Qd = np.zeros((n, n))
    Phi[:c, :c] = Phi_c
    Qd[:c, :c] = Qd_c
    Phi[diagonal, diagonal] = phi
    Qd[diagonal, diagonal] = qd
    return Phi, Qd


@functools.lru_cache(maxsize=16)
def _discretise_diagonal_once(f: bytes, q: bytes, dt_s: float) -> tuple[FloatArray, FloatArray]:
    """``discretise_diagonal`` of the diagonals as bytes, remembered (``_discretise_split``)."""
    phi, qd = discretise_diagonal(np.frombuffer(f), np.frombuffer(q), dt_s)
    phi.setflags(write=False)
    qd.setflags(write=False)
    return phi, qd


def update(
    x: FloatArray, P: FloatArray, residual: FloatArray, H: FloatArray, R: FloatArray
) -> tuple[FloatArray, FloatArray, float]:
    """One measurement update; ``residual = Y - h(x)``. Returns ``(x⁺, P⁺, NIS)``.

    The normalised innovation squared ``rᵀ S⁻¹ r`` is returned for residual monitoring
    (Balaram 2000 sec. 1.2: sensors enabled or disabled on their residuals).
    """
    m, n = residual.shape[0], x.shape[0]
    if H.shape != (m, n) or not np.isfinite(H).all():
        raise ValueError(f"H must be a finite ({m}, {n}) matrix, got shape {H.shape}")
    _check_square("R", R, m)
    if not np.isfinite(residual).all():
        raise ValueError("the residual is not finite")
    HP = H @ P
    S = HP @ H.T + R
    # LAPACK's Cholesky directly: what scipy's cho_factor and cho_solve call, without their
    # per-call argument checks (the arguments are checked above).
    factor, info = dpotrf(0.5 * (S + S.T), lower=False, clean=False)
    if info != 0:
        raise np.linalg.LinAlgError(f"the innovation covariance is not positive definite ({info})")
    K = dpotrs(factor, HP)[0].T  # K = P Hᵀ S⁻¹ (P and S symmetric)
    nis = float(residual @ dpotrs(factor, residual)[0])
    return (*_joseph(x, P, K, residual, H, R), nis)


def joseph_update(
    x: FloatArray, P: FloatArray, innovation: FloatArray, H: FloatArray, R: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Jiang, Li et al. 2014 eqs. 28-30: updated state and covariance; ``x`` (n,), ``P``
    (n, n), ``innovation`` (m,) the measurement minus its prediction ``y - h(x)``, ``H``
    (m, n), ``R`` (m, m). The gain by an LU solve (module docstring).

    Raises ``ValueError`` naming the argument whose shape or values are wrong.
    """
    n, m = x.shape[0], innovation.shape[0]
    if x.ndim != 1 or P.shape != (n, n):
        raise ValueError(f"P: must be ({n}, {n}) for a state of {n}, got {P.shape}")
    if innovation.ndim != 1 or H.shape != (m, n):
        raise ValueError(f"H: must be ({m}, {n}), got {H.shape}")
    if R.shape != (m, m):
        raise ValueError(f"R: must be ({m}, {m}), got {R.shape}")
    for name, a in (("x", x), ("P", P), ("innovation", innovation), ("H", H), ("R", R)):
        if not np.isfinite(a).all():
            raise ValueError(f"{name}: must be finite")
    S = H @ P @ H.T + R
    K = cast(FloatArray, np.linalg.solve(S, H @ P).T)  # eq. 28 (S symmetric: S^-1 H P = K^T)
    return _joseph(x, P, K, innovation, H, R)


def _joseph(
    x: FloatArray,
    P: FloatArray,
    K: FloatArray,
    innovation: FloatArray,
    H: FloatArray,
    R: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """``x + K r`` (eq. 29) and ``(I - K H) P (I - K H)ᵀ + K R Kᵀ`` (eq. 30), symmetrised."""
    x_new: FloatArray = x + K @ innovation
    I_KH = np.eye(x.shape[0]) - K @ H
    P_new: FloatArray = I_KH @ P @ I_KH.T + K @ R @ K.T
    P_new += P_new.T
    P_new *= 0.5
    return x_new, P_new
