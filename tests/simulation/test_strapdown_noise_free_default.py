"""A noise-free strapdown flight through the default ``casep.separate`` of its file: the truth recovered, or a misfit.

The simulator writes ``dv = S_V D_true`` (linear in the coefficients), so a noise-free file fitted with the model it
was made with leaves rounding only, and with a model that lacks terms the flight excites leaves those terms' part,
smooth and far above the record's sample-to-sample change: a model error, which the default fit once whitened with
a Gauss-Markov noise as slow as the record and returned as a success with a gyro bias 569 of its std off.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import casep
from casep.estimators.registry import STATUS_MISFIT
from casep.simulation.scenarios import STRAPDOWN_TRUTH, get_scenario
from casep.simulation.simulate import simulate_flight, write_simulation

AXIAL = "strapdown15_axial"
RATE = 20.0  # Hz


def _separate(sim, path, model):
    write_simulation(sim, path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the noise-free, conditioning and misfit warnings: the result is judged
        return casep.separate(path, model)


@pytest.fixture(scope="module")
def axial_truth():
    names = casep.load_model(AXIAL).names
    return {k: v for k, v in STRAPDOWN_TRUTH.items() if k in names}


def test_noise_free_file_with_its_own_model_recovers_the_truth(tmp_path, axial_truth):
    """The default path on the noise-free file: every coefficient within 0.01 of the std the same flight with the
    scenario's tracking noise gets (the noisy fit's std stand for the CRLB: the noise-free fit's own are rounding)."""
    scenario = get_scenario("strapdown-boost")
    clean = simulate_flight(scenario.without_noise(), model=AXIAL, truth=axial_truth, rate=RATE)
    noisy = simulate_flight(scenario, seed=1, model=AXIAL, truth=axial_truth, rate=RATE)
    res = _separate(clean, tmp_path / "clean.csv", AXIAL)
    ref = _separate(noisy, tmp_path / "noisy.csv", AXIAL)
    assert res.success and ref.success, (res.message, ref.message)
    err = np.abs(res.estimate - clean.truth) / ref.std
    assert err.max() <= 0.01, dict(zip(res.names, err))
    assert np.max(np.abs((ref.estimate - noisy.truth) / ref.std)) < 4.0


def test_noise_free_file_missing_terms_fails_as_misfit(tmp_path):
    """strapdown33's errors fitted with strapdown15_axial: noise-free, the 18 terms it lacks leave a smooth residual
    (5 mm/s) far above the record's own sample-to-sample change: failed as a misfit naming the missing terms; the
    same flight with tracking noise, whose residual the missing terms barely touch, stays an honest success."""
    scenario = get_scenario("strapdown-boost")
    clean = simulate_flight(scenario.without_noise(), rate=RATE)  # strapdown33 and its truth
    res = _separate(clean, tmp_path / "clean.csv", AXIAL)
    assert res.status == STATUS_MISFIT, res.message
    assert "as slow as the record" in res.message and "may lack terms" in res.message
    noisy = simulate_flight(scenario, seed=1, rate=RATE)
    ref = _separate(noisy, tmp_path / "noisy.csv", AXIAL)
    truth = dict(zip(noisy.model.names, noisy.truth))
    assert ref.success, ref.message
    assert np.max(np.abs((ref.estimate - np.array([truth[n] for n in ref.names])) / ref.std)) < 4.0
