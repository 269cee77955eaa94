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


def _units_result(x: list[float], sd: float, units: list[str]):
    """A least-squares result with estimates `x` and std about `sd` each."""
    rng = np.random.default_rng(7)
    S = rng.standard_normal((400, len(x)))
    return casep.solve_ols(S, S @ x + sd * np.sqrt(400) * rng.standard_normal(400), names=[f"c{i}" for i in
                           range(len(x))], units=units)


def test_beyond_the_linear_model_fails_whatever_the_std():
    """Rates in deg/s in rad/s columns gave bg_x 1.07e6 +- 5.3e5 deg/h and sg_z 3.5e6 +- 1.3e6 ppm with status 1:
    |x| - 5 std stays below 100 x the declared magnitude. An estimate beyond 0.1 (1e5 ppm, 20600 arcsec) or 0.1 rad/s
    (20600 deg/h) fails (status -5) however large its std; 0.9 x those limits is judged as before
    (silent at these declared magnitudes)."""
    units = ["deg/h", "ppm", "arcsec"]
    scales = {"c0": 1e6, "c1": 1e6, "c2": 1e6}  # declared magnitudes that let the |x| - 5 std rule pass
    bad = check_magnitudes(_units_result([1.07e6, 3.5e6, 0.0], 5e5, units), scales)
    assert not bad.success and bad.status == -5
    assert "beyond what a linear error model can describe" in bad.message and "deg/s in rad/s columns" in bad.message
    rows = bad.diagnostics["beyond_linear"]
    assert {"c0", "c1"} <= {r["name"] for r in rows}
    assert [abs(r["estimate"]) / r["limit"] for r in rows] == sorted((abs(r["estimate"]) / r["limit"] for r in rows),
                                                                     reverse=True)
    ok = check_magnitudes(_units_result([0.9 * 20626.5, 0.9e5, 0.9 * 20626.5], 200.0, units), scales)
    assert ok.success and "beyond_linear" not in ok.diagnostics
