"""The numpy quaternion kernels against SciPy's Rotation (an independent implementation), to 1e-14."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from casep.rotations import (
    dcm_to_quat,
    quat_conjugate,
    quat_from_rotvec,
    quat_multiply,
    quat_rotate,
    quat_to_dcm,
    quat_to_rotvec,
    rotation_increments,
)

TOL = 1e-14


def _unit(rng, n):
    q = rng.standard_normal((n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _same_rotation(p, q):
    """Quaternions equal up to the sign (q and -q are one rotation)."""
    s = np.where(np.sum(p * q, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    return np.abs(p - s * q).max()


def _rotvecs(rng):
    """Random rotation vectors, tiny ones and ones near pi about each axis (Shepperd's four branches)."""
    axes = rng.standard_normal((40, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate([rng.uniform(0, np.pi, 30), [1e-12, 1e-8, 1e-4, np.pi - 1e-6] + [0.0] * 6])
    special = np.vstack([np.eye(3) * (np.pi - 1e-3), np.eye(3) * 2.5])
    return np.vstack([axes * angles[:, None], special])


def test_product_rotation_and_conjugate_match_scipy():
    rng = np.random.default_rng(1)
    p, q, v = _unit(rng, 50), _unit(rng, 50), rng.standard_normal((50, 3))
    Rp, Rq = Rotation.from_quat(p, scalar_first=True), Rotation.from_quat(q, scalar_first=True)
    assert _same_rotation(quat_multiply(p, q), (Rp * Rq).as_quat(scalar_first=True)) < TOL
    assert np.abs(quat_rotate(q, v) - Rq.apply(v)).max() < 4 * TOL  # |v| up to ~4
    assert _same_rotation(quat_conjugate(q), Rq.inv().as_quat(scalar_first=True)) < TOL
    assert np.abs(quat_to_dcm(q) - Rq.as_matrix()).max() < TOL


def test_rotation_vectors_both_ways_match_scipy():
    rng = np.random.default_rng(2)
    phi = _rotvecs(rng)
    q = quat_from_rotvec(phi)
    assert _same_rotation(q, Rotation.from_rotvec(phi).as_quat(scalar_first=True)) < TOL
    assert np.abs(quat_to_rotvec(q) - Rotation.from_quat(q, scalar_first=True).as_rotvec()).max() < 4 * TOL
    assert np.abs(quat_to_rotvec(-q) - phi).max() < 1e-8  # the sign of q does not change the rotation
    assert np.all(quat_to_rotvec(np.array([1.0, 0.0, 0.0, 0.0])) == 0.0)  # the identity: no division by zero


def test_dcm_to_quat_matches_scipy_in_every_branch():
    rng = np.random.default_rng(3)
    for phi in _rotvecs(rng):
        C = Rotation.from_rotvec(phi).as_matrix()
        q = dcm_to_quat(C)
        assert q[0] >= 0
        assert _same_rotation(q, Rotation.from_matrix(C).as_quat(scalar_first=True)) < TOL, phi


def test_rotation_increments_are_the_navigators_attitude_steps():
    """A solution propagated from the increments steps by exactly them: the like-with-like the checks use."""
    from casep.navigation.strapdown import increments_from_rates, propagate_attitude

    rng = np.random.default_rng(4)
    t = np.arange(400) / 100.0
    w = 0.3 * rng.standard_normal((400, 3)) + np.sin(2 * np.pi * 31.0 * t)[:, None]  # vibration at 31 Hz
    q = propagate_attitude(np.array([1.0, 0.0, 0.0, 0.0]), increments_from_rates(t, w, np.zeros_like(w)))
    steps = quat_to_rotvec(quat_multiply(quat_conjugate(q[:-1]), q[1:]))
    phi = rotation_increments(t, w)
    assert np.abs(steps - phi).max() < 1e-12 * np.abs(phi).max() * 400
    assert np.abs(phi - 0.5 * (w[1:] + w[:-1]) * 0.01).max() > 1e-3  # not the trapezoid: the check could differ
