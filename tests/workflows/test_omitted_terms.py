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


def _judged(tmp_path_factory, name: str, seed: int, truth: dict | None, spec: FitSpec | None = None,
            model_name: str = MODEL, path=None):
    if path is None:
        path = tmp_path_factory.mktemp("omitted") / f"{name}.csv"
        sim = simulate_flight("strapdown-boost", seed=seed, rate=5.0, truth=truth)
        write_simulation(sim, path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        flight, problem, model = _problem(path, model_name, False)
        res = fit(problem, spec or FitSpec.build())
        out = omitted_terms.judge_omitted(res, flight, problem, model)
    truth = json.loads(path.with_name(f"{path.stem}.truth.json").read_text())["coefficients"]  # natural units
    return res, out, (flight, problem, path), truth


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
    res, out, (flight, problem, _), _ = _judged(tmp_path_factory, "white", 5, None,
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


@pytest.fixture(scope="module")
def rank_deficient(tmp_path_factory, full):
    """strapdown33 on the same flight (its truth strapdown33's): rank 21 of 33, its richer model strapdown42_extended's
    9 further terms (ka2_*, phi0_*, l_*)."""
    return _judged(tmp_path_factory, "full", 1, None, model_name="strapdown33", path=full[2][2])


def test_a_rank_deficient_fit_tests_only_what_the_rows_determine_beside_it(rank_deficient):
    """12 of strapdown33's 33 coefficients are exactly dependent on the boost; of strapdown42_extended's 9 further
    terms the rows determine 7 combinations beside the fit (ka2_y and ka2_z act on a lateral specific force the boost
    does not have: their columns are 1e-9 of the others, left out). The Wald chi-square of those 7 is the extra sum
    of squares of the whitened rows (numpy least squares with and without the 7 columns, rank 21 and 28); the terms
    are carried in the std of the 21 coefficients the fit states, the others keep no std; the message says so.
    Before: no consider parameter at all (the fit's covariance is not finite), and nothing said."""
    from casep.noise.model import NoiseModel, whiten

    res, out, (flight, problem, _), _ = rank_deficient
    record = out.diagnostics["omitted_terms"]
    assert record["richer"] == "strapdown42_extended" and len(record["terms"]) == 9 and record["dof"] == 7
    assert not any(nm in ("ka2_y", "ka2_z") for r in record["each"] for nm, *_ in r["terms"])
    assert out.success and record["p_value"] > FAIL_P  # the truth has none of the 9 terms
    stated = np.isfinite(np.asarray(res.std))
    assert stated.sum() == 21 and np.array_equal(np.isfinite(np.asarray(out.std)), stated)
    assert np.all(np.asarray(out.std)[stated] >= np.asarray(res.std)[stated])
    assert "(in the std of the 21 of 33 coefficients the fit states)" in out.message
    cols = omitted_terms._extra_columns(res, problem, flight, load_model("strapdown42_extended"))
    assert cols is not None
    keep = [j for j, nm in enumerate(cols[1]) if nm not in ("ka2_y", "ka2_z")]
    S = problem.sv()
    N, _, n = S.shape
    both, yw = whiten(np.concatenate([S, (cols[0] * cols[3])[:, :, keep]], axis=2), np.asarray(problem.y),
                      np.asarray(problem.t), NoiseModel.from_dict(res.diagnostics["noise"]))[:2]
    B, y = both.reshape(3 * N, -1), yw.reshape(-1)
    A = B[:, :n]
    assert np.linalg.matrix_rank(A) == 21 and np.linalg.matrix_rank(B) == 28
    rss0 = np.sum((y - A @ np.linalg.lstsq(A, y, rcond=1e-10)[0]) ** 2)
    rss1 = np.sum((y - B @ np.linalg.lstsq(B, y, rcond=1e-10)[0]) ** 2)
    assert record["chi2"] == pytest.approx((rss0 - rss1) / float(res.sigma) ** 2, rel=1e-6)


def test_columns_in_the_designs_span_leave_nothing_to_test(rank_deficient):
    """Columns that are combinations of the fit's own (here of strapdown33's S_V, rank-deficient) leave only the
    projection's rounding beside it: no combination is determined (before: the share of the largest left, itself
    rounding, kept rounding directions as determined)."""
    res, _, (_, problem, _), _ = rank_deficient
    S = problem.sv()
    inside = np.einsum("ntk,kc->ntc", S, np.random.default_rng(0).normal(size=(S.shape[2], 2)))
    V = omitted_terms._determined(res, problem, inside)
    assert V is not None and V.shape == (2, 0)


@pytest.fixture(scope="module")
def stretched(tmp_path_factory):
    """The strapdown boost (5 Hz, seed 1, every strapdown33 term at the scenario's truth) written as a one-file
    telemetry (``v_tel_*``: the true velocity plus the simulated dv; ``v_trk_*``: the true velocity) whose tracking
    after the 110-115 s gap has 0.5 m/s more white noise (seeded): its stretches' noise differs 7-fold, so the result
    fails and states what the flight determines (:func:`casep.workflows.judging.judge_tracking`). Fitted under
    strapdown12, whose 21 further strapdown33 terms the rows cannot tell from its own (carried as consider
    parameters, :func:`omitted_terms.judge_omitted`). ``(fit, judged, truth in natural units, scales)``."""
    from casep.io.files import write_table
    from casep.workflows.judging import judge_tracking

    sim = simulate_flight("strapdown-boost", seed=1, rate=5.0)
    fl, v = sim.flight, sim.trajectory.velocity
    noise = np.where(fl.t > 115.0, 0.5, 0.0)[:, None] * np.random.default_rng(101).standard_normal(v.shape)
    cols = {"t": fl.t, **{c: fl.signals[c] for c in ("q_w", "q_x", "q_y", "q_z", "fb_x", "fb_y", "fb_z", "w_x",
                                                     "w_y", "w_z")}}
    for i, a in enumerate("xyz"):
        cols[f"v_tel_{a}"] = v[:, i] + np.where(fl.observed, fl.dv[:, i], 0.0)
        cols[f"v_trk_{a}"] = np.where(fl.observed, v[:, i] + noise[:, i], np.nan)  # empty: untracked
    path = tmp_path_factory.mktemp("stretched") / "telemetry.csv"
    write_table(path, cols, nan_as_missing=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        flight, problem, model = _problem(path, "strapdown12", False)
        res = fit(problem, FitSpec.build())
        out = judge_tracking(omitted_terms.judge_omitted(res, flight, problem, model), flight, problem, model.scales)
    truth = dict(zip(sim.model.names, sim.truth))
    return res, out, np.array([truth.get(n, 0.0) for n in res.names]), np.array([model.scales[n] for n in res.names])


def test_the_combinations_stated_for_stretches_of_different_noise_carry_the_omitted_terms(stretched):
    """The combinations a flight whose tracking noise differs between stretches is said to determine carry the terms
    the model leaves out, as its coefficients' std do (``with_consider``). Before, their std left them out: the
    best-determined after the accelerometer's, ``sg_x`` with the gyro terms, was 41-51 of its std off the truth
    (seeds 1-4), the terms strapdown12 lacks in its estimate. With them every stated combination is within 3 std (here
    0.6 at most); the variance each gains is ``w_s^T E w_s``, ``E`` what judge_omitted added to the coefficients'
    covariance (the fitted and the judged covariances' difference)."""
    from casep.estimators.registry import STATUS_TRACKING

    res, out, truth, scale = stretched
    assert out.status == STATUS_TRACKING and out.diagnostics["omitted_terms"]["richer"] == "strapdown33"
    combos = out.diagnostics["determined"]["combinations"]
    assert len(combos) >= 2
    err = np.array([c["estimate"] - np.dot(c["weights"], truth / scale) for c in combos])
    assert np.all(np.abs(err / [c["std"] for c in combos]) < 3.0)
    assert np.max(np.abs(err / [c["std_without_consider"] for c in combos])) > 10.0  # without them: silently wrong
    E = np.asarray(out.covariance) - np.asarray(res.covariance)
    for c in combos:
        ws = np.asarray(c["weights"]) / scale
        assert c["std"] ** 2 - c["std_without_consider"] ** 2 == pytest.approx(ws @ E @ ws, rel=1e-6)


def test_a_combination_the_consider_terms_widen_to_its_declared_magnitude_is_not_stated_as_determined(stretched):
    """Whether a stated combination is determined (std below 1 declared magnitude) is decided on its final std, the
    consider terms in it: 5 combinations of 0.05-0.9 declared magnitudes on the noise reach 1.9-3.8 with strapdown33's
    terms. Before, the decision was made on the noise alone and they were stated as determined; now they are not, the
    message says why (each one's std before and after the widening), and the count stated is of those below 1."""
    _, out, _, _ = stretched
    det = out.diagnostics["determined"]
    left = det["left_out"]
    assert left and all(c["std"] >= 1.0 > c["std_without_consider"] for c in left)
    assert det["combinations"] and all(c["std"] < 1.0 for c in det["combinations"])
    assert f"determines {len(det['combinations'])} of 12 combinations better than" in out.message
    said = out.message.split(f"{len(left)} more combination(s) are not stated as determined: ")[1]
    assert said.startswith("their std reach 1 declared magnitude(s) once widened by") and "the consider terms" in said
    c = min(left, key=lambda c: c["std"])  # its std before the consider terms and after, in the text
    assert f"{c['std_without_consider']:.3g} with the IMU's noise, {c['std']:.3g} with the consider terms" in said
