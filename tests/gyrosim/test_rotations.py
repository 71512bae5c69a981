import numpy as np

from gyrosim.rotations import (
    quat_angle_between,
    quat_cumulative_product,
    quat_from_rotvec,
    quat_from_two_vectors,
    quat_multiply,
    quat_rotate,
    quat_to_matrix,
    quat_to_rotvec,
    right_jacobian_apply,
)


def test_rotvec_round_trip_and_matrix_agree():
    rng = np.random.default_rng(0)
    # the logarithm returns angles in [0, π]: draw directions with angles below π
    d = rng.normal(size=(500, 3))
    r = d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(0, 3.1, size=(500, 1))
    q = quat_from_rotvec(r)
    np.testing.assert_allclose(quat_to_rotvec(q), r, atol=1e-12)
    v = rng.normal(size=(500, 3))
    np.testing.assert_allclose(quat_rotate(q, v), np.einsum("nij,nj->ni", quat_to_matrix(q), v), atol=1e-12)


def test_cumulative_product_equals_sequential_loop():
    rng = np.random.default_rng(1)
    steps = quat_from_rotvec(rng.normal(size=(1000, 3)) * 0.1)
    ref = [steps[0]]
    for s in steps[1:]:
        ref.append(quat_multiply(ref[-1], s))
    assert quat_angle_between(np.array(ref), quat_cumulative_product(steps)).max() < 1e-12


def test_two_vectors_including_antiparallel():
    a = np.array([[0, 0, 1.0], [0, 0, 1.0], [1.0, 2, 3]])
    b = np.array([[1.0, 0, 0], [0, 0, -1.0], [-3.0, 1, 0.5]])
    q = quat_from_two_vectors(a, b)
    out = quat_rotate(q, a / np.linalg.norm(a, axis=1, keepdims=True))
    np.testing.assert_allclose(out, b / np.linalg.norm(b, axis=1, keepdims=True), atol=1e-12)


def test_right_jacobian_matches_finite_difference():
    # ω = J_r(φ) φ̇ for q(t) = Exp(φ(t)): compare with the rate from a finite difference of q
    rng = np.random.default_rng(2)
    phi = rng.normal(size=3) * 0.7
    phidot = rng.normal(size=3)
    h = 1e-6
    dq = quat_multiply(
        quat_from_rotvec(phi - h * phidot) * np.array([1, -1, -1, -1]), quat_from_rotvec(phi + h * phidot)
    )
    omega_fd = quat_to_rotvec(dq) / (2 * h)
    np.testing.assert_allclose(right_jacobian_apply(phi, phidot), omega_fd, atol=1e-8)
