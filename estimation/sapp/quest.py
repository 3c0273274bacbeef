"""QUEST: optimal attitude from weighted vector observations, for Sungaze.

Shuster, M.D. and Oh, S.D., "Three-Axis Attitude Determination from Vector Observations",
J. Guidance and Control 4(1), 1981, pp. 70-77 (Ali et al. 2005 ref. [6]). Ali et al.
2005 sec. 2.2.3: Sungaze feeds observed and expected sun vectors to QUEST after each image
and may stop early once the covariance is below 1.5 deg 3σ.

The equations, labelled Q1-Q11 at the lines that implement them. Shuster and Oh's numbers
are given where secondary sources cite them; the paper itself is not among the seeds, so
those numbers are unverified (the recipe is the one in docs/REFERENCES.md).

- Q1  weights ``a_i = σ_tot² / σ_i²`` with ``σ_tot⁻² = Σ σ_i⁻²`` (so ``Σ a_i = 1``).
- Q2  attitude profile matrix ``B = Σ a_i b_i r_iᵀ``; ``S = B + Bᵀ``, ``σ = tr B``,
  ``Z = (B23 - B32, B31 - B13, B12 - B21) = Σ a_i b_i × r_i``.
- Q3  ``κ = tr adj S``, ``Δ = det S`` (S&O eq. 63).
- Q4  characteristic equation of K:
  ``λ⁴ - (a + b)λ² - cλ + (ab + cσ - d) = 0`` with ``a = σ² - κ``, ``b = σ² + ZᵀZ``,
  ``c = Δ + ZᵀSZ``, ``d = ZᵀS²Z`` (S&O eqs. 70-71).
- Q5  Newton-Raphson on Q4 from ``λ₀ = Σ a_i`` (= 1). Not when unobservable (below): there
  ``λ_max`` is a double root of Q4, which rounding of the coefficients (a few ulp) moves by
  ``~sqrt(ulp)`` or makes complex, so Newton wanders (loss errors up to ~1e-6 seen) or even
  lands on the other double root, -1. ``λ_max`` is then the top eigenvalue of the symmetric
  ``K = [[S - σI, Z], [Zᵀ, σ]]`` (Davenport), accurate to a few ulp whatever its multiplicity.
- Q6  ``α = λ² - σ² + κ``, ``β = λ - σ``, ``γ = (λ + σ)α - Δ`` (S&O eq. 66).
- Q7  ``X = (αI + βS + S²)Z`` (adjugate form of the Gibbs vector ``Y = X/γ``, S&O eq. 68).
- Q8  optimal quaternion ``q̄ = [X, γ] / sqrt(γ² + |X|²)`` (S&O eq. 69), in Shuster's
  convention ``A(q̄) = (q₄² - |Q|²)I + 2QQᵀ - 2q₄[Q×]``. That is the *transpose* of the
  Hamilton matrix of the same four numbers, so in this project's convention (docs/CONVENTIONS.md)
  ``q_b_r = [-X, γ] / norm``.
- Q9  method of sequential rotations: ``γ`` and ``X`` both vanish at a 180 deg rotation.
  Rotating the reference frame by 180 deg about axis k (``r' = R_k r``, ``B' = B R_kᵀ``;
  λ is unchanged because K' is similar to K) moves the singularity; the frame with the
  largest ``|γ|`` is the best conditioned. Undo: ``q_b_r = q_b_r' ⊗ q_r'_r``.
- Q10 loss ``L = Σ a_i - λ_max`` (with ``L = ½ Σ a_i |b_i - A r_i|²``).
- Q11 QUEST measurement model covariance (S&O, "QUEST measurement model", where each
  measured unit vector has isotropic error σ_i² (I - b_i b_iᵀ) about its true direction):
  ``P_θθ = (Σ σ_i⁻² (I - b_i b_iᵀ))⁻¹``. θ is the attitude error as a rotation vector in
  the *body* frame, multiplying on the *left*:
  ``q_b_r_true = quat_from_rotvec(θ_b) ⊗ q_b_r_estimate`` (Ali et al. 2005's ``δq^B ⊗ ^Bq``).

With one direction (or all directions parallel) the attitude about it is unobservable: the
information matrix of Q11 is singular, QUEST's Q6-Q8 give 0/0 in every frame, and the
solution is flagged ``observable=False`` with an infinite covariance; its quaternion is then
the shortest-arc rotation between the weighted mean directions (one of infinitely many).

Flight software: numpy only; bad arguments raise ``ValueError`` naming the parameter.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.quaternion import quat_canonical, quat_from_rotvec, quat_multiply

FloatArray = NDArray[np.float64]

# Newton-Raphson on Q4: quadratic convergence from λ₀ = 1 takes 1-3 steps for sensor errors
# below a degree (S&O); the cap only guards pathological input.
NEWTON_MAX_ITERATIONS = 100  # dimensionless, design choice
NEWTON_TOLERANCE = 1e-15  # on |Δλ|, λ dimensionless (Σ a_i = 1), ~ float64 resolution
# Smallest eigenvalue of the normalised information matrix Σ a_i (I - b_i b_iᵀ) (which lies
# in [0, 1]) below which the attitude counts as unobservable: two directions δ rad apart give
# about δ²/4, so this flags separations under ~2e-6 rad (0.4 arcsec). Design choice.
OBSERVABILITY_EIGENVALUE_MIN = 1e-12  # dimensionless

# 180 deg rotations of the reference frame about x, y, z (Q9): R_k and q_r'_r = [e_k, 0].
_R_FLIP = (np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.diag([-1.0, -1.0, 1.0]))
_Q_FLIP = (
    np.array([1.0, 0.0, 0.0, 0.0]),
    np.array([0.0, 1.0, 0.0, 0.0]),
    np.array([0.0, 0.0, 1.0, 0.0]),
)


@dataclass(frozen=True)
class QuestSolution:
    """QUEST's answer for observations ``b_i ≈ R(q_b_r) r_i``.

    ``q_b_r``: ``[x, y, z, w]``, ``w >= 0``, takes reference coordinates to body ones.
    ``covariance_rad2``: (3, 3) covariance of the body-frame, left-multiplying error θ (Q11);
    all ``inf`` when not observable. ``three_sigma_deg``: 3 sqrt(largest eigenvalue) in deg.
    ``loss``: Wahba's loss with normalised weights (Q10); ``lambda_max``: K's top eigenvalue.
    ``flip_axis``: the reference-frame 180 deg rotation used (Q9), None, 0 (x), 1 or 2.
    """

    q_b_r: FloatArray
    covariance_rad2: FloatArray
    three_sigma_deg: float
    observable: bool
    loss: float
    lambda_max: float
    n_observations: int
    flip_axis: int | None


def _adjugate_trace(S: FloatArray) -> float:
    """tr adj S: the sum of the principal 2x2 minors (exact for a singular S)."""
    return float(
        S[1, 1] * S[2, 2]
        - S[1, 2] * S[2, 1]
        + S[0, 0] * S[2, 2]
        - S[0, 2] * S[2, 0]
        + S[0, 0] * S[1, 1]
        - S[0, 1] * S[1, 0]
    )


def _profile_terms(B: FloatArray) -> tuple[FloatArray, float, FloatArray, float, float]:
    """S, σ, Z, κ, Δ of an attitude profile matrix B."""
    S = B + B.T  # Q2
    sigma = float(np.trace(B))  # Q2
    Z = np.array([B[1, 2] - B[2, 1], B[2, 0] - B[0, 2], B[0, 1] - B[1, 0]])  # Q2
    kappa = _adjugate_trace(S)  # Q3
    delta = float(np.linalg.det(S))  # Q3
    return S, sigma, Z, kappa, delta


def _lambda_max(B: FloatArray, lam0: float) -> float:
    """The largest root of the characteristic equation (Q4) by Newton-Raphson (Q5)."""
    S, sigma, Z, kappa, delta = _profile_terms(B)
    a = sigma**2 - kappa  # Q4
    b = sigma**2 + float(Z @ Z)  # Q4
    c = delta + float(Z @ S @ Z)  # Q4
    d = float(Z @ S @ S @ Z)  # Q4
    k = a * b + c * sigma - d  # Q4
    lam = lam0  # Q5
    for _ in range(NEWTON_MAX_ITERATIONS):
        f = lam**4 - (a + b) * lam**2 - c * lam + k  # Q4
        f_prime = 4.0 * lam**3 - 2.0 * (a + b) * lam - c  # Q5
        if f_prime == 0.0:
            break
        step = f / f_prime  # Q5
        lam -= step  # Q5
        if abs(step) <= NEWTON_TOLERANCE:
            break
    return lam


def _lambda_max_symmetric(B: FloatArray) -> float:
    """The largest eigenvalue of Davenport's K for profile matrix B, by a symmetric eigensolver
    (errors of a few ulp even for a multiple eigenvalue, unlike the roots of Q4)."""
    S, sigma, Z, _, _ = _profile_terms(B)
    K = np.empty((4, 4))
    K[:3, :3] = S - sigma * np.eye(3)
    K[:3, 3] = Z
    K[3, :3] = Z
    K[3, 3] = sigma
    return float(np.linalg.eigvalsh(K)[-1])


def _gibbs_adjugate(B: FloatArray, lam: float) -> tuple[FloatArray, float]:
    """X and γ of the adjugate form (Q6-Q7) for profile matrix B at eigenvalue λ."""
    S, sigma, Z, kappa, delta = _profile_terms(B)
    alpha = lam**2 - sigma**2 + kappa  # Q6
    beta = lam - sigma  # Q6
    gamma = (lam + sigma) * alpha - delta  # Q6
    X = (alpha * np.eye(3) + beta * S + S @ S) @ Z  # Q7
    return X, gamma


def _shortest_arc(r: FloatArray, b: FloatArray) -> FloatArray:
    """q_b_r of the smallest rotation taking direction r onto direction b (unit vectors)."""
    axis = np.cross(r, b)
    s = float(np.linalg.norm(axis))
    angle = math.atan2(s, float(r @ b))
    if s < 1e-12:
        if angle < 1.0:
            return np.array([0.0, 0.0, 0.0, 1.0])
        # Antiparallel: any axis perpendicular to r.
        helper = np.eye(3)[int(np.argmin(np.abs(r)))]
        axis = np.cross(r, helper)
        s = float(np.linalg.norm(axis))
    return quat_from_rotvec(axis / s * angle)


class QuestAccumulator:
    """Running QUEST sums for Sungaze's image-by-image use; constant memory.

    Keeps ``Σ σ_i⁻² b_i r_iᵀ``, ``Σ σ_i⁻² (I - b_i b_iᵀ)`` and ``Σ σ_i⁻²``; ``solve()`` may
    be called after any ``add`` and gives exactly what ``quest`` gives for the same data.

    >>> acc = QuestAccumulator()
    >>> acc.add([0.0, -1.0, 0.0], [1.0, 0.0, 0.0], 1e-3)  # North seen on the rover's left
    >>> acc.add([0.0, 0.0, 1.0], [0.0, 0.0, 1.0], 1e-3)  # Down is down
    >>> sol = acc.solve()
    >>> (np.round(sol.q_b_r, 6) + 0.0).tolist()  # rover yawed +90 deg (facing East)
    [0.0, 0.0, -0.707107, 0.707107]
    >>> round(sol.three_sigma_deg, 4)  # 3 x 1 mrad, since the two vectors are 90 deg apart
    0.1719
    """

    def __init__(self) -> None:
        self._B_weighted = np.zeros((3, 3))
        self._information = np.zeros((3, 3))
        self._b_weighted_sum = np.zeros(3)
        self._r_weighted_sum = np.zeros(3)
        self._weight_sum = 0.0
        self._n = 0
        self._first_b = np.zeros(3)
        self._first_r = np.zeros(3)

    def state(self) -> dict[str, Any]:
        """The running sums as plain data (``estimation.state``)."""
        return {
            "B_weighted": self._B_weighted.copy(),
            "information": self._information.copy(),
            "b_weighted_sum": self._b_weighted_sum.copy(),
            "r_weighted_sum": self._r_weighted_sum.copy(),
            "weight_sum": self._weight_sum,
            "n": self._n,
            "first_b": self._first_b.copy(),
            "first_r": self._first_r.copy(),
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state()``'s output onto this accumulator."""
        for name in ("B_weighted", "information", "b_weighted_sum", "r_weighted_sum"):
            setattr(self, f"_{name}", np.array(state[name], dtype=np.float64))
        self._first_b = np.array(state["first_b"], dtype=np.float64)
        self._first_r = np.array(state["first_r"], dtype=np.float64)
        self._weight_sum = float(state["weight_sum"])
        self._n = int(state["n"])

    @property
    def n_observations(self) -> int:
        """How many observations have been added."""
        return self._n

    def add(self, b_vector: ArrayLike, r_vector: ArrayLike, sigma_rad: float) -> None:
        """Add one observation: ``b_vector`` measured in body, ``r_vector`` in reference.

        Both (3,), normalised here (any non-zero length); ``sigma_rad`` > 0 is the per-axis
        angular error of ``b_vector`` (rad).
        """
        b = _unit(b_vector, "b_vector")
        r = _unit(r_vector, "r_vector")
        sigma = float(sigma_rad)
        if not (math.isfinite(sigma) and sigma > 0.0):
            raise ValueError(f"sigma_rad must be positive and finite, got {sigma_rad!r}")
        w = sigma**-2  # Q1 (un-normalised weight)
        if self._n == 0:
            self._first_b, self._first_r = b, r
        self._B_weighted += w * np.outer(b, r)  # Q2
        self._information += w * (np.eye(3) - np.outer(b, b))  # Q11
        self._b_weighted_sum += w * b
        self._r_weighted_sum += w * r
        self._weight_sum += w
        self._n += 1

    def solve(self) -> QuestSolution:
        """QUEST on everything added so far (at least one observation)."""
        if self._n == 0:
            raise ValueError("QuestAccumulator.solve needs at least one observation (add)")
        sigma_tot2 = 1.0 / self._weight_sum  # Q1
        B = self._B_weighted * sigma_tot2  # Q1, Q2: B = Σ a_i b_i r_iᵀ
        info_normalised = self._information * sigma_tot2  # Σ a_i (I - b_i b_iᵀ)
        eig_min = float(np.linalg.eigvalsh(info_normalised)[0])

        if eig_min < OBSERVABILITY_EIGENVALUE_MIN:
            lam = _lambda_max_symmetric(B)  # a double root of Q4: not by Newton (Q5)
            loss = 1.0 - lam  # Q10
            # Mean directions, or the first pair if they cancel (e.g. b and -b).
            use_mean = (
                min(np.linalg.norm(self._r_weighted_sum), np.linalg.norm(self._b_weighted_sum))
                > 1e-6 * self._weight_sum
            )
            r_dir = _unit(self._r_weighted_sum, "r") if use_mean else self._first_r
            b_dir = _unit(self._b_weighted_sum, "b") if use_mean else self._first_b
            q = _shortest_arc(r_dir, b_dir)
            return QuestSolution(
                q_b_r=quat_canonical(q),
                covariance_rad2=np.full((3, 3), np.inf),
                three_sigma_deg=math.inf,
                observable=False,
                loss=loss,
                lambda_max=lam,
                n_observations=self._n,
                flip_axis=None,
            )

        lam = _lambda_max(B, lam0=1.0)  # Q5: λ₀ = Σ a_i = 1
        loss = 1.0 - lam  # Q10
        # Q9: the reference frame (unrotated or flipped about x, y, z) with the largest |γ|.
        best_axis: int | None = None
        X, gamma = _gibbs_adjugate(B, lam)
        for axis in range(3):
            X_k, gamma_k = _gibbs_adjugate(B @ _R_FLIP[axis].T, lam)  # Q9: B' = B R_kᵀ
            if abs(gamma_k) > abs(gamma):
                best_axis, X, gamma = axis, X_k, gamma_k
        q = np.concatenate([-X, [gamma]])  # Q8 in the Hamilton convention
        q /= np.linalg.norm(q)  # Q8
        if best_axis is not None:
            q = quat_multiply(q, _Q_FLIP[best_axis])  # Q9: q_b_r = q_b_r' ⊗ q_r'_r

        P = np.linalg.inv(self._information)  # Q11
        P = 0.5 * (P + P.T)
        three_sigma_deg = 3.0 * math.degrees(math.sqrt(float(np.linalg.eigvalsh(P)[-1])))
        return QuestSolution(
            q_b_r=quat_canonical(q),
            covariance_rad2=P,
            three_sigma_deg=three_sigma_deg,
            observable=True,
            loss=loss,
            lambda_max=lam,
            n_observations=self._n,
            flip_axis=best_axis,
        )


def quest(b_vectors: ArrayLike, r_vectors: ArrayLike, sigma_rad: ArrayLike) -> QuestSolution:
    """Optimal ``q_b_r`` with ``b_i ≈ R(q_b_r) r_i`` (Wahba's problem) and its covariance.

    ``b_vectors``: (N, 3) measured directions in the body (observation) frame;
    ``r_vectors``: (N, 3) the same directions in the reference frame (LL for Sungaze);
    both normalised here. ``sigma_rad``: scalar or (N,), per-axis angular error of each
    ``b_i`` (rad); the weights are ``a_i ∝ σ_i⁻²`` (Q1).

    >>> sol = quest([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], 1e-3)
    >>> (np.round(sol.q_b_r, 6) + 0.0).tolist(), sol.observable
    ([0.0, 0.0, -0.707107, 0.707107], True)
    """
    b = np.asarray(b_vectors, dtype=float)
    r = np.asarray(r_vectors, dtype=float)
    if b.ndim != 2 or b.shape[1] != 3 or b.shape[0] == 0:
        raise ValueError(f"b_vectors must have shape (N, 3) with N >= 1, got {b.shape}")
    if r.shape != b.shape:
        raise ValueError(f"r_vectors must have the shape of b_vectors {b.shape}, got {r.shape}")
    sig = np.asarray(sigma_rad, dtype=float)
    if sig.ndim == 0:
        sig = np.full(b.shape[0], float(sig))
    if sig.shape != (b.shape[0],):
        raise ValueError(f"sigma_rad must be a scalar or have shape ({b.shape[0]},)")
    acc = QuestAccumulator()
    for b_i, r_i, s_i in zip(b, r, sig, strict=True):
        acc.add(b_i, r_i, float(s_i))
    return acc.solve()


def _unit(v: ArrayLike, name: str) -> FloatArray:
    """``v`` (3,) normalised; ``ValueError`` naming ``name`` if not finite or zero."""
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be a finite 3-vector, got {v!r}")
    n = float(np.linalg.norm(a))
    if n < 1e-12:
        raise ValueError(f"{name} must be non-zero, got {v!r}")
    out: FloatArray = a / n
    return out
