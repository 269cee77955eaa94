"""A combination of columns that is rounding noise relative to the declared magnitudes (casep.regression.linalg.
rounding_directions) is an exact dependency: the rank counts it, the condition numbers are infinite together with
it (one rule), and its members are named exactly dependent, the others not. The case: two columns proportional up
to 1e-11 of their size (an exact dependency of the model that the discretisation of S_V leaves above the 1e-16
of double rounding, as the rotation of the whole IMU against the body and an initial attitude error on strapdown
telemetry)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from casep.estimators.solve import fit
from casep.estimators.spec import FitSpec
from casep.regression.linalg import (
    DEPENDENT_SINGULAR,
    NEEDED_ALPHA,
    analyze_rank,
    condition_numbers,
    constraint_growth,
    direction_needed,
    member_null_direction,
    rounding_directions,
)
from casep.regression.problem import Problem, rounding_level


def _problem(leak: float, seed: int = 0, c_true: float = 0.0) -> Problem:
    """Noisy rows of three coefficients (declared magnitude 1 each): a, b independent, c = -2 b plus `leak` times
    a random direction of b's size; c's true value `c_true`."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 100.0, 500)
    S = np.zeros((t.size, 3, 3))
    S[:, 0, 0] = 1.0
    S[:, 1, 1] = t / 100.0
    S[:, 2, 1] = 0.5 * np.sin(t / 7.0)
    S[:, :, 2] = -2.0 * S[:, :, 1] + leak * rng.standard_normal((t.size, 3))
    y = np.einsum("kij,j->ki", S, np.array([0.3, -0.2, c_true])) + 0.01 * rng.standard_normal((t.size, 3))
    pb = Problem.from_arrays(S, y, t, names=("a", "b", "c"))
    pb.magnitudes = {"a": 1.0, "b": 1.0, "c": 1.0}
    return pb


def test_dependency_at_the_rounding_level_is_exact():
    """Before: rank 3/3 beside a natural-units condition number of None (printed "inf"); b, c called a
    near-dependency, with estimates of +-1e9."""
    pb = _problem(1e-11)
    ra = pb.rank()
    assert ra.rank == 2
    assert list(ra.dependent) == [False, True, True]
    assert condition_numbers(pb.red, ra) == {"condition_number": None, "condition_number_equilibrated": None}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = fit(pb, FitSpec.build("ols", noise="white", robust="none"))
    assert res.rank == 2 and bool(res.identifiable[0])
    assert abs(res.estimate[0] - 0.3) < 5 * res.std[0]
    assert not res.identifiable[1] and not res.identifiable[2]
    assert all("exactly dependent" in res.reasons[k] for k in ("b", "c")), res.reasons
    assert ra.exact_groups() == [[1, 2]]
    note = res.diagnostics["warning"]
    assert "exactly dependent (the data cannot separate these" in note and "[b, c]" in note, note
    assert "near-dependencies" not in note, note


def test_near_dependency_above_the_rounding_level_keeps_its_rank():
    """1e-5 of the columns' size: a real near-dependency, full rank and finite condition numbers."""
    pb = _problem(1e-5)
    ra = pb.rank()
    assert ra.rank == 3 and not ra.dependent.any()
    cn = condition_numbers(pb.red, ra)
    assert cn["condition_number"] is not None and cn["condition_number_equilibrated"] is not None
    assert cn["condition_number_equilibrated"] > 1e4


def test_no_declared_magnitude_no_rounding_direction():
    pb = _problem(1e-11)
    U, s, Vt = np.linalg.svd(pb.red.R)
    assert rounding_directions(pb.red, U, s, Vt, [1.0, 1.0, None], rounding_level, np.zeros(3, dtype=bool),
                               1e-4).shape == (0, 3)
    assert analyze_rank(pb.red).rank == 3  # without magnitudes: LAPACK's rule alone


def test_full_rank_gives_finite_condition_numbers_whatever_the_units():
    """Before: a full-rank S whose columns differ by 1e14 in size (arcsec against m) had a natural-units condition
    number of None, printed "inf" beside "rank 3/3"."""
    t = np.linspace(0.0, 100.0, 500)
    rng = np.random.default_rng(1)
    S = rng.standard_normal((t.size, 3, 3)) * np.array([1.0, 1e-7, 1e7])
    y = rng.standard_normal((t.size, 3))
    pb = Problem.from_arrays(S, y, t, names=("a", "b", "c"))
    ra = pb.rank()
    cn = condition_numbers(pb.red, ra)
    assert ra.rank == 3
    assert cn["condition_number"] is not None and cn["condition_number"] > 1e13
    assert cn["condition_number_equilibrated"] is not None and cn["condition_number_equilibrated"] < 10


def test_two_columns_identical_up_to_rounding_are_one_exact_group():
    """c = b up to 1e-13 of its size: rank 2 of 3, [b, c] named exactly dependent, no finite condition number."""
    rng = np.random.default_rng(5)
    t = np.linspace(0.0, 100.0, 500)
    S = np.zeros((t.size, 3, 3))
    S[:, 0, 0] = 1.0
    S[:, 1, 1] = t / 100.0
    S[:, 2, 1] = 0.5 * np.sin(t / 7.0)
    S[:, :, 2] = S[:, :, 1] * (1.0 + 1e-13 * rng.standard_normal((t.size, 3)))
    y = np.einsum("kij,j->ki", S, np.array([0.3, -0.2, 0.1])) + 0.01 * rng.standard_normal((t.size, 3))
    pb2 = Problem.from_arrays(S, y, t, names=("a", "b", "c"))
    pb2.magnitudes = {"a": 1.0, "b": 1.0, "c": 1.0}
    ra = pb2.rank()
    assert ra.rank == 2 and ra.exact_groups() == [[1, 2]]
    assert condition_numbers(pb2.red, ra) == {"condition_number": None, "condition_number_equilibrated": None}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = fit(pb2, FitSpec.build("ols", noise="white", robust="none"))
    assert res.rank == 2 and "exactly dependent (the data cannot separate these" in res.diagnostics["warning"]
    assert "[b, c]" in res.diagnostics["warning"]


def test_a_direction_the_data_need_keeps_its_rank():
    """The same 1e-11 leak, but c's true value 1e10 times its declared magnitude: along the leak the data carry
    1e-11 x 1e10 = 0.1 of b's column, ten times the noise: dropping the direction would leave those residuals (the
    MEMS record under a tactical model). Full rank, finite condition numbers, c estimated."""
    pb = _problem(1e-11, c_true=1e10)
    ra = pb.rank()
    assert ra.rank == 3 and not ra.dependent.any()
    cn = condition_numbers(pb.red, ra)
    assert cn["condition_number_equilibrated"] is not None and cn["condition_number_equilibrated"] > 1e10
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = fit(pb, FitSpec.build("ols", noise="white", robust="none"))
    assert res.rank == 3
    assert abs(res.estimate[2] - 1e10) < 5 * res.std[2], (res.estimate[2], res.std[2])


def _constrained_rss(S2: np.ndarray, y: np.ndarray, n: np.ndarray) -> float:
    """RSS of the least squares ``S2 x = y`` with ``x`` kept orthogonal to `n`, by a basis of n's complement
    (independent of the SVD formula)."""
    B = np.linalg.svd(np.eye(n.size) - np.outer(n, n))[0][:, : n.size - 1]  # orthonormal basis of n-perp
    x = np.linalg.lstsq(S2 @ B, y, rcond=None)[0]
    return float(np.sum((y - S2 @ B @ x) ** 2))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_constraint_growth_is_the_rss_difference_of_the_constrained_fit(seed):
    """Closed form against brute force: the growth of the RSS when the fit may not move along a direction (scaled
    coordinates) is the difference of two least squares on the rows, the constrained one by a basis of the
    complement."""
    rng = np.random.default_rng(seed)
    S2 = rng.standard_normal((60, 4)) * np.array([1.0, 3.0, 0.5, 2.0])
    S2[:, 3] = S2[:, 2] + 1e-3 * rng.standard_normal(60)  # ill-conditioned, not singular
    y = S2 @ rng.standard_normal(4) + 0.1 * rng.standard_normal(60)
    pb = Problem.from_arrays(S2.reshape(20, 3, 4), y.reshape(20, 3), np.arange(20.0))
    red = pb.red
    U, s, Vt = np.linalg.svd(red.R)
    b = U.T @ red.qty
    Z = S2 / red.scale  # the scaled columns: the coordinates of R
    full = float(np.sum((y - Z @ np.linalg.lstsq(Z, y, rcond=None)[0]) ** 2))
    for n in (Vt[-1], Vt[0], rng.standard_normal(4)):
        n = n / np.linalg.norm(n)
        want = _constrained_rss(Z, y, n) - full
        assert constraint_growth(s, Vt, b, n) == pytest.approx(want, rel=1e-7, abs=1e-10 * full)
    assert constraint_growth(s, Vt, b, Vt[-1]) == pytest.approx(b[-1] ** 2, rel=1e-12)


def test_the_rank_decision_against_the_chi_square_quantile():
    """The LR rule in closed form: chi2_1's upper NEEDED_ALPHA quantile is z^2 with z = Phi^-1(1 - alpha/2),
    10.8276 for 1e-3; a growth just under it times the noise variance is not needed, just over it is; at the
    rounding level of the direction itself never."""
    q = 10.827566170662733  # scipy.stats.chi2.isf(1e-3, 1)
    assert NEEDED_ALPHA == 1e-3
    assert not direction_needed(0.999 * q * 2.0, 2.0, 0.0)
    assert direction_needed(1.001 * q * 2.0, 2.0, 0.0)
    assert not direction_needed(1e6, 0.0, 1e3)  # noise-free: within its own rounding
    assert direction_needed(1e6, 0.0, 1.0)


def test_a_direction_whose_bulk_lies_off_its_members_is_no_dependency():
    """The smallest singular direction of [a, a + d, b] with d tiny lies on a and a + d; restricted to a member set
    that leaves one of them out it is no dependency of the data (None); on both it is, and unit, ||R n|| tiny."""
    rng = np.random.default_rng(3)
    A = rng.standard_normal((50, 3))
    A[:, 1] = A[:, 0] + 1e-12 * rng.standard_normal(50)
    R = np.linalg.qr(A / np.linalg.norm(A, axis=0))[1]
    U, s, Vt = np.linalg.svd(R)
    tol = DEPENDENT_SINGULAR * s[0]
    assert member_null_direction(R, Vt[-1], np.array([True, False, True]), tol, []) is None
    n = member_null_direction(R, Vt[-1], np.array([True, True, False]), tol, [])
    assert n is not None and n[2] == 0.0 and np.linalg.norm(n) == pytest.approx(1.0)
    assert np.linalg.norm(R @ n) <= tol
    assert member_null_direction(R, Vt[-1], np.array([True, True, False]), tol, [n]) is None  # one only
