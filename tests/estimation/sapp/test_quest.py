"""QUEST (estimation/sapp/quest.py) against scipy's SVD Wahba solver, hand-computed covariances,
Monte Carlo consistency (NEES) and a Sungaze-like sun arc."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation.sapp.quest import QuestAccumulator, quest


def _unit_rows(v: np.ndarray) -> np.ndarray:
    out: np.ndarray = v / np.linalg.norm(v, axis=-1, keepdims=True)
    return out


def _perturb(b: np.ndarray, sigma: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """QUEST's measurement model: isotropic tangent error of sigma rad per axis about b."""
    out = np.empty_like(b)
    for i, (v, s) in enumerate(zip(b, sigma, strict=True)):
        helper = np.eye(3)[int(np.argmin(np.abs(v)))]
        t1 = np.cross(v, helper)
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(v, t1)
        n1, n2 = rng.normal(0.0, s, 2)
        w = v + n1 * t1 + n2 * t2
        out[i] = w / np.linalg.norm(w)
    return out


def _angle_between(q1: np.ndarray, q2: np.ndarray) -> float:
    return float((Rotation.from_quat(q1) * Rotation.from_quat(q2).inv()).magnitude())


def _random_problem(
    rng: np.random.Generator, n: int
) -> tuple[Rotation, np.ndarray, np.ndarray, np.ndarray]:
    R_b_r = Rotation.random(random_state=rng)
    r = _unit_rows(rng.normal(size=(n, 3)))
    sigma = rng.uniform(2e-4, 2e-3, n)
    return R_b_r, R_b_r.apply(r), r, sigma


def test_noise_free_recovers_truth_and_matches_scipy() -> None:
    rng = np.random.default_rng(1981)
    worst_truth = worst_scipy = worst_loss = 0.0
    for trial in range(60):
        R_b_r, b, r, sigma = _random_problem(rng, 2 + trial % 5)
        sol = quest(b, r, sigma)
        ref, _ = Rotation.align_vectors(b, r, weights=sigma**-2)
        worst_truth = max(worst_truth, _angle_between(sol.q_b_r, R_b_r.as_quat()))
        worst_scipy = max(worst_scipy, _angle_between(sol.q_b_r, ref.as_quat()))
        worst_loss = max(worst_loss, abs(sol.loss), abs(sol.lambda_max - 1.0))
        assert sol.observable
        assert sol.q_b_r[3] >= 0.0
        assert abs(np.linalg.norm(sol.q_b_r) - 1.0) < 1e-14
    assert worst_truth < 1e-10
    assert worst_scipy < 1e-10
    assert worst_loss < 1e-12


def test_noisy_matches_scipy_and_stays_within_the_noise() -> None:
    rng = np.random.default_rng(7)
    for trial in range(60):
        R_b_r, b_true, r, sigma = _random_problem(rng, 2 + trial % 6)
        b = _perturb(b_true, sigma, rng)
        sol = quest(b, r, sigma)
        ref, _ = Rotation.align_vectors(b, r, weights=sigma**-2)
        # Both solve the same weighted Wahba problem: same optimum.
        assert _angle_between(sol.q_b_r, ref.as_quat()) < 1e-9
        # The loss is Wahba's: ½ Σ a_i |b_i - A r_i|², a_i normalised.
        a = sigma**-2 / np.sum(sigma**-2)
        A = Rotation.from_quat(sol.q_b_r).as_matrix()
        loss = 0.5 * float(np.sum(a * np.sum((b - r @ A.T) ** 2, axis=1)))
        assert abs(sol.loss - loss) < 1e-12
        # The error from the truth is within the noise: Mahalanobis distance < 5 sigma.
        theta_b = (R_b_r * Rotation.from_quat(sol.q_b_r).inv()).as_rotvec()
        assert float(theta_b @ np.linalg.solve(sol.covariance_rad2, theta_b)) < 25.0


@pytest.mark.parametrize("angle_deg", [179.9, 180.0])
@pytest.mark.parametrize(
    "axis", [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, -2.0, 0.5)]
)
def test_near_180_degree_rotations_recovered_exactly(
    angle_deg: float, axis: tuple[float, float, float]
) -> None:
    rng = np.random.default_rng(180)
    R_b_r = Rotation.from_rotvec(math.radians(angle_deg) * np.array(axis) / np.linalg.norm(axis))
    r = _unit_rows(rng.normal(size=(3, 3)))
    sol = quest(R_b_r.apply(r), r, 1e-3)
    assert _angle_between(sol.q_b_r, R_b_r.as_quat()) < 1e-10
    assert sol.flip_axis is not None  # the sequential rotation did the work


def test_small_rotation_uses_the_unrotated_frame() -> None:
    rng = np.random.default_rng(3)
    R_b_r = Rotation.from_rotvec([0.01, -0.02, 0.03])
    r = _unit_rows(rng.normal(size=(4, 3)))
    sol = quest(R_b_r.apply(r), r, 1e-3)
    assert sol.flip_axis is None
    assert _angle_between(sol.q_b_r, R_b_r.as_quat()) < 1e-12


@pytest.mark.parametrize("phi_deg", [5.0, 30.0, 90.0, 150.0])
def test_two_vector_covariance_matches_hand_computation(phi_deg: float) -> None:
    # Equal sigmas, vectors phi apart: information σ⁻²(2I - b1b1ᵀ - b2b2ᵀ) has eigenvalues
    # 2σ⁻² (about b1 x b2) and σ⁻²(1 ± cos φ) in the plane, so the variances are
    # σ²/2, σ²/(1 + cos φ), σ²/(1 - cos φ).
    sigma = 5e-4
    phi = math.radians(phi_deg)
    R_b_r = Rotation.from_euler("zyx", [40.0, -10.0, 5.0], degrees=True)
    r = np.array([[1.0, 0.0, 0.0], [math.cos(phi), math.sin(phi), 0.0]])
    sol = quest(R_b_r.apply(r), r, sigma)
    expected = sorted(
        [sigma**2 / 2, sigma**2 / (1 + math.cos(phi)), sigma**2 / (1 - math.cos(phi))]
    )
    np.testing.assert_allclose(np.linalg.eigvalsh(sol.covariance_rad2), expected, rtol=1e-9)
    # The weak axis lies in the plane of the two body vectors: along their bisector when
    # φ < 90 deg (information σ⁻²(1 - cos φ)), along their difference when φ > 90 deg.
    b1, b2 = R_b_r.apply(r)
    weak_expected = b1 + b2 if phi_deg < 90.0 else b1 - b2
    weak_axis = np.linalg.eigh(sol.covariance_rad2)[1][:, -1]
    if phi_deg != 90.0:  # at 90 deg the two in-plane variances are equal
        assert abs(weak_axis @ weak_expected) / np.linalg.norm(weak_expected) > 1 - 1e-9
    three_sigma_deg = 3.0 * math.degrees(sigma / math.sqrt(1 - abs(math.cos(phi))))
    assert sol.three_sigma_deg == pytest.approx(three_sigma_deg, rel=1e-9)


def test_covariance_is_honest_nees_over_random_geometries() -> None:
    rng = np.random.default_rng(2005)
    trials = 400
    nees = np.empty(trials)
    for k in range(trials):
        R_b_r, b_true, r, sigma = _random_problem(rng, 2 + k % 4)
        sol = quest(_perturb(b_true, sigma, rng), r, sigma)
        theta_b = (R_b_r * Rotation.from_quat(sol.q_b_r).inv()).as_rotvec()
        nees[k] = theta_b @ np.linalg.solve(sol.covariance_rad2, theta_b)
    # NEES ~ χ²(3): mean 3, standard error sqrt(6/400) = 0.12; allow ±3.5 standard errors.
    assert abs(float(np.mean(nees)) - 3.0) < 0.43


def test_covariance_matches_monte_carlo_in_a_fixed_geometry() -> None:
    # The error is body-frame, left-multiplying: R_true = exp(θ_b) R_estimate. A wrong frame
    # or side would rotate the ellipsoid away from the sampled one.
    rng = np.random.default_rng(11)
    R_b_r = Rotation.from_euler("zyx", [120.0, 30.0, -70.0], degrees=True)
    r = _unit_rows(np.array([[1.0, 0.2, 0.1], [0.9, 0.5, -0.2], [0.3, 0.1, 1.0]]))
    sigma = np.array([3e-4, 1e-3, 2e-3])
    b_true = R_b_r.apply(r)
    P = quest(b_true, r, sigma).covariance_rad2
    thetas = np.empty((800, 3))
    for k in range(len(thetas)):
        sol = quest(_perturb(b_true, sigma, rng), r, sigma)
        thetas[k] = (R_b_r * Rotation.from_quat(sol.q_b_r).inv()).as_rotvec()
    eigval, eigvec = np.linalg.eigh(P)
    sample_var = np.mean((thetas @ eigvec) ** 2, axis=0)
    # Relative standard error of a variance from 800 samples: sqrt(2/800) = 0.05.
    np.testing.assert_allclose(sample_var / eigval, 1.0, atol=0.2)
    assert np.max(np.abs(np.mean(thetas @ eigvec, axis=0)) / np.sqrt(eigval)) < 0.15


def _sun_ll(hour_angle_rad: np.ndarray, dec_rad: float, lat_rad: float) -> np.ndarray:
    """Sun unit vector in LL (North, East, Down) from hour angle, declination, latitude."""
    north = math.cos(lat_rad) * math.sin(dec_rad) - math.sin(lat_rad) * math.cos(dec_rad) * np.cos(
        hour_angle_rad
    )
    east = -math.cos(dec_rad) * np.sin(hour_angle_rad)
    up = math.sin(lat_rad) * math.sin(dec_rad) + math.cos(lat_rad) * math.cos(dec_rad) * np.cos(
        hour_angle_rad
    )
    return np.stack([north, east, -up], axis=-1)


def test_sungaze_three_sigma_shrinks_as_the_sun_arc_grows() -> None:
    # Gusev-like latitude, mid-afternoon sun; one image every 30 s for 10 min. Mars turns
    # 350.89 deg/day (IAU 2009), about 2.44 deg of hour angle in 10 min.
    rng = np.random.default_rng(2004)
    rate_rad_s = math.radians(350.89198226) / 88775.244  # per second of a sol
    t_s = np.arange(0.0, 601.0, 30.0)
    sun_ll = _sun_ll(math.radians(45.0) + rate_rad_s * t_s, math.radians(-10.0), -0.2543)
    R_b_ll = Rotation.from_euler("zyx", [-75.0, 4.0, -6.0], degrees=True).inv()
    sigma = 2e-4  # rad per axis per image (Pancam ~0.28 mrad/pixel, sub-pixel centroid)
    sun_b = _perturb(R_b_ll.apply(sun_ll), np.full(len(t_s), sigma), rng)

    acc = QuestAccumulator()
    three_sigma = []
    for b, r in zip(sun_b, sun_ll, strict=True):
        acc.add(b, r, sigma)
        sol = acc.solve()
        three_sigma.append(sol.three_sigma_deg)
        if acc.n_observations == 1:
            assert not sol.observable
    assert math.isinf(three_sigma[0])
    assert all(b < a for a, b in itertools.pairwise(three_sigma))
    # The weak axis is the sun line: rotation about it is what only the arc reveals.
    weak_axis = np.linalg.eigh(sol.covariance_rad2)[1][:, -1]
    assert abs(weak_axis @ np.mean(sun_b, axis=0)) > 0.999
    # Hand estimate for the roll about the sun line: N images uniform over an arc Δ give
    # information ≈ σ⁻² Σ (x_i - x̄)² = σ⁻² Δ² N(N + 1)/(12(N - 1)); N = 21, Δ ≈ 2.34 deg
    # (2.44 deg of hour angle x cos dec): 3σ ≈ 0.6 deg.
    arc_rad = float(np.arccos(np.clip(sun_ll[0] @ sun_ll[-1], -1.0, 1.0)))
    n = len(t_s)
    expected_3sigma_deg = 3 * math.degrees(
        sigma / (arc_rad * math.sqrt(n * (n + 1) / (12 * (n - 1))))
    )
    assert three_sigma[-1] == pytest.approx(expected_3sigma_deg, rel=0.05)
    # And the estimate is within it.
    err_deg = math.degrees(_angle_between(sol.q_b_r, R_b_ll.as_quat()))
    assert err_deg < three_sigma[-1]
    # The batch function gives the accumulator's answer.
    batch = quest(sun_b, sun_ll, sigma)
    np.testing.assert_array_equal(batch.q_b_r, sol.q_b_r)


def test_scaling_all_sigmas_scales_only_the_covariance() -> None:
    rng = np.random.default_rng(5)
    _, b_true, r, sigma = _random_problem(rng, 4)
    b = _perturb(b_true, sigma, rng)
    s1, s2 = quest(b, r, sigma), quest(b, r, 10.0 * sigma)
    assert _angle_between(s1.q_b_r, s2.q_b_r) < 1e-12
    np.testing.assert_allclose(s2.covariance_rad2, 100.0 * s1.covariance_rad2, rtol=1e-10)
    assert s2.three_sigma_deg == pytest.approx(10.0 * s1.three_sigma_deg, rel=1e-10)


def test_single_or_parallel_directions_are_flagged_not_crashed() -> None:
    R_b_r = Rotation.from_euler("zyx", [30.0, 20.0, 10.0], degrees=True)
    r = _unit_rows(np.array([[0.3, -0.4, 0.866]]))
    for rows in (r, np.repeat(r, 3, axis=0)):
        sol = quest(R_b_r.apply(rows), rows, 1e-3)
        assert not sol.observable
        assert math.isinf(sol.three_sigma_deg)
        assert np.all(np.isinf(sol.covariance_rad2))
        # The reported attitude still maps the direction onto its measurement.
        b_pred = Rotation.from_quat(sol.q_b_r).apply(rows[0])
        np.testing.assert_allclose(b_pred, R_b_r.apply(rows[0]), atol=1e-12)
        assert abs(sol.loss) < 1e-12
    # Opposite directions (b, -b) are one line: still unobservable about it.
    rows = np.array([[0.0, 0.6, 0.8], [0.0, -0.6, -0.8]])
    sol = quest(R_b_r.apply(rows), rows, 1e-3)
    assert not sol.observable
    np.testing.assert_allclose(
        Rotation.from_quat(sol.q_b_r).apply(rows[0]), R_b_r.apply(rows[0]), atol=1e-12
    )
    # Two directions 1e-8 rad apart are as good as one.
    rows = np.array([[1.0, 0.0, 0.0], [1.0, 1e-8, 0.0]])
    assert not quest(R_b_r.apply(rows), rows, 1e-3).observable
    # ...while 1e-3 rad apart they are observable, with a huge but finite 3σ.
    rows = np.array([[1.0, 0.0, 0.0], [1.0, 1e-3, 0.0]])
    sol = quest(R_b_r.apply(rows), rows, 1e-3)
    assert sol.observable and 50.0 < sol.three_sigma_deg < math.inf


def test_unobservable_lambda_max_is_exact_not_a_wandering_double_root() -> None:
    # One direction seen once or repeatedly: K's eigenvalues are exactly {1, 1, -1, -1}, so
    # λ_max = 1 and the loss is 0. As a double root of the characteristic equation (Q4), λ_max
    # is only determined to ~sqrt(ulp) after rounding of its coefficients, and Newton from
    # λ₀ = 1 wandered up to 1e-6 away or fell onto -1 (loss 2). The symmetric eigensolver gets
    # it to a few ulp: 8 eps bounds the rounding of K's entries and of the solver.
    rng = np.random.default_rng(1)
    eps = np.finfo(float).eps
    for _ in range(300):
        R_b_r = Rotation.random(random_state=rng)
        rows = np.repeat(_unit_rows(rng.normal(size=(1, 3))), rng.integers(1, 5), axis=0)
        sol = quest(R_b_r.apply(rows), rows, 10.0 ** rng.uniform(-5.0, -1.0))
        assert not sol.observable
        assert abs(sol.lambda_max - 1.0) <= 8 * eps and abs(sol.loss) <= 8 * eps


def test_bad_arguments_raise_value_error_naming_the_parameter() -> None:
    good = np.eye(3)
    with pytest.raises(ValueError, match="b_vectors"):
        quest(np.zeros((0, 3)), np.zeros((0, 3)), 1e-3)
    with pytest.raises(ValueError, match="b_vectors"):
        quest(np.ones(3), np.ones(3), 1e-3)
    with pytest.raises(ValueError, match="r_vectors"):
        quest(good, good[:2], 1e-3)
    with pytest.raises(ValueError, match="sigma_rad"):
        quest(good, good, [1e-3, 1e-3])
    with pytest.raises(ValueError, match="sigma_rad"):
        quest(good, good, 0.0)
    with pytest.raises(ValueError, match="sigma_rad"):
        quest(good, good, math.nan)
    with pytest.raises(ValueError, match="b_vector"):
        quest(np.zeros((3, 3)), good, 1e-3)
    with pytest.raises(ValueError, match="r_vector"):
        quest(good, np.full((3, 3), math.inf), 1e-3)
    with pytest.raises(ValueError, match="add"):
        QuestAccumulator().solve()
