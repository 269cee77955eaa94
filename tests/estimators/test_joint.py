"""Several flights: the stacked reduction against an explicit weighted stack, the consistency tests
against their chi-square laws (seeded), fusion of square-root information against the joint fit."""

import numpy as np
import pytest

from casep.estimators.joint import coefficient_consistency, overall_consistency, stack_sqrt_information
from casep.regression.joint import JointLayout, flight_rss, joint_reduction
from casep.regression.linalg import reduce_qr


def _solve(red):
    """Least-squares theta of a reduced system (full rank here): x_Z = R^-1 q, theta = x_Z / c."""
    return np.linalg.solve(red.R, red.qty) / red.scale


def _flights(rng, K=3, n=6, pf=(False, False, False, False, True, True), m=(300, 500, 400), scales=None):
    """K random regressions with badly scaled columns; truth shared + per-flight."""
    pf = np.array(pf)
    scales = np.logspace(-1, 2, n) if scales is None else scales  # natural-unit spread 1e3
    S = [rng.standard_normal((m[k], n)) * scales for k in range(K)]
    layout = JointLayout(tuple(f"c{j}" for j in range(n)), pf, tuple(f"F{k}" for k in range(K)))
    theta = rng.standard_normal(layout.n_params)
    return S, layout, theta


def test_joint_reduction_equals_weighted_stacked_lstsq(rng):
    """Independent construction: the full weighted stack with per-flight columns, solved by lstsq."""
    S, layout, theta = _flights(rng)
    sig = [0.1, 0.5, 2.0]
    y = [S[k] @ theta[layout.columns(k)] + sig[k] * rng.standard_normal(S[k].shape[0]) for k in range(3)]
    big = np.zeros((sum(s.shape[0] for s in S), layout.n_params))
    r0 = 0
    for k in range(3):
        big[r0:r0 + S[k].shape[0], layout.columns(k)] = S[k] / sig[k]
        r0 += S[k].shape[0]
    ybig = np.concatenate([y[k] / sig[k] for k in range(3)])
    ref, rss_ref, *_ = np.linalg.lstsq(big, ybig, rcond=None)
    joint = joint_reduction([reduce_qr(S[k], y[k]) for k in range(3)], sig, layout)
    est = _solve(joint)
    assert joint.m == big.shape[0]
    np.testing.assert_allclose(est, ref, rtol=1e-10, atol=0)
    rss = joint.rho2 + float(np.sum((joint.qty - joint.R @ (est * joint.scale)) ** 2))
    np.testing.assert_allclose(rss, rss_ref[0], rtol=1e-10)
    assert layout.joint_names[-1] == "c5[F2]" and len(layout.joint_names) == layout.n_params


def test_noise_free_recovery_with_per_flight_terms(rng):
    S, layout, theta = _flights(rng)
    y = [S[k] @ theta[layout.columns(k)] for k in range(3)]
    joint = joint_reduction([reduce_qr(S[k], y[k]) for k in range(3)], [1.0, 1.0, 1.0], layout)
    np.testing.assert_allclose(_solve(joint), theta, rtol=1e-9, atol=1e-12)


def test_coefficient_consistency_follows_chi2_and_catches_a_biased_flight(rng):
    v = np.array([1.0, 4.0, 0.25, 2.0])
    chi = [coefficient_consistency(3.0 + np.sqrt(v) * rng.standard_normal(4), v).chi2 for _ in range(4000)]
    assert abs(np.mean(chi) - 3.0) < 0.15  # E chi2(3) = 3; std of the mean sqrt(6/4000) = 0.04
    p = [coefficient_consistency(3.0 + np.sqrt(v) * rng.standard_normal(4), v).p_value for _ in range(2000)]
    assert abs(np.mean(np.array(p) < 0.05) - 0.05) < 0.015  # size of the 5 % test (binomial std 0.005)
    biased = coefficient_consistency(np.array([3.0, 3.0, 3.0 + 10 * 0.5, 3.0]), v)
    assert biased.p_value < 1e-4
    assert coefficient_consistency(np.array([1.0, np.nan]), np.array([1.0, np.nan])) is None


def test_overall_chow_test_size_and_power(rng):
    S, layout, theta = _flights(rng)
    sig = [0.1, 0.5, 2.0]

    def stat(bias=0.0):
        y = [S[k] @ theta[layout.columns(k)] + sig[k] * rng.standard_normal(S[k].shape[0]) for k in range(3)]
        y[1] = y[1] + bias * S[1][:, 0]  # flight F1 with an unmodelled error along c0
        reds = [reduce_qr(S[k], y[k]) for k in range(3)]
        joint = joint_reduction(reds, sig, layout)
        est = _solve(joint)
        rss_joint = [float(np.sum((y[k] - S[k] @ est[layout.columns(k)]) ** 2)) for k in range(3)]
        own = [flight_rss(r) for r in reds]
        return overall_consistency(rss_joint, [o[0] for o in own], sig, [o[1] for o in own], layout.n_params)

    runs = [stat() for _ in range(400)]
    assert runs[0].dof == 3 * 6 - 10  # freeing the 4 shared coefficients in 3 flights: 8
    chi = np.array([r.chi2 for r in runs])
    assert abs(chi.mean() - 8.0) < 0.6  # E chi2(8) = 8, std of the mean sqrt(16/400) = 0.2
    assert stat(bias=3.0).p_value < 1e-6  # c0 of F1 off by ~13 of its std (0.5 / (0.1 sqrt(500)) = 0.22)


def test_fusing_square_root_information_equals_the_joint_fit(rng):
    """Two flights, no per-flight terms: fusing their (R diag(c), q) factors = the joint weighted fit."""
    S, layout, theta = _flights(rng, K=2, pf=(False,) * 6, m=(300, 500))
    sig = [0.2, 1.0]
    y = [S[k] @ theta + sig[k] * rng.standard_normal(S[k].shape[0]) for k in range(2)]
    reds = [reduce_qr(S[k], y[k]) for k in range(2)]
    R, z = stack_sqrt_information([(r.R * r.scale / s, r.qty / s) for r, s in zip(reds, sig)])
    fused = np.linalg.solve(R, z)
    np.testing.assert_allclose(fused, _solve(joint_reduction(reds, sig, layout)), rtol=1e-10)
    with pytest.raises(ValueError, match="nothing to fuse"):
        stack_sqrt_information([])


def test_bad_layout_and_sigma():
    with pytest.raises(ValueError, match="per_flight"):
        JointLayout(("a", "b"), np.array([True]), ("A",))
    with pytest.raises(ValueError, match="repeat"):
        JointLayout(("a",), np.array([False]), ("A", "A"))
    lay = JointLayout(("a",), np.array([False]), ("A",))
    red = reduce_qr(np.ones((3, 1)), np.ones(3))
    with pytest.raises(ValueError, match="sigma must be finite"):
        joint_reduction([red], [0.0], lay)
