"""A flight's problem after the checks before estimation (casep.checks.flight): the checks
are the caller's, not the Problem's, and the problem built after them is the one without them."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import casep
from casep.checks.flight import check_before_estimation, flight_problem
from casep.exceptions import PlausibilityWarning
from casep.io.flight import FlightDataError
from casep.regression.problem import Problem
from casep.simulation.simulate import simulate_flight
from casep.units import G0


@pytest.fixture(scope="module")
def sim():
    return simulate_flight("paper", seed=3, rate=5.0)


def test_flight_problem_checks_first_and_builds_the_same_problem(sim):
    """f in g: the checks warn with the factor; the regression built after them equals the one built
    without them (Problem.from_flight judges nothing: no warning), to the last bit."""
    fl = casep.FlightData(t=sim.flight.t, f=sim.flight.f / G0, dv=sim.flight.dv, source="in_g.csv")
    with pytest.warns(PlausibilityWarning, match=r"in_g\.csv.*multiply by 9\.80665"):
        checked = flight_problem(fl, sim.model, keep_sv=False, block_rows=100)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        plain = Problem.from_flight(fl, sim.model, keep_sv=False, block_rows=100)
    np.testing.assert_array_equal(checked.red.R, plain.red.R)
    np.testing.assert_array_equal(checked.y, plain.y)
    assert (checked.n, checked.source, checked.model) == (plain.n, "in_g.csv", sim.model.name)


def test_too_few_samples_refused_before_s_v_is_integrated(sim, monkeypatch):
    """The sample count is refused with the file and the model named, before any S_V is built."""
    fl = casep.FlightData(t=sim.flight.t[:10], f=sim.flight.f[:10], dv=sim.flight.dv[:10], source="short.csv")

    def no_sv(*args, **kwargs):
        raise AssertionError("S_V integrated before the checks")

    monkeypatch.setattr(Problem, "from_flight", no_sv)
    with pytest.raises(FlightDataError, match=rf"short\.csv: .*10 samples are too few for model `{sim.model.name}`"):
        flight_problem(fl, sim.model)
    with pytest.raises(FlightDataError, match="too few"):
        check_before_estimation(fl, sim.model)


def test_the_public_name_is_the_checked_builder():
    assert casep.flight_problem is flight_problem and casep.checks.flight_problem is flight_problem
