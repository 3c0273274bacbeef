"""Pseudo-normalised correlation, the vectorised correlation surfaces and the biquadratic
subpixel peak (estimation/vo/correlation.py, search.py; Cheng, Maimone and Matthies 2005 sec. 2)."""

from __future__ import annotations

import numpy as np
import pytest

from estimation.vo import correlation as corr
from estimation.vo.search import PaddedImage, search


def test_offset_and_common_gain_leave_the_score_unchanged() -> None:
    rng = np.random.default_rng(1)
    a = rng.normal(100.0, 20.0, (9, 9))
    b = a + rng.normal(0.0, 5.0, (9, 9))
    reference = corr.pseudo_normalised_correlation(a, b)
    assert 0.8 < reference < 1.0
    # An offset on either window, and one gain on both, change nothing.
    assert corr.pseudo_normalised_correlation(a + 37.0, b - 12.0) == pytest.approx(reference)
    assert corr.pseudo_normalised_correlation(3.0 * a, 3.0 * b + 5.0) == pytest.approx(reference)


def test_a_gain_between_the_windows_costs_two_g_over_one_plus_g_squared() -> None:
    """Unlike NCC, the pseudo-normalised score sees contrast: b = g a scores 2g / (1 + g²)."""
    rng = np.random.default_rng(2)
    a = rng.normal(0.0, 1.0, (7, 7))
    for g in (0.5, 1.0, 1.5, 4.0):
        expected = 2.0 * g / (1.0 + g * g)
        assert corr.pseudo_normalised_correlation(a, g * a + 9.0) == pytest.approx(expected)
    assert corr.pseudo_normalised_correlation(a, -a) == pytest.approx(-1.0)
    assert corr.pseudo_normalised_correlation(np.ones((3, 3)), 2 * np.ones((3, 3))) == 0.0
    with pytest.raises(ValueError, match="a, b"):
        corr.pseudo_normalised_correlation(np.ones((3, 3)), np.ones((3, 4)))


@pytest.mark.parametrize("shape", [(5, 9), (40, 40)])  # the einsum and matchTemplate paths
def test_surfaces_equal_the_score_at_every_position(shape: tuple[int, int]) -> None:
    rng = np.random.default_rng(3)
    t = 7
    n = 3
    templates = rng.uniform(0, 255, (n, t, t)).astype(np.float32)
    regions = rng.uniform(0, 255, (n, shape[0] + t - 1, shape[1] + t - 1)).astype(np.float32)
    regions[1, 2 : 2 + t, 3 : 3 + t] = 0.5 * templates[1] + 40.0  # a planted match
    surfaces = corr.correlation_surfaces(templates, regions)
    assert surfaces.shape == (n, *shape)
    for k in range(n):
        for i in range(0, shape[0], 3):
            for j in range(0, shape[1], 5):
                window = regions[k, i : i + t, j : j + t]
                expected = corr.pseudo_normalised_correlation(templates[k], window)
                assert surfaces[k, i, j] == pytest.approx(expected, abs=2e-5)
    assert surfaces[1, 2, 3] == pytest.approx(0.8, abs=1e-5)  # g = 0.5: 2g / (1 + g²)


def test_biquadratic_peak_is_exact_on_a_quadratic() -> None:
    rng = np.random.default_rng(4)
    y, x = np.mgrid[-1:2, -1:2].astype(float)
    for _ in range(20):
        # A random concave quadratic with its peak inside the 3x3 neighbourhood.
        L = rng.normal(0.0, 1.0, (2, 2))
        A = L @ L.T + 0.2 * np.eye(2)  # -H / 2, positive definite
        peak = rng.uniform(-0.45, 0.45, 2)
        dx, dy = x - peak[0], y - peak[1]
        s = 3.0 - (A[0, 0] * dx * dx + 2 * A[0, 1] * dx * dy + A[1, 1] * dy * dy)
        offset, hessian, ok = corr.biquadratic_peak(s[None])
        assert ok[0]
        np.testing.assert_allclose(offset[0], peak, atol=1e-12)
        np.testing.assert_allclose(hessian[0], -2.0 * A, atol=1e-12)


def test_biquadratic_peak_refuses_minima_saddles_and_far_peaks() -> None:
    y, x = np.mgrid[-1:2, -1:2].astype(float)
    minimum = x**2 + y**2
    saddle = x**2 - y**2
    far = -((x - 3.0) ** 2) - y**2  # maximum 3 px away: not this neighbourhood's peak
    _, _, ok = corr.biquadratic_peak(np.stack([minimum, saddle, far]))
    assert not ok.any()
    with pytest.raises(ValueError, match="samples"):
        corr.biquadratic_peak(np.zeros((2, 3, 4)))


def test_peak_covariance_is_the_scaled_inverse_curvature_plus_floor() -> None:
    H = np.array([[[-2.0, 0.5], [0.5, -1.0]]])
    cov = corr.peak_covariance(H, 0.01, 0.1)
    np.testing.assert_allclose(cov[0], 0.01 * np.linalg.inv(-H[0]) + 0.01 * np.eye(2))
    with pytest.raises(ValueError, match="hessian"):
        corr.peak_covariance(-H, 0.01, 0.1)
    with pytest.raises(ValueError, match="scale"):
        corr.peak_covariance(H, 0.0, 0.1)


def test_search_finds_a_subpixel_shift_and_never_leaves_the_image() -> None:
    """A smooth image shifted by a known subpixel amount is found to a few hundredths."""
    rng = np.random.default_rng(5)
    from scipy import ndimage

    base = ndimage.gaussian_filter(rng.normal(0.0, 1.0, (80, 80)), 1.5)
    shift = np.array([0.3, -0.2])  # (du, dv)
    moved = ndimage.shift(base, (shift[1], shift[0]), order=3, mode="nearest")
    first, second = PaddedImage(base, 20), PaddedImage(moved, 20)
    centres = np.array([[30.0, 30.0], [45.0, 50.0], [3.0, 40.0]])  # the last is at the edge
    templates, inside = first.templates_at(centres, 9)
    np.testing.assert_array_equal(inside, [True, True, False])
    start = np.rint(centres).astype(int) - 4
    found = search(
        templates, second, start[:, 1], start[:, 0], 9, 9, cov_scale=0.01, min_sigma_px=0.0
    )
    assert found.ok[:2].all()
    np.testing.assert_allclose(found.uv_px[:2] - centres[:2], [shift, shift], atol=0.05)
    assert (found.score[:2] > 0.95).all()
    # The edge feature's candidates include windows leaving the image; none may win there.
    assert not found.ok[2] or found.uv_px[2, 0] >= 4
