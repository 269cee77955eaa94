"""A noise-free pair of files at two rates: the residuals sit at the interpolation error of the telemetry carried
to the tracking times, known from the data (casep.io.pair.interpolation_floor); the noise-free rule counts it as
no noise, so the robust filter calls no sample a glitch, and a pair with noise far above that floor is not
noise-free."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import casep
from casep.exceptions import NoiseFreeWarning


def _pair(noise_std: float):
    from casep.io.pair import pair_flight
    from casep.simulation.scenarios import NoiseModel, get_scenario
    from casep.simulation.simulate import simulate_two_rate

    sc = dataclasses.replace(get_scenario("paper-azimuth"), noise=NoiseModel("white", noise_std))
    d = simulate_two_rate(sc, seed=3, telemetry_rate=20.0, tracking_rate=8.0)
    return pair_flight(d.t_tel, d.f, d.v_tel, d.t_trk, d.v_trk, source="tel + trk")


@pytest.fixture(scope="module")
def model():
    return casep.load_model("platform36")


def test_noise_free_pair_rejects_no_glitch(model):
    flight = _pair(0.0)
    assert flight.meta["interpolation_floor_m_s"] > 0.0
    pb = casep.Problem.from_flight(flight, model)
    assert pb.ls_rms() > 1e-9 * np.max(np.abs(pb.y))  # above the rounding level: the floor is what decides
    assert pb.is_noise_free()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", casep.IllConditionedWarning)
        with pytest.warns(NoiseFreeWarning, match="interpolation floor"):
            res = casep.separate(flight, model)
    assert "robust" not in res.diagnostics and res.success


def test_noisy_pair_is_not_noise_free(model):
    flight = _pair(0.01)
    assert not casep.Problem.from_flight(flight, model).is_noise_free()
