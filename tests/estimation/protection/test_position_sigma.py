"""The onboard position uncertainty against a Monte Carlo of its own error sources: drives
on wheel odometry with a systematic slip error and a heading error, and VO steps whose
errors are drawn from VO's covariance. The 2σ disc must hold ~95 % of the true errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimation.protection.position_sigma import PositionUncertainty

FRACTION = 0.03
HEADING_3SIGMA_RAD = math.radians(6.0)


def test_wheel_odometry_drives_cover_at_two_sigma() -> None:
    rng = np.random.default_rng(7)
    runs = 20_000
    u = PositionUncertainty()
    err = np.zeros((runs, 2))
    for distance in (12.0, 5.0, 20.0, 8.0):  # four drives, each its own slip and heading
        u.begin_drive(HEADING_3SIGMA_RAD)
        slip = rng.normal(0.0, FRACTION, runs)
        heading = rng.normal(0.0, HEADING_3SIGMA_RAD / 3.0, runs)
        for _ in range(4):  # in four segments: the same systematic errors
            u.drove(distance / 4, FRACTION)
            err[:, 0] += slip * distance / 4
            err[:, 1] += heading * distance / 4
    radial = np.hypot(err[:, 0], err[:, 1])
    coverage = float(np.mean(radial <= 2.0 * u.sigma_m))
    assert 0.90 <= coverage <= 0.99
    # σ is the error's spread along its worst direction
    assert u.sigma_m == pytest.approx(float(np.std(radial * np.sign(err[:, 0]))), rel=0.1)


def test_a_vo_update_replaces_the_odometry_growth_by_vos_covariance() -> None:
    u = PositionUncertainty()
    u.begin_drive(HEADING_3SIGMA_RAD)
    u.drove(0.5, FRACTION)
    before_pair = u.sigma_m
    u.drove(0.5, FRACTION)
    grown = u.sigma_m
    cov = np.zeros((6, 6))
    cov[3:6, 3:6] = np.diag([0.004**2, 0.002**2, 0.01**2])
    u.vo_update(before_pair, cov)
    assert u.sigma_m == pytest.approx(math.hypot(before_pair, 0.004))
    assert u.sigma_m < grown
    # and growth starts again from there, linearly in the new distance
    u.drove(1.0, FRACTION)
    heading = HEADING_3SIGMA_RAD / 3.0
    assert u.sigma_m == pytest.approx(
        math.sqrt(math.hypot(before_pair, 0.004) ** 2 + (FRACTION**2 + heading**2))
    )


def test_a_chain_of_vo_steps_covers_at_two_sigma() -> None:
    rng = np.random.default_rng(11)
    runs, step_sigma = 20_000, 0.01
    u = PositionUncertainty()
    u.begin_drive(HEADING_3SIGMA_RAD)
    err = np.zeros((runs, 2))
    cov = np.zeros((6, 6))
    cov[3:6, 3:6] = np.diag([step_sigma**2, step_sigma**2, step_sigma**2])
    for _ in range(30):
        pair = u.sigma_m
        u.drove(0.5, FRACTION)  # grown, then replaced by VO's measurement of the step
        u.vo_update(pair, cov)
        err += rng.normal(0.0, step_sigma, (runs, 2))
    worst_axis = err[:, 0]
    assert u.sigma_m == pytest.approx(float(np.std(worst_axis)), rel=0.05)
    assert 0.93 <= float(np.mean(np.abs(worst_axis) <= 2.0 * u.sigma_m)) <= 0.97
