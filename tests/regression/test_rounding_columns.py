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


def test_joint_fit_counts_a_rounding_column_as_zero():
    """Several flights fitted jointly (casep.regression.joint): the same rule on the joint reduction. Before: c got
    a plain estimate from the two flights' rounding noise (the joint problem carried no declared magnitudes)."""
    from casep.regression.joint import Flights, JointLayout, JointProblem

    (pa, x), (pb, _) = _problem(1e-16, seed=0), _problem(1e-16, seed=1)
    layout = JointLayout(("a", "b", "c"), [False, False, False], ("A", "B"))
    assert list(JointProblem([pa, pb], [1.0, 1.0], layout).rank().zero) == [False, False, True]
    res = _fit(Flights((pa, pb), layout))
    assert np.allclose(res.estimate[:2], x[:2], rtol=0, atol=1e-12), res.estimate
    assert not res.identifiable[2] and np.isnan(res.estimate[2]) and np.isnan(res.std[2])
    assert "rounding level" in res.reasons["c"], res.reasons


def test_diagnose_counts_a_rounding_column_as_zero():
    """diagnose (``casep diagnose``: a flight's Problem, its noise model fitted; raw arrays with their `scales`; the
    joint problem of several flights): no bound for the rounding column, the others' as without it. Before: c's
    CRLB std 0.13 (the bound ignored the rank analysis' rounding columns; raw arrays and the joint problem did not
    apply the rule at all)."""
    from casep.checks.diagnostics import diagnose, diagnose_noise
    from casep.regression.joint import JointLayout, JointProblem

    pb, _ = _problem(1e-16)
    without = diagnose(pb.sv()[:, :, :2], pb.y, names=("a", "b"), sigma=1e-3).crlb_std
    scales = {"a": 1.0, "b": 1.0, "c": 1.0}
    for d in (diagnose(pb, sigma=1e-3), diagnose(pb.sv(), pb.y, names=("a", "b", "c"), scales=scales, sigma=1e-3)):
        assert np.isnan(d.crlb_std[2]) and d.identifiability["c"] == "unidentifiable"
        assert "rounding level" in d.reasons["c"], d.reasons
        np.testing.assert_allclose(d.crlb_std[:2], without, rtol=1e-9)
    gm = diagnose(pb.sv(), pb.y, names=("a", "b", "c"), scales=scales, sigma=1e-3, t=pb.t, tau=5.0)
    assert np.isnan(gm.crlb_std[2]) and np.all(np.isfinite(gm.crlb_std[:2]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # noise-free rows: the noise model at their rounding
        assert np.isnan(diagnose_noise(pb, "white").crlb_std[2])
    other, _ = _problem(1e-16, seed=1)
    jp = JointProblem([pb, other], [1.0, 1.0], JointLayout(("a", "b", "c"), [False] * 3, ("A", "B")))
    assert np.isnan(diagnose(jp, sigma=1.0).crlb_std[2])
