"""The correlation times' uncertainty in the raw-IMU std (:func:`casep.workflows.imu_separate.tau_spread`): the part of
a change of covariance that adds variance (:func:`casep.workflows.imu_separate.relative_positive_part`) against its
closed form, its invariance to the coefficients' units, and on a record at rest too short to bound tau."""

from __future__ import annotations

import numpy as np
import pytest

from casep.workflows.row_estimators import relative_positive_part


def _pair(rng: np.random.Generator, lam: np.ndarray, m: int = 6) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A covariance ``C = L L^T`` (seeded), ``M = L Q diag(lam) Q^T L^T`` (``Q`` orthogonal: the generalized
    eigenvalues of ``(M, C)`` are `lam`) and the closed form of the part that adds variance,
    ``L Q diag(max(lam, 0)) Q^T L^T``."""
    L = rng.standard_normal((m, m)) + 3.0 * np.eye(m)
    Q = np.linalg.qr(rng.standard_normal((m, m)))[0]
    return L @ L.T, (L @ Q * lam) @ Q.T @ L.T, (L @ Q * np.clip(lam, 0.0, None)) @ Q.T @ L.T


def test_the_part_that_adds_variance_is_the_generalized_eigenvalues_positive_part():
    """``M v = lam C v``: the part keeps the positive ``lam`` (closed form, to 1e-10 of the largest entry); an ``M``
    that only removes variance adds none, one that only adds is kept whole."""
    rng = np.random.default_rng(0)
    lam = np.array([-2.0, -0.5, 0.0, 0.3, 1.5, 4.0])
    C, M, want = _pair(rng, lam)
    got = relative_positive_part(M, C)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-10 * np.abs(want).max())
    np.testing.assert_allclose(relative_positive_part(-np.abs(lam)[0] * C, C), 0.0, atol=1e-12 * np.abs(C).max())
    np.testing.assert_allclose(relative_positive_part(2.5 * C, C), 2.5 * C, rtol=1e-10)
    assert np.linalg.eigvalsh(got).min() > -1e-10 * np.abs(got).max()


def test_the_part_is_the_same_in_any_units_unlike_the_plain_positive_part():
    """Coefficients in units 1e-8 to 1e8 apart (``R C R``, ``R M R``, ``R`` diagonal: the spans of a pad record at rest,
    where what the record does not determine has std 1e10 declared magnitudes) give ``R P R`` to 1e-8 relative per
    entry (of ``sqrt(P_ii P_jj)``). The positive part of ``eigh(M)`` taken in those units is another matrix (off by
    more than 10 % of ``sqrt(P_ii P_jj)``): it depends on the units."""
    rng = np.random.default_rng(1)
    lam = np.array([-1.0, 0.2, 0.7, -0.3, 2.0, 0.05])
    C, M, want = _pair(rng, lam)
    r = 10.0 ** np.linspace(-8.0, 8.0, 6)
    R = np.outer(r, r)
    got = relative_positive_part(M * R, C * R) / R
    d = np.sqrt(np.outer(np.diag(want), np.diag(want)))
    assert np.max(np.abs(got - want) / d) < 1e-8
    w, V = np.linalg.eigh(M * R)
    plain = ((V * np.clip(w, 0.0, None)) @ V.T) / R
    assert np.max(np.abs(plain - want) / d) > 0.1


def test_a_singular_covariance_adds_nothing_outside_its_range():
    """``C = B B^T`` of rank 3 in 5 dimensions and ``M = B K B^T``: in the coordinates ``u`` of ``B u`` the metric is
    the identity, so the part is ``B K_+ B^T`` with ``K_+`` the plain positive part of ``K`` (closed form), zero
    along ``C``'s null space."""
    rng = np.random.default_rng(2)
    B = rng.standard_normal((5, 3))
    K = rng.standard_normal((3, 3))
    K = K + K.T
    got = relative_positive_part(B @ K @ B.T, B @ B.T)
    lam, U = np.linalg.eigh(K)
    assert lam.min() < 0 < lam.max()
    want = (B @ U * np.clip(lam, 0.0, None)) @ U.T @ B.T
    np.testing.assert_allclose(got, want, atol=1e-10 * np.abs(want).max())
    null = np.linalg.svd(B.T)[2][3:]  # C's null space
    assert np.abs(null @ got @ null.T).max() < 1e-10 * np.abs(want).max()


def test_a_record_too_short_to_bound_tau_says_so_and_its_spread_is_scipys_generalized_positive_part():
    """16 white tracking epochs at 1 Hz (the profile of each axis's tau flat over 0.2-15 s): every axis's kept interval
    reaches the record length (:func:`casep.noise.fit.tau_kept`), and the spread is finite and equals, axis by axis,
    ``C V diag(max(lam, 0)) V^T C`` from SciPy's generalized symmetric eigensolver (``eigh(M, C)``, ``V^T C V = I``)
    of the profile's mean covariance less the fit's (1e-9 of the largest entry)."""
    from scipy.linalg import eigh

    from casep.noise.fit import tau_kept, tau_profile
    from casep.noise.known import tracking_covariance_times
    from casep.regression.problem import Problem
    from casep.workflows.row_estimators import tau_spread

    rng = np.random.default_rng(0)
    t = np.arange(16.0)
    S = np.stack([np.ones((16, 3)), np.tile((t - t.mean())[:, None], (1, 3))], axis=2)
    pb = Problem.from_arrays(S, 0.02 * rng.standard_normal((16, 3)), t)
    profile = tau_profile(pb)
    kept = tau_kept(t, profile)
    assert all(top and hi == pytest.approx(15.0) for _, hi, top in kept), kept
    a = np.linalg.pinv(S.reshape(48, 2))  # the OLS estimators on the raw rows, (2, 48)
    extra = tau_spread(a, pb, profile)

    def cov(nm):
        return a @ tracking_covariance_times(a.T.reshape(16, 3, 2), t, nm).reshape(48, 2)

    c0 = cov(profile[0])
    want = np.zeros((2, 2))
    for points in profile[1]:
        lam, V = eigh(sum(w * cov(nm) for w, nm in points) - c0, c0)
        want += (c0 @ V * np.clip(lam, 0.0, None)) @ V.T @ c0
    assert np.all(np.isfinite(extra)) and np.abs(want).max() > 0
    np.testing.assert_allclose(extra, want, rtol=0, atol=1e-9 * np.abs(want).max())


def test_an_unbounded_correlation_time_is_said_with_its_numbers():
    """The warning names the axes whose kept interval reaches the record length, with the interval, the record length
    and the largest std factor; a record that bounds every axis says nothing."""
    import warnings

    from casep.exceptions import UndecidedNoiseWarning
    from casep.workflows.imu_separate import warn_tau_unbounded

    record = {"record_s": 15.0, "std_factor_max": 1.21, "std_factor_worst": "dt_trk",
              "axes": {"x": {"kept_s": [0.2, 15.0], "bounded": False}, "y": {"kept_s": [0.4, 3.6], "bounded": True},
                       "z": {"kept_s": [0.84, 15.0], "bounded": False}}}
    with pytest.warns(UndecidedNoiseWarning, match=r"on axes x \(0\.2 to 15 s\), z \(0\.84 to 15 s\): .*\(15 s, "
                                                   r"rec\)\..*up to 1\.21 x \(dt_trk\)") as said:
        warn_tau_unbounded("rec", record)
    assert len(said) == 1 and " y " not in str(said[0].message)
    record["axes"] = {ax: {**v, "bounded": True} for ax, v in record["axes"].items()}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_tau_unbounded("rec", record)


def _stated(factor: float | None) -> dict:
    """A noise account's ``tau_stated`` (:func:`casep.workflows.imu_separate._tau_stated_record`): x within, y and z
    outside (y's interval closed, z's reaching the record length)."""
    return {"level": 3.841, "std_factor_max": factor, "std_factor_worst": "bg_x",
            "axes": {"x": {"tau_s": 1.0, "reml_tau_s": 1.12, "drop": 0.4, "within": True, "interval_s": None},
                     "y": {"tau_s": 0.05, "reml_tau_s": 1.34, "drop": 46.9, "within": False,
                           "interval_s": [0.52, 11.3]},
                     "z": {"tau_s": 0.05, "reml_tau_s": 0.99, "drop": 30.3, "within": False,
                           "interval_s": [0.24, None]}}}


def test_a_stated_tau_the_data_reject_is_said_with_its_numbers_and_fails_when_its_std_fall_short():
    """The warning names each axis whose stated tau is outside its interval, with the stated tau, the interval, REML's
    tau and the drop against the level, and the std factor (against the closest tau the data accept); beyond
    TAU_STATED_FACTOR it returns the failure's message (the caller fails the result), at or below it None; every axis
    within: nothing said."""
    import warnings

    from casep.exceptions import NoiseLevelWarning
    from casep.workflows.imu_separate import TAU_STATED_FACTOR, warn_tau_stated

    said_y = r"y \(stated 0\.05 s, interval 0\.52 s to 11\.3 s, REML 1\.34 s; -2 ln Lambda 46\.9 > 3\.841\)"
    said_z = r"z \(stated 0\.05 s, interval 0\.24 s to the record length, REML 0\.99 s; -2 ln Lambda 30\.3 > 3\.841\)"
    tail = (r" \(rec\); the std at the stated tau are 1\.31 x smaller than at the closest tau the data accept "
            r"\(bg_x\)\. Leave tau out")
    with pytest.warns(NoiseLevelWarning, match=f"on axes {said_y}, {said_z}{tail}") as said:
        assert warn_tau_stated("rec", _stated(1.31)) is None
    assert len(said) == 1 and "x (stated" not in str(said[0].message)
    beyond = rf"2\.4 x smaller than at the closest tau the data accept \(bg_x\), beyond {TAU_STATED_FACTOR:g} x"
    with pytest.warns(NoiseLevelWarning, match=beyond):
        failure = warn_tau_stated("rec", _stated(2.4))
    assert failure is not None and failure.startswith("failed: the data put the stated") and "2.4 x" in failure
    with pytest.warns(NoiseLevelWarning, match="not smaller than at the closest tau the data accept"):
        assert warn_tau_stated("rec", _stated(1.0)) is None
    record = _stated(2.4)
    record["axes"] = {ax: {**v, "within": True} for ax, v in record["axes"].items()}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert warn_tau_stated("rec", record) is None
