"""Maximum-likelihood motion refinement with each feature's 3D error model.

Cheng, Maimone and Matthies 2005, sec. 2, eqs. 15-17: with ``P_pj`` and ``P_cj``
the observed positions of feature ``j`` before and after the motion,

    P_cj = R P_pj + T + e_j                                           (15)

and the rotation (three angles) and translation are "directly determined by minimizing the
summation in the exponent"

    Σ_j r_jᵀ W_j r_j                                                  (16)
    r_j = P_cj - R P_pj - T                                           (17)

where ``W_j`` is the inverse covariance of ``e_j``; with independent errors in both points,
``W_j = (Σ_cj + R Σ_pj Rᵀ)⁻¹``. "The minimization of this nonlinear problem is done by
linearization and an iterative process [8]": Gauss-Newton on a small rotation ``φ``
applied on the left, ``R ← exp([φ]×) R``, and on ``T``. Linearised,
``r_j(φ, δT) ≈ r_j + [R P_pj]× φ - δT``, so ``J_j = [[R P_pj]×, -I]`` and each step solves
``(Σ J_jᵀ W_j J_j) δ = -Σ J_jᵀ W_j r_j``, re-evaluating ``W_j`` with the new ``R``. The
inverse of the normal matrix at the solution is the covariance of ``(φ, T)``.

Frames: ``P_p`` in the previous body frame ``b0``, ``P_c`` in the current ``b1``; ``R`` is
``R_b1_b0``, ``T`` the ``b0`` origin in ``b1`` (m), ``φ`` is expressed in ``b1`` (rad).
Flight software: numpy and scipy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.camera_model import check_rotation_matrix

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class MlMotion:
    """Refined motion: ``R`` = ``R_b1_b0`` (3, 3), ``T`` (3,) m; ``covariance`` (6, 6) of
    ``(φ, T)`` (rad, m; ``φ`` the left rotation error in ``b1``); ``cost`` eq. 16 at the
    solution; ``iterations`` taken; ``converged``: the last step was within tolerance."""

    R: FloatArray
    T: FloatArray
    covariance: FloatArray
    cost: float
    iterations: int
    converged: bool


def skew(v: FloatArray) -> FloatArray:
    """``[v]×`` for a stack of vectors (..., 3) -> (..., 3, 3): ``[v]× x = v × x``."""
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def _normal_equations(
    p: FloatArray, c: FloatArray, cov_p: FloatArray, cov_c: FloatArray, R: FloatArray, T: FloatArray
) -> tuple[FloatArray, FloatArray, float]:
    """``A = Σ Jᵀ W J``, ``g = Σ Jᵀ W r`` and the cost ``Σ rᵀ W r`` at ``(R, T)``."""
    q = p @ R.T  # R P_pj
    r = c - q - T  # (17)
    W = np.linalg.inv(cov_c + R @ cov_p @ R.T)  # inverse covariance of e_j, (15)
    J = np.concatenate([skew(q), np.broadcast_to(-np.eye(3), (len(p), 3, 3))], axis=2)
    JtW = np.swapaxes(J, 1, 2) @ W  # (N, 6, 3)
    A = np.einsum("nij,njk->ik", JtW, J)
    g = np.einsum("nij,nj->i", JtW, r)
    cost = float(np.einsum("ni,nij,nj->", r, W, r))  # (16)
    return A, g, cost


def refine_ml(
    p_prev: ArrayLike,
    p_cur: ArrayLike,
    cov_prev: ArrayLike,
    cov_cur: ArrayLike,
    R0: ArrayLike,
    T0: ArrayLike,
    *,
    max_iterations: int,
    tol_rad: float,
    tol_m: float,
) -> MlMotion:
    """Gauss-Newton minimisation of eq. 16 from ``(R0, T0)`` (module docstring).

    ``p_prev``, ``p_cur`` (N, 3), N >= 3; ``cov_prev``, ``cov_cur`` (N, 3, 3) positive
    definite. Converged when a step changes the rotation by less than ``tol_rad`` and the
    translation by less than ``tol_m``.
    """
    p = np.asarray(p_prev, dtype=np.float64)
    c = np.asarray(p_cur, dtype=np.float64)
    cov_p = np.asarray(cov_prev, dtype=np.float64)
    cov_c = np.asarray(cov_cur, dtype=np.float64)
    n = p.shape[0]
    if p.shape != (n, 3) or c.shape != (n, 3) or n < 3:
        raise ValueError(f"p_prev/p_cur: need two (N, 3) with N >= 3, got {p.shape}, {c.shape}")
    if cov_p.shape != (n, 3, 3) or cov_c.shape != (n, 3, 3):
        raise ValueError(f"cov_prev/cov_cur: must be ({n}, 3, 3)")
    if max_iterations < 1:
        raise ValueError(f"max_iterations: must be positive, got {max_iterations}")
    if not (tol_rad > 0.0 and tol_m > 0.0):
        raise ValueError("tol_rad/tol_m: must be positive")
    R = check_rotation_matrix(R0, "R0").copy()
    T = np.asarray(T0, dtype=np.float64).reshape(3).copy()
    converged = False
    iterations = 0
    for iterations in range(1, max_iterations + 1):  # noqa: B007 (the count is reported)
        A, g, _ = _normal_equations(p, c, cov_p, cov_c, R, T)
        try:
            step = np.linalg.solve(A, -g)
        except np.linalg.LinAlgError:
            break  # degenerate geometry (e.g. collinear points): no convergence
        R = Rotation.from_rotvec(step[:3]).as_matrix() @ R
        T = T + step[3:]
        if np.linalg.norm(step[:3]) < tol_rad and np.linalg.norm(step[3:]) < tol_m:
            converged = True
            break
    A, _, cost = _normal_equations(p, c, cov_p, cov_c, R, T)
    covariance: FloatArray
    try:
        covariance = np.linalg.inv(A).astype(np.float64)
    except np.linalg.LinAlgError:
        covariance = np.full((6, 6), np.nan)
        converged = False
    converged &= bool(np.all(np.isfinite(covariance)))
    return MlMotion(R, T, covariance, cost, iterations, converged)
