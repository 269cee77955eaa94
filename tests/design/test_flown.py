"""casep.design.flown: the design model's promised change of the objective against the re-flown flights'."""

from types import SimpleNamespace

import pytest

from casep.design.flown import ATOL, RTOL, PromiseCheck, promise_check, relative_change


def test_relative_change_closed_form():
    assert relative_change(4.0, 1.0) == pytest.approx(0.75)
    assert relative_change(-2.0, -3.0) == pytest.approx(0.5)  # log det objectives are negative: |before|
    assert relative_change(0.0, 5.0) == 0.0


@pytest.mark.parametrize("design, flown, kept", [
    (0.50, 0.50, True),
    (0.50, 0.48, True),  # 4 % of 0.48 apart: within RTOL
    (0.50, 0.40, False),  # 25 % and 0.1 apart
    (0.005, 0.0, True),  # 0.005 apart: within ATOL although the relative gap is huge
    (0.03, 0.0, False),
])
def test_kept_within_the_tolerances(design, flown, kept):
    check = PromiseCheck(design, flown)
    assert check.kept is kept
    gap = abs(design - flown)
    assert kept == (gap <= RTOL * max(abs(flown), 1e-12) or gap <= ATOL)
    assert (check.warning() is None) is kept
    if not kept:
        assert f"promised a {100 * design:.1f} % change" in check.warning()
        assert f"give {100 * flown:.1f} %" in check.warning()


def test_promise_check_of_a_result():
    flown = SimpleNamespace(before=10.0, after=5.0, verification={"before": 8.0, "after": 6.0})
    c = promise_check(flown)
    assert c.design_change == pytest.approx(0.5) and c.flown_change == pytest.approx(0.25) and not c.kept
    own = SimpleNamespace(before=10.0, after=5.0, verification={})  # one's own trajectory: nothing re-flown
    assert promise_check(own) == PromiseCheck(0.5, 0.5)
