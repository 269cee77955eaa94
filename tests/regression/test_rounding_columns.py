"""A column that is rounding noise relative to its coefficient's declared magnitude (casep.regression.linalg.
rounding_columns) counts as a zero column: no estimate, a note saying why; a small column well above the rounding
level keeps its estimate."""

from __future__ import annotations

import warnings

import numpy as np

from casep.estimators.solve import fit
from casep.estimators.spec import FitSpec
from casep.regression.linalg import rounding_columns
from casep.regression.problem import Problem, rounding_level


def _problem(weak: float, seed: int = 0) -> tuple[Problem, np.ndarray]:
    """Noise-free rows of three coefficients (declared magnitude 1 each): two ordinary columns and one of size
    `weak` times theirs, whose direction is random (rounding noise when `weak` ~ 1e-16)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 100.0, 500)
    S = np.zeros((t.size, 3, 3))
    S[:, 0, 0] = 1.0
    S[:, 1, 1] = t / 100.0
    S[:, :, 2] = weak * rng.standard_normal((t.size, 3))
    x = np.array([0.3, -0.2, 0.5])
    y = np.einsum("kij,j->ki", S[:, :, :2], x[:2])  # the truth's third term is below the rounding of y
    pb = Problem.from_arrays(S, y, t, names=("a", "b", "c"))
    pb.magnitudes = {"a": 1.0, "b": 1.0, "c": 1.0}
    return pb, x


def _fit(pb: Problem):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the noise-free warning
        return fit(pb, FitSpec.build("ols", noise="white", robust="none"))


def test_rounding_column_gets_no_estimate_and_a_note():
    """Before: c got a plain estimate, -0.24 +- 0.13 (its truth 0.5 is below the rounding of y): rounding noise
    fitted to rounding noise."""
    pb, x = _problem(1e-16)
    assert list(rounding_columns(pb.red, [1.0, 1.0, 1.0], rounding_level)) == [False, False, True]
    res = _fit(pb)
    assert np.allclose(res.estimate[:2], x[:2], rtol=0, atol=1e-12), res.estimate
    assert not res.identifiable[2] and np.isnan(res.estimate[2]) and np.isnan(res.std[2])
    assert "rounding level" in res.reasons["c"], res.reasons


def test_small_column_above_the_rounding_level_keeps_its_estimate():
    """1e-6 of the others (a weakly excited term, three orders above the 1e-9 rule): estimated, not zeroed."""
    pb, _ = _problem(1e-6)
    assert not rounding_columns(pb.red, [1.0, 1.0, 1.0], rounding_level).any()
    assert bool(_fit(pb).identifiable[2])


def test_no_declared_magnitude_no_rounding_rule():
    pb, _ = _problem(1e-16)
    assert not rounding_columns(pb.red, [1.0, 1.0, None], rounding_level).any()
