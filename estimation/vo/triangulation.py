"""Stereo triangulation by the shortest segment between two rays, and its covariance.

Cheng, Maimone and Matthies 2005, sec. 2, eqs. 1-11 (the OCR of the seed is
garbled; these are the standard Matthies/Cheng forms, re-derived below). With optical
centres ``C_1``, ``C_2``, unit rays ``r_1``, ``r_2`` to the same feature, and ``P_1``, ``P_2``
the ends of the shortest segment between the rays:

    P_1 = C_1 + r_1 m_1                                              (1)
    P_2 = C_2 + r_2 m_2                                              (2)
    (P_2 - P_1) · r_1 = (C_2 - C_1 + r_2 m_2 - r_1 m_1) · r_1 = 0     (3)
    (P_2 - P_1) · r_2 = (C_2 - C_1 + r_2 m_2 - r_1 m_1) · r_2 = 0     (4)
    m_1 = [B·r_1 - (B·r_2)(r_1·r_2)] / [1 - (r_1·r_2)²]              (5)
    m_2 = (r_1·r_2) m_1 - B·r_2                                      (6)
    P = (P_1 + P_2) / 2                                              (7)

with ``B = C_2 - C_1``. Differentiating with respect to the pixel coordinates ``q`` of the
feature in both images (``'`` = d/dq; ``a = r_1·r_2``, ``a' = r_1'·r_2 + r_1·r_2'``):

    m_1' = [B·r_1' - a B·r_2' - (B·r_2) a' + 2 a m_1 a'] / (1 - a²)   (8)
    m_2' = a' m_1 + a m_1' - B·r_2'                                  (9)
    P'   = (r_1' m_1 + r_1 m_1' + r_2' m_2 + r_2 m_2') / 2           (10)
    Σ_P  = J diag(Σ_l, Σ_r) Jᵀ,   J = dP/d(u_l, v_l, u_r, v_r)        (11)

(eq. 8 is the paper's quotient rule with the common factor ``1 - a²`` cancelled). The gap
``|P_2 - P_1|`` measures the goodness of the match: features with large gaps are thrown out
(by the caller, ``estimation.vo.stereo``). Everything is vectorised over N features; all
vectors in the body frame ``b``, metres. Flight software: numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.checks import finite_array
from estimation.vo.geometry import PointedPair

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Triangulated:
    """Triangulated features: ``p_b`` (N, 3) points (eq. 7), ``gap_m`` (N,) the shortest
    distance between the rays, ``range_left_m`` / ``range_right_m`` (N,) the distances
    ``m_1``, ``m_2`` along each ray (negative: behind that eye), ``cov_b`` (N, 3, 3) the
    points' covariance (eq. 11), m²."""

    p_b: FloatArray
    gap_m: FloatArray
    range_left_m: FloatArray
    range_right_m: FloatArray
    cov_b: FloatArray


def midpoint(
    c1: ArrayLike, c2: ArrayLike, r1: FloatArray, r2: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Eqs. 1-7 for rays ``r1``, ``r2`` (N, 3, unit) from centres ``c1``, ``c2`` (3,).

    Returns ``P`` (N, 3), ``gap`` (N,), ``m1``, ``m2`` (N,). Parallel rays (``|a| = 1``) have
    no shortest segment: their outputs are NaN.

    >>> P, gap, m1, m2 = midpoint([0, 0, 0], [1, 0, 0],
    ...     np.array([[0.0, 0.0, 1.0]]), np.array([[-1.0, 0.0, 1.0]]) / np.sqrt(2))
    >>> np.round(P, 12).tolist(), np.round(gap, 12).tolist()
    ([[0.0, 0.0, 1.0]], [0.0])
    """
    C1 = finite_array(c1, "c1", (3,))
    C2 = finite_array(c2, "c2", (3,))
    B = C2 - C1
    a = np.einsum("ni,ni->n", r1, r2)
    b1 = r1 @ B
    b2 = r2 @ B
    denominator = 1.0 - a * a
    parallel = denominator <= 1e-15
    safe = np.where(parallel, 1.0, denominator)
    m1 = np.where(parallel, np.nan, (b1 - b2 * a) / safe)  # (5)
    m2 = a * m1 - b2  # (6)
    P1 = C1 + r1 * m1[:, None]  # (1)
    P2 = C2 + r2 * m2[:, None]  # (2)
    P = 0.5 * (P1 + P2)  # (7)
    gap = np.linalg.norm(P2 - P1, axis=1)
    return P, gap, m1, m2


def midpoint_jacobian(
    B: ArrayLike,
    r1: FloatArray,
    r2: FloatArray,
    dr1: FloatArray,
    dr2: FloatArray,
    m1: FloatArray,
    m2: FloatArray,
) -> FloatArray:
    """Eqs. 8-10: ``dP/dq`` (N, 3, Q) given the rays' derivatives ``dr1``, ``dr2`` (N, 3, Q)
    with respect to the Q pixel coordinates ``q``, and ``m1``, ``m2`` from :func:`midpoint`."""
    base = finite_array(B, "B", (3,))
    a = np.einsum("ni,ni->n", r1, r2)
    b2 = r2 @ base
    da = np.einsum("niq,ni->nq", dr1, r2) + np.einsum("ni,niq->nq", r1, dr2)  # a'
    db1 = np.einsum("i,niq->nq", base, dr1)  # B·r_1'
    db2 = np.einsum("i,niq->nq", base, dr2)  # B·r_2'
    dm1 = (db1 - a[:, None] * db2 - b2[:, None] * da + 2.0 * (a * m1)[:, None] * da) / (
        1.0 - a * a
    )[:, None]  # (8)
    dm2 = da * m1[:, None] + a[:, None] * dm1 - db2  # (9)
    dP: FloatArray = 0.5 * (
        dr1 * m1[:, None, None]
        + r1[:, :, None] * dm1[:, None, :]
        + dr2 * m2[:, None, None]
        + r2[:, :, None] * dm2[:, None, :]
    )  # (10)
    return dP


def triangulate(
    pair: PointedPair,
    uv_left_px: ArrayLike,
    uv_right_px: ArrayLike,
    cov_left_px2: ArrayLike,
    cov_right_px2: ArrayLike,
) -> Triangulated:
    """Points and covariances of matched features (eqs. 1-11), body frame.

    ``uv_left_px``, ``uv_right_px`` (N, 2) the matched pixels; ``cov_left_px2``,
    ``cov_right_px2`` (N, 2, 2) their covariances ``Σ_l``, ``Σ_r`` (px²), taken independent.
    """
    uv_l = np.asarray(uv_left_px, dtype=np.float64)
    uv_r = np.asarray(uv_right_px, dtype=np.float64)
    if uv_l.shape != uv_r.shape or uv_l.ndim != 2 or uv_l.shape[1] != 2:
        raise ValueError(f"uv_left_px/uv_right_px: need two (N, 2), got {uv_l.shape}, {uv_r.shape}")
    n = uv_l.shape[0]
    cov_l = _covariances(cov_left_px2, n, "cov_left_px2")
    cov_r = _covariances(cov_right_px2, n, "cov_right_px2")
    r1, d1 = pair.rays_b(uv_l)
    r2, d2 = pair.rays_b(uv_r)
    P, gap, m1, m2 = midpoint(pair.c_left_b, pair.c_right_b, r1, r2)
    zeros = np.zeros_like(d1)
    dr1 = np.concatenate([d1, zeros], axis=2)  # r_1 depends on (u_l, v_l) only
    dr2 = np.concatenate([zeros, d2], axis=2)  # r_2 on (u_r, v_r)
    J = midpoint_jacobian(pair.baseline_b, r1, r2, dr1, dr2, m1, m2)
    cov_q = np.zeros((n, 4, 4))
    cov_q[:, :2, :2] = cov_l
    cov_q[:, 2:, 2:] = cov_r
    cov_P = J @ cov_q @ np.swapaxes(J, 1, 2)  # (11)
    return Triangulated(P, gap, m1, m2, cov_P)


def _covariances(value: ArrayLike, n: int, name: str) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (n, 2, 2):
        raise ValueError(f"{name}: must be ({n}, 2, 2), got shape {arr.shape}")
    return arr
