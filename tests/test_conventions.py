"""Pin the frame and quaternion conventions of docs/CONVENTIONS.md against scipy and geometry."""

import numpy as np
from scipy.spatial.transform import Rotation

from estimation.quaternion import (
    quat_canonical,
    quat_conjugate,
    quat_from_rotvec,
    quat_multiply,
)


def test_yaw_right_90_maps_body_forward_to_east() -> None:
    # +90 deg about z (Down) turns the rover right, from facing North to facing East.
    R_ll_b = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    expected = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(R_ll_b, expected, atol=1e-15)
    forward_b = np.array([1.0, 0.0, 0.0])
    np.testing.assert_allclose(R_ll_b @ forward_b, [0.0, 1.0, 0.0], atol=1e-15)  # East


def test_q_and_minus_q_are_one_rotation() -> None:
    q = Rotation.from_euler("zyx", [30, -10, 5], degrees=True).as_quat()
    np.testing.assert_allclose(
        Rotation.from_quat(q).as_matrix(), Rotation.from_quat(-q).as_matrix(), atol=1e-15
    )
    np.testing.assert_allclose(quat_canonical(-q), quat_canonical(q), atol=1e-15)


def test_hamilton_product_equals_matrix_product() -> None:
    rng = np.random.default_rng(7)
    for _ in range(50):
        q_a_b = Rotation.random(random_state=rng).as_quat()
        q_b_c = Rotation.random(random_state=rng).as_quat()
        q_a_c = quat_multiply(q_a_b, q_b_c)
        R_a_c = Rotation.from_quat(q_a_b).as_matrix() @ Rotation.from_quat(q_b_c).as_matrix()
        np.testing.assert_allclose(Rotation.from_quat(q_a_c).as_matrix(), R_a_c, atol=1e-12)
        # and it is scipy's own composition
        scipy_q = (Rotation.from_quat(q_a_b) * Rotation.from_quat(q_b_c)).as_quat()
        np.testing.assert_allclose(quat_canonical(q_a_c), quat_canonical(scipy_q), atol=1e-12)


def test_conjugate_inverts_and_rotvec_matches_scipy() -> None:
    rng = np.random.default_rng(8)
    theta = rng.normal(size=(20, 3))
    theta[0] = [1e-12, -2e-12, 0.0]
    q = quat_from_rotvec(theta)
    np.testing.assert_allclose(
        quat_canonical(q), quat_canonical(Rotation.from_rotvec(theta).as_quat()), atol=1e-12
    )
    ident = quat_multiply(q, quat_conjugate(q))
    np.testing.assert_allclose(quat_canonical(ident), np.tile([0, 0, 0, 1.0], (20, 1)), atol=1e-12)


def test_body_correction_on_left_llcorrection_on_right() -> None:
    # Ali et al. 2005: δq^B ⊗ ^Bq^{LL} rotates about a body axis; ^Bq^{LL} ⊗ δq^{LL} about an LL
    # axis.
    q_b_ll = Rotation.from_euler("z", 90, degrees=True).inv().as_quat()
    dq = quat_from_rotvec([0.0, 0.0, 0.1])
    left = Rotation.from_quat(quat_multiply(dq, q_b_ll))
    right = Rotation.from_quat(quat_multiply(q_b_ll, dq))
    # about the common z axis both agree; about x they must differ (non-commuting)
    np.testing.assert_allclose(left.as_matrix(), right.as_matrix(), atol=1e-12)
    dqx = quat_from_rotvec([0.1, 0.0, 0.0])
    # The left factor acts in the body frame: R(δq ⊗ q_b_ll) = R(δq) R_b_ll, and the right
    # one in LL: R(q_b_ll ⊗ δq) = R_b_ll R(δq).
    R_dq = Rotation.from_quat(dqx).as_matrix()
    R_b_ll = Rotation.from_quat(q_b_ll).as_matrix()
    np.testing.assert_allclose(
        Rotation.from_quat(quat_multiply(dqx, q_b_ll)).as_matrix(), R_dq @ R_b_ll, atol=1e-12
    )
    np.testing.assert_allclose(
        Rotation.from_quat(quat_multiply(q_b_ll, dqx)).as_matrix(), R_b_ll @ R_dq, atol=1e-12
    )
    assert not np.allclose(
        Rotation.from_quat(quat_multiply(dqx, q_b_ll)).as_matrix(),
        Rotation.from_quat(quat_multiply(q_b_ll, dqx)).as_matrix(),
    )


def test_settled_heading_follows_the_convention() -> None:
    # The simulator's own attitude: yaw 90 deg (facing East) maps body forward to Site East,
    # and body right to Site South; a nose-up pitch lifts body forward (Down < 0).
    from sim.rover.settle import rotation_s_b

    R_s_b = rotation_s_b(np.zeros(1), np.zeros(1), np.array([np.pi / 2]))[0][0]
    np.testing.assert_allclose(R_s_b @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(R_s_b @ [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], atol=1e-15)
    R_up = rotation_s_b(np.zeros(1), np.array([0.1]), np.zeros(1))[0][0]
    assert (R_up @ [1.0, 0.0, 0.0])[2] < 0.0
