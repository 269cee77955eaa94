"""The parts of casep.montecarlo on their own: the result's statistics and protocol, the method
spec language, the campaign's context (its per-campaign cache), the task cut and the progress lines."""

from __future__ import annotations

import json
import pickle
import re

import numpy as np
import pytest

from casep.estimators.registry import METHODS
from casep.montecarlo import MonteCarloResult, run_montecarlo
from casep.montecarlo.methods import parse_method
from casep.montecarlo.progress import Progress
from casep.montecarlo.tasks import chunks
from casep.results import Result


def _result() -> MonteCarloResult:
    """Two coefficients, four runs, errors and stds chosen so every statistic is known by hand."""
    truth = np.array([1.0, -2.0])
    err = np.array([[0.1, 1.0], [-0.3, -1.0], [0.2, 1.0], [0.0, -1.0]])
    std = np.array([[0.1, 1.0], [0.1, 1.0], [0.1, np.inf], [0.1, np.nan]])
    return MonteCarloResult(scenario="hand", runs=4, seed=9, names=("a", "b"), units=("mg", "ppm"), truth=truth,
                            crlb_std=np.array([0.2, 0.5]), estimates={"ols": truth + err, "rels": truth + err},
                            stds={"ols": std, "rels": None}, seconds={"ols": 0.5})


def test_result_statistics_by_hand():
    st = _result().stats("ols")
    # bias = mean error; rms = sqrt(mean error^2); efficiency = crlb / rms
    np.testing.assert_allclose(st["bias"], [0.0, 0.0], atol=1e-15)
    rms = np.sqrt([(0.01 + 0.09 + 0.04 + 0.0) / 4, 1.0])
    np.testing.assert_allclose(st["rms"], rms)
    np.testing.assert_allclose(st["efficiency"], np.array([0.2, 0.5]) / rms)
    # coverage over the runs with a finite std: a: |e| <= 1.96 * 0.1 in runs 0, 3 of 4 (0.3 and 0.2 are out);
    # b: runs 0 and 1 have a std (1.0 <= 1.96) -> 2 of 2; inf and nan are no interval
    np.testing.assert_allclose(st["coverage95"], [0.5, 1.0])
    assert np.isnan(_result().stats("rels")["coverage95"]).all()  # the method gives no std


def test_result_follows_the_result_protocol():
    res = _result()
    assert isinstance(res, Result)
    d = res.to_dict()
    assert json.loads(json.dumps(d, allow_nan=False)) == d  # plain data
    assert d["methods"]["rels"]["coefficients"][0]["coverage95"] is None
    assert d["methods"]["ols"]["coefficients"][1]["efficiency"] == pytest.approx(0.5)
    text = res.text()
    assert text.splitlines()[0] == "scenario hand, 4 runs, seed 9"
    assert text.endswith(res.method_table()) and "median efficiency" in text


@pytest.mark.parametrize("spec, name, linear, denoise", [
    ("ols", "ols", True, False), ("ridge", "ridge", False, False), ("ridge:1e-5", "ridge", True, False),
    ("wavelet+ols", "ols", False, True), ("wavelet+ridge:2", "ridge", False, True), ("gls", "gls", False, False),
    ("bounded", "bounded", False, False), ("map", "map", True, False),
])
def test_method_specs(spec, name, linear, denoise):
    m = parse_method(spec)
    assert (m.text, m.name, m.linear, m.denoise) == (spec, name, linear, denoise)
    assert m.options == ({"lam": float(spec.rsplit(":", 1)[1])} if ":" in spec else {})


@pytest.mark.parametrize("spec, message", [("ridge:0", "lambda must be > 0"), ("ridge:x", "needs a number"),
                                           ("wavelet+foo", "unknown method `wavelet+foo`")])
def test_bad_method_specs_are_refused_naming_them(spec, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        parse_method(spec)


@pytest.mark.parametrize("runs", [1, 15, 16, 17, 100, 1000, 5000])
def test_tasks_cover_the_runs_once_and_gls_chunks_stay_small(runs):
    for specs in ([parse_method("ols")], [parse_method("ols"), parse_method("gls")]):
        cut = chunks(specs, runs)
        assert [k for c in cut for k in c] == list(range(runs))
        sizes = {len(c) for c in cut[:-1]} or {len(cut[0])}
        assert len(sizes) == 1 and len(cut[-1]) <= max(sizes) <= 128
        if len(specs) == 2:
            assert max(len(c) for c in cut) <= METHODS["gls"].max_runs_per_task == 16


def test_campaign_context_caches_its_maps_and_never_sends_them():
    """The linear maps are built once per campaign context (per worker), and pickling the context
    (what Dask scatters) leaves the cached maps and model behind."""
    from casep.montecarlo.campaign import _context  # the campaign's own set-up, as run_montecarlo builds it

    ctx, _, _ = _context("paper", 2.0, 1, None, None, None, None, None, None, linear=("ols", "map"))
    maps = ctx.nominal_maps
    assert set(maps) == {"ols", "map"} and ctx.nominal_maps is maps
    _ = ctx.model
    back = pickle.loads(pickle.dumps(ctx))
    assert "nominal_maps" not in back.__dict__ and "model" not in back.__dict__
    np.testing.assert_array_equal(back.nominal_maps["ols"].K, maps["ols"].K)  # rebuilt alike where used


def test_progress_lines_mode_writes_whole_lines_per_stage(capsys):
    p = Progress(4, ["ols,rls", "rels"], "lines", every=0.0)
    for _ in range(4):
        p(1)
    p.next_stage()
    p(4)
    p.close()
    err = capsys.readouterr().err
    assert "\r" not in err
    lines = err.splitlines()
    assert lines[0].startswith("montecarlo: ols,rls 1/4 runs (method 1 of 2, 12 % of all)")
    assert lines[-1].startswith("montecarlo: rels 4/4 runs (method 2 of 2, 100 % of all)")
    assert lines[-1].endswith("s elapsed, ETA 0 s")
    assert not any("ETA -" in line for line in lines[1:])


def test_progress_off_writes_nothing(capsys):
    res = run_montecarlo("paper", runs=2, methods=["ols"], seed=1, rate=1.0, workers=1, progress=False, noise="white")
    assert res.runs == 2 and capsys.readouterr().err == ""
