"""Allan deviation and noise identification (casep.noise.identification)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from casep.noise.identification import allan_deviation, avar_gauss_markov, avar_random_walk, avar_white, identify_noise


def _ar1(rng, n, dt, T, q):
    a = np.exp(-dt / T)
    e = rng.standard_normal(n) * q * np.sqrt(1 - a * a)
    y = np.empty(n)
    y[0] = q * rng.standard_normal()
    for k in range(1, n):
        y[k] = a * y[k - 1] + e[k]
    return y


def test_closed_forms_against_allantools(rng):
    """The models' Allan variances against allantools' overlapping ADEV of long seeded series:
    white, AR(1) (exact sampled form; the continuous one within 3 % for tau >= 10 dt) and random
    walk, within 6 % (statistical error of 1e5 samples at these taus)."""
    dt = 0.01
    taus = np.array([0.01, 0.1, 1.0, 3.0])
    x = 0.1 * rng.standard_normal(100_000)
    t, ad, _ = allan_deviation(x, dt, taus)
    np.testing.assert_allclose(ad, np.sqrt(avar_white(t, dt, 0.01)), rtol=0.06)
    y = _ar1(rng, 100_000, dt, 1.0, 0.1)
    t, ad, _ = allan_deviation(y, dt, taus)
    np.testing.assert_allclose(ad, np.sqrt(avar_gauss_markov(t, 0.01, 1.0, dt)), rtol=0.06)
    np.testing.assert_allclose(avar_gauss_markov(t[1:], 0.01, 1.0), avar_gauss_markov(t[1:], 0.01, 1.0, dt), rtol=0.03)
    w = np.cumsum(0.01 * rng.standard_normal(100_000))
    t, ad, _ = allan_deviation(w, dt, taus)
    np.testing.assert_allclose(ad, np.sqrt(avar_random_walk(t, dt, 1e-4)), rtol=0.06)


@pytest.mark.parametrize("kind", ["white", "gauss_markov", "random_walk"])
def test_each_noise_is_identified_from_its_own_series(rng, kind):
    dt, n = 0.05, 4000
    e = {"white": lambda: 0.1 * rng.standard_normal((n, 3)),
         "gauss_markov": lambda: np.column_stack([_ar1(rng, n, dt, 1.0, 0.1) for _ in range(3)]),
         "random_walk": lambda: np.cumsum(0.01 * rng.standard_normal((n, 3)), axis=0)}[kind]()
    ni = identify_noise(e, dt)
    assert ni.choice == kind, ni.text()
    if kind == "gauss_markov":
        assert 0.7 < ni.fits["gauss_markov"]["T"] < 1.4
        assert "--method gls --tau" in ni.recommendation
    if kind == "white":
        assert ni.fits["white"]["s"] == pytest.approx(0.1, rel=0.1)


def test_flight_residuals_white_and_gauss_markov(tmp_path):
    """From OLS residuals of simulated flights (20 Hz): paper -> white; paper-ar1 (tau 1 s) ->
    Gauss-Markov with T in [0.5, 1.5] s (the 36 fitted regressors take part of the slow noise, so
    T comes out low: 0.7-0.9 s measured); CLI JSON and figure."""
    from casep.cli import main
    from casep.io.files import write_flight
    from casep.simulation.simulate import simulate_flight

    out = {}
    for sc in ("paper", "paper-ar1"):
        write_flight(simulate_flight(sc, seed=1, rate=20.0).flight, tmp_path / f"{sc}.csv")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # ill-conditioned
            assert main(["noise", str(tmp_path / f"{sc}.csv"), "--json", str(tmp_path / f"{sc}.json"),
                         "--figures", str(tmp_path / "fig")]) == 0
        out[sc] = json.loads((tmp_path / f"{sc}.json").read_text())
    assert out["paper"]["choice"] == "white"
    assert out["paper-ar1"]["choice"] == "gauss_markov" and 0.5 < out["paper-ar1"]["fits"]["gauss_markov"]["T"] < 1.5
    assert (tmp_path / "fig" / "allan.png").read_bytes()[:4] == b"\x89PNG"


def test_bad_input():
    with pytest.raises(ValueError, match="too few"):
        identify_noise(np.zeros((10, 3)), 0.1)
    with pytest.raises(ValueError, match="`dt` must be finite"):
        identify_noise(np.ones((100, 3)), 0.0)
    with pytest.raises(ValueError, match="must be finite"):
        identify_noise(np.full((100, 3), np.nan), 0.1)
