"""Triangulation by the shortest segment between two rays and its covariance (Cheng, Maimone and
Matthies 2005 eqs. 1-11; estimation/vo/triangulation.py, geometry.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimation.camera_model import PinholeCamera
from estimation.vo.geometry import PointedPair
from estimation.vo.stereo_rig import NAVCAM
from estimation.vo.triangulation import midpoint, midpoint_jacobian, triangulate

# A hand-checkable pair: camera axes = body axes, f = 100 px, principal point (50, 50),
# the right eye 0.2 m along +x.
SIMPLE = PointedPair(
    PinholeCamera(101, 101, 100.0, 50.0, 50.0), np.eye(3), np.zeros(3), np.array([0.2, 0, 0])
)
NO_COV = np.zeros((1, 2, 2))


def test_hand_computed_intersection() -> None:
    """Point (0.1, 0.05, 2): left pixel (55, 52.5), right (45, 52.5), disparity f B / z = 10."""
    out = triangulate(SIMPLE, [[55.0, 52.5]], [[45.0, 52.5]], NO_COV, NO_COV)
    np.testing.assert_allclose(out.p_b[0], [0.1, 0.05, 2.0], atol=1e-12)
    assert out.gap_m[0] == pytest.approx(0.0, abs=1e-12)
    # m1, m2: the distances from each eye, sqrt(0.1² + 0.05² + 2²) by symmetry.
    assert out.range_left_m[0] == pytest.approx(math.sqrt(0.01 + 0.0025 + 4.0))
    assert out.range_right_m[0] == pytest.approx(math.sqrt(0.01 + 0.0025 + 4.0))


def test_hand_computed_skew_rays() -> None:
    """Right pixel one row low: the rays r1 ~ (0.05, 0.025, 1) from the origin and
    r2 ~ (-0.05, 0.035, 1) from (0.2, 0, 0) pass each other. Their common normal is
    n = r1 x r2 ~ (-0.01, -0.1, 0.003); the gap is |B . n| / |n| with B = (0.2, 0, 0)."""
    out = triangulate(SIMPLE, [[55.0, 52.5]], [[45.0, 53.5]], NO_COV, NO_COV)
    n = np.array([0.025 - 0.035, -0.05 - 0.05, 0.05 * 0.035 + 0.05 * 0.025])
    assert out.gap_m[0] == pytest.approx(0.2 * abs(n[0]) / np.linalg.norm(n), rel=1e-12)
    # The midpoint solves (P2 - P1) . r_i = 0 (eqs. 3-4): check against a linear solve.
    r1 = np.array([0.05, 0.025, 1.0]) / np.linalg.norm([0.05, 0.025, 1.0])
    r2 = np.array([-0.05, 0.035, 1.0]) / np.linalg.norm([-0.05, 0.035, 1.0])
    B = np.array([0.2, 0.0, 0.0])
    A = np.array([[1.0, -r1 @ r2], [r1 @ r2, -1.0]])
    m1, m2 = np.linalg.solve(A, [B @ r1, B @ r2])
    np.testing.assert_allclose(out.p_b[0], 0.5 * (m1 * r1 + B + m2 * r2), atol=1e-12)


def test_parallel_rays_have_no_intersection() -> None:
    r = np.array([[0.0, 0.0, 1.0]])
    P, gap, m1, _ = midpoint([0, 0, 0], [0.2, 0, 0], r, r)
    assert np.isnan(P).all() and np.isnan(m1).all() and np.isnan(gap).all()


def test_navcam_depth_is_f_b_over_disparity() -> None:
    rig = NAVCAM.at_resolution(256)
    pair = PointedPair.from_rig(rig, 0.0, 0.0)  # looking along body +x
    cam = rig.camera
    d = 12.0
    out = triangulate(pair, [[cam.c_u_px, cam.c_v_px]], [[cam.c_u_px - d, cam.c_v_px]],
                      NO_COV, NO_COV)  # fmt: skip
    depth = cam.f_px * rig.baseline_m / d
    head = np.asarray(rig.head_b)
    # The left eye is half a baseline to the left of the head; the point is straight ahead of it.
    expected = head + np.array([depth, -0.5 * rig.baseline_m, 0.0])
    np.testing.assert_allclose(out.p_b[0], expected, atol=1e-9)


def _pixels_of(pair: PointedPair, p_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    uv_l, uv_r = pair.project(p_b)
    return uv_l, uv_r


def test_analytic_jacobian_matches_finite_differences() -> None:
    rig = NAVCAM.at_resolution(256)
    pair = PointedPair.from_rig(rig, math.radians(20.0), math.radians(-35.0))
    rng = np.random.default_rng(0)
    p_b = pair.c_left_b + pair.R_b_cam @ np.array([0.5, 0.3, 3.0]) + rng.normal(0, 0.3, (5, 3))
    uv_l, uv_r = _pixels_of(pair, p_b)
    uv_r[:, 1] += 0.3  # skew rays: the general case
    q = np.concatenate([uv_l, uv_r], axis=1)

    def point(qq: np.ndarray) -> np.ndarray:
        r1, _ = pair.rays_b(qq[:, :2])
        r2, _ = pair.rays_b(qq[:, 2:])
        P, _, _, _ = midpoint(pair.c_left_b, pair.c_right_b, r1, r2)
        return P

    r1, d1 = pair.rays_b(uv_l)
    r2, d2 = pair.rays_b(uv_r)
    _, _, m1, m2 = midpoint(pair.c_left_b, pair.c_right_b, r1, r2)
    zeros = np.zeros_like(d1)
    J = midpoint_jacobian(
        pair.baseline_b, r1, r2, np.concatenate([d1, zeros], 2), np.concatenate([zeros, d2], 2),
        m1, m2,
    )  # fmt: skip
    h = 1e-4
    numeric = np.stack([(point(q + h * e) - point(q - h * e)) / (2 * h) for e in np.eye(4)], axis=2)
    np.testing.assert_allclose(J, numeric, rtol=1e-6, atol=1e-9)


def test_covariance_matches_a_monte_carlo_of_noisy_matches() -> None:
    """Eq. 11 against 20 000 triangulations of matches perturbed with Σ_l and Σ_r."""
    rig = NAVCAM.at_resolution(256)
    pair = PointedPair.from_rig(rig, 0.0, math.radians(-30.0))
    p_true = pair.c_left_b + pair.R_b_cam @ np.array([-0.4, 0.2, 4.0])
    uv_l, uv_r = _pixels_of(pair, p_true[None])
    cov_l = np.array([[0.04, 0.01], [0.01, 0.02]])  # anisotropic, correlated, px²
    cov_r = np.array([[0.09, -0.02], [-0.02, 0.03]])
    out = triangulate(pair, uv_l, uv_r, cov_l[None], cov_r[None])
    rng = np.random.default_rng(42)
    n = 20_000
    noisy_l = uv_l + rng.multivariate_normal([0, 0], cov_l, n)
    noisy_r = uv_r + rng.multivariate_normal([0, 0], cov_r, n)
    samples = triangulate(pair, noisy_l, noisy_r, np.zeros((n, 2, 2)), np.zeros((n, 2, 2)))
    sample_cov = np.cov(samples.p_b.T)
    predicted = out.cov_b[0]
    # Depth dominates (disparity error); compare in the predicted covariance's own metric.
    whitened = np.linalg.solve(np.linalg.cholesky(predicted), sample_cov)
    whitened = np.linalg.solve(np.linalg.cholesky(predicted), whitened.T)
    np.testing.assert_allclose(whitened, np.eye(3), atol=0.05)
    np.testing.assert_allclose(samples.p_b.mean(axis=0), p_true, atol=3 * math.sqrt(
        predicted[2, 2] / n) + 1e-3)  # fmt: skip


def test_bad_arguments_are_named() -> None:
    with pytest.raises(ValueError, match="cov_left_px2"):
        triangulate(SIMPLE, [[55.0, 52.5]], [[45.0, 52.5]], np.zeros((2, 2)), NO_COV)
    with pytest.raises(ValueError, match="uv_left_px"):
        triangulate(SIMPLE, [[55.0, 52.5]], [[45.0, 52.5], [1.0, 1.0]], NO_COV, NO_COV)
    with pytest.raises(ValueError, match="c1"):
        midpoint([0, 0], [1, 0, 0], np.eye(3)[:1], np.eye(3)[:1])
