"""The result protocol (casep.results: to_dict, text) on the analysis results; the old method names stay aliases."""

from __future__ import annotations

import json

import numpy as np
import pytest

from casep.analysis.diagnostics import diagnose
from casep.analysis.noise import NoiseModel
from casep.analysis.noise_id import identify_noise
from casep.analysis.outliers import flag_outliers
from casep.analysis.problem import Problem
from casep.analysis.whiteness import whiteness_test
from casep.results import Result


@pytest.fixture(scope="module")
def regression():
    rng = np.random.default_rng(7)
    N = 400
    t = np.arange(N) * 0.05
    S = rng.standard_normal((N, 3, 4))
    y = S @ np.array([1.0, -2.0, 0.5, 3.0]) + 0.1 * rng.standard_normal((N, 3))
    y[123, 1] += 5.0  # one outlier, 50 noise sigma
    return S, y, t


def _plain(obj):
    return json.loads(json.dumps(obj.to_dict(), allow_nan=False, default=float))


def test_diagnostics_and_noise_results_follow_the_protocol(regression):
    S, y, t = regression
    diag = diagnose(S, y)
    noise = NoiseModel.gauss_markov(1.5)
    white = whiteness_test(y - S @ np.linalg.lstsq(S.reshape(-1, 4), y.reshape(-1), rcond=None)[0], t)
    ident = identify_noise(0.1 * np.random.default_rng(1).standard_normal(4096), 0.05)
    for res in (diag, noise, white, ident):
        assert isinstance(res, Result), type(res).__name__
        assert isinstance(_plain(res), dict) and res.text()
    with pytest.warns(DeprecationWarning):
        assert diag.text() == diag.report() and "condition number" in diag.text()
    assert noise.text() == noise.line() and "GM tau 1.5 s" in noise.text()
    assert white.success and white.status == 0 and "whiteness" in white.message
    with pytest.warns(DeprecationWarning):
        assert ident.text() == ident.report() and "Allan deviation" in ident.text()


def test_outlier_flags_follow_the_protocol(regression):
    S, y, t = regression
    flags = flag_outliers(Problem.from_arrays(S, y, t))
    assert isinstance(flags, Result)
    assert flags.count >= 1 and flags.rows[0]["sample"] == 123 and flags.rows[0]["axis"] == "y"
    assert _plain(flags)["count"] == flags.count
    with pytest.warns(DeprecationWarning):
        assert flags.text() == flags.summary() and flags.text(top=1) == flags.summary(1)
    assert "sample 124" in flags.text()
