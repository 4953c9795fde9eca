"""Frames: the compiled and the vectorised rotation agree, and every conversion inverts."""

from __future__ import annotations

import math

import numpy as np

from auvsim.physics.frames import (
    FLIP,
    attitude_rates,
    euler_angles,
    mujoco_from_ned,
    ned_from_mujoco,
    quat_to_rot,
    quaternion_from_euler,
    quaternion_product,
    rotation_matrices,
    rotation_rpy,
    skew,
    yaw_of,
)


def _random_quaternions(n: int, seed: int = 4) -> np.ndarray:
    q = np.random.default_rng(seed).standard_normal((n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_compiled_and_vectorised_rotations_agree_and_are_rotations():
    q = _random_quaternions(50)
    vectorised = rotation_matrices(q)
    for k in range(len(q)):
        np.testing.assert_array_equal(quat_to_rot(q[k]), vectorised[k])
    np.testing.assert_allclose(vectorised @ vectorised.transpose(0, 2, 1),
                               np.broadcast_to(np.eye(3), (50, 3, 3)), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(vectorised), 1.0, atol=1e-12)


def test_attitude_rates_invert_each_intervals_rotation():
    """Each interval's rate times its length is the rotation vector of ``C_k^T C_k+1``
    (Rodrigues' formula gives the rotation back), a negated quaternion (the same attitude)
    included, a rotation of 1e-7 rad and none at all too."""
    def product(a, b):  # Hamilton product of [w, x, y, z] quaternions
        return np.r_[a[0] * b[0] - a[1:] @ b[1:], a[0] * b[1:] + b[0] * a[1:]
                     + np.cross(a[1:], b[1:])]

    steps = [(0.1, -0.2, 0.3), (0.0, 0.0, 1e-7), (0.0, 0.0, 0.0), (-0.3, 0.05, -1.2)]
    q = [quaternion_from_euler(0.2, 0.1, 2.5)]
    for rpy in steps:
        q.append(product(q[-1], quaternion_from_euler(*rpy)))
    q[-1] = -q[-1]  # the short way round: -q is q's attitude
    t = np.array([0.0, 2.0, 2.5, 4.0, 4.1])
    rates = attitude_rates(t, np.array(q))
    c = rotation_matrices(np.array(q))
    assert rates.shape == (4, 3) and np.all(rates[2] == 0)
    for k, rpy in enumerate(steps):
        vec = rates[k] * (t[k + 1] - t[k])
        angle = np.linalg.norm(vec)
        u = vec / angle if angle else vec
        kx = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
        back = np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx
        np.testing.assert_allclose(back, c[k].T @ c[k + 1], atol=1e-12)
        np.testing.assert_allclose(back, rotation_rpy(*rpy), atol=1e-12)


def test_skew_is_the_cross_product_for_one_vector_and_for_arrays():
    v, a = np.random.default_rng(6).standard_normal((2, 5, 3))
    np.testing.assert_allclose(skew(v) @ a[..., None], np.cross(v, a)[..., None], atol=1e-15)
    np.testing.assert_array_equal(skew(v[0]), skew(v)[0])
    np.testing.assert_array_equal(skew(v[0]), -skew(v[0]).T)


def test_euler_round_trip_matches_the_zyx_rotation():
    rng = np.random.default_rng(5)
    for _ in range(20):
        rpy = rng.uniform([-3, -1.5, -3], [3, 1.5, 3])
        q = quaternion_from_euler(*rpy)
        np.testing.assert_allclose(np.linalg.norm(q), 1.0, atol=1e-15)
        np.testing.assert_allclose(euler_angles(q), rpy, atol=1e-12)
        np.testing.assert_allclose(quat_to_rot(q), rotation_rpy(*rpy), atol=1e-12)


def test_mujoco_conversion_inverts():
    q = quaternion_from_euler(0.1, -0.2, 2.0)
    position, v_body = np.array([3.0, -4.0, 20.0]), np.array([1.5, 0.2, -0.1])
    qpos, v_world = mujoco_from_ned(position, q, v_body)
    np.testing.assert_array_equal(qpos[:3], position * FLIP)  # NWU: y west, z up
    qvel = np.r_[v_world, 0.01, -0.02, 0.03]
    state = ned_from_mujoco(qpos, qvel)
    np.testing.assert_allclose(state["position_ned"], position)
    np.testing.assert_allclose(state["quaternion"], q)
    np.testing.assert_allclose(state["velocity_body"], v_body, atol=1e-15)
    np.testing.assert_allclose(state["velocity_ned"], quat_to_rot(q) @ v_body, atol=1e-15)
    np.testing.assert_array_equal(state["angular_rate"], [0.01, 0.02, -0.03])


def test_quaternions_of_arrays_are_those_of_each_row():
    rpy = np.random.default_rng(6).uniform(-4, 4, (200, 3))
    rows = quaternion_from_euler(*rpy.T)
    assert rows.shape == (200, 4) and quaternion_from_euler(*rpy[0]).shape == (4,)
    np.testing.assert_array_equal(rows, [quaternion_from_euler(*r) for r in rpy])
    # The Hamilton product composes the rotations, broadcast over rows.
    a, b = _random_quaternions(50), _random_quaternions(50, seed=7)
    np.testing.assert_allclose(rotation_matrices(quaternion_product(a, b)),
                               rotation_matrices(a) @ rotation_matrices(b), atol=1e-12)
    np.testing.assert_allclose(rotation_matrices(quaternion_product(a[0], b)),
                               rotation_matrices(a[:1]) @ rotation_matrices(b), atol=1e-12)


def test_yaw_of_one_rotation_and_of_a_stack():
    """Known answers: the yaw of ZYX rotations (roll and pitch leave it alone) for one
    (a float) and for a stack of them (each, in an array)."""
    yaws = np.radians([-170.0, -30.0, 0.0, 45.0, 179.0])
    stack = np.stack([rotation_rpy(0.3, -0.2, y) for y in yaws])
    assert isinstance(yaw_of(stack[1]), float)
    assert math.isclose(yaw_of(stack[1]), yaws[1], abs_tol=1e-12)
    np.testing.assert_allclose(yaw_of(stack), yaws, atol=1e-12)
