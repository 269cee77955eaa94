"""A heading the data contradict is named first, whatever else fails (:meth:`casep.workflows.imu_separate._Run.
heading_judged`, :func:`casep.workflows.imu_separate.heading_first`).

The numbers are those of the simulated strapdown boost (``casep simulate --scenario strapdown-boost --seed 11``,
rotating Earth, geodetic tracking, MEMS noise added to the IMU) separated under ``strapdown15_axial`` with the heading
given 10 deg off: the test read +9.63 +- 0.55 deg (z 17.2), the suggested heading 200.44 deg (the truth 200.07), and
the rows navigated there at the coefficients fitted at the wrong heading still held -6.96 deg. A rule that took that
for the passes' remainder hid the heading behind "the model may lack terms: try strapdown33" (status -5).
"""

from __future__ import annotations

import dataclasses
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from casep.estimators.registry import STATUS_MAGNITUDE, STATUS_NOT_CONVERGED, STATUS_PRIOR_CONFLICT, failed
from casep.exceptions import SetupWarning
from casep.workflows import imu_separate
from casep.workflows.imu_separate import _Run, heading_first, heading_said


@dataclasses.dataclass
class _Res:
    """The fields of a result that the heading's judgement reads and writes."""

    status: int = 1
    success: bool = True
    message: str = "converged"
    diagnostics: dict = dataclasses.field(default_factory=dict)


def _record(estimate: float, std: float, heading: float = 210.067) -> dict:
    z = abs(estimate) / np.hypot(0.1, std)
    return {"estimate_deg": estimate, "std_deg": std, "heading_deg": heading, "stated_std_deg": 0.1, "z": z,
            "limit_z": 5.0, "suggested_heading_deg": heading - estimate, "conflict": bool(z > 5.0)}


def _judged(monkeypatch, res: _Res, first: dict, again: dict, settled: bool = True, said: int | None = None) -> _Res:
    """:meth:`_Run.heading_judged` on a stand-in run whose heading test reads `first` at the given heading and
    `again` at the heading it points to (`settled`: the passes met their stop rule; `said`: the SetupWarnings
    expected, one for a conflict by default)."""
    reads = iter([first, again])
    monkeypatch.setattr(imu_separate, "heading_conflict", lambda *a, **k: dict(next(reads)))
    problem = SimpleNamespace(y=np.ones((4, 3)), ls_rms=lambda: 0.1, is_noise_free=lambda rms: False,
                              with_y=lambda y: SimpleNamespace(y=y))
    run = SimpleNamespace(heading_derivative=lambda p: np.ones((4, 3)), at_rounding=lambda rms: False,
                          with_heading_noise=lambda *a: res, heading={"heading_deg": 210.067, "heading_axis": "y"},
                          heading_std=0.1, levelling=lambda: None, tau_profile=lambda p: None,
                          rows_at_heading=lambda D, h: np.zeros((4, 3)))
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        out = _Run.heading_judged(run, res, problem, SimpleNamespace(meta={}), np.zeros(3), settled=settled)
    warned = [str(w.message) for w in seen if w.category is SetupWarning]
    assert len(warned) == ((1 if first["conflict"] else 0) if said is None else said), warned
    return out


def test_a_heading_beyond_the_limit_is_named_though_the_linear_test_does_not_settle_there(monkeypatch):
    """z 17 at the given heading and -6.96 deg left at the one it points to (above half of the +9.63 found): the
    heading is named (status -10) with the heading to give, said approximate; no line says that the record checks
    the heading "only to" some degrees."""
    out = _judged(monkeypatch, _Res(), _record(9.63, 0.55), _record(-6.96, 0.55, 200.437))
    test = out.diagnostics["heading"]["test"]
    assert test["conflict"] and not test["settled"] and test["at_suggested_deg"] == -6.96, test
    assert out.status == STATUS_PRIOR_CONFLICT and not out.success
    assert out.message.startswith("failed: the data contradict the heading given: at --heading 210.067 deg"), \
        out.message
    assert "+9.63 +- 0.55 deg off" in out.message and "200.4" in out.message and "approximate" in out.message
    assert heading_said(test) is None


def test_a_heading_within_the_limit_is_not_named(monkeypatch):
    """z 4.7 (the heading known to 2 deg, read 9.4 deg off): no conflict, the result as it was, and its line says to
    what the record checks the heading."""
    res = _Res()
    out = _judged(monkeypatch, res, _record(9.4, 2.0), _record(0.0, 2.0))
    test = out.diagnostics["heading"]["test"]
    assert not test["conflict"] and out.success and out.message == "converged"
    assert "only to 10 deg" in heading_said(test)[0]


@pytest.mark.parametrize("before", [None, ("failed: the correction of bg_y is 33.2 of its std ... leaves the linear "
                                           "model", STATUS_NOT_CONVERGED)])
def test_the_heading_is_named_first_and_the_other_failures_after_it(monkeypatch, before):
    """A step that failed before the heading's test (status -7) and failures added after it (a misfit, estimates
    beyond the linear model, on the first line and after a later line, where ``failed`` appends them): the status is
    the heading's (-10), its failure opens the message, every other failure follows on the next line as a possible
    consequence of the turn, in order, and the message's other lines are kept."""
    res = _Res() if before is None else failed(_Res(), before[1], before[0])
    out = _judged(monkeypatch, res, _record(9.63, 0.35), _record(0.1, 0.35, 200.437))
    assert out.diagnostics["heading"]["test"]["settled"]
    out = failed(out, STATUS_MAGNITUDE, "failed: the noise model took the residuals for a Gauss-Markov noise as slow "
                                        "as the record ...: model strapdown15_axial may lack terms: try strapdown33")
    out = dataclasses.replace(out, message=out.message + "\nthe record checks the IMU clock's rate only to 95 ppm")
    out = failed(out, STATUS_MAGNITUDE, "failed: 2 estimate(s) beyond what a linear error model can describe")
    done = heading_first(out)
    first, second, *rest = done.message.split("\n")
    assert done.status == STATUS_PRIOR_CONFLICT and not done.success
    assert first.startswith("failed: the data contradict the heading given"), first
    assert "--heading 200.4 is what the data point to" in first, first
    assert "; failed: " not in first
    others = ["the noise model took", "2 estimate(s) beyond"]
    if before is not None:
        others.insert(0, "the correction of bg_y")
    assert second.startswith("with the turn named above (the heading, or the frames), the other findings may be its "
                                     "consequences"), second
    at = [second.index(o) for o in others]
    assert at == sorted(at), second
    assert rest == ["the record checks the IMU clock's rate only to 95 ppm"], rest
    assert heading_first(_Res(message="failed: x", success=False, status=-5)).status == -5  # no test: unchanged


def test_passes_stopped_before_settling_keep_the_half_rule_and_their_own_failure_first(monkeypatch):
    """An iteration stopped at its pass bound (an IMU gap in the roll ramp, two passes: +2.14 +- 0.078 deg, z 17,
    0.35 deg left at the heading it points to): the rows hold the passes' remainder, so the heading is said after the
    failure that stopped them (status kept, heading_first leaves it); with the turn left there above half of the one
    found, no conflict at all."""
    stopped = failed(_Res(), STATUS_NOT_CONVERGED, "failed: the iteration did not converge in 2 passes: the IMU gap")
    out = heading_first(_judged(monkeypatch, stopped, _record(2.14, 0.078), _record(0.35, 0.078, 207.9),
                                settled=False))
    test = out.diagnostics["heading"]["test"]
    assert test["conflict"] and not test["first"] and out.status == STATUS_NOT_CONVERGED, test
    assert out.message.startswith("failed: the iteration did not converge") and "contradict the heading" in out.message
    stopped = failed(_Res(), STATUS_NOT_CONVERGED, "failed: the iteration did not converge in 2 passes")
    out = _judged(monkeypatch, stopped, _record(2.14, 0.078), _record(1.5, 0.078, 207.9), settled=False, said=0)
    assert not out.diagnostics["heading"]["test"]["conflict"] and out.message.endswith("2 passes")


def test_a_heading_known_beyond_the_small_angle_reach_is_not_judged(monkeypatch):
    """-417 +- 34 deg (late tracking tags, two passes): std times the limit beyond 30 deg, no conflict, no warning."""
    out = _judged(monkeypatch, _Res(), _record(-417.5, 34.4), _record(278.9, 34.4), said=0)
    test = out.diagnostics["heading"]["test"]
    assert not test["judged"] and not test["conflict"] and out.success
