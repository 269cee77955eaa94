"""The noise parameters' uncertainty in the std of a least-squares fit under a REML noise model
(:mod:`casep.noise.inflation`): against the dense Kenward-Roger formula, a seeded Monte Carlo on short records
where the plug-in std are too small, and the limit of a long record."""

from __future__ import annotations

import time
import warnings

import numpy as np

from casep.estimators.ols import solve_ols
from casep.noise.fit import estimable_basis
from casep.noise.inflation import parameter_inflation
from casep.regression.problem import Problem
from casep.regression.rows import prepare_rows


def _noise(rng, t: np.ndarray, tau: float, gm: float, white: float) -> np.ndarray:
    """Gauss-Markov (tau, std gm) plus white (std white) noise on the times t."""
    e = np.empty(t.size)
    e[0] = gm * rng.normal()
    for k in range(1, t.size):
        a = np.exp(-(t[k] - t[k - 1]) / tau)
        e[k] = a * e[k - 1] + np.sqrt(1.0 - a * a) * gm * rng.normal()
    return e + white * rng.normal(size=t.size)


def _design(t: np.ndarray) -> np.ndarray:
    """Six coefficients: a bias per axis and three shared slow columns (a trend, a sine, a square)."""
    u = t / t[-1]
    S = np.zeros((t.size, 3, 6))
    for a in range(3):
        S[:, a, a] = 1.0
    S[:, 0, 3], S[:, 1, 3], S[:, 2, 3] = u, np.sin(2 * np.pi * u), u**2
    S[:, 0, 4], S[:, 2, 4] = np.sin(2 * np.pi * u), u
    S[:, 1, 5], S[:, 2, 5] = u**2, np.sin(2 * np.pi * u)
    return S


X0 = np.array([0.1, -0.2, 0.05, 0.3, -0.1, 0.2])


def _draw(seed: int, n: int, dt: float = 0.2, tau: float = 1.0, gm: float = 0.05, white: float = 0.03) -> Problem:
    rng = np.random.default_rng([11, seed])
    t = np.arange(n) * dt
    S = _design(t)
    y = S @ X0 + np.stack([_noise(rng, t, tau, gm, white) for _ in range(3)], axis=1)
    return Problem.from_arrays(S, y, t)


def _dense_kenward_roger(pb: Problem, nm) -> np.ndarray:
    """Kenward and Roger's adjusted covariance in the estimable basis, from dense N x N matrices:
    ``Phi + 2 Phi [sum W_ij (Q_ij - P_i Phi P_j - R_ij / 4)] Phi``, ``W`` twice the inverse Hessian of the
    dense -2 l_R (variances not profiled); the same parameters as the module (ln tau, logit w, v per axis)."""
    B = estimable_basis(pb)
    X = pb.sv() @ B  # (N, 3, p)
    y = pb.y
    t = pb.t
    N, _, p = X.shape
    v0 = [nm.sigma**2 * s**2 for s in nm.scale]
    x0 = np.array([np.log(nm.tau[0]), np.log(nm.share[0] / (1 - nm.share[0])),
                   np.log(nm.tau[1]), np.log(nm.share[1] / (1 - nm.share[1])),
                   np.log(nm.tau[2]), np.log(nm.share[2] / (1 - nm.share[2])), *v0])
    D = np.abs(t[:, None] - t[None, :])

    def sig(x, a):
        tau, w, v = np.exp(x[2 * a]), 1 / (1 + np.exp(-x[2 * a + 1])), x[6 + a]
        return v * ((1 - w) * np.exp(-D / tau) + w * np.eye(N))

    def neg2(x):
        A, val = np.zeros((p, p)), 0.0
        b = np.zeros(p)
        yy = 0.0
        for a in range(3):
            C = sig(x, a)
            Ci = np.linalg.inv(C)
            val += np.linalg.slogdet(C)[1]
            A += X[:, a].T @ Ci @ X[:, a]
            b += X[:, a].T @ Ci @ y[:, a]
            yy += y[:, a] @ Ci @ y[:, a]
        return val + np.linalg.slogdet(A)[1] + yy - b @ np.linalg.solve(A, b)

    h = 2e-3 * np.where(np.arange(9) >= 6, np.abs(x0), 1.0)
    E = np.diag(h)
    H = np.empty((9, 9))
    for i in range(9):
        for j in range(9):
            H[i, j] = (neg2(x0 + E[i] + E[j]) - neg2(x0 + E[i] - E[j]) - neg2(x0 - E[i] + E[j])
                       + neg2(x0 - E[i] - E[j])) / (4 * h[i] * h[j])
    W = np.linalg.inv(0.5 * H)
    Ci = [np.linalg.inv(sig(x0, a)) for a in range(3)]
    Phi = np.linalg.inv(sum(X[:, a].T @ Ci[a] @ X[:, a] for a in range(3)))

    def axis(i):
        return i // 2 if i < 6 else i - 6

    def dsig(i, j=None):  # d Sigma_a / d x_i (and d^2 / d x_i d x_j), central differences
        a = axis(i)
        if j is None:
            return (sig(x0 + E[i], a) - sig(x0 - E[i], a)) / (2 * h[i])
        return (sig(x0 + E[i] + E[j], a) - sig(x0 + E[i] - E[j], a) - sig(x0 - E[i] + E[j], a)
                + sig(x0 - E[i] - E[j], a)) / (4 * h[i] * h[j])

    P = [-(X[:, axis(i)].T @ Ci[axis(i)] @ dsig(i) @ Ci[axis(i)] @ X[:, axis(i)]) for i in range(9)]
    inner = np.zeros((p, p))
    for i in range(9):
        for j in range(9):
            term = -P[i] @ Phi @ P[j]
            if axis(i) == axis(j):
                a = axis(i)
                Xa, C = X[:, a], Ci[a]
                term = term + Xa.T @ C @ dsig(i) @ C @ dsig(j) @ C @ Xa - 0.25 * (Xa.T @ C @ dsig(i, j) @ C @ Xa)
            inner += W[i, j] * term
    return Phi, 2 * Phi @ inner @ Phi


def test_the_correction_equals_the_dense_kenward_roger_formula():
    """On a 40-sample record per axis (noise Gauss-Markov plus white fitted by REML, every parameter inside its
    interval), the module's correction (central differences of the Gram matrices, the O(N) colouring) equals
    Kenward and Roger's adjusted covariance formed with dense 40 x 40 matrices (the second-derivative term ``R_ij``
    explicitly) to 0.2 % of the correction (measured 0.03 %; both use central differences); the correction kept is its
    positive part in the plug-in's metric."""
    pb = _draw(3, 40)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        nm = prepare_rows(pb, "gmw", robust=None).noise
    inf = parameter_inflation(pb, nm, raw=True)  # before its negative part is dropped
    assert inf is not None and len(inf.parameters) == 9
    Phi, delta = _dense_kenward_roger(pb, nm)
    np.testing.assert_allclose(inf.phi, Phi, rtol=1e-9, atol=1e-12 * np.abs(Phi).max())
    np.testing.assert_allclose(inf.delta, delta, atol=2e-3 * np.abs(delta).max())  # measured 3e-4
    assert np.abs(delta).max() > 0.2 * np.abs(Phi).max()  # 40 samples for 9 parameters: a large correction
    clipped = parameter_inflation(pb, nm)
    assert clipped is not None
    Li = np.linalg.inv(np.linalg.cholesky(Phi))
    d_raw = np.linalg.eigvalsh(Li @ delta @ Li.T)
    d = np.linalg.eigvalsh(Li @ clipped.delta @ Li.T)  # never narrower than the plug-in; the positive part kept
    np.testing.assert_allclose(d, np.sort(np.clip(d_raw, 0.0, None)), atol=2e-3 * d_raw.max())


def test_plug_in_std_are_too_small_on_short_records_and_the_corrected_ones_hold():
    """Seeded Monte Carlo (seeds 0-59, 60 samples per axis at 5 Hz, Gauss-Markov tau 1 s std 0.05 plus white
    0.03, six coefficients, noise 'gmw' by REML: nine noise parameters): pooled over the 360 z values the plug-in
    std give RMS z 1.275 and coverage of 1.96 std 0.872; the corrected ones (Kenward-Roger with the t variance)
    0.978 and 0.944. Bounds: plug-in RMS z above 1.12, corrected RMS z in [0.85, 1.10] and coverage in
    [0.92, 0.98] (the pooled RMS z's sampling std is about 0.05 at this size). 19-25 s CPU (a loaded machine)."""
    c0 = time.process_time()
    z0, z1 = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for seed in range(60):
            pb = _draw(seed, 60)
            rows = prepare_rows(pb, "gmw", robust=None)
            res = solve_ols(rows.solved)
            inf = parameter_inflation(pb, rows.noise)
            assert inf is not None
            sd = np.sqrt(np.diag(inf.adjusted(res.covariance)))
            z0.append((res.estimate - X0) / res.std)
            z1.append((res.estimate - X0) / sd)
    z0, z1 = np.concatenate(z0), np.concatenate(z1)
    rms0, rms1 = float(np.sqrt(np.mean(z0**2))), float(np.sqrt(np.mean(z1**2)))
    cover = float(np.mean(np.abs(z1) <= 1.96))
    print(f"plug-in RMS z {rms0:.3f} coverage {np.mean(np.abs(z0) <= 1.96):.3f}; corrected RMS z {rms1:.3f} "
          f"coverage {cover:.3f}; {time.process_time() - c0:.1f} s CPU")
    assert rms0 > 1.12
    assert 0.85 <= rms1 <= 1.10
    assert 0.92 <= cover <= 0.98


def test_a_known_correlation_and_one_scale_need_no_correction():
    """Closed form: with the correlation known (tau given) and one common scale, the GLS estimate does not depend
    on the variance and its covariance is linear in it (``Phi = v Phi_1``): ``Lambda = 0``, ``d^2 Phi / dv^2 = 0``,
    so the correction is zero (to the central differences' rounding, 1e-6 of the plug-in)."""
    from casep.noise.model import NoiseModel

    pb = _draw(5, 80)
    nm = NoiseModel(kind="auto", tau=(1.0, 1.0, 1.0), scale=(1.0, 1.0, 1.0), rule="given", sigma=0.06)
    inf = parameter_inflation(pb, nm, raw=True)
    assert inf is not None and inf.parameters == ["variance"]
    assert np.abs(inf.delta).max() < 1e-6 * np.abs(inf.phi).max()  # measured 2.4e-8


def test_the_correction_falls_as_one_over_the_record_length():
    """The noise parameters' uncertainty is O(1/N): the std factor's excess ``f^2 - 1`` (median over the
    coefficients, noise 'gmw' fitted on one seeded draw per length) falls by about 4 per 4 times the samples.
    Measured (100, 400, 1600 samples per axis): 0.336, 0.0898, 0.0222 (ratios 0.27, 0.25)."""
    excess = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for n in (100, 400, 1600):
            pb = _draw(2, n)
            inf = parameter_inflation(pb, prepare_rows(pb, "gmw", robust=None).noise)
            assert inf is not None
            excess.append(inf.info["std_factor_median"] ** 2 - 1.0)
    print("f^2 - 1:", excess)
    assert excess[0] > 0.1
    assert 0.1 < excess[1] / excess[0] < 0.4
    assert 0.1 < excess[2] / excess[1] < 0.4


def test_every_least_squares_fit_under_a_reml_noise_model_carries_it():
    """The rule is applied where the rows are solved (:func:`casep.estimators.solve.solve_spec`, the path of
    ``casep separate`` and of every raw-IMU pass): OLS under noise 'gmw' reports the corrected std and says what it
    added; under white noise of one std nothing is added."""
    from casep.estimators.solve import noise_parameter_covariance, solve_problem

    pb = _draw(4, 60)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rows = prepare_rows(pb, "gmw", robust=None)
        plug = solve_ols(rows.solved)
        res = solve_problem(pb, "ols", noise="gmw", robust=None).result
        white = solve_problem(pb, "ols", noise="white").result
    added = noise_parameter_covariance(res)
    inf = parameter_inflation(pb, rows.noise)
    assert added is not None and inf is not None
    np.testing.assert_allclose(added, inf.adjusted(plug.covariance) - plug.covariance, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(res.std, np.sqrt(plug.std**2 + np.diag(added)), rtol=1e-12)
    assert np.all(res.std > plug.std)
    assert res.diagnostics["noise_parameters"]["dof_min"] > 0.0
    assert noise_parameter_covariance(white) is None


def test_the_kernels_equal_dense_matrices():
    """The compiled first-order recursion (both ways) against a loop; the transposed whitening times the whitening,
    ``W^T W X``, against the dense inverse covariance; ``Sigma X`` (:func:`casep.noise.known.axis_covariance_times`)
    against the dense covariance (jittered times with a gap, Gauss-Markov plus white), to 1e-10."""
    from casep._kernels import first_order
    from casep.noise.known import axis_covariance_times
    from casep.noise.model import _series_transpose, whiten_series

    rng = np.random.default_rng(21)
    t = np.cumsum(np.concatenate([[0.0], 0.1 * (1 + 0.4 * rng.uniform(-1, 1, 79))]))
    t[40:] += 3.0
    X = rng.normal(size=(80, 4))
    a = rng.uniform(0, 1, 80)
    fwd, bwd = X.copy(), X.copy()
    for k in range(1, 80):
        fwd[k] += a[k] * fwd[k - 1]
    for k in range(78, -1, -1):
        bwd[k] += a[k] * bwd[k + 1]
    np.testing.assert_allclose(first_order(a, X), fwd, rtol=1e-13)
    np.testing.assert_allclose(first_order(a, X, reverse=True), bwd, rtol=1e-13)
    tau, w = 0.7, 0.3
    C = (1 - w) * np.exp(-np.abs(t[:, None] - t[None, :]) / tau) + w * np.eye(80)
    WtW = _series_transpose(whiten_series(X, t, tau, w)[0], t, tau, w)
    np.testing.assert_allclose(WtW, np.linalg.solve(C, X), rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(axis_covariance_times(X, t, tau, 1 - w, w), C @ X, rtol=1e-10, atol=1e-12)
