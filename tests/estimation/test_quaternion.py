"""The quaternion helpers (``estimation.quaternion``) against scipy's ``Rotation``, the
independent reference, on random inputs: arrays and the plain-float per-cycle forms agree
with it to 1e-12."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation.quaternion import (
    q_canonical,
    q_from_rotvec,
    q_multiply,
    q_normalised,
    q_rotate,
    quat_angle_between,
    quat_canonical,
    quat_from_rotvec,
    quat_multiply,
    quat_rotate,
)

RNG = np.random.default_rng(20261202)
N = 500
Q1 = Rotation.random(N, random_state=1).as_quat()
Q2 = Rotation.random(N, random_state=2).as_quat()
V = RNG.normal(size=(N, 3)) * RNG.uniform(1e-3, 1e3, (N, 1))
# rotation vectors from tiny (the series branch) to beyond pi
THETA = RNG.normal(size=(N, 3)) * np.logspace(-10, 0.6, N)[:, None]
TOL = 1e-12


def test_quat_multiply_is_scipys_composition() -> None:
    expected = (Rotation.from_quat(Q1) * Rotation.from_quat(Q2)).as_quat()
    ours = quat_multiply(Q1, Q2)
    assert np.allclose(quat_canonical(ours), quat_canonical(expected), rtol=0.0, atol=TOL)
    floats = np.array([q_multiply(tuple(a), tuple(b)) for a, b in zip(Q1, Q2, strict=True)])
    assert np.allclose(floats, ours, rtol=0.0, atol=TOL)


def test_quat_rotate_is_scipys_apply() -> None:
    expected = Rotation.from_quat(Q1).apply(V)
    scale = np.linalg.norm(V, axis=1, keepdims=True)
    assert np.allclose(quat_rotate(Q1, V) / scale, expected / scale, rtol=0.0, atol=TOL)
    floats = np.array([q_rotate(tuple(q), tuple(v)) for q, v in zip(Q1, V, strict=True)])
    assert np.allclose(floats / scale, expected / scale, rtol=0.0, atol=TOL)


def test_quat_from_rotvec_is_scipys_from_rotvec() -> None:
    expected = quat_canonical(Rotation.from_rotvec(THETA).as_quat())
    assert np.allclose(quat_canonical(quat_from_rotvec(THETA)), expected, rtol=0.0, atol=TOL)
    floats = np.array([q_canonical(q_from_rotvec(tuple(t))) for t in THETA])
    assert np.allclose(floats, expected, rtol=0.0, atol=TOL)


def test_quat_angle_between_is_scipys_magnitude() -> None:
    scaled = Q1 * RNG.uniform(0.5, 2.0, (N, 1))  # scipy normalises; so do we
    expected = (Rotation.from_quat(scaled) * Rotation.from_quat(Q2).inv()).magnitude()
    assert np.allclose(quat_angle_between(scaled, Q2), expected, rtol=0.0, atol=TOL)
    # near zero, where an arccos would lose digits
    small = Rotation.from_rotvec(THETA[:50]) * Rotation.from_quat(Q2[:50])
    expected_small = np.linalg.norm(THETA[:50], axis=1)
    got = quat_angle_between(small.as_quat(), Q2[:50])
    assert np.allclose(got, expected_small, rtol=1e-9, atol=TOL)


def test_q_normalised_and_canonical() -> None:
    for q in Q1 * RNG.uniform(-3.0, 3.0, (N, 1)):
        unit = q_normalised(tuple(q))
        assert np.linalg.norm(unit) == pytest.approx(1.0, abs=1e-15)
        canonical = q_canonical(unit)
        assert canonical[3] >= 0.0
        assert np.allclose(canonical, quat_canonical(q / np.linalg.norm(q)), rtol=0.0, atol=TOL)
