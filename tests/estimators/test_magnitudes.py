"""The magnitude judgement names the likelier cause from the numbers it has: when the whiteness test of the fit
measured std too small by a factor that brings every estimate back within its declared magnitude, the noise
model, not a set-up or unit mistake."""

from __future__ import annotations

import dataclasses

import numpy as np

import casep
from casep.estimators.registry import check_magnitudes


def _result(factor: float | None):
    rng = np.random.default_rng(5)
    S = rng.standard_normal((200, 2))
    res = casep.solve_ols(S, S @ [50.0, 0.0] + rng.standard_normal(200), names=["a", "b"], units=["u", "u"])
    diag = {**dict(res.diagnostics), "whiteness": {"std_factor_median": factor}}
    return dataclasses.replace(res, diagnostics=diag)


def test_noise_model_named_when_the_std_factor_explains_the_magnitudes():
    res = _result(None)
    sd = float(res.std[0])
    scale = (50.0 - 5.0 * sd) / 1e4 * 0.99  # a beyond MAGNITUDE_FAIL (1e4) by |x| - 5 std
    plain = check_magnitudes(res, {"a": scale, "b": 1.0})
    assert not plain.success and "set-up mistake" in plain.message
    factor = 50.0 / (5.0 * sd)  # std that large: |x| - 5 std <= 0
    noisy = check_magnitudes(_result(factor), {"a": scale, "b": 1.0})
    assert not noisy.success and "noise model is the likelier cause" in noisy.message
    assert f"{factor:.2g} x too small" in noisy.message
