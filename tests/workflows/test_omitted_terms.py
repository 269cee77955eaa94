"""The terms strapdown15_axial leaves out (casep.workflows.omitted_terms) on the simulated strapdown boost (5 Hz,
the scenario's Gauss-Markov plus white tracking noise): strapdown33's extra columns beside the fit. With every
strapdown33 term drawn at the scenario's truth the rows cannot see them (they act through the model's own columns),
so the result carries them as consider parameters and its covariance covers the error (checked against the truth);
drawn 30 times larger along what the rows do see, the result fails naming them; the truth limited to the model's
terms passes. The Wald chi-square is checked against the extra sum of squares of two least-squares fits (numpy)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from casep.estimators.joint import FAIL_P
from casep.estimators.registry import STATUS_MISFIT
from casep.estimators.solve import fit
from casep.estimators.spec import FitSpec
from casep.model.loader import load_model
from casep.simulation.simulate import simulate_flight, write_simulation
from casep.workflows import omitted_terms
from casep.workflows.separate import _problem

MODEL = "strapdown15_axial"
#: chi-square(15) at 1 - 1e-3: a Mahalanobis distance of the error below it is a covariance that covers the error
CHI2_15_999 = 37.70
#: the scenario's truth of the model's 15 terms (``casep simulate --truth``), the others 0
LIMITED = {"ba_x": 0.8, "sa_x": 250.0, "ba_y": -0.5, "ma_yx": 20.0, "ba_z": 0.6, "ma_zx": -40.0, "bg_x": 1.0,
           "sg_x": 80.0, "gg_xx": 0.5, "bg_y": -0.8, "mg_yx": 40.0, "gg_yx": 0.4, "bg_z": 0.5, "mg_zx": 20.0,
           "gg_zx": -0.2}


def _judged(tmp_path_factory, name: str, seed: int, truth: dict | None, spec: FitSpec | None = None):
    path = tmp_path_factory.mktemp("omitted") / f"{name}.csv"
    sim = simulate_flight("strapdown-boost", seed=seed, rate=5.0, truth=truth)
    write_simulation(sim, path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        flight, problem, model = _problem(path, MODEL, False)
        res = fit(problem, spec or FitSpec.build())
        out = omitted_terms.judge_omitted(res, flight, problem, model)
    truth = json.loads(path.with_name(f"{name}.truth.json").read_text())["coefficients"]  # natural units
    return res, out, (flight, problem), truth


@pytest.fixture(scope="module")
def full(tmp_path_factory):
    return _judged(tmp_path_factory, "full", 1, None)


def _mahalanobis(res, truth: dict) -> float:
    e = np.asarray(res.estimate) - np.array([truth.get(n, 0.0) for n in res.names])
    return float(e @ np.linalg.solve(np.asarray(res.covariance), e))


def test_the_scenario_truth_is_carried_as_consider_parameters(full):
    res, out, _, truth = full
    record = out.diagnostics["omitted_terms"]
    assert out.success and record["richer"] == "strapdown33" and record["dof"] == 6
    assert record["p_value"] > FAIL_P  # the rows cannot tell the pitch-plane terms from the model's own
    assert record["alias"]["combination_std"] > 10.0  # ... which they move by tens of std
    assert _mahalanobis(res, truth) > 10 * CHI2_15_999  # the fit's own covariance: silently wrong
    assert _mahalanobis(out, truth) < CHI2_15_999  # with the omitted terms as consider parameters: covered
    assert "strapdown33's 18 terms this model leaves out are in the std" in out.message


def test_terms_the_rows_see_fail_the_result(tmp_path_factory):
    big = {**LIMITED, "sg_y": 3000.0, "sg_z": 3000.0}  # 30 x declared, along the best-determined combination
    _, out, _, _ = _judged(tmp_path_factory, "big", 2, big)
    assert not out.success and out.status == STATUS_MISFIT
    record = out.diagnostics["omitted_terms"]
    assert record["p_value"] < FAIL_P
    first = record["each"][0]  # the combination farthest from 0: sg_y and sg_z, of the same sign
    assert {nm for nm, *_ in first["terms"]} >= {"sg_y", "sg_z"} and first["z"] > 5.0, first
    assert "fit strapdown33" in out.message and "sg_y" in out.message and "ppm" in out.message


@pytest.mark.parametrize("seed", [3, 4])
def test_the_truth_limited_to_the_model_passes(tmp_path_factory, seed):
    res, out, _, truth = _judged(tmp_path_factory, f"limited{seed}", seed, LIMITED)
    assert out.success
    assert out.diagnostics["omitted_terms"]["p_value"] > 1e-3
    assert _mahalanobis(res, truth) < CHI2_15_999


def test_the_wald_chi_square_is_the_extra_sum_of_squares(tmp_path_factory):
    """White noise: the Wald chi-square of the determined combinations equals (RSS of the model - RSS with the
    richer model's columns) / sigma^2 of two numpy least-squares fits."""
    res, out, (flight, problem), _ = _judged(tmp_path_factory, "white", 5, None,
                                             FitSpec.build(noise="white", robust="none"))
    record = out.diagnostics["omitted_terms"]
    S = problem.sv().reshape(-1, len(res.names))
    cols = omitted_terms._extra_columns(res, problem, flight, load_model("strapdown33"))
    assert cols is not None
    y = np.asarray(problem.y).reshape(-1)
    both = np.concatenate([S, cols[0].reshape(S.shape[0], -1)], axis=1)
    rss0 = np.sum((y - S @ np.linalg.lstsq(S, y, rcond=None)[0]) ** 2)
    rss1 = np.sum((y - both @ np.linalg.lstsq(both, y, rcond=1e-10)[0]) ** 2)
    assert record["chi2"] == pytest.approx((rss0 - rss1) / float(res.sigma) ** 2, rel=1e-3)
