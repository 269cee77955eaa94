"""The late-start check (casep.checks.late_start): a flight whose telemetry begins after lift-off."""

from __future__ import annotations

import numpy as np
import pytest

import casep
from casep.checks.late_start import late_start_evidence
from casep.exceptions import CasepWarning
from casep.io.flight import LateStartWarning
from casep.simulation.simulate import simulate_flight


def _cut(fl, t0):
    k = fl.t >= t0
    return casep.FlightData(fl.t[k], fl.f[k], fl.dv[k], source=f"cut at {t0:g} s")


@pytest.mark.parametrize("rate", [20.0, 100.0])
def test_late_start_warning_on_flight_cut_at_20s(rate, platform36):
    fl = simulate_flight("paper", seed=3, rate=rate).flight
    assert late_start_evidence(fl) == {}
    cut = _cut(fl, 20.0)
    ev = late_start_evidence(cut)
    # dv(20 s) of the paper truth is (-0.36, -0.20, 0.21) m/s against 0.1 m/s noise.
    np.testing.assert_allclose(ev["dv0"], [-0.36, -0.20, 0.21], atol=0.1)
    # (the unmodelled dv0 and phi0 also leave residuals the time-offset check may flag)
    with pytest.warns(CasepWarning) as rec:
        casep.separate(cut, platform36)
    late = [str(w.message) for w in rec if w.category is LateStartWarning]
    assert len(late) == 1
    msg = late[0]
    assert "cut at 20 s: the flight seems to start after lift-off (t0 = 20 s)" in msg
    assert "initial velocity error dv0" in msg and "initial platform misalignment phi0" in msg
    assert "platform36_dv0" in msg and "platform39_misalignment" in msg and "chi-square" in msg
    with pytest.warns(CasepWarning) as rec:
        casep.separate(cut, "platform36_dv0")
    late = [str(w.message) for w in rec if w.category is LateStartWarning]
    assert len(late) == 1 and "has no initial platform misalignment phi0" in late[0] and "dv0 (" not in late[0]
    assert "or it starts at lift-off with an initial velocity error" in late[0]  # dv evidence alone


@pytest.mark.parametrize("scenario", ["paper", "paper-pitch", "paper-ar1"])
def test_no_late_start_alarm_on_flights_from_liftoff(scenario):
    for seed in range(6):
        fl = simulate_flight(scenario, seed=seed, rate=20.0 if seed % 2 else 100.0).flight
        assert late_start_evidence(fl) == {}, (scenario, seed)
