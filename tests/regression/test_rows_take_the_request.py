"""prepare_rows takes the fit request's noise part (NoiseSpec), checked by it alone: no second list of choices."""

from __future__ import annotations

import numpy as np
import pytest

import casep.regression.rows as rows_module
from casep.noise.spec import NoiseSpec
from casep.regression.problem import Problem
from casep.regression.rows import prepare_rows


@pytest.fixture(scope="module")
def problem():
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 60.0, 0.1)
    S = rng.normal(size=(t.size, 3, 4))
    y = S @ np.array([1.0, -2.0, 0.5, 3.0]) + 0.01 * rng.normal(size=(t.size, 3))
    return Problem.from_arrays(S, y, t)


def test_a_noise_spec_is_taken_as_checked(problem):
    spec = NoiseSpec("white", robust="none")
    by_spec = prepare_rows(problem, spec)
    by_words = prepare_rows(problem, "white", robust=None)
    assert by_spec.noise.kind == by_words.noise.kind == "white" and by_spec.robust is None
    np.testing.assert_allclose(by_spec.solved.y, by_words.solved.y, rtol=0, atol=0)


@pytest.mark.parametrize(("kw", "flag"), [({"robust": "tukey"}, "--robust"), ({"noise": "pink"}, "--noise"),
                                          ({"tau": -1.0, "noise": "gm"}, "--tau")])
def test_bad_words_are_refused_by_the_request(problem, kw, flag):
    with pytest.raises(ValueError, match=rf"^option {flag} \(`\w+`\) must be "):
        prepare_rows(problem, **kw)


def test_no_second_list_of_robust_choices():
    assert not hasattr(rows_module, "ROBUST_CHOICES")


@pytest.mark.parametrize("kind", ["bumps", "glitches"])
def test_a_smooth_misfit_is_said_and_not_filtered_as_glitches(kind):
    """Robust 'auto': three smooth bumps the model lacks (1e-3 over ~2 s, in 1e-5 white noise: runs of ~18 samples
    beyond 4 sigma, as the second-order terms of a noise-free strapdown flight leave) are a model misfit: the
    robust fit is not engaged and the misfit is said; the same size as isolated one-sample glitches engages it."""
    from casep.exceptions import NoiseNotWhiteWarning
    from casep.noise.robust import MAX_RUN

    rng = np.random.default_rng(11)
    t = np.arange(0.0, 60.0, 0.1)
    S = rng.normal(size=(t.size, 3, 4))
    e = 1e-5 * rng.normal(size=(t.size, 3))
    if kind == "bumps":
        e[:, 0] += 1e-3 * sum(np.exp(-(((t - c) / 0.5) ** 2)) for c in (15.0, 30.0, 45.0))
    else:
        e[rng.choice(np.arange(10, t.size - 10), 12, replace=False), 0] += 1e-3
    pb = Problem.from_arrays(S, S @ np.array([1.0, -2.0, 0.5, 3.0]) + e, t)
    if kind == "bumps":
        with pytest.warns(NoiseNotWhiteWarning, match=rf"in 3 run\(s\) of {MAX_RUN} or more .* smooth misfit"):
            rows = prepare_rows(pb, "white")
        assert rows.robust is None and rows.keep.all() and rows.misfit_runs["stepped"] is None
        # the runs recorded where they lie (the result then fails: casep.workflows.judging), around each bump
        runs = rows.misfit_runs["runs"]
        assert rows.misfit_runs["count"] == len(runs) == 3 and rows.misfit_runs["in_runs"] >= 3 * MAX_RUN
        for r, c in zip(runs, (15.0, 30.0, 45.0)):
            assert c - 1.5 < r["first"]["t"] < r["last"]["t"] < c + 1.5 and r["samples"] >= MAX_RUN, runs
    else:
        rows = prepare_rows(pb, "white")
        assert rows.robust is not None and rows.robust["automatic"]["glitches_found"] >= 12
        assert rows.misfit_runs is None


@pytest.mark.parametrize("robust", ["auto", "huber"])
def test_spikes_on_noise_free_rows_are_exactly_the_glitches(robust):
    """Four 5 m/s spikes on noise-free rows, a misfit of 0 otherwise: exactly the four samples rejected (neither
    the smooth misfit they leave in a least-squares fit nor rounding-level residuals judged on a ~0 MAD), no
    misfit warning, and the estimate that of the rows without the spikes (noise-free: exact to rounding)."""
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 120.0, 0.1)
    tt = t / t[-1]
    S = np.zeros((t.size, 3, 12))  # smooth columns, as S_V: the misfit the spikes leave in a fit is smooth
    for a in range(3):
        S[:, a, 4 * a:4 * a + 4] = (1 + a) * np.stack([np.ones_like(tt), tt, tt**2, np.sin(3 * tt)], -1)
    x_true = rng.normal(size=12)
    y = S @ x_true
    spikes = rng.choice(np.arange(20, t.size - 20), 4, replace=False)
    y[spikes, rng.integers(3, size=4)] += 5.0 * rng.choice([-1.0, 1.0], 4)
    rows = prepare_rows(Problem.from_arrays(S, y, t), "auto", robust=robust)  # filterwarnings=error: no warning
    assert sorted(np.flatnonzero(~rows.keep)) == sorted(spikes)
    x, _ = rows_module._ls(rows.solved)
    np.testing.assert_allclose(x, x_true, rtol=0, atol=1e-9)


def test_a_fit_says_every_sample_it_removed():
    """The result of a robust fit names every sample it left out (``removed_samples``, not only the 200 it locates),
    and :func:`casep.estimators.solve.kept_samples` reads them back; a fit that removed none says none."""
    from casep.estimators.solve import fit, kept_samples
    from casep.estimators.spec import FitSpec

    rng = np.random.default_rng(3)
    t = np.arange(0.0, 120.0, 0.1)
    S = rng.normal(size=(t.size, 3, 4))
    y = S @ np.array([1.0, -2.0, 0.5, 3.0]) + 0.01 * rng.normal(size=(t.size, 3))
    spikes = np.sort(rng.choice(np.arange(20, t.size - 20), 210, replace=False))
    clean = Problem.from_arrays(S, y.copy(), t)
    y[spikes, rng.integers(3, size=spikes.size)] += 5.0
    spec = FitSpec.build("ols", noise="white", robust="huber")
    res = fit(Problem.from_arrays(S, y, t), spec, checks=False)
    assert res.diagnostics["removed_samples"] == spikes.tolist() and len(res.diagnostics["robust"]["rejected"]) == 200
    assert np.array_equal(kept_samples(res.diagnostics, t.size), ~np.isin(np.arange(t.size), spikes))
    plain = fit(clean, FitSpec.build("ols", noise="white", robust="none"), checks=False)
    assert "removed_samples" not in plain.diagnostics and kept_samples(plain.diagnostics, t.size).all()


def test_a_tracking_velocity_held_between_1_hz_updates_is_said():
    """After 30 s the tracking velocity is the one of the last whole second 0.4 s late, held for the 10 epochs of
    each second, plus a Gauss-Markov error (3 m/s, tau 5 s) that changes every epoch: the rows (``v_tel - v_trk``)
    step every 1 s (the vehicle decelerating at 8 to 12 m/s^2) and the fit's misfit runs are said to be a stepped
    tracking, with its stretch, period and count; the bumps of a missing term are not (the test above)."""
    from casep.exceptions import NoiseNotWhiteWarning
    from casep.regression.rows import stepped_rows

    rng = np.random.default_rng(5)
    t = np.round(np.arange(0.0, 60.0, 0.1), 10)
    S = rng.normal(size=(t.size, 3, 4))
    accel = np.array([-8.0, 10.0, -12.0])  # m/s^2
    late = t >= 30.0
    lag = np.where(late, t - (np.floor(t + 1e-9) - 0.4), 0.0)  # how old the held velocity is, s
    gm = np.zeros((t.size, 3))
    beta = np.exp(-0.1 / 5.0)
    for k in range(1, t.size):
        gm[k] = beta * gm[k - 1] + np.sqrt(1.0 - beta**2) * rng.normal(0.0, 3.0, 3)
    e = 0.05 * rng.normal(size=(t.size, 3)) + late[:, None] * (lag[:, None] * accel + gm)
    pb = Problem.from_arrays(S, S @ np.array([1.0, -2.0, 0.5, 3.0]) + e, t)
    said = r"the residuals step every 1 s over t = 30\.\.59 s \(30 steps in a row"
    with pytest.warns(NoiseNotWhiteWarning, match=said):
        rows = prepare_rows(pb, "white")
    assert rows.misfit_runs["stepped"] == {"first_t": 30.0, "last_t": 59.0, "period_s": pytest.approx(1.0),
                                           "steps": 30}
    # the same error without the hold (the Gauss-Markov error alone, every epoch fresh): no steps said
    assert stepped_rows(t, S @ np.ones(4) + 0.05 * rng.normal(size=(t.size, 3)) + late[:, None] * gm, 0) is None
