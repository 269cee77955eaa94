"""Every path solves the request's method through the one entry point ``fit`` (:mod:`casep.estimators.solve`).

A registered method's solver is dispatched by its registry entry (:meth:`Method.solve`; the public
``solve_ols`` & co. are :meth:`Method.call`). While each path runs (one flight, several flights, radar,
Monte Carlo, calibration), a wrapper of :meth:`Method.solve` records whether ``fit`` is on the call stack:
every dispatch must be inside it. On the code before radar and calibration were routed through ``fit``,
the radar and calibration cases fail here. The structure test (``tests/test_structure.py``) states the
same rule on the source: no ``METHODS[...].solve`` outside that module.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import casep
import casep.estimators.solve as solve_module
from casep.estimators._options import Method

SOLVE = Path(solve_module.__file__).resolve()


def _inside_fit(frame) -> bool:
    while frame is not None:
        if frame.f_code.co_name == "fit" and Path(frame.f_code.co_filename).resolve() == SOLVE:
            return True
        frame = frame.f_back
    return False


@pytest.fixture
def dispatches(monkeypatch):
    """``[(method, inside fit)]`` of every :meth:`Method.solve` while the test runs."""
    seen: list[tuple[str, bool]] = []
    real = Method.solve

    def recording(self, problem, **kw):
        seen.append((self.name, _inside_fit(sys._getframe(1))))
        return real(self, problem, **kw)

    monkeypatch.setattr(Method, "solve", recording)
    return seen


def _all_inside(seen, methods):
    assert {m for m, _ in seen} == set(methods), seen
    assert all(inside for _, inside in seen), [m for m, inside in seen if not inside]


def test_the_wrapper_sees_a_dispatch_outside_fit(dispatches):
    """The test can fail: a method dispatched by its registry entry outside ``fit`` is recorded as such."""
    from casep.estimators.registry import METHODS

    rng = np.random.default_rng(0)
    pb = casep.Problem.from_arrays(rng.normal(size=(40, 3, 2)), rng.normal(size=(40, 3)), np.arange(40.0))
    METHODS["ols"].solve(pb)
    casep.fit(pb, casep.FitSpec("ols", noise=casep.NoiseSpec("white", robust=None)), checks=False)
    assert dispatches == [("ols", False), ("ols", True)]


def test_one_flight_and_several_flights(dispatches):
    from casep.simulation import get_scenario, simulate_flight
    from casep.workflows.flights import separate_flights

    sc = get_scenario("paper")
    a, b = (simulate_flight(sc, seed=s, rate=2.0) for s in (1, 2))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a 2 Hz flight's conditioning and noise: not the question here
        casep.separate(a.flight, a.model, "pcr", noise="white")
        separate_flights([a.flight, b.flight], a.model, "ols", noise="white")
    _all_inside(dispatches, ["pcr", "ols"])


def test_radar(dispatches):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "radar"))
    from test_radar import SITE, STATIONS, TRUTH

    from casep.simulation.radar import simulate_radar
    from casep.workflows.radar import separate_radar

    sim = simulate_radar(STATIONS[:1], SITE, seed=3, telemetry_rate=2, radar_rate=2, tracking_truth={"S1": TRUTH["S1"]})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a short 2 Hz track: its residual checks are not the question here
        separate_radar(sim.telemetry, list(sim.radars), SITE, sim.model, sim.tracking, "ols", noise="white",
                       diagnostics=False)
    _all_inside(dispatches, ["ols"])


def test_calibration(dispatches):
    from casep.calibration.calibrate import calibrate
    from casep.calibration.model import load_calibration_model
    from casep.calibration.simulate import ferraris_design, simulate_session

    model = load_calibration_model("ferraris")
    truth = dict.fromkeys(model.names, 0.1)
    for i, a in enumerate("xyz"):
        truth[f"Ma_{a}{a}"] = 200.0 + 10 * i  # a.u. per m/s^2
        truth[f"Mg_{a}{a}"] = 16.0 + i  # a.u. per deg/s
    ses, segs = simulate_session(model, truth, ferraris_design(20, 40), rate=50.0, noise=(3.0, 1.0), seed=2)
    cal = calibrate(ses, segs, model, "huber")
    _all_inside(dispatches, ["huber"])
    assert np.all(np.isfinite(cal.result.estimate))


def test_monte_carlo(dispatches):
    from casep.montecarlo import run_montecarlo

    run_montecarlo("paper", runs=2, methods=["ols", "gls"], seed=4, rate=2.0, workers=1, progress=False,
                   noise="auto")
    _all_inside(dispatches, ["ols", "gls"])
