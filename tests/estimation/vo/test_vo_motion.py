"""Motion estimation: the closed-form weighted fit, RANSAC and the maximum-likelihood
refinement (Cheng, Maimone and Matthies 2005 eqs. 12-17; estimation/vo/motion.py, ml_motion.py,
odometry.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation.vo.ml_motion import refine_ml
from estimation.vo.motion import fit_rigid, motion_weights, ransac_motion
from estimation.vo.odometry import body_motion

R_TRUE = Rotation.from_euler("ZYX", [4.0, -1.5, 2.0], degrees=True).as_matrix()
T_TRUE = np.array([-0.45, 0.06, 0.02])


def _points(rng: np.random.Generator, n: int) -> np.ndarray:
    """Terrain-like points in front of a mast camera: 2-8 m ahead, spread sideways."""
    return np.column_stack(
        [rng.uniform(2.0, 8.0, n), rng.uniform(-3.0, 3.0, n), rng.uniform(-0.5, 1.5, n)]
    )


def _stereo_like_covariances(p: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Anisotropic covariances: range error growing as range², cross-range as range,
    elongated along the line of sight from the mast head (Cheng, Maimone and Matthies 2005's error
    ellipsoids)."""
    covs = []
    for point in p:
        los = point / np.linalg.norm(point)
        r = np.linalg.norm(point)
        basis = np.linalg.qr(np.column_stack([los, rng.normal(size=(3, 2))]))[0]
        sig = np.array([0.004 * r * r, 0.001 * r, 0.001 * r])
        covs.append(basis @ np.diag(sig**2) @ basis.T)
    return np.array(covs)


def test_closed_form_recovers_a_known_transform_exactly() -> None:
    rng = np.random.default_rng(0)
    p = _points(rng, 30)
    c = p @ R_TRUE.T + T_TRUE
    R, T = fit_rigid(p, c, rng.uniform(0.1, 1.0, 30))
    np.testing.assert_allclose(R, R_TRUE, atol=1e-12)
    np.testing.assert_allclose(T, T_TRUE, atol=1e-12)


def test_closed_form_agrees_with_scipys_weighted_wahba_solver() -> None:
    """With noise, the weighted fit is the weighted Wahba problem of the centred points,
    which scipy's Rotation.align_vectors solves independently (Kabsch/SVD)."""
    rng = np.random.default_rng(1)
    p = _points(rng, 40)
    w = rng.uniform(0.1, 1.0, 40)
    c = p @ R_TRUE.T + T_TRUE + rng.normal(0.0, 0.02, (40, 3))
    R, T = fit_rigid(p, c, w)
    p_bar = w @ p / w.sum()
    c_bar = w @ c / w.sum()
    reference, _ = Rotation.align_vectors(c - c_bar, p - p_bar, weights=w)
    np.testing.assert_allclose(R, reference.as_matrix(), atol=1e-10)
    np.testing.assert_allclose(T, c_bar - R @ p_bar, atol=1e-12)


def test_closed_form_never_returns_a_reflection() -> None:
    rng = np.random.default_rng(2)
    p = rng.normal(size=(3, 3))
    c = p * np.array([1.0, 1.0, -1.0])  # a mirror image: the best rotation is not it
    R, _ = fit_rigid(p, c, np.ones(3))
    assert np.linalg.det(R) == pytest.approx(1.0)


def test_batched_fit_matches_one_at_a_time() -> None:
    rng = np.random.default_rng(3)
    p = _points(rng, 24).reshape(4, 6, 3)
    c = p @ R_TRUE.T + T_TRUE + rng.normal(0.0, 0.05, p.shape)
    w = rng.uniform(0.2, 1.0, (4, 6))
    R, T = fit_rigid(p, c, w)
    for k in range(4):
        Rk, Tk = fit_rigid(p[k], c[k], w[k])
        np.testing.assert_allclose(R[k], Rk, atol=1e-12)
        np.testing.assert_allclose(T[k], Tk, atol=1e-12)


def test_weights_follow_eq_14() -> None:
    a = np.array([np.eye(3) * 0.01, np.eye(3) * 0.02])
    b = np.array([np.eye(3) * 0.01, np.eye(3) * 0.01])
    w = motion_weights(a, b)
    raw = 1.0 / (np.linalg.det(a) + np.linalg.det(b))
    np.testing.assert_allclose(w, raw / raw.max())
    with pytest.raises(ValueError, match="cov_prev"):
        motion_weights(-a, b)


def _gap_3d(p: np.ndarray, c: np.ndarray):  # type: ignore[no-untyped-def]
    """A reprojection-like gap for unit tests: the 3D distance in mm stands for pixels."""

    def gap(R: np.ndarray, T: np.ndarray) -> np.ndarray:
        moved = np.einsum("kij,nj->kni", R, p) + T[:, None, :]
        out: np.ndarray = 1000.0 * np.linalg.norm(moved - c[None], axis=2)
        return out

    return gap


def test_ransac_rejects_planted_outliers() -> None:
    rng = np.random.default_rng(4)
    n, n_bad = 80, 25
    p = _points(rng, n)
    c = p @ R_TRUE.T + T_TRUE + rng.normal(0.0, 0.002, (n, 3))
    bad = rng.choice(n, n_bad, replace=False)
    c[bad] += rng.uniform(0.1, 1.0, (n_bad, 3)) * rng.choice([-1, 1], (n_bad, 3))
    result = ransac_motion(p, c, np.ones(n), _gap_3d(p, c), iterations=100, sample_size=6,
                           threshold_px=10.0, rng=np.random.default_rng(0))  # fmt: skip
    is_bad = np.zeros(n, dtype=bool)
    is_bad[bad] = True
    np.testing.assert_array_equal(result.inliers, ~is_bad)
    assert result.score == n - n_bad
    np.testing.assert_allclose(result.R, R_TRUE, atol=2e-4)
    np.testing.assert_allclose(result.T, T_TRUE, atol=2e-3)
    # A plain least-squares fit over everything is ruined by the same outliers.
    _, T_all = fit_rigid(p, c, np.ones(n))
    assert np.linalg.norm(T_all - T_TRUE) > 10 * np.linalg.norm(result.T - T_TRUE)


def test_ransac_is_repeatable_with_the_same_generator() -> None:
    rng = np.random.default_rng(5)
    p = _points(rng, 30)
    c = p @ R_TRUE.T + T_TRUE + rng.normal(0.0, 0.01, (30, 3))
    args = (p, c, np.ones(30), _gap_3d(p, c))
    kw = {"iterations": 20, "sample_size": 6, "threshold_px": 15.0}
    a = ransac_motion(*args, **kw, rng=np.random.default_rng(7))  # type: ignore[arg-type]
    b = ransac_motion(*args, **kw, rng=np.random.default_rng(7))  # type: ignore[arg-type]
    np.testing.assert_array_equal(a.R, b.R)
    with pytest.raises(ValueError, match="sample_size"):
        ransac_motion(*args, iterations=5, sample_size=2, threshold_px=1.0,
                      rng=np.random.default_rng(0))  # fmt: skip


def test_ransac_rescores_a_given_hypothesis_beside_its_samples() -> None:
    """Mostly outliers: one random sample seldom finds the motion, the first pass's estimate
    given as ``hypothesis`` is scored with the samples and wins."""
    rng = np.random.default_rng(11)
    n, n_good = 60, 15
    p = _points(rng, n)
    c = p @ R_TRUE.T + T_TRUE + rng.normal(0.0, 0.002, (n, 3))
    c[n_good:] += rng.uniform(0.2, 1.0, (n - n_good, 3)) * rng.choice([-1, 1], (n - n_good, 3))
    kw = {"iterations": 1, "sample_size": 6, "threshold_px": 10.0}
    blind = ransac_motion(p, c, np.ones(n), _gap_3d(p, c), **kw, rng=np.random.default_rng(0))  # type: ignore[arg-type]
    guided = ransac_motion(p, c, np.ones(n), _gap_3d(p, c), **kw, rng=np.random.default_rng(0),  # type: ignore[arg-type]
                           hypothesis=(R_TRUE, T_TRUE))  # fmt: skip
    assert blind.score < n_good
    assert guided.score == n_good and guided.inliers[:n_good].all()
    np.testing.assert_allclose(guided.T, T_TRUE, atol=3e-3)


def test_ransac_tries_every_sample_of_a_small_set() -> None:
    """7 inliers among 12 features: 200 random 6-samples miss every all-inlier sample about
    one time in five; C(12, 6) = 924 samples are few enough to try them all, so the inlier
    set is found whatever the generator."""
    rng = np.random.default_rng(21)
    n, n_good = 12, 7
    p = _points(rng, n)
    c = p @ R_TRUE.T + T_TRUE + rng.normal(0.0, 0.002, (n, 3))
    c[n_good:] += rng.uniform(0.2, 1.0, (n - n_good, 3)) * rng.choice([-1, 1], (n - n_good, 3))
    kw = {"iterations": 200, "sample_size": 6, "threshold_px": 10.0}
    for seed in range(20):
        result = ransac_motion(p, c, np.ones(n), _gap_3d(p, c), **kw,  # type: ignore[arg-type]
                               rng=np.random.default_rng(seed))  # fmt: skip
        assert result.score == n_good and result.inliers[:n_good].all()
        np.testing.assert_allclose(result.T, T_TRUE, atol=3e-3)


def test_ml_refinement_beats_least_squares_with_anisotropic_covariances() -> None:
    """Monte Carlo over 40 seeds: stereo-like elongated errors; the ML estimate (eqs. 15-17)
    has a clearly smaller error than the determinant-weighted closed form (eqs. 12-14)."""
    ls_err, ml_err, ls_rot, ml_rot, nees = [], [], [], [], []
    for seed in range(40):
        rng = np.random.default_rng(100 + seed)
        p_true = _points(rng, 60)
        cov_p = _stereo_like_covariances(p_true, rng)
        cov_c = _stereo_like_covariances(p_true @ R_TRUE.T + T_TRUE, rng)
        p = p_true + np.array([rng.multivariate_normal(np.zeros(3), s) for s in cov_p])
        c = p_true @ R_TRUE.T + T_TRUE
        c = c + np.array([rng.multivariate_normal(np.zeros(3), s) for s in cov_c])
        R0, T0 = fit_rigid(p, c, motion_weights(cov_p, cov_c))
        ml = refine_ml(p, c, cov_p, cov_c, R0, T0, max_iterations=20, tol_rad=1e-9, tol_m=1e-8)
        assert ml.converged and ml.iterations < 10
        ls_err.append(np.linalg.norm(T0 - T_TRUE))
        ml_err.append(np.linalg.norm(ml.T - T_TRUE))
        ls_rot.append(Rotation.from_matrix(R0 @ R_TRUE.T).magnitude())
        phi = Rotation.from_matrix(R_TRUE @ ml.R.T).as_rotvec()  # R_true = exp([φ]x) R
        ml_rot.append(np.linalg.norm(phi))
        e = np.concatenate([phi, T_TRUE - ml.T])
        nees.append(e @ np.linalg.solve(ml.covariance, e))
    assert np.mean(ml_err) < 0.3 * np.mean(ls_err)
    assert np.mean(ml_rot) < 0.3 * np.mean(ls_rot)
    # The ML covariance is honest: the normalised error averages the 6 degrees of freedom.
    assert 6.0 * 0.7 < np.mean(nees) < 6.0 * 1.3


def test_ml_is_exact_without_noise_and_reports_non_convergence() -> None:
    rng = np.random.default_rng(6)
    p = _points(rng, 10)
    c = p @ R_TRUE.T + T_TRUE
    cov = np.broadcast_to(np.eye(3) * 1e-4, (10, 3, 3))
    ml = refine_ml(p, c, cov, cov, np.eye(3), np.zeros(3), max_iterations=20, tol_rad=1e-10,
                   tol_m=1e-10)  # fmt: skip
    assert ml.converged
    np.testing.assert_allclose(ml.R, R_TRUE, atol=1e-12)
    np.testing.assert_allclose(ml.T, T_TRUE, atol=1e-12)
    assert ml.cost == pytest.approx(0.0, abs=1e-18)
    one_step = refine_ml(p, c, cov, cov, np.eye(3), np.zeros(3), max_iterations=1,
                         tol_rad=1e-10, tol_m=1e-10)  # fmt: skip
    assert not one_step.converged


def test_body_motion_covariance_matches_a_numerical_jacobian() -> None:
    """(φ, T) of P_c = R P_p + T mapped to (θ, p_b1_b0) of the body motion, to first order."""
    rng = np.random.default_rng(7)
    A = rng.normal(size=(6, 6))
    cov = A @ A.T * 1e-4
    motion = body_motion(R_TRUE, T_TRUE, cov)
    np.testing.assert_allclose(motion.R_b0_b1, R_TRUE.T)
    np.testing.assert_allclose(motion.p_b1_b0, -R_TRUE.T @ T_TRUE)

    def output(x: np.ndarray) -> np.ndarray:
        R = Rotation.from_rotvec(x[:3]).as_matrix() @ R_TRUE
        T = T_TRUE + x[3:]
        theta = Rotation.from_matrix(R.T @ R_TRUE).as_rotvec()  # R_b0_b1 = exp([θ]x) R̂_b0_b1
        return np.concatenate([theta, -R.T @ T])

    h = 1e-7
    J = np.column_stack([(output(h * e) - output(-h * e)) / (2 * h) for e in np.eye(6)])
    np.testing.assert_allclose(motion.covariance, J @ cov @ J.T, rtol=1e-6, atol=1e-14)
    assert motion.q_b0_b1 == pytest.approx(Rotation.from_matrix(R_TRUE.T).as_quat())


def test_ml_refuses_bad_arguments() -> None:
    p = np.zeros((2, 3))
    with pytest.raises(ValueError, match="p_prev"):
        refine_ml(p, p, np.zeros((2, 3, 3)), np.zeros((2, 3, 3)), np.eye(3), np.zeros(3),
                  max_iterations=5, tol_rad=1e-6, tol_m=1e-6)  # fmt: skip
    with pytest.raises(ValueError, match="R0"):
        z3, z33 = np.zeros((3, 3)), np.zeros((3, 3, 3))
        refine_ml(z3, z3, z33, z33, 2 * np.eye(3), np.zeros(3), max_iterations=5, tol_rad=1e-6,
                  tol_m=1e-6)  # fmt: skip
