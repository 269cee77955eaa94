"""A combination of columns that is rounding noise relative to the declared magnitudes (casep.regression.linalg.
rounding_directions) is an exact dependency: the rank counts it, the condition numbers are infinite together with
it (one rule), and its members are named exactly dependent, the others not. The case: two columns proportional up
to 1e-11 of their size (an exact dependency of the model that the discretisation of S_V leaves above the 1e-16
of double rounding, as the rotation of the whole IMU against the body and an initial attitude error on strapdown
telemetry)."""

from __future__ import annotations

import warnings

import numpy as np

from casep.estimators.solve import fit
from casep.estimators.spec import FitSpec
from casep.regression.linalg import analyze_rank, condition_numbers, rounding_directions
from casep.regression.problem import Problem, rounding_level


def _problem(leak: float, seed: int = 0) -> Problem:
    """Noisy rows of three coefficients (declared magnitude 1 each): a, b independent, c = -2 b plus `leak` times
    a random direction of b's size."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 100.0, 500)
    S = np.zeros((t.size, 3, 3))
    S[:, 0, 0] = 1.0
    S[:, 1, 1] = t / 100.0
    S[:, 2, 1] = 0.5 * np.sin(t / 7.0)
    S[:, :, 2] = -2.0 * S[:, :, 1] + leak * rng.standard_normal((t.size, 3))
    y = np.einsum("kij,j->ki", S, np.array([0.3, -0.2, 0.0])) + 0.01 * rng.standard_normal((t.size, 3))
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
    assert rounding_directions(pb.red, s, Vt, [1.0, 1.0, None], rounding_level, np.zeros(3, dtype=bool)).shape == (0, 3)
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
