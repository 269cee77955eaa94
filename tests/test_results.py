"""Every result type follows the result protocol of casep.results (``to_dict()``, ``text()``)."""

from __future__ import annotations

import importlib
import json

import numpy as np
import pytest

from casep.results import Result

RESULT_TYPES = [
    ("casep.estimators.result", "EstimateResult"),
    ("casep.impact.result", "ImpactAnalysis"),
    ("casep.montecarlo.result", "MonteCarloResult"),
    ("casep.design.result", "DesignResult"),
    ("casep.calibration.result", "Calibration"),
    ("casep.workflows.radar", "RadarResult"),
    ("casep.workflows.demo", "DemoResult"),
    ("casep.analysis.denoise", "DenoiseResult"),
    ("casep.analysis.diagnostics", "Diagnostics"),
    ("casep.analysis.noise", "NoiseModel"),
    ("casep.analysis.whiteness", "WhitenessTest"),
    ("casep.analysis.noise_id", "NoiseIdentification"),
    ("casep.analysis.outliers", "OutlierFlags"),
]


@pytest.mark.parametrize("module, name", RESULT_TYPES)
def test_every_result_type_has_to_dict_and_text(module, name):
    cls = getattr(importlib.import_module(module), name)
    for method in ("to_dict", "text"):
        assert callable(getattr(cls, method, None)), f"{name} has no {method}()"


def test_an_estimate_is_a_result_plain_data_and_text_agree():
    """to_dict() is plain JSON data holding the numbers text() prints; the old name table() is text()."""
    from casep import solve_ols

    rng = np.random.default_rng(3)
    S = rng.standard_normal((200, 3, 4))
    D = np.array([1.0, -2.0, 0.5, 3.0])
    y = S @ D + 0.01 * rng.standard_normal((200, 3))
    res = solve_ols(S, y, names=["a", "b", "c", "d"])
    assert isinstance(res, Result)
    data = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    est = [c["estimate"] for c in data["coefficients"]]
    ref = np.linalg.lstsq(S.reshape(-1, 4), y.reshape(-1), rcond=None)[0]  # independent least squares
    np.testing.assert_allclose(est, ref, rtol=1e-10, atol=1e-12)
    assert res.text() == res.table()
    for name in ("a", "b", "c", "d"):
        assert name in res.text()
