"""The raw-IMU passes under correlated tracking noise (Gauss-Markov plus white, the usual GNSS mixture).

The test that takes what a record does not determine back to the prior:
:func:`casep.workflows.imu_separate.prior_fits_p` judges whether a record fits as well with combinations at the
prior as where a fit kept them. Under Gauss-Markov plus white noise (the usual GNSS mixture) the white residual
variance understates how much the sum of squares moves by chance; the white passes' own factor
(:func:`casep.estimators.solve.richer_noise_factor`) corrects it. Checked here by a seeded Monte Carlo on a linear
record whose truth is the prior: the rejections at 1 % must be as rare as 1 %, and without the factor they are not
(the test has power against the defect it guards).

The spectrum of what a record determines (:func:`casep.workflows.imu_separate._scaled_spectrum`) on a design of
condition 1e10: the fit's std under its noise model, not the white ones.
"""

import numpy as np

from casep.estimators.solve import fit, richer_noise_factor
from casep.estimators.spec import FitSpec
from casep.regression.problem import Problem
from casep.workflows.imu_separate import BACK_TO_PRIOR_P, prior_fits_p

SEEDS = 40
DT, T_END = 0.2, 60.0  # 5 Hz tracking, 60 s
GM_STD, TAU, WHITE_STD = 0.03, 3.0, 0.02  # m/s, s, m/s: a GNSS receiver's velocity noise


def _gm_white(rng: np.random.Generator, n: int) -> np.ndarray:
    """Gauss-Markov (stationary, `TAU`) plus white noise, (n, 3)."""
    phi = np.exp(-DT / TAU)
    x = np.empty((n, 3))
    x[0] = rng.normal(0.0, GM_STD, 3)
    for k in range(1, n):
        x[k] = phi * x[k - 1] + rng.normal(0.0, GM_STD * np.sqrt(1.0 - phi**2), 3)
    return x + rng.normal(0.0, WHITE_STD, (n, 3))


def _design(t: np.ndarray) -> np.ndarray:
    """(N, 3, 5): a bias and a ramp on x, a slow and a faster sine on y, a bias on z."""
    S = np.zeros((t.size, 3, 5))
    S[:, 0, 0] = 1.0
    S[:, 0, 1] = t / T_END
    S[:, 1, 2] = np.sin(2 * np.pi * t / 40.0)
    S[:, 1, 3] = np.sin(2 * np.pi * t / 7.0)
    S[:, 2, 4] = 1.0
    return S


def _ssr_prior(S: np.ndarray, y: np.ndarray, U: np.ndarray) -> float:
    """The sum of squares of the least-squares fit with the combinations `U` (orthonormal columns) held at 0."""
    A = S.reshape(-1, S.shape[-1])
    Q, _ = np.linalg.qr(U, mode="complete")
    B = A @ Q[:, U.shape[1]:]
    r = y.ravel() - B @ np.linalg.lstsq(B, y.ravel(), rcond=None)[0]
    return float(r @ r)


def test_prior_test_holds_its_level_under_gauss_markov_plus_white_noise():
    t = np.arange(0.0, T_END, DT)
    S = _design(t)
    U = np.linalg.svd(S.reshape(-1, 5), full_matrices=False)[2][-2:].T  # the two least determined combinations
    spec = FitSpec.build("ols", noise="white", robust="none")
    with_factor, without, factors = 0, 0, []
    for seed in range(SEEDS):
        y = _gm_white(np.random.default_rng(seed), t.size)  # the truth is the prior: 0
        problem = Problem.from_arrays(S, y, t)
        res = fit(problem, spec, checks=False)
        ssr = float(np.sum(np.square(res.residuals)))
        prior = _ssr_prior(S, y, U)
        dof = res.residuals.size - 5
        factor = richer_noise_factor(res, problem)
        factors.append(factor)
        with_factor += prior_fits_p(ssr, prior, dof, 2, factor) < BACK_TO_PRIOR_P
        without += prior_fits_p(ssr, prior, dof, 2) < BACK_TO_PRIOR_P
    # at a 1 % level, 40 runs reject 0.4 on average; 3 or more has probability 0.0008
    assert with_factor <= 2, (with_factor, np.median(factors))
    # the white variance alone rejects the truth in a quarter of the runs or more (25 of 40 here, factor 3.7): the
    # defect the factor removes
    assert without >= SEEDS // 4, without


def test_prior_p_closed_form():
    """chi^2_2's survival function is exp(-x/2): the statistic's scale checked on numbers."""
    ssr, dof = 2.0, 100  # s^2 = 0.02
    grow = 0.02 * 4.0 * 3.0  # 3 in the scale s^2 factor^2 (factor 2)
    assert abs(prior_fits_p(ssr, ssr + grow, dof, 2, 2.0) - np.exp(-1.5)) < 1e-12
    assert abs(prior_fits_p(ssr, ssr + grow, dof, 2) - np.exp(-6.0)) < 1e-12
    assert prior_fits_p(ssr, ssr - 1.0, dof, 2) == 1.0  # the prior fits better: no evidence against it
    assert prior_fits_p(0.0, 1e-6, dof, 2) == 0.0  # a noise-free record: the prior is not taken


def test_the_spectrum_carries_the_noise_models_std_on_a_badly_conditioned_design():
    """A design whose singular values span 1e10 (a tactical aircraft's strapdown33: 1e9 equilibrated), the fit's
    covariance 4 times the white std (Gauss-Markov plus white tracking at 5 Hz, tau 2.5 s): every combination the
    design resolves is stated at 4 times its white std. Read where the white variance exceeds 1e-10 of the largest
    eigenvalue, no combination was resolved by both, and the white std were taken, 4 times too small."""
    from casep.workflows.imu_separate import _scaled_spectrum

    rng = np.random.default_rng(0)
    n, N, sigma, k = 11, 40, 0.03, 4.0
    s = np.logspace(0, -10, n)
    U, _ = np.linalg.qr(rng.standard_normal((3 * N, n)))
    V, _ = np.linalg.qr(rng.standard_normal((n, n)))
    S = (U * s) @ V.T
    problem = Problem.from_arrays(S.reshape(N, 3, n), rng.standard_normal((N, 3)), np.arange(N) * 0.2)
    C = (V * (k * sigma / s) ** 2) @ V.T  # the fit's covariance: k times the white one, sigma^2 (S^T S)^-1
    sig, q = _scaled_spectrum(C, np.ones(n), problem, sigma)
    resolved = s**2 >= 1e-10  # the design's own resolution (_SPECTRUM_RTOL)
    white = sigma / s
    order = np.argsort(white)  # sig and q come in the order of the design's singular values
    # C holds the smallest resolved variances to ~1e-5 of themselves (its rounding, n eps lambda_max)
    np.testing.assert_allclose(np.sort(sig)[resolved[order]], (k * white[order])[resolved[order]], rtol=1e-4)


def test_the_spectrum_carries_the_noise_models_std_when_the_covariance_resolves_none():
    """A design that leaves combinations undetermined by 1e12 (a 20 Hz rolling boost under ``strapdown33``: std of
    1e12 declared magnitudes beside 2.5e-4): the fit's covariance holds every resolved variance below its rounding
    (``n eps lambda_max``), so none could carry the noise model's factor, and the white std were taken. The combination
    that failed that record (0.70 sg_y - 0.69 sg_z, an estimate 6.3 of its white std 29) was 1.7 of its Gauss-Markov
    plus white std (106), and its truth -0.77. With the noise model the factor comes from the estimators on the rows
    it whitens (:func:`_whitened_ratio`), checked here against the generalised least-squares variances under the
    dense covariance of the Gauss-Markov plus white noise written out (Cholesky whitening, not the filter)."""
    from casep.noise.model import NoiseModel
    from casep.workflows.imu_separate import _scaled_spectrum

    rng = np.random.default_rng(1)
    N, n, sigma, tau, share = 60, 11, 0.1, 1.0, 0.2
    t = np.arange(N) * 0.2
    x = 2.0 * t / t[-1] - 1.0
    smooth = [np.polynomial.legendre.Legendre.basis(d)(x) for d in range(4)]  # slow velocity-error profiles
    B = np.zeros((N, 3, 12))
    for a in range(3):
        for d in range(4):
            B[:, a, 4 * a + d] = smooth[d]
    U, _ = np.linalg.qr(B.reshape(3 * N, 12)[:, :n])  # orthonormal, smooth on the rows
    s = np.logspace(0, -12, n)
    V, _ = np.linalg.qr(rng.standard_normal((n, n)))
    S = (U * s) @ V.T
    problem = Problem.from_arrays(S.reshape(N, 3, n), rng.standard_normal((N, 3)), t)
    C = (V * (4.0 * sigma / s) ** 2) @ V.T  # its largest eigenvalue 1.6e23: every resolved variance its rounding
    noise = NoiseModel.gauss_markov(tau, share=share)
    nd = {**noise.to_dict(), "kind": "auto"}
    white = np.sort(sigma / s)
    sig0, _ = _scaled_spectrum(C, np.ones(n), problem, sigma)  # without the noise model: the white std (the defect)
    np.testing.assert_allclose(np.sort(sig0), white, rtol=1e-6)
    sig, q = _scaled_spectrum(C, np.ones(n), problem, sigma, noise=nd)
    # the independent variances: the dense covariance of each axis, sigma^2 ((1 - w) exp(-|dt| / tau) + w I)
    R = sigma**2 * ((1.0 - share) * np.exp(-np.abs(t[:, None] - t[None, :]) / tau) + share * np.eye(N))
    L = np.linalg.cholesky(np.kron(R, np.eye(3)))  # rows axis-interleaved, as S.reshape(3 N, n)
    a = np.linalg.pinv(np.linalg.solve(L, S))  # (n, 3N): the GLS estimator on the rows whitened by L
    order = np.argsort(sig0)
    resolved = white**2 <= white[0] ** 2 / 1e-10  # the design's own resolution (_SPECTRUM_RTOL)
    gls = np.array([np.sum((q[:, i] @ a) ** 2) for i in order])
    k2 = float(np.median(gls[resolved] / white[resolved] ** 2))
    assert k2 > 2.0, k2  # the correlated noise's std well above the white ones: the test can fail the defect
    np.testing.assert_allclose(np.sort(sig), white * np.sqrt(k2), rtol=1e-6)
