"""Collinearity and identifiability diagnostics (casep.checks.diagnostics)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.linalg import toeplitz

import casep
from casep.checks.diagnostics import crlb_covariance, diagnose
from casep.cli import main
from casep.exceptions import IllConditionedWarning


def _as_flight(M: np.ndarray) -> np.ndarray:
    """(3N, n) -> (N, 3, n)."""
    return M.reshape(-1, 3, M.shape[1])


def test_orthogonal_columns(rng):
    Q, _ = np.linalg.qr(rng.standard_normal((300, 5)))
    S = _as_flight(Q * np.array([1.0, 10.0, 0.1, 3.0, 7.0]))
    d = diagnose(S, sigma=1.0)
    assert d.condition_number_equilibrated == pytest.approx(1.0, rel=1e-12)
    np.testing.assert_allclose(d.vif, 1.0, rtol=1e-12)
    P = d.proportions
    # Each dimension carries exactly one coefficient: a permutation matrix.
    np.testing.assert_allclose(np.sort(P, axis=0)[-1], 1.0, atol=1e-10)
    np.testing.assert_allclose(P.sum(axis=0), 1.0, atol=1e-12)
    assert d.groups == [] and d.unidentifiable == []


def test_duplicate_and_zero_columns(rng):
    M = rng.standard_normal((300, 4))
    M[:, 2] = 0.0
    M[:, 3] = -2.0 * M[:, 1]
    d = diagnose(_as_flight(M), sigma=1.0, names=["a", "b", "z", "twin"])
    assert d.identifiability == {"a": "identifiable", "b": "unidentifiable", "z": "unidentifiable",
                                 "twin": "unidentifiable"}
    assert "twin" in d.reasons["b"] and "b" in d.reasons["twin"] and "zero column" in d.reasons["z"]
    assert np.isfinite(d.crlb_std[0]) and np.isnan(d.crlb_std[1:]).all()
    assert np.isinf(d.vif[1]) and np.isinf(d.vif[3]) and np.isnan(d.vif[2])


def test_small_case_against_independent_formulas(rng):
    M = rng.standard_normal((60, 4))
    M[:, 3] = M[:, 0] + 0.05 * M[:, 3]  # a near-dependency
    d = diagnose(_as_flight(M), sigma=0.3)
    Z = M / np.linalg.norm(M, axis=0)
    ZtZi = np.linalg.inv(Z.T @ Z)
    np.testing.assert_allclose(d.vif, np.diag(ZtZi), rtol=1e-9)  # VIF_j = diag((Z^T Z)^-1)_j
    lam, V = np.linalg.eigh(Z.T @ Z)  # eigen-decomposition: s^2 = lambda
    order = np.argsort(-lam)
    lam, V = lam[order], V[:, order]
    phi = V**2 / lam[None, :]  # (j, k)
    np.testing.assert_allclose(d.proportions, (phi / phi.sum(axis=1, keepdims=True)).T, atol=1e-9)
    np.testing.assert_allclose(d.condition_indices, np.sqrt(lam[0] / lam), rtol=1e-9)
    np.testing.assert_allclose(d.crlb_covariance, 0.09 * np.linalg.inv(M.T @ M), rtol=1e-8)
    assert d.groups == [["c0", "c3"]]


@pytest.mark.montecarlo
def test_crlb_equals_monte_carlo_spread_of_ols(platform36, truth36, rng):
    t = np.arange(0.0, 60.0, 0.2)
    S = casep.build_sv(platform36, t, casep.simulation.synthetic.excitation_force(t, duration=60.0))
    crlb = np.sqrt(np.diag(crlb_covariance(S, 0.1)))
    est = np.array([casep.solve_ols(S, S @ truth36 + 0.1 * rng.standard_normal((t.size, 3))).estimate
                    for _ in range(300)])
    ratio = est.std(axis=0) / crlb
    assert 0.9 < np.sqrt(np.mean(ratio**2)) < 1.1  # pooled
    assert np.all((ratio > 0.8) & (ratio < 1.2))  # each: +-20 % (300 runs: 4 sigma)


def test_ar1_bound_equals_gls_covariance(rng):
    N, n, sigma, tau = 80, 3, 0.2, 0.5
    t = np.cumsum(rng.uniform(0.05, 0.15, N))
    S = rng.standard_normal((N, 3, n))
    # Dense GLS: per axis Sigma_ij = sigma^2 exp(-|t_i - t_j| / tau) (stationary Gauss-Markov).
    Sig = sigma**2 * np.exp(-np.abs(t[:, None] - t[None, :]) / tau)
    Si = np.linalg.inv(Sig)
    F = sum(S[:, i, :].T @ Si @ S[:, i, :] for i in range(3))
    np.testing.assert_allclose(crlb_covariance(S, sigma, t=t, tau=tau), np.linalg.inv(F), rtol=1e-8)
    # Uniform grid: Sigma is the Toeplitz AR(1) matrix sigma^2 a^|i-j|.
    tu = np.arange(N) * 0.1
    a = np.exp(-0.1 / tau)
    Fu = sum(S[:, i, :].T @ np.linalg.inv(sigma**2 * toeplitz(a ** np.arange(N))) @ S[:, i, :] for i in range(3))
    np.testing.assert_allclose(crlb_covariance(S, sigma, t=tu, tau=tau), np.linalg.inv(Fu), rtol=1e-8)


def test_bayesian_bound_equals_map_posterior(paper_problem, platform36):
    S, y, truth = paper_problem
    tau = np.where(np.arange(36) % 2 == 0, np.abs(truth) * 3 + 1e-3, np.inf)
    prior = {n: {"mean": 0.0, "std": t} for n, t in zip(platform36.names, tau) if np.isfinite(t)}
    post = casep.solve_map(S, y, prior, sigma=0.1, names=platform36.names)
    bound = crlb_covariance(S, 0.1, prior_std=tau)
    np.testing.assert_allclose(bound, post.covariance, rtol=1e-7, atol=1e-12 * np.nanmax(np.abs(bound)))


def test_pitch_plane_exactly_zero_columns_unidentifiable(platform36):
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper-pitch", seed=0, rate=10.0)
    S = casep.build_sv(platform36, sim.flight.t, sim.flight.f)
    d = diagnose(S, sim.flight.dv, names=platform36.names)
    zero = {platform36.names[j] for j in np.flatnonzero(np.abs(S).sum(axis=(0, 1)) == 0)}
    assert len(zero) == 12 and set(d.unidentifiable) == zero


def test_weak_verdict_uses_scales(paper_problem, platform36):
    S, y, _ = paper_problem
    d = diagnose(S, y, names=platform36.names, scales=platform36.scales)  # declared: Table 1 magnitudes
    assert d.identifiability["Ka0x"] == "identifiable" and d.identifiability["Kg1xy"] == "weak"
    loose = diagnose(S, y, names=platform36.names, scales={n: 1e9 for n in platform36.names})
    assert all(v == "identifiable" for v in loose.identifiability.values())
    c0 = d.combinations[0]
    assert c0["std"] < 1e-2 and max(abs(w) for w in c0["combination"].values()) == 1.0


def test_every_estimator_warns_with_number_and_coefficients(paper_problem, platform36):
    S, y, _ = paper_problem
    calls = [lambda: casep.solve_ols(S, y, names=platform36.names),
             lambda: casep.solve_rls(S, y, names=platform36.names),
             lambda: casep.solve_ridge(S, y, lam=1e-6, names=platform36.names),
             lambda: casep.solve_pcr(S, y, names=platform36.names),
             lambda: casep.solve_map(S, y, {"Kg0x": {"mean": 0, "std": 1}}, names=platform36.names),
             lambda: casep.solve_bounded(S, y, {"Kg0x": [-100, 100]}, names=platform36.names)]
    for call in calls:
        with pytest.warns(IllConditionedWarning, match=r"equilibrated condition number \d\.\d+e\+0[45].*\[Kg"):
            res = call()
        assert "ill-conditioned" in res.diagnostics["warning"] and "warning: ill-conditioned" in res.text()


def test_well_conditioned_problem_does_not_warn(rng):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", IllConditionedWarning)
        res = casep.solve_ols(rng.standard_normal((300, 4)), rng.standard_normal(300))
    assert "warning" not in res.diagnostics and set(res.diagnostics) >= {"crlb_std", "vif", "groups"}


def test_cli_diagnose_json_and_figures(tmp_path, capsys):
    assert main(["simulate", "--scenario", "paper-pitch", "--rate", "10", "-o", str(tmp_path / "f.csv")]) == 0
    out = tmp_path / "d.json"
    figs = tmp_path / "figs"
    figs.mkdir()
    assert main(["diagnose", str(tmp_path / "f.csv"), "--sigma", "0.1", "--json", str(out),
                 "--figures", str(figs)]) == 0
    text = capsys.readouterr().out
    assert "unidentifiable 12 of 36" in text and "near-dependencies" in text
    d = json.loads(out.read_text())["diagnostics"]
    for key in ("condition_number", "condition_number_equilibrated", "sigma", "crlb_std", "vif", "unidentifiable",
                "groups"):
        assert key in d
    assert d["sigma"] == 0.1 and d["crlb_std"]["Kg1xz"] is None and len(d["unidentifiable"]) == 12
    corr = np.array(d["correlation"], dtype=float)
    assert corr.shape == (36, 36) and np.nanmax(np.abs(np.diag(corr) - 1)) < 1e-12
    for name in ("singular_values.png", "variance_decomposition.png"):
        assert (figs / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_diagnose_ar1_and_bad_inputs(tmp_path, capsys):
    assert main(["simulate", "--scenario", "paper-ar1", "--rate", "10", "-o", str(tmp_path / "f.csv")]) == 0
    out = tmp_path / "d.json"
    assert main(["diagnose", str(tmp_path / "f.csv"), "--sigma", "0.1", "--tau", "1", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["diagnostics"]["noise"] == {"model": "ar1", "tau": 1.0}
    (tmp_path / "s.json").write_text('{"Kq": 1}')
    assert main(["diagnose", str(tmp_path / "f.csv"), "--scales", str(tmp_path / "s.json")]) == 2
    assert "unknown coefficient `Kq`" in capsys.readouterr().err
    # --figures creates a missing folder (test_result.py); a file in its place is refused
    assert main(["diagnose", str(tmp_path / "f.csv"), "--figures", str(tmp_path / "s.json")]) == 2
    assert "exists and is not a folder" in capsys.readouterr().err



def test_bound_follows_the_noise_model_separate_fits():
    """Gauss-Markov rows (sigma 0.1 m/s, tau 1 s): diagnose_noise fits the noise model as separate does, and its
    bound is the Gauss-Markov bound of the true noise (crlb_covariance's AR(1) whitening with the true sigma and
    tau) within the fit's error; the white bound of the same rows is several times smaller."""
    from casep.checks.diagnostics import diagnose_noise
    from casep.regression.problem import Problem

    rng = np.random.default_rng(3)
    t = np.arange(0.0, 120.0, 0.1)
    S = np.zeros((t.size, 3, 6))
    for a in range(3):
        S[:, a, a] = t  # a bias on each axis
        S[:, a, 3 + a] = np.cumsum(np.sin(0.1 * t + a)) * 0.1  # a scale factor on a varying force
    a1 = np.exp(-0.1 / 1.0)
    e = np.empty((t.size, 3))
    e[0] = 0.1 * rng.standard_normal(3)
    for k in range(1, t.size):
        e[k] = a1 * e[k - 1] + 0.1 * np.sqrt(1 - a1**2) * rng.standard_normal(3)
    pb = Problem.from_arrays(S, S @ np.ones(6) + e, t)
    fitted = diagnose_noise(pb)
    true = np.sqrt(np.diag(crlb_covariance(S, 0.1, t=t, tau=1.0)))
    ratio = fitted.crlb_std / true
    assert np.all((ratio > 0.8) & (ratio < 1.25)), ratio
    assert np.median(diagnose(pb).crlb_std / true) < 0.5  # white: far too small on these rows
    assert fitted.noise["model"] == "gauss-markov" and 0.6 < fitted.noise["axes"]["x"]["tau_s"] < 1.6
    assert "noise auto" in fitted.text() and diagnose_noise(pb, "white").noise["model"] == "white"


def test_best_determined_combinations_say_their_order_and_units(paper_problem, platform36):
    """The combinations come best first by condition index (their std are in different units, so not in order);
    the text says so, and each line gives its std's unit and its condition index."""
    import re

    S, y, _ = paper_problem
    d = diagnose(S, y, names=platform36.names, units=platform36.units, scales=platform36.scales)
    ci = [c["condition_index"] for c in d.combinations]
    assert len(ci) >= 2 and ci[0] == pytest.approx(1.0, rel=1e-12) and np.all(np.diff(ci) >= 0), ci
    text = d.text()
    assert "best first by condition index" in text
    lines = text.split("best-determined combinations")[1].splitlines()[1:]
    assert len(lines) == len(d.combinations)
    for line, c in zip(lines, d.combinations):
        lead = next(iter(c["combination"]))
        unit = platform36.units[platform36.names.index(lead)]
        m = re.search(r"std (\S+) (\S+)\s+(?:others (\S+) (\S+)\s+)?condition index (\S+)$", line)
        assert m and m.group(2) == unit and float(m.group(5)) == pytest.approx(c["condition_index"], rel=1e-2), line
        assert m.group(3) is not None and m.group(4) == unit, line  # the paper model declares every scale


def test_the_counts_say_unidentifiable_is_per_coefficient_and_combinations_may_be_known():
    """'unidentifiable' is a verdict on each coefficient alone; the text says that the combinations below may be
    known well, and how to read one led by a single coefficient."""
    from casep.checks.diagnostics import diagnose

    rng = np.random.default_rng(0)
    a = rng.standard_normal((20, 3))
    S = np.stack([a, a, rng.standard_normal((20, 3))], axis=2)  # x0 and x1 exactly dependent
    text = diagnose(S, names=["x0", "x1", "x2"], sigma=1.0).text()
    assert "unidentifiable 2 of 3 (each coefficient on its own" in text
    assert "determines that coefficient only to the other terms' size as well" in text


def test_a_combination_says_what_its_other_terms_leave_of_its_leading_coefficient():
    """Columns a and b = 2 a + 1e-4 c (c another signal), magnitudes 1 and 10: the best-determined combination is,
    per unit, ``b + 0.5 a`` (the data see ``a + 2 b`` up to the 1e-4 part), led by b; with a known to its magnitude 1
    it leaves b to ``0.5 * 1`` (closed form), far above the combination's std: the line says both."""
    t = np.linspace(0.0, 1.0, 400)
    a, c = np.sin(3.0 * t), np.cos(7.0 * t)
    S = np.stack([np.column_stack([a, 2.0 * a + 1e-4 * c])] * 3, axis=1)  # (N, 3 axes, 2 coefficients)
    d = diagnose(S, names=["a", "b"], units=["mg", "mg"], sigma=1e-3, scales={"a": 1.0, "b": 10.0})
    best = next(c for c in d.combinations if next(iter(c["combination"])) == "b")
    assert best["combination"]["a"] / best["combination"]["b"] == pytest.approx(0.5, rel=1e-3)  # the SVD's sign
    assert best["others_at_scale"] == pytest.approx(0.5, rel=1e-3)
    assert best["std"] < 1e-2 * best["others_at_scale"]
    line = next(ln for ln in d.text().splitlines() if ln.strip().lstrip("-").startswith("1 b"))
    assert f"others {best['others_at_scale']:.3g} mg" in line, line


def test_exactly_dependent_on_a_barely_excited_partner_has_the_bound_separate_reports(rng):
    """Columns a, b and c = 1e-8 (0.3 a + 0.7 b): with declared magnitudes a and b have a bound, equal to the std
    OLS reports with the same sigma (the solution of least size in declared magnitudes), and say how far c moves
    them; c stays unidentifiable. Without magnitudes all three are unidentifiable."""
    t = np.linspace(0.0, 100.0, 600)
    f = 1.0 + 0.5 * np.sin(0.1 * t)
    S = np.column_stack([t, t * f, 1e-8 * (0.3 * t + 0.7 * t * f)])
    y = S @ np.array([0.8, -0.5, 0.6]) + 0.05 * rng.standard_normal(t.size)
    scales = {"a": 1.0, "b": 2.0, "c": 60.0}
    d = diagnose(_as_flight(S), names=["a", "b", "c"], units=["mg", "ppm", "arcsec"], sigma=0.05, scales=scales)
    pb = casep.Problem.from_arrays(S, y, names=["a", "b", "c"], units=["mg", "ppm", "arcsec"])
    pb.magnitudes = scales
    res = casep.solve_ols(pb, sigma=0.05)
    np.testing.assert_allclose(d.crlb_std[:2], res.std[:2], rtol=1e-8)
    assert d.identifiability["c"] == "unidentifiable" and d.identifiability["a"] != "unidentifiable"
    assert "within their declared magnitudes" in d.reasons["a"]
    plain = diagnose(_as_flight(S), names=["a", "b", "c"], units=["mg", "ppm", "arcsec"], sigma=0.05,
                     scales={"a": 1.0, "b": 2.0})
    assert plain.unidentifiable == ["a", "b", "c"]


def test_cli_diagnose_takes_the_model_separate_takes(tmp_path, capsys):
    """A strapdown flight simulated with strapdown33 is diagnosed with strapdown33 without --model (it was
    platform36, the platform model, on a strapdown file), as separate would fit it."""
    f = str(tmp_path / "sd.csv")
    assert main(["simulate", "--scenario", "strapdown-boost", "--rate", "5", "-o", f]) == 0
    capsys.readouterr()
    assert main(["diagnose", f, "--noise", "white"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("model strapdown33,") and "ba_x" in out and "Kg0x" not in out
