"""The prior versus the flight alone: the flight fitted as its own fit is (its noise model, not white noise)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import stats

from casep.exceptions import CasepWarning
from casep.simulation.simulate import simulate_flight
from casep.workflows.fusion import fuse
from casep.workflows.prior_consistency import flight_prior_consistency
from casep.workflows.separate import separate

MODEL = "platform36"
#: Gauss-Markov tracking noise (tau 1 s) at 5 Hz: a white-noise fit of these rows understates the std.
SCENARIO, RATE = "paper-ar1", 5.0


def _flight(seed):
    return simulate_flight(SCENARIO, seed=seed, rate=RATE).flight


def _own_fit(flight):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CasepWarning)
        return separate(flight, MODEL)


def test_flight_alone_is_the_flights_own_fit_the_chi2_of_fusing_the_two():
    """Two results of the same truth: the prior's chi-square against the flight alone is that of fusing the prior
    with the flight's own result (for two results, sum_k (D_k - D)^T C_k^-1 (D_k - D) = d^T (C_1 + C_2)^-1 d)."""
    prior = _own_fit(_flight(1))
    flight = _flight(2)
    c = flight_prior_consistency(flight, MODEL, prior)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CasepWarning)
        fused = fuse([prior, _own_fit(flight)])
    ov = fused.diagnostics["consistency"]["overall"]
    assert c.dof == ov["dof"] == 36
    assert c.chi2 == pytest.approx(ov["chi2"], rel=1e-6)


@pytest.mark.montecarlo
def test_prior_versus_flight_alone_chi2_is_calibrated():
    """Independent pairs of flights of one instrument: the chi-squares sum to about their dof (a white-noise fit of
    the flight alone gave about 1.6 times it here, twice it on the strapdown boost). Band: the sum's chi2 quantiles
    at 1e-4 each side."""
    pairs = [(1, 2), (3, 4), (5, 6), (7, 8)]
    chi2, dof = 0.0, 0
    for a, b in pairs:
        c = flight_prior_consistency(_flight(b), MODEL, _own_fit(_flight(a)))
        chi2, dof = chi2 + c.chi2, dof + c.dof
    assert dof == 36 * len(pairs)
    assert stats.chi2.ppf(1e-4, dof) < chi2 < stats.chi2.isf(1e-4, dof), (chi2, dof)
    assert np.isfinite(chi2)


def test_a_prior_the_flight_disagrees_with_fails_the_estimate_and_another_seed_does_not():
    """The MAP estimate with a prior: the prior from another flight of the same instrument (seed 1) is used (success);
    the same prior with one well-determined coefficient moved 8 of its std is contradicted by the flight (the
    consistency verdict, overall p < DISAGREE_P) and the estimate fails with the prior-conflict status, naming the
    coefficient and what to do, instead of reporting the average of the two as a success."""
    from casep.calibration.consistency import DISAGREE_P
    from casep.estimators.map import prior_from_result
    from casep.estimators.registry import STATUS_PRIOR_CONFLICT
    from casep.estimators.spec import FitSpec
    from casep.workflows.prior_consistency import with_prior_consistency

    own = _own_fit(_flight(1))
    prior = prior_from_result(own)
    flight = _flight(2)

    def estimate(p):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", CasepWarning)
            spec = FitSpec("map", {"prior": p})
            return with_prior_consistency(separate(flight, MODEL, spec=spec), flight, MODEL, p, spec=spec)

    res, cons = estimate(prior)
    assert cons.consistent and res.success, (cons.p_value, res.message)
    # the best-determined coefficient relative to its std (least shadowed by correlations): moved by 8 std
    name = min(cons.names, key=lambda n: prior[n]["std"] / max(abs(prior[n]["mean"]), 1e-300))
    bad = {**prior, name: {"mean": prior[name]["mean"] + 8.0 * prior[name]["std"], "std": prior[name]["std"]}}
    res_bad, cons_bad = estimate(bad)
    assert cons_bad.p_value < DISAGREE_P and name in cons_bad.disagree
    # here the MAP fit's own misfit check fails it first (failed() keeps the first status); the conflict is said
    assert not res_bad.success
    assert "prior conflict" in res_bad.message and name in res_bad.message and "drop the prior" in res_bad.message
    assert res_bad.diagnostics["prior_consistency"]["overall"]["consistent"] is False
    # an estimate no other check fails, with a prior the flight contradicts: the prior-conflict status
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CasepWarning)
        flagged, _ = with_prior_consistency(res, flight, MODEL, bad, spec=FitSpec("map", {"prior": bad}))
    assert not flagged.success and flagged.status == STATUS_PRIOR_CONFLICT and name in flagged.message
