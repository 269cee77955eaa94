"""The strapdown mechanisation against closed forms.

- Classic coning (a cone of half-angle alpha swept at W rad/s): the body rate and the attitude are
  known in closed form. The previous-sample coning correction leaves a drift of
  ``alpha^2 W (W h)^4 / 60`` rad/s (expand the exact coning increment ``alpha^2/2 (x - sin x)`` and
  the correction ``dtheta_{k-1} x dtheta_k / 12`` in ``x = W h``: they differ by ``alpha^2 x^5 / 60``
  per step); without it the drift is ``alpha^2 W (W h)^2 / 12``.
- Translation with gravity off (an inertial frame): constant acceleration (exact) and a circle at
  constant speed with the body turning with its velocity (the closed-form circle).
- Angle and velocity increments and sampled rates and forces of one motion: the same solution to
  the order of the algorithms.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from casep.navigation.strapdown import (
    body_velocity_increments,
    increments_from_deltas,
    increments_from_rates,
    propagate_attitude,
    propagate_translation,
    quat_from_rotvec,
    quat_multiply,
    quat_rotate,
)

ALPHA, W = math.radians(1.0), 2 * math.pi * 10.0  # a 1 deg cone at 10 Hz


def _cone_truth(t: np.ndarray) -> np.ndarray:
    s, c = math.sin(ALPHA / 2), math.cos(ALPHA / 2)
    return np.column_stack([np.full_like(t, c), 0 * t, s * np.cos(W * t), s * np.sin(W * t)])


def _cone_rate(t: np.ndarray) -> np.ndarray:
    """``2 q* dq/dt`` of the truth (derived in closed form)."""
    return np.column_stack([np.full_like(t, -2 * W * math.sin(ALPHA / 2) ** 2), -W * math.sin(ALPHA) * np.sin(W * t),
                            W * math.sin(ALPHA) * np.cos(W * t)])


def _cone_increments(t: np.ndarray) -> np.ndarray:
    """The rate's exact integrals over each interval."""
    return np.column_stack([-2 * W * math.sin(ALPHA / 2) ** 2 * np.diff(t), math.sin(ALPHA) * np.diff(np.cos(W * t)),
                            math.sin(ALPHA) * np.diff(np.sin(W * t))])


def _integral(fun, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Integrals of ``fun(t) -> (n, 3)`` over each [a_k, b_k]: Simpson's rule on 64 sub-steps (~1e-13 here)."""
    fine = np.linspace(0.0, 1.0, 65)
    wts = np.ones(65)
    wts[1:-1:2], wts[2:-1:2] = 4, 2
    wts /= 3 * 64
    tt = a[:, None] + (b - a)[:, None] * fine[None, :]
    return (b - a)[:, None] * np.einsum("k,nkc->nc", wts, fun(tt.ravel()).reshape(len(a), 65, 3))


def _angle_error(q: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    d = quat_multiply(q_true * np.array([1, -1, -1, -1]), q)
    return 2.0 * np.linalg.norm(d[:, 1:], axis=1)


def test_the_quaternion_kernels_are_the_layer_0_ones():
    """Kept importable here; tested against SciPy in tests/test_rotations.py."""
    import casep.navigation.strapdown as nav
    import casep.rotations as rot

    for name in ("quat_multiply", "quat_rotate", "quat_from_rotvec", "quat_to_dcm", "dcm_to_quat",
                 "increments_from_rates", "increments_from_deltas", "Increments"):
        assert getattr(nav, name) is getattr(rot, name)


def test_the_prefix_product_is_the_sequential_product(rng):
    inc = increments_from_deltas(rng.normal(scale=0.05, size=(999, 3)), np.zeros((999, 3)))
    q0 = quat_from_rotvec(np.array([0.3, -0.2, 0.1]))
    q = propagate_attitude(q0, inc)
    seq = [q0]
    for dq in quat_from_rotvec(inc.dtheta + inc.coning):
        seq.append(quat_multiply(seq[-1], dq))
    np.testing.assert_allclose(q, np.array(seq), atol=1e-13)


@pytest.mark.parametrize("source", ["increments", "rates"])
def test_coning_attitude_error_is_bounded_by_the_algorithms_order(source):
    errors = []
    for rate in (200.0, 400.0, 800.0):
        t = np.arange(0.0, 10.0 + 1e-9, 1.0 / rate)
        if source == "increments":
            dth = _cone_increments(t)
            inc = increments_from_deltas(dth, np.zeros_like(dth))
        else:
            inc = increments_from_rates(t, _cone_rate(t), np.zeros((len(t), 3)))
        err = float(_angle_error(propagate_attitude(_cone_truth(t[:1])[0], inc), _cone_truth(t)).max())
        x = W / rate
        bound = ALPHA ** 2 * W * 10.0 * x ** 4 / 60.0  # the previous-sample algorithm's drift over 10 s
        uncorrected = ALPHA ** 2 * W * 10.0 * x ** 2 / 12.0
        assert err < (1.2 if source == "increments" else 2.5) * bound + 1e-12, (rate, err, bound)
        errors.append(err)
    inc.coning[:] = 0.0  # the same at 800 Hz without the coning correction: the uncorrected drift
    plain = float(_angle_error(propagate_attitude(_cone_truth(t[:1])[0], inc), _cone_truth(t)).max())
    assert plain == pytest.approx(uncorrected, rel=0.05) and plain > 100 * bound
    assert 12.0 < errors[0] / errors[1] < 20.0 and 12.0 < errors[1] / errors[2] < 20.0  # fourth order


def test_constant_acceleration_without_gravity_is_exact(rng):
    a_b = np.array([3.0, -1.0, 0.5])
    q0 = quat_from_rotvec(np.array([0.2, 0.4, -0.1]))
    t = np.cumsum(np.concatenate([[0.0], rng.uniform(0.004, 0.006, 2000)]))  # uneven steps
    inc = increments_from_rates(t, np.zeros((len(t), 3)), np.tile(a_b, (len(t), 1)))
    q = propagate_attitude(q0, inc)
    dV = quat_rotate(q[:-1], body_velocity_increments(inc))
    v0, r0 = np.array([10.0, 0.0, -2.0]), np.array([1.0, 2.0, 3.0])
    r, v, _ = propagate_translation(t, dV, r0, v0, None)
    a = quat_rotate(q0, a_b)
    tau = (t - t[0])[:, None]
    np.testing.assert_allclose(v, v0 + a * tau, atol=1e-11)
    np.testing.assert_allclose(r, r0 + v0 * tau + 0.5 * a * tau ** 2, atol=1e-9)


@pytest.mark.parametrize("source", ["rates", "increments"])
def test_a_circle_at_constant_speed_without_gravity(source):
    """Body x along the velocity, turning at ``Om = V/R`` about z: ``f_b = (0, V Om, 0)``, ``w_b = (0, 0, Om)``.

    Truth: ``r = R (sin Om t, 1 - cos Om t, 0)``, ``v = V (cos Om t, sin Om t, 0)``. The position
    is integrated by the trapezoid on velocity: error ``h^2/12 V Om^2 t`` (bound 2x)."""
    V, R, rate = 50.0, 200.0, 100.0
    Om = V / R
    t = np.arange(0.0, 60.0 + 1e-9, 1.0 / rate)
    n = len(t)
    if source == "rates":
        inc = increments_from_rates(t, np.tile([0.0, 0.0, Om], (n, 1)), np.tile([0.0, V * Om, 0.0], (n, 1)))
    else:
        h = 1.0 / rate  # the exact increments of the constant body rate and force
        inc = increments_from_deltas(np.tile([0.0, 0.0, Om * h], (n - 1, 1)),
                                     np.tile([0.0, V * Om * h, 0.0], (n - 1, 1)))
    q = propagate_attitude(np.array([1.0, 0, 0, 0]), inc)
    dV = quat_rotate(q[:-1], body_velocity_increments(inc))
    r, v, _ = propagate_translation(t, dV, np.zeros(3), np.array([V, 0.0, 0.0]), None)
    th = Om * t
    np.testing.assert_allclose(v, V * np.column_stack([np.cos(th), np.sin(th), 0 * t]), atol=1e-9)
    pos_bound = 2 * (1 / rate) ** 2 / 12 * V * Om ** 2 * 60.0
    r_true = R * np.column_stack([np.sin(th), 1 - np.cos(th), 0 * t])
    assert np.abs(r - r_true).max() < pos_bound, (np.abs(r - r_true).max(), pos_bound)
    np.testing.assert_allclose(_angle_error(q, quat_from_rotvec(np.outer(th, [0, 0, 1]))), 0.0, atol=1e-11)


def test_increments_and_rates_of_one_motion_give_the_same_solution():
    """A coning body under a varying specific force: rates and forces sampled at 400 Hz, and the exact
    increments of the same motion (integrated by Simpson's rule on 64 sub-steps, ~1e-13). The
    truth velocity is the integral of ``C(t) f(t)`` with the closed-form attitude, by the same rule.
    Both attitudes stay within 2.5 times the coning bound of the truth; the velocity error is the
    attitude error acting on the force across the cone axis (|f_yz| <= 1.5 m/s^2) over 20 s."""
    rate, T = 400.0, 20.0
    t = np.arange(0.0, T + 1e-9, 1.0 / rate)

    def f(tt):
        return np.column_stack([9.0 + 2 * np.sin(3 * tt), 0.5 * np.cos(5 * tt), 1.0 + 0 * tt])

    def f_nav(tt):
        return quat_rotate(_cone_truth(tt), f(tt))

    v_true = np.vstack([np.zeros(3), np.cumsum(_integral(f_nav, t[:-1], t[1:]), axis=0)])
    inc_d = increments_from_deltas(_integral(_cone_rate, t[:-1], t[1:]), _integral(f, t[:-1], t[1:]))
    inc_r = increments_from_rates(t, _cone_rate(t), f(t))
    q0 = _cone_truth(t[:1])[0]
    bound = ALPHA ** 2 * W * T * (W / rate) ** 4 / 60.0
    sol = []
    for inc in (inc_d, inc_r):
        q = propagate_attitude(q0, inc)
        r, v, _ = propagate_translation(t, quat_rotate(q[:-1], body_velocity_increments(inc)), np.zeros(3),
                                        np.zeros(3), None)
        assert _angle_error(q, _cone_truth(t)).max() < 2.5 * bound
        assert np.abs(v - v_true).max() < 2.5 * bound * 1.5 * T
        sol.append((q, v))
    assert _angle_error(sol[0][0], sol[1][0]).max() < 2.5 * bound
    assert np.abs(sol[0][1] - sol[1][1]).max() < 2.5 * bound * 1.5 * T


@pytest.mark.parametrize("source", ["increments", "rates"])
def test_sculling_is_corrected(source):
    """Classic sculling: the body rocks about x, ``theta = A sin(Om t)``, while the specific force along
    body y oscillates in phase, ``f_y = B sin(Om t)``: the navigation-frame force has a mean
    ``A B / 2`` along z that no single sample shows. The truth velocity is the integral of
    ``Rx(theta) f`` (Simpson, 64 sub-steps). Without the sculling term the velocity misses
    ``A B (Om h)^2 / 12`` per second; with it, ``A B (Om h)^4 / 60`` (the analogue of the coning
    residual; the rates' cubic quadrature within 2.5 times that)."""
    A, B, Om, rate, T = 0.01, 5.0, 2 * math.pi * 20.0, 400.0, 10.0
    t = np.arange(0.0, T + 1e-9, 1.0 / rate)

    def rate_b(tt):
        return np.column_stack([A * Om * np.cos(Om * tt), 0 * tt, 0 * tt])

    def f_b(tt):
        return np.column_stack([0 * tt, B * np.sin(Om * tt), 0 * tt])

    def f_nav(tt):
        th = A * np.sin(Om * tt)
        return np.column_stack([0 * tt, B * np.sin(Om * tt) * np.cos(th), B * np.sin(Om * tt) * np.sin(th)])

    v_true = np.vstack([np.zeros(3), np.cumsum(_integral(f_nav, t[:-1], t[1:]), axis=0)])
    assert v_true[-1, 2] == pytest.approx(A * B / 2 * T, rel=1e-3)  # the rectified drift itself
    if source == "increments":
        inc = increments_from_deltas(_integral(rate_b, t[:-1], t[1:]), _integral(f_b, t[:-1], t[1:]))
    else:
        inc = increments_from_rates(t, rate_b(t), f_b(t))
    errors = []
    for keep in (True, False):
        if not keep:
            inc.sculling[:] = 0.0
        q = propagate_attitude(np.array([1.0, 0, 0, 0]), inc)
        _, v, _ = propagate_translation(t, quat_rotate(q[:-1], body_velocity_increments(inc)), np.zeros(3),
                                        np.zeros(3), None)
        errors.append(np.abs(v - v_true).max())
    x = Om / rate  # the residual of the previous-sample sculling term, as for coning: A B T x^4 / 60
    assert errors[0] < (1.2 if source == "increments" else 2.5) * A * B * T * x ** 4 / 60, errors
    assert errors[1] == pytest.approx(A * B * (Om / rate) ** 2 / 12 * T, rel=0.3)  # what sculling corrects
