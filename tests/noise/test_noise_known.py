"""REML of the tracking noise beside a known noise state (:mod:`casep.noise.known`): the Kalman whitening's
restricted likelihood against the dense one, the compiled filter against its numpy reference, ``Sigma_track V``
against the dense covariance, and with no known term the fit is the REML fit of :func:`casep.noise.fit.fit_noise`."""

from __future__ import annotations

import numpy as np
import pytest

from casep import _compiled
from casep._kernels import joint_filter_numpy
from casep.noise.fit import Reml, estimable_basis, fit_noise
from casep.noise.known import (
    KnownStates,
    TrackingParameters,
    fit_tracking,
    joint_whiten,
    restricted_likelihood,
    tracking_covariance_times,
)
from casep.regression.problem import Problem


def _times(rng, n: int, dt: float = 0.2) -> np.ndarray:
    """Jittered spacing (+-40 %) with a gap of 20 steps."""
    steps = dt * (1.0 + 0.4 * rng.uniform(-1, 1, n - 1))
    steps[n // 2] = 20 * dt
    return np.concatenate([[0.0], np.cumsum(steps)])


def _known(rng, M: int, s: int = 5) -> KnownStates:
    """A known state of s dimensions: transitions near the identity, positive semi-definite noises of rank 2."""
    T = np.eye(s) + 0.1 * rng.normal(size=(M, s, s))
    B = 0.01 * rng.normal(size=(M, s, 2))
    H = rng.normal(size=(M, 3, s))
    P0 = 1e-4 * np.diag(rng.uniform(0.0, 1.0, s))
    return KnownStates(T, B @ np.swapaxes(B, 1, 2), H, P0)


def _track_dense(theta: TrackingParameters, t: np.ndarray) -> np.ndarray:
    """Sigma_track (3M, 3M), rows epoch by epoch, x y z."""
    M = t.size
    out = np.zeros((3 * M, 3 * M))
    for j in range(3):
        C = theta.d[j] * np.eye(M)
        if theta.tau[j] is not None:
            C = C + theta.c[j] * np.exp(-np.abs(t[:, None] - t[None, :]) / theta.tau[j])
        out[j::3, j::3] = C
    return out


#: One axis of each kind: Gauss-Markov plus white, white, Gauss-Markov.
THETA = TrackingParameters((9e-4, 0.0, 4e-4), (1.0, None, 0.3), (2e-4, 5e-4, 0.0))


def test_the_restricted_likelihood_equals_the_dense_one(rng):
    """-2 l_R = ln det Sigma + ln det(Z^T Sigma^-1 Z) + y^T (Sigma^-1 - Sigma^-1 Z (Z^T Sigma^-1 Z)^-1 Z^T
    Sigma^-1) y with Sigma = Sigma_track + Sigma_known formed densely (M = 40 epochs, uneven times and a gap):
    the filter's to 1e-10."""
    M, p = 40, 4
    t = _times(rng, M)
    known = _known(rng, M)
    Z = np.linalg.qr(rng.normal(size=(3 * M, p)))[0]
    y = 0.03 * rng.normal(size=3 * M)
    Sigma = _track_dense(THETA, t) + known.dense()
    Si = np.linalg.inv(Sigma)
    A = Z.T @ Si @ Z
    r = y - Z @ np.linalg.solve(A, Z.T @ Si @ y)
    dense = np.linalg.slogdet(Sigma)[1] + np.linalg.slogdet(A)[1] + r @ Si @ r
    X = np.concatenate([Z, y[:, None]], axis=1).reshape(M, 3, p + 1)
    assert restricted_likelihood(X, t, THETA, known) == pytest.approx(dense, rel=1e-10, abs=1e-10)
    U, logdet = joint_whiten(X, t, THETA, known)  # U^T U = X^T Sigma^-1 X
    np.testing.assert_allclose(U.T @ U, X.reshape(3 * M, -1).T @ Si @ X.reshape(3 * M, -1), rtol=1e-9)
    assert logdet == pytest.approx(np.linalg.slogdet(Sigma)[1], rel=1e-12)


def test_the_known_state_dense_form_is_its_covariance(rng):
    """KnownStates.dense against the covariance of 4000 seeded draws of the state recursion (3 sd of each entry)."""
    M = 6
    known = _known(rng, M, s=3)
    D = known.dense()
    draws = np.empty((4000, 3 * M))
    z = rng.standard_normal((4000, 3)) @ np.sqrt(known.P0)  # P0 diagonal
    for r in range(M):
        lam, vec = np.linalg.eigh(known.Q[r])
        z = z @ known.T[r].T + rng.standard_normal((4000, 3)) @ (vec * np.sqrt(np.clip(lam, 0, None))).T
        draws[:, 3 * r:3 * r + 3] = z @ known.H[r].T
    C = draws.T @ draws / draws.shape[0]
    sd = np.sqrt((np.outer(np.diag(D), np.diag(D)) + D**2) / draws.shape[0])  # of a sample second moment
    assert np.all(np.abs(C - D) < 4.5 * sd + 1e-12)


def test_the_compiled_filter_equals_its_numpy_reference(rng):
    M = 60
    t = _times(rng, M)
    known = _known(rng, M)
    X = rng.normal(size=(M, 3, 4))
    dt = np.concatenate([[np.inf], np.diff(t)])
    a = np.column_stack([np.exp(-dt / 1.0), np.zeros(M), np.exp(-dt / 0.3)])
    qb = np.array(THETA.c) * (1.0 - a**2)
    d = np.array(THETA.d)
    outs = [np.empty((3 * M, 4)), np.empty((3 * M, 4))]
    lds = [kernel(X, known.T, known.Q, known.H, known.P0, a, qb, d, out)
           for kernel, out in zip((_compiled.joint_filter, joint_filter_numpy), outs)]
    np.testing.assert_allclose(outs[0], outs[1], rtol=1e-10, atol=1e-10)
    assert lds[0] == pytest.approx(lds[1], rel=1e-12)


def test_the_tracking_covariance_times_a_matrix_is_the_dense_product(rng):
    M = 50
    t = _times(rng, M)
    V = rng.normal(size=(M, 3, 2))
    got = tracking_covariance_times(V, t, THETA.model("auto", "reml"))
    np.testing.assert_allclose(got.reshape(3 * M, 2), _track_dense(THETA, t) @ V.reshape(3 * M, 2),
                               rtol=1e-12, atol=1e-16)


def test_with_no_known_term_the_fit_is_the_remls():
    """A known term of zero: the maximum of the whole restricted likelihood is that of fit_noise's profiled one
    (Gauss-Markov plus white on every axis, 300 epochs, seeded): tau and both std within the searches'
    tolerance (1e-3 in their logarithms)."""
    from casep.simulation.noise import ar1_noise

    rng = np.random.default_rng(4)
    t = 0.2 * np.arange(300)
    S = rng.normal(size=(t.size, 3, 2))
    e = ar1_noise(t, 0.03, 1.0, rng) + 0.015 * rng.standard_normal((t.size, 3))
    pb = Problem.from_arrays(S, S @ np.array([1.0, -2.0]) + e, t)
    reml = fit_noise(pb, "gmw")
    zero = KnownStates(np.ones((t.size, 1, 1)), np.zeros((t.size, 1, 1)), np.zeros((t.size, 3, 1)), np.zeros((1, 1)))
    X = np.stack(Reml(pb, estimable_basis(pb)).Z, axis=1)
    start = TrackingParameters.of(reml)
    moved = TrackingParameters(tuple(1.5 * c for c in start.c), tuple(0.7 * x for x in start.tau),
                               tuple(1.3 * d for d in start.d)).model("gmw", "reml")
    got, _ = fit_tracking(X, t, moved, zero, xatol=1e-3)
    a, b = TrackingParameters.of(got), start
    np.testing.assert_allclose(a.tau, b.tau, rtol=0.03)
    np.testing.assert_allclose(np.sqrt(a.c), np.sqrt(b.c), rtol=0.01)
    np.testing.assert_allclose(np.sqrt(a.d), np.sqrt(b.d), rtol=0.01)


def test_a_gauss_markov_part_searched_down_to_nothing_makes_the_axis_white():
    """The search may drive an axis' Gauss-Markov variance below the rounding of its white one (seen on a car
    window): the white share then rounds to 1, which no noise model holds; the axis is white, its covariance the
    same to the rounding, the other axes as they were."""
    t = np.cumsum(np.full(30, 0.25))
    theta = TrackingParameters((1e-30, 9e-4, 0.0), (3e5, 1.0, None), (4e-4, 2e-4, 5e-4))
    noise = theta.model("gmw", "REML")
    assert noise.tau == (None, 1.0, None) and noise.share[0] == 0.0
    assert noise.share[1] == pytest.approx(2e-4 / 11e-4, rel=1e-12)
    white = TrackingParameters((0.0, 9e-4, 0.0), (None, 1.0, None), (4e-4, 2e-4, 5e-4))
    assert np.allclose(_track_dense(TrackingParameters.of(noise), t), _track_dense(white, t), rtol=1e-12, atol=0.0)


def test_the_correlation_time_stays_within_the_records_span_as_in_fit_noise():
    """A velocity error that is a random walk plus white noise (a Gauss-Markov term slower than any record): the
    restricted likelihood grows with tau beyond the record's span, where ``c`` and ``tau`` trade (seen on car
    windows: tau 9e5 s, std 17 m/s). The search keeps ln tau within :func:`casep.noise.fit.tau_search_bounds`, as
    fit_noise does: neither ends beyond the upper bound (here an axis ends at it, the other two within it).

    Where ``c`` and ``tau`` trade the likelihood is flat: where on it a search stops is the rounding's (one axis'
    tau ended at the bound, or at 27.8 s, by the rounding of fit_noise's REML kernels, and fit_tracking's at 22.7
    s), so tau and ``c`` are not compared. What the two agree on is what the rows determine: ``-2 l_R`` of both
    answers under one evaluator (:func:`casep.noise.known.restricted_likelihood`) within 0.1, a likelihood ratio the
    data cannot tell from none (a parameter's one std is a change of 1); fit_tracking, started at fit_noise's answer,
    never ends above it; and the random walk's intensity ``c / tau`` within 5 %, a third of its own relative std
    (at least ``sqrt(2 / 120)``, 13 %: a variance from 120 increments). Measured on seeds 1-8 with either REML path
    (compiled, or ``Reml.COMPILED = False``): ``-2 l_R`` apart by at most 0.064, ``c / tau`` by 3.5 %."""
    from casep.noise.fit import tau_search_bounds

    rng = np.random.default_rng(1)
    t = 0.25 * np.arange(120)
    S = rng.normal(size=(t.size, 3, 2))
    e = 0.02 * np.cumsum(rng.standard_normal((t.size, 3)), axis=0) + 0.01 * rng.standard_normal((t.size, 3))
    pb = Problem.from_arrays(S, S @ np.array([1.0, -2.0]) + e, t)
    reml = fit_noise(pb, "gmw")
    hi = np.exp(tau_search_bounds(t)[1])
    zero = KnownStates(np.ones((t.size, 1, 1)), np.zeros((t.size, 1, 1)), np.zeros((t.size, 3, 1)), np.zeros((1, 1)))
    X = np.stack(Reml(pb, estimable_basis(pb)).Z, axis=1)
    got, _ = fit_tracking(X, t, reml, zero, xatol=1e-3)
    a, b = TrackingParameters.of(got), TrackingParameters.of(reml)
    for theta in (a, b):
        assert all(x is not None and x <= hi * (1.0 + 1e-9) for x in theta.tau), theta.tau
    assert max(b.tau) == pytest.approx(hi, rel=1e-9)  # an axis at the bound: the bound is what held it
    la, lb = restricted_likelihood(X, t, a, zero), restricted_likelihood(X, t, b, zero)
    assert la <= lb + 1e-9 * abs(lb) and lb - la <= 0.1, (la, lb)
    np.testing.assert_allclose(np.divide(a.c, a.tau), np.divide(b.c, b.tau), rtol=5e-2)


def test_a_part_of_unknown_size_is_scaled_exactly_and_fitted_by_the_reml(rng):
    """A known term with a part (:meth:`KnownStates.scaled`): ``Sigma + q Sigma_part`` formed densely, to 1e-12; and
    a velocity random walk of that part (``Q_part = dt I`` per unit q, 400 epochs at 0.2 s) under white tracking
    noise: :func:`fit_tracking` finds its variance within 30 % of the truth's (0.8-1.25 in std) started 1e4 away, and
    a part absent from the rows comes out below 1e-3 of the truth's; a start per part is required."""
    M = 30
    base = _known(rng, M)
    Q_k = np.einsum("mij,mkj->mik", *(2 * [0.01 * rng.normal(size=(M, 5, 2))]))
    P0_k = np.diag(rng.uniform(0.0, 1.0, 5))
    scaled = KnownStates(base.T, base.Q, base.H, base.P0, ((Q_k, P0_k),))
    want = base.dense() + 0.7 * KnownStates(base.T, Q_k, base.H, P0_k).dense()
    np.testing.assert_allclose(scaled.scaled([0.7]).dense(), want, rtol=0, atol=1e-12 * np.abs(want).max())

    t = 0.2 * np.arange(400)
    M = t.size
    part = (np.tile(np.eye(3), (M, 1, 1)) * 0.2, np.eye(3))  # a random walk of variance q per s, q at the start
    walk = KnownStates(np.tile(np.eye(3), (M, 1, 1)), np.zeros((M, 3, 3)), np.tile(np.eye(3), (M, 1, 1)),
                       np.zeros((3, 3)), (part,))
    S = rng.normal(size=(M, 3, 2))
    q = 4e-4
    for truth in (q, 0.0):
        e = 0.02 * rng.standard_normal((M, 3)) + np.sqrt(truth) * (rng.standard_normal((M, 3)) * np.sqrt(0.2)
                                                                    ).cumsum(axis=0)
        e += np.sqrt(truth) * rng.standard_normal(3)  # the prior
        pb = Problem.from_arrays(S, S @ np.array([1.0, -2.0]) + e, t)
        start = TrackingParameters((0.0,) * 3, (None,) * 3, (1e-3,) * 3).model("white", "reml")  # 0.03 m/s
        X = np.stack(Reml(pb, estimable_basis(pb)).Z, axis=1)
        got, _ = fit_tracking(X, t, start, walk, part_start=(q * 1e4,))
        (q_fit,) = got.extra["known_scales"]
        if truth:
            assert 0.8 <= np.sqrt(q_fit / truth) <= 1.25, q_fit
        else:
            assert q_fit < 1e-3 * q, q_fit
    with pytest.raises(ValueError, match="one positive start per part"):
        fit_tracking(X, t, start, walk)


def _instability_record(rng, q: float, M: int = 100, dt: float = 0.25, tau: float = 20.0, white: float | None = None):
    """One simulated window (the module's pooled-size tests): the velocity error of a first-order Gauss-Markov bias
    of variance `q` (correlation time `tau`) and of a white velocity random walk (4 mm/s per sqrt(s)), seen through
    0.02 m/s of white tracking noise, with a velocity offset and a bias ramp per axis fitted. Drawn by the processes'
    own recursions; the known term's states (:class:`KnownStates`, the bias's part per unit variance) written apart.
    With `white` the random walk's variance is `white` times that and the walk is a part of unknown size too (per
    unit of the 4 mm/s walk's variance, before the bias's: start 1)."""
    from casep.noise.known import RemlRows

    a, sv = np.exp(-dt / tau), 0.004 * np.sqrt(1.0 if white is None else white)
    b = np.empty((M, 3))
    b[0] = np.sqrt(q) * rng.standard_normal(3)
    for r in range(1, M):
        b[r] = a * b[r - 1] + np.sqrt(q * (1 - a * a)) * rng.standard_normal(3)
    v = np.zeros((M, 3))
    v[1:] = np.cumsum(dt * b[:-1] + sv * np.sqrt(dt) * rng.standard_normal((M - 1, 3)), axis=0)
    t = dt * np.arange(M)
    S = np.zeros((M, 3, 6))
    S[:, :, :3] = np.eye(3)
    S[:, :, 3:] = t[:, None, None] * np.eye(3)
    pb = Problem.from_arrays(S, S @ rng.normal(size=6) + v + 0.02 * rng.standard_normal((M, 3)), t)
    T = np.tile(np.eye(6), (M, 1, 1))
    T[1:, :3, 3:] = dt * np.eye(3)  # V_r = V_(r-1) + dt b_(r-1),  b_r = a b_(r-1) + w
    T[1:, 3:, 3:] = a * np.eye(3)
    Q = np.zeros((M, 6, 6))
    Q[1:, :3, :3] = 0.004**2 * dt * np.eye(3)
    H = np.zeros((M, 3, 6))
    H[:, :, :3] = np.eye(3)
    Q_k = np.zeros((M, 6, 6))
    Q_k[1:, 3:, 3:] = (1 - a * a) * np.eye(3)
    P0_k = np.zeros((6, 6))
    P0_k[3:, 3:] = np.eye(3)
    start = TrackingParameters((0.0,) * 3, (None,) * 3, (1e-3,) * 3).model("white", "reml")
    X = np.stack(Reml(pb, estimable_basis(pb)).Z, axis=1)
    if white is None:
        return RemlRows(X, t, start, KnownStates(T, Q, H, np.zeros((6, 6)), ((Q_k, P0_k),)), (1e-6,))
    parts = ((Q, np.zeros((6, 6))), (Q_k, P0_k))
    return RemlRows(X, t, start, KnownStates(T, np.zeros_like(Q), H, np.zeros((6, 6)), parts), (1.0, 1e-6))


def test_a_pooled_size_over_windows_recovers_the_instability_within_its_interval():
    """Six simulated windows whose bias instability's variance is ``m_k q`` (m_k 0.5, 1, 2, 3, 0, 1.5; q of 0.3 mg
    in std): :func:`pool_parts` with the weights finds q within its 95 % interval (seeds 1-5 all cover it, 0.68-1.24
    times the truth in std; seed 1 here, 1.17), the interval excludes 0 and spans less than a factor 3 in std, and
    the summed likelihood prefers the term by more than 3.84. One record pooled alone is
    :func:`fit_tracking`'s own fit of its part (the one rule), to the searches' tolerance; bad weights are errors."""
    from casep.noise.known import pool_parts

    rng = np.random.default_rng(1)
    q = 3e-3**2
    w = np.array([0.5, 1.0, 2.0, 3.0, 0.0, 1.5])
    got = pool_parts([_instability_record(rng, wk * q) for wk in w], w)
    lo, hi = got.interval[0]
    assert lo <= q <= hi and lo > 0 and np.sqrt(hi / lo) < 3.0, (got.q, got.interval)
    assert got.neg2_reml_none - got.neg2_reml > 3.84 and len(got.models) == w.size
    one = _instability_record(rng, q)
    alone = pool_parts([one])
    own = fit_tracking(one.X, one.t, one.start, one.known, part_start=one.part_start)[0].extra["known_scales"][0]
    assert abs(np.log(alone.q[0] / own)) < 0.1, (alone.q, own)
    for bad in ([1.0, -1.0], [0.0, 0.0], [1.0]):
        with pytest.raises(ValueError, match="weight"):
            pool_parts([one, one], bad)


def test_a_stated_tau_is_judged_by_the_profile_likelihood_fit_noise_gives_with_no_known_term():
    """A known term of zero (Gauss-Markov 1 s plus white on every axis, 200 epochs, seeded), stated taus 1 s (the
    truth), 5 s and 0.2 s: :func:`stated_tau_check`'s drops are those of :func:`casep.noise.fit.fit_noise`'s own
    restricted likelihood (sigma profiled out, its own search) at the same points, the other axes at its free fit's
    taus (0.1 in -2 l_R; on x an upper bound of it, below the level); the true tau is within the 95 % interval, the
    wrong ones are not, and at the ends of the interval found for them fit_noise's drop is the level (0.2); the
    closest taus the data accept are the stated one and the nearer ends. The free fit is fit_noise's (3 % in tau),
    though a simplex started at the stated 0.2 s stopped at 0.46 s on z, 10 below the maximum at 1.3 s."""
    from casep.noise.fit import PROFILE_LR
    from casep.noise.known import stated_tau_check
    from casep.simulation.noise import ar1_noise

    rng = np.random.default_rng(4)
    t = 0.2 * np.arange(200)
    S = rng.normal(size=(t.size, 3, 2))
    e = ar1_noise(t, 0.03, 1.0, rng) + 0.015 * rng.standard_normal((t.size, 3))
    pb = Problem.from_arrays(S, S @ np.array([1.0, -2.0]) + e, t)
    zero = KnownStates(np.ones((t.size, 1, 1)), np.zeros((t.size, 1, 1)), np.zeros((t.size, 3, 1)), np.zeros((1, 1)))
    X = np.stack(Reml(pb, estimable_basis(pb)).Z, axis=1)
    stated = (1.0, 5.0, 0.2)
    fit, _ = fit_tracking(X, t, fit_noise(pb, "gmw", tau=stated), zero)
    free, axes, near = stated_tau_check(X, t, fit, zero, stated)
    base = fit_noise(pb, "gmw")
    np.testing.assert_allclose(free.tau, base.tau, rtol=0.03)

    def drop(j: int, tau: float) -> float:  # fit_noise's profile point: axis j at tau, the others at its fit's
        tt = list(base.tau)
        tt[j] = tau
        return fit_noise(pb, "gmw", tau=tt).extra["neg2_reml"] - base.extra["neg2_reml"]

    assert [a["within"] for a in axes] == [True, False, False], axes
    for j, a in enumerate(axes):
        assert a["tau_s"] == stated[j] and a["reml_tau_s"] == free.tau[j]
        if a["within"]:  # an upper bound (the variances on a grid) already below the level: not refitted
            assert a["drop_bound"] and drop(j, stated[j]) - 0.1 <= a["drop"] < PROFILE_LR and a["interval_s"] is None
            continue
        assert not a["drop_bound"] and a["drop"] == pytest.approx(drop(j, stated[j]), abs=0.1), (j, a)
        lo, hi = a["interval_s"]
        assert lo < 1.0 < hi and not lo <= stated[j] <= hi, a
        assert drop(j, lo) == pytest.approx(PROFILE_LR, abs=0.2) and drop(j, hi) == pytest.approx(PROFILE_LR, abs=0.2)
    # the closest taus the data accept: the stated on x, the interval's upper end on y (5 s above it), lower on z
    assert near.rule.startswith("tau given") and near.tau == (1.0, axes[1]["interval_s"][1], axes[2]["interval_s"][0])


def test_a_stated_tau_of_gauss_markov_noise_without_white_is_judged_without_a_white_part():
    """Noise ``gm`` with a stated tau (no white part: Gauss-Markov 1 s only, 200 epochs, seeded), stated 1, 3 and 0.3 s:
    the free fit stays Gauss-Markov on every axis (a white part found in the scan would make the stated fit lose to a
    richer model, not to another tau), its taus fit_noise's ``gm`` ones (1 %), and the drops of the axes outside are
    fit_noise's ``gm`` profile's (0.1)."""
    from casep.noise.known import stated_tau_check
    from casep.simulation.noise import ar1_noise

    rng = np.random.default_rng(7)
    t = 0.2 * np.arange(200)
    S = rng.normal(size=(t.size, 3, 2))
    pb = Problem.from_arrays(S, S @ np.array([1.0, -2.0]) + ar1_noise(t, 0.03, 1.0, rng), t)
    zero = KnownStates(np.ones((t.size, 1, 1)), np.zeros((t.size, 1, 1)), np.zeros((t.size, 3, 1)), np.zeros((1, 1)))
    X = np.stack(Reml(pb, estimable_basis(pb)).Z, axis=1)
    stated = (1.0, 3.0, 0.3)
    free, axes, _ = stated_tau_check(X, t, fit_tracking(X, t, fit_noise(pb, "gm", tau=stated), zero)[0], zero, stated)
    base = fit_noise(pb, "gm")
    assert free.kind == "gm" and free.share == (0.0, 0.0, 0.0)
    np.testing.assert_allclose(free.tau, base.tau, rtol=0.01)
    assert [a["within"] for a in axes] == [True, False, False], axes
    for j in (1, 2):
        tt = list(base.tau)
        tt[j] = stated[j]
        want = fit_noise(pb, "gm", tau=tt).extra["neg2_reml"] - base.extra["neg2_reml"]
        assert axes[j]["drop"] == pytest.approx(want, abs=0.1), (j, axes[j], want)


def test_a_pooled_white_scale_beside_the_instability_takes_weights_per_part():
    """Weights per record and part (:func:`pool_parts`): windows whose velocity random walk is 2.5 times the given
    variance (a part of weight 1, the white noise in motion against its density at rest) beside an instability of
    variance ``w_k q`` (weight ``w_k``): both pooled sizes hold the truth within their 95 % intervals (seeds 1-5 all
    do: the scale 0.87-1.31 times the truth, q 0.82-1.19 times in std; seed 1 here), and ``-2 l_R`` at the reference
    (1, 0) is above the best by more than 3.84 (by 21-59 on those seeds); a part no record weighs is an error."""
    from casep.noise.known import pool_parts

    rng = np.random.default_rng(1)
    q, k = 3e-3**2, 2.5
    w = np.array([0.5, 1.0, 2.0, 3.0])
    recs = [_instability_record(rng, wk * q, white=k) for wk in w]
    got = pool_parts(recs, np.column_stack([np.ones(w.size), w]), reference=(1.0, 0.0))
    (lo_k, hi_k), (lo_q, hi_q) = got.interval
    assert lo_k <= k <= hi_k, (got.q, got.interval)
    assert lo_q <= q <= hi_q, (got.q, got.interval)
    assert got.reference is not None and got.reference[1] - got.neg2_reml > 3.84
    with pytest.raises(ValueError, match="weight"):
        pool_parts(recs, np.column_stack([np.ones(w.size), 0.0 * w]))
