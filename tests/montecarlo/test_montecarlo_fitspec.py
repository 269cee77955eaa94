"""A Monte Carlo campaign fits each run through the one entry point ``fit(problem, spec)``.

Each per-run method is a FitSpec built once for the campaign (checked before any run, by the fit
request's own rules, so a campaign refuses what ``casep separate`` refuses); each run is solved by
:func:`casep.estimators.solve.fit` on the rows prepared once per run for every method.
"""

from __future__ import annotations

import numpy as np
import pytest

import casep.estimators.solve as solve
from casep.estimators.spec import FitSpec
from casep.montecarlo import run_montecarlo


@pytest.mark.parametrize("methods, noise", [(["rels", "wavelet+ols"], "white"), (["ols", "huber"], "auto")])
def test_every_run_of_a_per_run_method_goes_through_fit(monkeypatch, methods, noise):
    seen: list[FitSpec] = []
    real = solve.fit

    def counting(problem, spec, **kw):
        seen.append(spec)
        return real(problem, spec, **kw)

    monkeypatch.setattr(solve, "fit", counting)
    res = run_montecarlo("paper", runs=2, methods=methods, seed=4, rate=2.0, workers=1, progress=False, noise=noise)
    assert len(seen) == 2 * len(methods)  # every run of every method (none batched past the entry point here)
    assert all(isinstance(s, FitSpec) for s in seen)
    assert {s.method for s in seen} == {m.split("+")[-1] for m in methods}
    if "wavelet+ols" in methods:
        assert any(s.noise.denoise == "wavelet" for s in seen)  # de-noised by fit's own rule, not a second copy
    for m in methods:
        assert np.all(np.isfinite(res.estimates[m]))


def test_a_campaign_refuses_what_separate_refuses_before_any_run():
    with pytest.raises(ValueError) as e:
        FitSpec.build("gls", denoise="wavelet")
    with pytest.raises(ValueError) as mc:
        run_montecarlo("paper", runs=2, methods=["wavelet+gls"], seed=1, rate=2.0, workers=1, progress=False)
    assert str(mc.value) == f"method `wavelet+gls`: {e.value}"


def test_a_given_tau_means_gauss_markov_as_in_separate(monkeypatch):
    """``tau`` with noise "auto" is Gauss-Markov noise of that correlation time (NoiseSpec's rule, as
    casep.separate reads it), not a second rule of the campaign's own."""
    seen: list[FitSpec] = []
    real = solve.fit
    monkeypatch.setattr(solve, "fit", lambda p, s, **kw: seen.append(s) or real(p, s, **kw))
    run_montecarlo("paper", runs=1, methods=["ols"], seed=1, rate=2.0, workers=1, progress=False, tau=1.5)
    assert seen and seen[0].noise.kind == "gm" and seen[0].noise.tau == 1.5
