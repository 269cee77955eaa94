"""casep.workflows.judging.judge_setup asks the misfit rule (casep.checks.plausibility.misfit_problem) once."""

import dataclasses

import numpy as np

import casep
import casep.checks.plausibility as plausibility
from casep.io.flight import FlightData
from casep.workflows.judging import judge_setup


def test_judge_setup_calls_misfit_problem_once(monkeypatch):
    """One call, with the axes the whiteness test rejected and the model's advice; its message fails the result."""
    calls = []

    def spy(flight, rms, correlated, **kw):
        calls.append((tuple(correlated), kw))
        return "a model error"

    monkeypatch.setattr(plausibility, "misfit_problem", spy)
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 20.0, 0.1)
    fl = FlightData(t, np.tile([10.0, 0.0, 0.0], (t.size, 1)), rng.normal(0, 0.05, (t.size, 3)))
    res = casep.solve_ols(rng.standard_normal((60, 1)), rng.standard_normal(60), names=["sa_x"], units=["ppm"])
    res = dataclasses.replace(res, diagnostics={**res.diagnostics, "whiteness": {"rejected": ["y"]}})
    out = judge_setup(res, fl, None)
    assert len(calls) == 1 and calls[0][0] == ("y",) and calls[0][1]["runs"] is None and calls[0][1]["advice"]
    assert not out.success and out.status == -8 and "a model error" in out.message


def test_runs_that_kept_the_robust_fit_off_fail_the_result_with_their_times():
    """Robust "auto" left off because the samples it would reject lie in runs (``diagnostics["misfit_runs"]``,
    :func:`casep.regression.rows.prepare_rows`'s record): the std do not cover the misfit, so no success; the
    message says where the runs are. A result without the record is not touched by the rule."""
    rng = np.random.default_rng(2)
    t = np.arange(0.0, 20.0, 0.1)
    fl = FlightData(t, np.tile([10.0, 0.0, 0.0], (t.size, 1)), rng.normal(0, 0.05, (t.size, 3)))
    res = casep.solve_ols(rng.standard_normal((60, 1)), rng.standard_normal(60), names=["sa_x"], units=["ppm"])
    assert judge_setup(res, fl, None).success
    where = [{"sample": k, "t": float(t[k]), "file": "trk.csv", "row": k, "line": k + 3} for k in (50, 69)]
    record = {"found": 23, "in_runs": 20, "count": 1, "runs": [{"first": where[0], "last": where[1], "samples": 20}]}
    out = judge_setup(dataclasses.replace(res, diagnostics={**res.diagnostics, "misfit_runs": record}), fl, None)
    assert not out.success and out.status == -8
    assert "20 of the 23 samples" in out.message and "lines 53..72 of trk.csv, t = 5..6.9 s (20)" in out.message
    assert "the std do not cover it" in out.message


def test_a_turn_across_lost_rows_fails_only_where_the_fit_uses_rows_after_it():
    """A gap across which the body turned beyond GAP_TURN_LIMIT fails the result (status -4) when observed rows follow
    it; after the fit's last observed row (a clipped IMU's rows left out from its first clipped sample) it reaches no
    row of the fit and the result stands."""
    from casep.io.strapdown import GAP_TURN_LIMIT

    rng = np.random.default_rng(2)
    t = np.arange(0.0, 20.0, 0.1)
    gap = {"row_before": 150, "row_after": 151, "t_before": 14.9, "t_after": 15.0, "length_s": 0.1, "rows_lost": 3,
           "turn_rad": 2.0 * GAP_TURN_LIMIT}
    res = casep.solve_ols(rng.standard_normal((60, 1)), rng.standard_normal(60), names=["sa_x"], units=["ppm"])
    for last, fails in ((19.9, True), (14.0, False)):
        fl = FlightData(t, np.tile([10.0, 0.0, 0.0], (t.size, 1)), rng.normal(0, 0.05, (t.size, 3)),
                        meta={"strapdown": {"lost_rows": [gap]}}, observed=t <= last)
        out = judge_setup(res, fl, None)
        assert out.success != fails and (out.status == -4) == fails, (last, out.status, out.message)
        assert ("the telemetry lost rows while the body turned" in out.message) == fails, out.message
