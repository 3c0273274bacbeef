"""Robust motion estimation: closed-form weighted least squares inside RANSAC.

Cheng, Maimone and Matthies 2005, sec. 2 "Robust Motion Estimation", eqs. 12-14:
for features seen at ``P_pj`` before and ``P_cj`` after the motion,

    e_j = P_cj - R P_pj - T                                           (12)
    M(R, T) = Σ_j w_j e_jᵀ e_j                                        (13)
    w_j = (det(Σ_pj) + det(Σ_cj))⁻¹                                    (14)

"There is a closed form solution for this least squares estimation [8]": the weighted
Arun/Horn/Umeyama solution (Umeyama 1991, IEEE PAMI 13(4)): with weighted centroids ``p̄``,
``c̄`` and ``H = Σ w_j (P_pj - p̄)(P_cj - c̄)ᵀ = U S Vᵀ``, ``R = V diag(1, 1, det(V Uᵀ)) Uᵀ``
(the sign fix keeps a proper rotation) and ``T = c̄ - R p̄``.

RANSAC (the paper's three steps): (1) fit a random sample of ``sample_size`` (6) features;
(2) reproject all features with that motion into the current images and count those whose
gap to their observed pixels is under a threshold; (3) repeat a fixed number of times and
keep the motion with the highest score; its inliers go on to the maximum-likelihood
refinement (``estimation.vo.ml_motion``). All hypotheses are fitted and scored at once
(batched SVD), and the best one is refitted on all its inliers to start that refinement.

Beyond the paper: when every sample can be drawn for at most ``EXHAUSTIVE_FACTOR`` times
the random budget (a few features tracked: C(12, 6) = 924), step 1 takes them all instead
(Fischler and Bolles 1981's fixed number of trials can miss the one consistent set: with 7
inliers of 12, 200 random samples of 6 miss every all-inlier sample 22 % of the time, and a
slipping step's first tracking pass then had no estimate to track again from).

Frames: ``P_p`` in the previous body frame ``b0``, ``P_c`` in the current one ``b1``, so
``R = R_b1_b0`` and ``T`` is the ``b0`` origin in ``b1`` (m). Flight software: numpy only.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

# Reprojection gaps of K hypotheses ``(R (K, 3, 3), T (K, 3))`` for N features: (K, N), px.
GapFunction = Callable[[FloatArray, FloatArray], FloatArray]

# Every sample is tried when there are at most this many times the random budget of them
EXHAUSTIVE_FACTOR = 5


def motion_weights(cov_prev: ArrayLike, cov_cur: ArrayLike) -> FloatArray:
    """Eq. 14, ``w_j = 1 / (det Σ_pj + det Σ_cj)``, scaled so the largest weight is 1
    (only ratios matter; the raw values, in m⁻⁶, overflow easily). (N,) from (N, 3, 3) each."""
    a = np.asarray(cov_prev, dtype=np.float64)
    b = np.asarray(cov_cur, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 3 or a.shape[1:] != (3, 3):
        raise ValueError(f"cov_prev/cov_cur: need two (N, 3, 3), got {a.shape}, {b.shape}")
    volume = np.linalg.det(a) + np.linalg.det(b)
    if np.any(~np.isfinite(volume)) or np.any(volume <= 0.0):
        raise ValueError("cov_prev/cov_cur: covariances must be positive definite")
    # Work relative to the smallest volume so the reciprocal cannot overflow.
    out: FloatArray = volume.min() / volume
    return out


def fit_rigid(
    p_prev: ArrayLike, p_cur: ArrayLike, weights: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Weighted least-squares ``(R, T)`` with ``P_c ≈ R P_p + T`` (eqs. 12-13, closed form).

    Batched: ``p_prev``, ``p_cur`` (..., S, 3), ``weights`` (..., S) non-negative; returns
    ``R`` (..., 3, 3) and ``T`` (..., 3). Needs three non-collinear weighted points for a
    unique answer.

    >>> R, T = fit_rigid([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[1, 2, 3], [1, 3, 3], [0, 2, 3]],
    ...                  [1, 1, 1])
    >>> (np.round(R, 12) + 0.0).tolist(), (np.round(T, 12) + 0.0).tolist()  # + 0.0: no -0.0
    ([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], [1.0, 2.0, 3.0])
    """
    p = np.asarray(p_prev, dtype=np.float64)
    c = np.asarray(p_cur, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    if p.shape != c.shape or p.shape[-1] != 3 or p.ndim < 2 or w.shape != p.shape[:-1]:
        raise ValueError(f"p_prev/p_cur/weights: need (..., S, 3) twice and (..., S); got "
                         f"{p.shape}, {c.shape}, {w.shape}")  # fmt: skip
    if np.any(w < 0.0) or np.any(w.sum(axis=-1) <= 0.0):
        raise ValueError("weights: must be non-negative with a positive sum")
    w_norm = w / w.sum(axis=-1, keepdims=True)
    p_bar = np.einsum("...s,...si->...i", w_norm, p)
    c_bar = np.einsum("...s,...si->...i", w_norm, c)
    H = np.einsum(
        "...s,...si,...sj->...ij", w_norm, p - p_bar[..., None, :], c - c_bar[..., None, :]
    )
    U, _, Vt = np.linalg.svd(H)
    V = np.swapaxes(Vt, -1, -2)
    Ut = np.swapaxes(U, -1, -2)
    d = np.sign(np.linalg.det(V @ Ut))
    d = np.where(d == 0.0, 1.0, d)
    D = np.broadcast_to(np.eye(3), H.shape).copy()
    D[..., 2, 2] = d
    R = V @ D @ Ut
    T = c_bar - np.einsum("...ij,...j->...i", R, p_bar)
    return R, T


@dataclass(frozen=True)
class RansacMotion:
    """The RANSAC winner refitted on its inliers: ``R`` (3, 3) = ``R_b1_b0``, ``T`` (3,) m,
    ``inliers`` (N,) the features within the gap threshold of the best hypothesis,
    ``score`` their number."""

    R: FloatArray
    T: FloatArray
    inliers: BoolArray
    score: int


def ransac_motion(
    p_prev: ArrayLike,
    p_cur: ArrayLike,
    weights: ArrayLike,
    gap_px: GapFunction,
    *,
    iterations: int,
    sample_size: int,
    threshold_px: float,
    rng: np.random.Generator,
    hypothesis: tuple[ArrayLike, ArrayLike] | None = None,
) -> RansacMotion:
    """The paper's RANSAC over the closed-form fit (module docstring).

    ``p_prev``, ``p_cur`` (N, 3), ``weights`` (N,) from :func:`motion_weights`; ``gap_px``
    gives the reprojection gaps of a batch of hypotheses (the caller knows the cameras).
    ``hypothesis`` ``(R (3, 3), T (3,))``: a motion scored with the samples' (the first
    tracking pass's estimate, rescored on the second pass's features); it wins ties.
    """
    p = np.asarray(p_prev, dtype=np.float64)
    c = np.asarray(p_cur, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    n = p.shape[0]
    if iterations < 1:
        raise ValueError(f"iterations: must be positive, got {iterations}")
    if sample_size < 3:
        raise ValueError(f"sample_size: must be at least 3, got {sample_size}")
    if n < sample_size:
        raise ValueError(f"p_prev: need at least sample_size = {sample_size} features, got {n}")
    if not threshold_px > 0.0:
        raise ValueError(f"threshold_px: must be positive, got {threshold_px}")
    # Step 1: `iterations` random samples without replacement, all at once (or every
    # sample, when there are few: module docstring).
    if math.comb(n, sample_size) <= EXHAUSTIVE_FACTOR * iterations:
        samples = np.array(list(combinations(range(n), sample_size)), dtype=np.intp)
    else:
        samples = np.argsort(rng.random((iterations, n)), axis=1)[:, :sample_size]
    R, T = fit_rigid(p[samples], c[samples], w[samples])
    if hypothesis is not None:
        R_h = np.asarray(hypothesis[0], dtype=np.float64).reshape(1, 3, 3)
        T_h = np.asarray(hypothesis[1], dtype=np.float64).reshape(1, 3)
        R, T = np.concatenate([R_h, R]), np.concatenate([T_h, T])
    # Step 2: reproject every feature under every hypothesis and count the small gaps.
    inliers_all = gap_px(R, T) < threshold_px
    scores = inliers_all.sum(axis=1)
    best = int(np.argmax(scores))  # step 3: the highest score wins (the first, on ties)
    inliers = inliers_all[best]
    R_best, T_best = R[best], T[best]
    if inliers.sum() >= 3:
        R_best, T_best = fit_rigid(p[inliers], c[inliers], w[inliers])
    return RansacMotion(R_best, T_best, inliers, int(scores[best]))
