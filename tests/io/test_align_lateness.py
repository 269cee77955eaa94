"""Tracking tags late by more than a sample period, left in place: a result whose dt_trk does not take the lateness
is failed, one whose dt_trk does is not (casep.io.align.lateness_left, judged by casep.workflows.judging)."""

from __future__ import annotations

import re

import pytest

from casep.io.align import LATENESS_Z, TimeAlignment, lateness_left, unaligned_lateness


def _record(tau: float = 1.0016, explains: bool = True, mode: str = "none") -> dict:
    """The pair's record (TimeAlignment.to_dict with the reader's mode) at 20 Hz, std 0.4 ms; the shift removes 90 %
    of the misfit over 3000 samples (it explains the data) or none of it."""
    cost = 0.1 if explains else 1.0
    return {**TimeAlignment(tau, cost, 1.0, 0.05, 3000, std=0.0004).to_dict(), "mode": mode}


#: A raw-IMU flight with tracking 1 s late: the pair's record (tau, period, explains, std).
LATE = _record()


def test_a_lateness_the_fit_does_not_take_is_a_problem_naming_both():
    why = lateness_left(LATE, 0.902317, 0.00904)
    assert why is not None
    assert re.search(r"tracking time tags look 1001\.6 ms late .*--time-offset auto.*the fit's dt_trk 902\.3 "
                     r"\+- 9 ms is 11 std from it", why), why
    assert "has no dt_trk" in (lateness_left(LATE, None, None) or "")


@pytest.mark.parametrize("offset, std", [(1.0016, 0.009), (1.0016 + 0.99 * LATENESS_Z * 0.009, 0.009)])
def test_a_lateness_the_fit_takes_is_none(offset, std):
    """dt_trk within LATENESS_Z combined std of the lateness (its own 9 ms, the coarse offset's 0.4 ms)."""
    assert lateness_left(LATE, offset, std) is None


def test_only_a_lateness_left_in_place_that_explains_the_data_is_judged():
    assert LATE["explains"] and LATE["exceeds_period"]
    assert lateness_left(_record(mode="auto"), None, None) is None  # aligned by the reader
    assert lateness_left(_record(explains=False), None, None) is None  # a site or frame misfit
    assert lateness_left(_record(0.04), None, None) is None  # within a sample period
    assert unaligned_lateness(LATE) == LATE["tau_s"]
