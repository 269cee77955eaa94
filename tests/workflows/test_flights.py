"""Several flights in one estimate (casep.workflows.flights): against an independent weighted stack."""

import dataclasses
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

import casep
from casep.simulation.scenarios import get_scenario
from casep.simulation.simulate import simulate_flight
from casep.workflows.flights import separate_flights


def _flight(seed, dt_ms, sigma, pitch=False, rate=10.0):
    sc = get_scenario("paper-pitch" if pitch else "paper")
    sc = dataclasses.replace(sc, noise=dataclasses.replace(sc.noise, sigma=sigma))
    return simulate_flight(sc, seed=seed, rate=rate, model="platform36_timeoffset",
                           truth={**sc.truth, "dt_trk": dt_ms})


@pytest.fixture(scope="module")
def two():
    return _flight(1, 20.0, 0.05), _flight(2, -7.0, 0.2)


def _kept(flight, res, k):
    """Flight `k`'s samples that the joint fit kept: all but those at the burnout's step of the acceleration that
    the fit with dt_trk left out (the rule of one flight, casep.workflows.separate.free_step_samples), which must
    be next to that step (samples 1051-1055 of the paper boost at 10 Hz)."""
    out = np.ones(flight.t.size, dtype=bool)
    left = res.settings["step_samples_left_out"][k]
    assert left and min(left) >= 1049 and max(left) <= 1057, left
    out[left] = False
    return out


def test_joint_ols_equals_weighted_stacked_least_squares(two):
    """Independent construction: both flights' S_V with a dt_trk column each, weighted by 1/sigma_k, without the
    samples at the burnout's step that the joint fit left out (the same rows on both sides)."""
    a, b = two
    model = a.model
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res, jp = separate_flights([a.flight, b.flight], model, "ols")
    j = model.index("dt_trk")
    n = model.n_coefficients
    blocks = []
    for k, sim in enumerate((a, b)):
        keep = _kept(sim.flight, res, k)
        S = casep.build_sv(model, sim.flight.t, sim.flight.f,
                           signals=sim.flight.model_signals(model.signals, model.name))[keep].reshape(-1, n)
        big = np.zeros((S.shape[0], n + 1))
        shared = [c for c in range(n) if c != j]
        big[:, :n - 1] = S[:, shared]
        big[:, n - 1 + k] = S[:, j]
        blocks.append((big / jp.sigmas[k], sim.flight.dv[keep].reshape(-1) / jp.sigmas[k]))
    A = np.vstack([x for x, _ in blocks])
    y = np.concatenate([v for _, v in blocks])
    c = np.linalg.norm(A, axis=0)
    ref = np.linalg.lstsq(A / c, y, rcond=None)[0] / c  # column-scaled: accurate at cond ~1e5
    np.testing.assert_allclose(res.estimate, ref, rtol=1e-8, atol=1e-10 * np.max(np.abs(ref)))
    assert res.names[-2].startswith("dt_trk[") and res.names[-1].startswith("dt_trk[") \
        and res.names[-1] != res.names[-2]
    # each flight's sigma from its own residuals: near the simulated noise
    np.testing.assert_allclose(jp.sigmas, [0.05, 0.2], rtol=0.05)


def test_noise_free_recovery_with_per_flight_offsets():
    # noise-free (1e-9 m/s would already move Ka terms of CRLB ~300 by 3e-4)
    a, b = _flight(1, 20.0, 0.0), _flight(2, -7.0, 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res, jp = separate_flights([a.flight, b.flight], a.model, "ols", sigma=1e-3, labels=["pad A", None])
    # a label given (a manifest's) names the flight; one not given: its file names
    assert res.names[-2] == "dt_trk[pad A]" and res.names[-1].startswith("dt_trk[") and res.names[-1] != res.names[-2]
    assert jp.layout.labels[0] == "pad A"
    est = jp.flight_estimates(res.estimate)
    np.testing.assert_allclose(est[0][-1], 20.0, rtol=1e-6)
    np.testing.assert_allclose(est[1][-1], -7.0, rtol=1e-6)
    np.testing.assert_allclose(est[0][:-1], np.asarray(a.truth)[:-1], rtol=1e-4, atol=1e-6)


def test_bad_input():
    a = _flight(1, 0.0, 0.1)
    with pytest.raises(ValueError, match="two or more"):
        separate_flights([a.flight], a.model)
    with pytest.raises(ValueError, match="option --method"):
        separate_flights([a.flight, a.flight], a.model, "lasso")
    b = _flight(2, 0.0, 0.1)
    with pytest.raises(ValueError, match="labels repeat"):
        separate_flights([a.flight, b.flight], a.model, labels=["A", "A"])
    with pytest.raises(ValueError, match="1 labels for 2 flights"):
        separate_flights([a.flight, b.flight], a.model, labels=["A"])


def test_consistency_flags_a_flight_with_an_unmodelled_error(two):
    """Agreeing flights pass the Chow test; a flight with a bias on a shared coefficient fails it."""
    from casep.workflows.flights import flights_summary

    a, b = two
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res, jp = separate_flights([a.flight, b.flight], a.model, "ols")
        ok = flights_summary(res, jp)
    assert ok["consistency"]["overall"]["p_value"] > 1e-3
    assert [f["coefficients"][0]["name"] for f in ok["flights"]] == ["dt_trk", "dt_trk"]
    assert abs(ok["flights"][0]["coefficients"][0]["estimate"] - 20.0) < 5 * ok["flights"][0]["coefficients"][0]["std"]
    # flight b with Ka0y off by 5 mg (its own std 0.83 mg at 0.2 m/s, 10 Hz): an unmodelled error. The
    # overall test sees it far more strongly (chi2 ~ 1e6): along the bias the flights' estimates are
    # compared with the other coefficients' correlations included, i.e. the conditional std (~4e-3 mg)
    m = a.model
    S = casep.build_sv(m, b.flight.t, b.flight.f, signals=b.flight.model_signals(m.signals, m.name))
    bias = np.zeros(m.n_coefficients)
    bias[m.index("Ka0y")] = 5.0
    bad = casep.FlightData(t=b.flight.t, f=b.flight.f, dv=b.flight.dv + S @ bias, source="biased.csv",
                           signals=b.flight.signals)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res2, jp2 = separate_flights([a.flight, bad], m, "ols")
        out = flights_summary(res2, jp2)
    assert out["consistency"]["overall"]["p_value"] < 1e-6
    per = out["consistency"]["per_coefficient"]
    assert per["Ka0y"]["p_value"] < 1e-6


def test_cli_several_flights_json(two, tmp_path):
    import json

    from casep.cli import main
    from casep.io.files import write_flight

    paths = []
    for k, sim in enumerate(two):
        p = tmp_path / f"f{k}.csv"
        write_flight(sim.flight, p)
        paths.append(str(p))
    out = tmp_path / "joint.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["separate", *paths, "--model", "platform36_timeoffset", "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert len(d["coefficients"]) == 36 and "dt_trk" not in d["names"]  # the shared ones
    assert [f["file"] for f in d["flights"]] == paths
    assert abs(d["flights"][0]["coefficients"][0]["estimate"] - 20.0) < 5 * d["flights"][0]["coefficients"][0]["std"]
    assert len(d["covariance"]) == 36 and d["consistency"]["overall"]["dof"] > 0
    assert main(["separate", *paths, "--model", "platform36_timeoffset", "--denoise", "wavelet", "--json",
                 str(out)]) == 0  # the request's rules apply to each flight (de-noised with its own sigma)
    d = json.loads(out.read_text())
    assert set(d["denoise"]["flights"]) == {Path(p).name for p in paths}


def test_monte_carlo_joint_ols_efficiency_and_coverage(two, rng):
    """Two flights with noise 0.05 and 0.2 m/s (so the 1/sigma^2 weighting matters), sigma estimated per
    flight: RMS error / reported std in [0.9, 1.1] and 95 % coverage in [0.93, 0.97] over the
    coefficients and 200 seeded noise draws (reduced size for CI)."""
    from casep.regression.problem import Problem

    m = two[0].model
    S = [casep.build_sv(m, s.flight.t, s.flight.f, signals=s.flight.model_signals(m.signals, m.name)) for s in two]
    truth = [np.asarray(s.truth) for s in two]
    sig = (0.05, 0.2)
    z, cover = [], []
    for _ in range(200):
        probs = [Problem.from_arrays(S[k], S[k] @ truth[k] + sig[k] * rng.standard_normal((S[k].shape[0], 3)),
                                     names=m.names, units=m.units, si_factors=m.si_factors, model=m.name)
                 for k in range(2)]
        for k, p in enumerate(probs):
            p.source = f"f{k}"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res, jp = separate_flights(probs, m, "ols")
        true = np.concatenate([truth[0][:-1], [truth[0][-1], truth[1][-1]]])
        e = (res.estimate - true) / res.std
        z.append(e)
        cover.append(np.abs(e) < 1.959964)
    z = np.array(z)
    ratio = np.sqrt(np.mean(z**2))
    assert 0.9 <= ratio <= 1.1, ratio
    assert 0.93 <= np.mean(cover) <= 0.97, np.mean(cover)


def test_fusing_two_saved_results_equals_the_joint_estimate(two, tmp_path):
    """Sequential combination: flight A's result, then B's, fused = A and B estimated together."""
    from casep.estimators.result import EstimateResult
    from casep.io.result_files import write_json_atomic
    from casep.workflows.fusion import fuse

    a, b = two
    p36 = casep.load_model("platform36")  # no per-flight coefficient: shared = all
    flights = []
    for sim in (a, b):
        S = casep.build_sv(p36, sim.flight.t, sim.flight.f)
        flights.append(casep.FlightData(t=sim.flight.t, f=sim.flight.f, dv=S @ np.asarray(sim.truth)[:-1]
                                        + 0.1 * np.random.default_rng(len(flights)).standard_normal((S.shape[0], 3)),
                                        source=f"{len(flights)}.csv"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        joint, jp = separate_flights(flights, p36, "ols")
        singles = [casep.solve_ols(casep.Problem.from_flight(f, p36), sigma=s) for f, s in zip(flights, jp.sigmas)]
    saved = []
    for k, r in enumerate(singles):  # through the JSON, as `casep fuse` reads them
        write_json_atomic(r.to_dict(), tmp_path / f"r{k}.json")
        saved.append(EstimateResult.from_json(tmp_path / f"r{k}.json"))
    fused = fuse(saved)
    # Through covariances (condition ~1e10 in natural units, ~cond^2 of the regression): agreement to a
    # small fraction of each std, not to rounding; the joint fit itself works on square-root factors.
    assert np.max(np.abs(fused.estimate - joint.estimate) / joint.std) < 1e-3
    np.testing.assert_allclose(fused.std, joint.std, rtol=1e-4)
    other = dataclasses.replace(saved[1], model="platform39_misalignment")
    with pytest.raises(ValueError, match="platform36.*platform39_misalignment"):
        fuse([saved[0], other])


def test_cli_fuse(tmp_path):
    from casep.cli import main
    from casep.io.files import write_flight

    paths = []
    for k, scen in enumerate(("paper", "paper", "paper-pitch")):
        sim = simulate_flight(scen, seed=k, rate=10.0)
        write_flight(sim.flight, tmp_path / f"f{k}.csv")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert main(["separate", str(tmp_path / f"f{k}.csv"), "--json", str(tmp_path / f"r{k}.json")]) == 0
        paths.append(str(tmp_path / f"r{k}.json"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["fuse", paths[0], paths[1], "--json", str(tmp_path / "fused.json")]) == 0
        # a pitch-plane flight leaves 12 coefficients without an estimate: refused, with the reason
        assert main(["fuse", paths[0], paths[2]]) == 2
    import json

    d = json.loads((tmp_path / "fused.json").read_text())
    assert d["method"] == "fused" and len(d["coefficients"]) == 36 and d["success"]


def test_diagnose_flights_joint_bound_against_summed_information(tmp_path):
    """Joint CRLB = sqrt(diag((sum_k S_k^T S_k / sigma_k^2)^-1)) built directly; never above a flight's own."""
    from casep.cli import main
    from casep.io.files import write_flight
    from casep.workflows.flights import diagnose_flights

    sims = [simulate_flight(s, seed=k, rate=10.0) for k, s in enumerate(("paper", "paper-azimuth"))]
    m = sims[0].model
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = diagnose_flights([s.flight for s in sims], m, sigma=[0.1, 0.3])
    info = sum(casep.build_sv(m, s.flight.t, s.flight.f).reshape(-1, m.n_coefficients).T
               @ casep.build_sv(m, s.flight.t, s.flight.f).reshape(-1, m.n_coefficients) / sg**2
               for s, sg in zip(sims, (0.1, 0.3)))
    c = np.sqrt(np.diag(info))
    ref = np.sqrt(np.diag(np.linalg.inv(info / np.outer(c, c)))) / c  # equilibrated inverse
    got = np.array([r["crlb_joint"] for r in d["coefficients"]])
    np.testing.assert_allclose(got, ref, rtol=1e-6)
    alone = np.array([[np.inf if v is None else v for v in r["crlb_alone"]] for r in d["coefficients"]])
    assert np.all(got <= alone.min(axis=1) * (1 + 1e-9))
    assert d["identifiable_joint"] >= max(d["identifiable_alone"])
    paths = []
    for k, s in enumerate(sims):
        write_flight(s.flight, tmp_path / f"f{k}.csv")
        paths.append(str(tmp_path / f"f{k}.csv"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["diagnose", *paths, "--json", str(tmp_path / "d.json")]) == 0
        assert main(["diagnose", *paths, "--figures", str(tmp_path / "fig")]) == 0
    png = (tmp_path / "fig" / "flights_crlb.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    noise = json.loads((tmp_path / "d.json").read_text())["noise"]  # each flight's, fitted as separate does
    assert len(noise) == 2 and all(n.startswith("noise auto") for n in noise)


def _quiet(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # one boost flight alone is ill-conditioned: said elsewhere
        return fn(*args, **kw)


def test_posterior_of_one_flight_as_prior_of_the_next_gives_the_joint_estimate(two):
    """Sequential fusion: OLS on flight 1, its posterior (shared coefficients, full covariance) as the
    MAP prior of flight 2 = both flights at once, estimates and std (the Gaussian likelihoods multiply;
    flight 1's per-flight dt_trk is marginalised by taking the covariance block)."""
    from casep.estimators.map import prior_from_result, solve_map
    from casep.estimators.ols import solve_ols
    from casep.regression.problem import Problem

    a, b = two
    m = a.model
    pa, pb = Problem.from_flight(a.flight, m), Problem.from_flight(b.flight, m)
    joint, _ = _quiet(separate_flights, [pa, pb], m, "ols", sigma=[0.05, 0.2])
    shared = [n for n in m.names if not m.per_flight[m.names.index(n)]]
    first = _quiet(solve_ols, pa, sigma=0.05)
    prior = prior_from_result(first, names=shared)
    assert set(prior["correlation"]["names"]) == set(shared)
    second = _quiet(solve_map, pb, prior=prior, sigma=0.2)
    idx = [list(joint.names).index(n) for n in shared]
    own = [list(second.names).index(n) for n in shared]
    err = np.abs(second.estimate[own] - joint.estimate[idx]) / joint.std[idx]
    assert np.max(err) < 1e-6, np.max(err)
    np.testing.assert_allclose(second.std[own], joint.std[idx], rtol=1e-6)
    # flight 2's own time offset is the joint one too
    np.testing.assert_allclose(second.estimate[m.index("dt_trk")], joint.estimate[-1], rtol=1e-6)


def test_rls_in_sequence_over_flights_equals_the_joint_bayesian_estimate(two):
    """RLS over flight 1's then flight 2's whitened rows is the exact Bayesian recursion: the MAP of
    the joint whitened problem with prior N(0, p0) on every joint coefficient (per-flight included)."""
    from casep.estimators.map import solve_map

    a, b = two
    p0 = 1e4
    res, jp = _quiet(separate_flights, [a.flight, b.flight], a.model, "rls", options={"p0": p0})
    assert res.method == "rls" and res.history is not None
    prior = {n: {"mean": 0.0, "std": float(np.sqrt(p0))} for n in jp.names}
    ref = _quiet(solve_map, jp, prior=prior, sigma=1.0)
    np.testing.assert_allclose(res.estimate, ref.estimate, rtol=1e-7, atol=1e-9 * np.max(np.abs(ref.estimate)))
    np.testing.assert_allclose(res.std, ref.std, rtol=1e-6)
    # the history runs over both flights, flight 2's rows after flight 1's
    assert jp.segment_starts == (0, int(_kept(a.flight, res, 0).sum()))


def test_gls_jointly_whitens_each_flight_with_its_own_tau(two):
    """Independent construction: each flight's rows AR(1)-whitened with its tau (ar1_whiten from
    diagnostics), divided by its whitened LS residual std, stacked, solved by column-scaled lstsq."""
    from casep.checks.diagnostics import ar1_whiten

    a, b = two
    model = a.model
    taus = [0.5, 2.0]
    res, jp = _quiet(separate_flights, [a.flight, b.flight], model, "gls", options={"tau": 1.0})
    assert res.method == "gls" and list(res.extras.flight_taus.values()) == [1.0, 1.0]
    res, jp = _quiet(separate_flights, [a.flight, b.flight], model, "gls", sigma=[0.05, 0.2], options={"tau": taus[0]})
    n, j = model.n_coefficients, model.index("dt_trk")
    rows = []
    for k, sim in enumerate((a, b)):
        fl, keep = sim.flight, _kept(sim.flight, res, k)  # the samples at the burnout's step left out
        S = casep.build_sv(model, fl.t, fl.f, signals=fl.model_signals(model.signals, model.name))[keep]
        Sw = ar1_whiten(S, fl.t[keep], 1.0, taus[0]).reshape(-1, n)
        yw = ar1_whiten(fl.dv[keep][:, :, None], fl.t[keep], 1.0, taus[0]).reshape(-1)
        big = np.zeros((Sw.shape[0], n + 1))
        shared = [c for c in range(n) if c != j]
        big[:, :n - 1], big[:, n - 1 + k] = Sw[:, shared], Sw[:, j]
        rows.append((big / [0.05, 0.2][k], yw / [0.05, 0.2][k]))
    A = np.vstack([r[0] for r in rows])
    y = np.concatenate([r[1] for r in rows])
    c = np.linalg.norm(A, axis=0)
    ref = np.linalg.lstsq(A / c, y, rcond=None)[0] / c
    np.testing.assert_allclose(res.estimate, ref, rtol=1e-7, atol=1e-9 * np.max(np.abs(ref)))
    # REML per flight: each flight's tau is its own GLS tau on the same rows (those the joint fit kept: the fit
    # itself, not separate, here, on each flight without the samples the joint fit left out at the burnout's step)
    from casep.checks.flight import flight_problem
    from casep.estimators.solve import fit
    from casep.estimators.spec import FitSpec

    auto, _ = _quiet(separate_flights, [a.flight, b.flight], model, "gls")
    kept = [dataclasses.replace(f, observed=f.observed & _kept(f, auto, k)) for k, f in enumerate((a.flight, b.flight))]
    own = [_quiet(fit, flight_problem(f, model), FitSpec.build("gls")).extras.tau for f in kept]
    np.testing.assert_allclose(list(auto.extras.flight_taus.values()), own, rtol=1e-9)


def test_huber_jointly_flags_an_outlier_in_one_flight_and_resists_it(two):
    a, b = two
    dv = b.flight.dv.copy()
    dv[200:220, 1] += 100 * 0.2  # 20 samples 100 sigma off in flight 2
    bad = dataclasses.replace(b.flight, dv=dv)
    # Huber in white noise, against least squares without the robust filter
    ols, _ = _quiet(separate_flights, [a.flight, b.flight], a.model, "ols", noise="white", robust="none")
    hub, _ = _quiet(separate_flights, [a.flight, bad], a.model, "huber", noise="white", robust="none")
    spoilt, _ = _quiet(separate_flights, [a.flight, bad], a.model, "ols", noise="white", robust="none")
    rows = hub.extras.outliers["largest"]
    assert hub.extras.outliers["count"] >= 20
    first = int(_kept(a.flight, hub, 0).sum())  # flight 1's samples kept (those at the burnout's step left out)
    assert {(r["sample"], r["axis"]) for r in rows[:20]} == {(first + i, "y") for i in range(200, 220)}
    label = hub.names[-1].split("[")[1].rstrip("]")  # flight 2's label, as in its dt_trk[...]
    assert {(r["flight"], r["flight_sample"]) for r in rows[:20]} == {(label, i) for i in range(200, 220)}
    assert 5 * np.max(np.abs(hub.estimate - ols.estimate) / ols.std) \
        < np.max(np.abs(spoilt.estimate - ols.estimate) / ols.std)


def test_rels_jointly_restarts_the_noise_memory_at_each_flight(two):
    """RELS over two flights: the MA regressors restart at flight 2's first sample. The same stacked
    whitened rows as one plain problem (memory carried over from flight 1's end) give a different
    answer, so the restart is in effect; on white noise both stay near joint RLS (MA(1) near 0)."""
    from casep.estimators.rls import solve_rls
    from casep.regression.problem import Problem

    a, b = two
    opts = {"noise_order": 1, "p0": 1e4}
    res, jp = _quiet(separate_flights, [a.flight, b.flight], a.model, "rels", options=opts)
    assert res.method == "rels" and abs(res.extras.ma_coefficients[0]) < 0.05
    plain = Problem.from_arrays(jp.sv(), jp.y, names=jp.names, units=jp.units, si_factors=jp.si_factors)
    carried = _quiet(solve_rls, plain, noise_order=1, p0=1e4, sigma=1.0)
    assert not np.array_equal(carried.estimate, res.estimate)
    rls, _ = _quiet(separate_flights, [a.flight, b.flight], a.model, "rls", options={"p0": 1e4})  # same prior
    assert np.max(np.abs(res.estimate - rls.estimate) / rls.std) < 0.1
    assert np.max(np.abs(carried.estimate - res.estimate) / rls.std) < 0.01


def test_cli_telemetry_and_tracking_pairs_per_flight(tmp_path):
    """`--tracking` once per flight: each pair read as in the one-flight case; the joint estimate equals
    separate_flights on the pairs read by read_flight_pair; a count mismatch is exit 2 naming both counts."""
    import json

    from casep.cli import main
    from casep.io.files import read_flight_pair
    from casep.simulation.simulate import simulate_two_rate

    files = []
    for k, sc in enumerate(("paper", "paper-azimuth")):
        d = simulate_two_rate(sc, seed=k + 1, telemetry_rate=20.0, tracking_rate=10.0)
        tel, trk = tmp_path / f"tel{k}.csv", tmp_path / f"trk{k}.csv"
        d.write(tel, trk)
        files.append((str(tel), str(trk)))
    out = tmp_path / "j.json"
    args = ["separate", files[0][0], files[1][0], "--tracking", files[0][1], "--tracking", files[1][1],
            "--json", str(out)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(args) == 0
        res, _ = separate_flights([read_flight_pair(*f) for f in files], "platform36", "ols")
    got = json.loads(out.read_text())
    np.testing.assert_allclose(got["estimates"], res.estimate, rtol=1e-12)
    assert [f["file"] for f in got["flights"]] == [f"{a} + {b}" for a, b in files]
    assert main(["separate", files[0][0], files[1][0], "--tracking", files[0][1]]) == 2
    assert main(["diagnose", files[0][0], files[1][0], "--tracking", files[0][1], "--tracking", files[1][1]]) == 0


def test_cli_prior_from_a_result_json_continues_the_estimate(two, tmp_path):
    """`separate B --method map --prior RESULT_A.json` (the result's estimate and covariance as prior)
    = `separate A B` on the shared coefficients (model without per-flight terms; same sigmas given);
    `diagnose B --prior RESULT_A.json` gives the MAP std as its Bayesian bound; a result of another
    model is refused naming both."""
    import json

    from casep.cli import main
    from casep.io.files import write_flight

    sims = [simulate_flight("paper", seed=5, rate=10.0), simulate_flight("paper-azimuth", seed=6, rate=10.0)]
    paths = []
    for k, s in enumerate(sims):
        write_flight(s.flight, tmp_path / f"f{k}.csv")
        paths.append(str(tmp_path / f"f{k}.csv"))
    r0, r1, rj = (str(tmp_path / n) for n in ("r0.json", "r1.json", "rj.json"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["separate", paths[0], "--sigma", "0.1", "--json", r0]) == 0
        assert main(["separate", paths[1], "--method", "map", "--prior", r0, "--sigma", "0.1", "--json", r1]) == 0
        assert main(["separate", *paths, "--sigma", "0.1", "--json", rj]) == 0
        assert main(["diagnose", paths[1], "--prior", r0, "--sigma", "0.1", "--json", str(tmp_path / "d.json")]) == 0
    seq, joint = (json.loads(Path(p).read_text()) for p in (r1, rj))
    std = np.array(joint["std"])
    assert np.max(np.abs(np.array(seq["estimates"]) - joint["estimates"]) / std) < 1e-6
    np.testing.assert_allclose(seq["std"], std, rtol=1e-6)
    diag = json.loads((tmp_path / "d.json").read_text())["diagnostics"]
    np.testing.assert_allclose([diag["crlb_std"][n] for n in seq["names"]], seq["std"], rtol=1e-6)
    write_flight(two[0].flight, tmp_path / "t.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["separate", str(tmp_path / "t.csv"), "--model", "platform36_timeoffset",
                     "--json", str(tmp_path / "rt.json")]) == 0
    assert main(["separate", paths[1], "--method", "map", "--prior", str(tmp_path / "rt.json")]) == 2


def test_per_flight_coefficients_are_not_fused_or_carried_as_a_prior(two):
    """A single-flight result of platform36_timeoffset holds its own dt_trk: fusing two such results,
    or using one as the prior of the next flight, must leave dt_trk out (each flight has its own),
    and then equals the joint estimate of the shared coefficients."""
    from casep.estimators.map import prior_from_result, solve_map
    from casep.estimators.ols import solve_ols
    from casep.regression.problem import Problem
    from casep.workflows.fusion import fuse

    a, b = two
    m = a.model
    pa, pb = Problem.from_flight(a.flight, m), Problem.from_flight(b.flight, m)
    ra, rb = _quiet(solve_ols, pa, sigma=0.05), _quiet(solve_ols, pb, sigma=0.2)
    joint, _ = _quiet(separate_flights, [pa, pb], m, "ols", sigma=[0.05, 0.2])
    fused = fuse([ra, rb], labels=["A", "B"])
    assert "dt_trk" not in fused.names and [f["file"] for f in fused.settings["fused"]] == ["A", "B"]
    # said, with each flight's own value: not dropped silently
    for r, f in zip((ra, rb), fused.settings["fused"]):
        j = list(r.names).index("dt_trk")
        assert f["left_out"] == {"dt_trk": {"estimate": r.estimate[j], "std": r.std[j], "unit": r.units[j]}}
        assert f"{f['file']}: dt_trk {r.estimate[j]:.4g} +- {r.std[j]:.2g} {r.units[j]}" in fused.message
    assert "per-flight terms left out of the fusion" in fused.message
    idx = [list(joint.names).index(n) for n in fused.names]
    # 1e-4 std: inverting the marginal covariances (correlations up to 1 - 1e-10) costs digits
    assert np.max(np.abs(fused.estimate - joint.estimate[idx]) / joint.std[idx]) < 1e-4
    # what the two do not determine, said as the joint fit says it (the one rule: the model's magnitudes)
    undetermined = {n: r for n, r in fused.reasons.items() if r.startswith("not determined")}
    assert undetermined and undetermined == {n: r for n, r in joint.reasons.items()
                                             if n in fused.names and r.startswith("not determined")}
    prior = prior_from_result(ra)
    assert "dt_trk" not in prior and "dt_trk" not in prior["correlation"]["names"]
    chained = _quiet(solve_map, pb, prior=prior, sigma=0.2)
    own = [list(chained.names).index(n) for n in fused.names]
    assert np.max(np.abs(chained.estimate[own] - joint.estimate[idx]) / joint.std[idx]) < 1e-4
    assert "Gaussian prior on 36 of 37 coefficients" in chained.text()
    with pytest.raises(ValueError, match="count twice"):
        fuse([ra, ra], labels=["A", "A again"])


def test_the_same_flight_twice_is_refused(two, tmp_path):
    from casep.cli import main
    from casep.io.files import write_flight

    a, _ = two
    with pytest.raises(ValueError, match="count twice"):
        separate_flights([a.flight, a.flight], a.model)
    write_flight(a.flight, tmp_path / "a.csv")
    assert main(["separate", str(tmp_path / "a.csv"), str(tmp_path / "a.csv"), "--model", "platform36_timeoffset"]) == 2


def test_chow_test_does_not_depend_on_the_method_or_a_common_sigma_error(two):
    """The overall test compares least-squares fits (not the chosen method's) in its F form, so PCR,
    MAP and OLS report the same statistic, and sigmas given twice too large leave it unchanged."""
    from casep.workflows.flights import flights_summary

    a, b = two
    prior = {"Kg0x": {"mean": 0.0, "std": 1.0}}
    stats = []
    for method, opts, sigma in (("ols", {}, None), ("pcr", {}, None), ("map", {"prior": prior}, None),
                                ("ols", {}, [0.05, 0.2]), ("ols", {}, [0.1, 0.4])):
        res, jp = _quiet(separate_flights, [a.flight, b.flight], a.model, method, sigma=sigma, options=opts)
        stats.append(flights_summary(res, jp)["consistency"]["overall"])
        assert res.sigma_source == "whitened"
    for s in stats[1:3]:
        assert s["chi2"] == pytest.approx(stats[0]["chi2"], rel=1e-9) \
            and s["p_value"] == pytest.approx(stats[0]["p_value"])
    assert stats[4]["chi2"] == pytest.approx(stats[3]["chi2"], rel=1e-9)  # both sigmas x 2: F unchanged


def test_chow_test_size_on_consistent_flights_and_power_against_an_unmodelled_30ms_offset(rng):
    """On consistent flights (paper + paper-azimuth at 5 Hz, sigma 0.1 and 0.3 m/s, each
    estimated from its own residuals) the overall test at 5 % fires about 5 % of the time (100 seeded
    draws through separate_flights + flights_summary: between 1 and 11, binomial 99 % range); a flight
    whose tracking is 30 ms late, estimated with a model without dt_trk, is rejected at 1 %. The draws'
    noise is white, and so is the fit's noise model (noise='white', robust='none': 0.03 s of CPU a draw
    instead of 0.26 s for the automatic choice, whose REML is tested in tests/noise/)."""
    from casep.regression.problem import Problem
    from casep.workflows.flights import flights_summary

    m = casep.load_model("platform36")
    sims = [simulate_flight(s, seed=k, rate=5.0) for k, s in enumerate(("paper", "paper-azimuth"))]
    S = [casep.build_sv(m, s.flight.t, s.flight.f) for s in sims]
    D = np.asarray(sims[0].truth)
    alarms = 0
    for _ in range(100):
        probs = []
        for k, (Sk, s, sg) in enumerate(zip(S, sims, (0.1, 0.3))):
            p = Problem.from_arrays(Sk, Sk @ D + sg * rng.standard_normal((Sk.shape[0], 3)), s.flight.t,
                                    names=m.names, units=m.units, si_factors=m.si_factors, model=m.name)
            p.source = f"flight{k}"
            probs.append(p)
        res, jp = _quiet(separate_flights, probs, m, "ols", noise="white", robust="none")
        alarms += flights_summary(res, jp)["consistency"]["overall"]["p_value"] < 0.05
    assert 1 <= alarms <= 11, alarms
    sc = get_scenario("paper-azimuth")
    late = simulate_flight(sc, seed=7, rate=5.0, model="platform36_timeoffset", truth={**sc.truth, "dt_trk": 30.0})
    res, jp = _quiet(separate_flights, [sims[0].flight, late.flight], m, "ols")
    assert flights_summary(res, jp)["consistency"]["overall"]["p_value"] < 0.01


def test_a_registered_method_works_jointly_through_its_declaration(two):
    """The several-flight path reads only the method's declaration: a method registered at run time (here a
    copy of least squares under another name, default hooks) gives the joint least-squares numbers."""
    from casep.estimators import registry

    a, b = two
    copy = dataclasses.replace(registry.METHODS["ols"], name="ls_copy", summary="least squares, registered")
    registry.register(copy)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res, _ = separate_flights([a.flight, b.flight], a.model, "ls_copy", noise="white", robust="none")
            ref, _ = separate_flights([a.flight, b.flight], a.model, "ols", noise="white", robust="none")
    finally:
        registry.unregister("ls_copy")
    assert res.method == "ls_copy"
    np.testing.assert_allclose(res.estimate, ref.estimate, rtol=1e-12)
    np.testing.assert_allclose(res.std, ref.std, rtol=1e-12)
    assert "ls_copy" not in registry.METHODS


def _stacked(jp, res):
    """Independent whitened rows of the joint fit: each flight's S_V P_k / sigma_k and dv_k / sigma_k (the rows the
    method solved: under white noise the flight's own)."""
    out = []
    for k, (p, s) in enumerate(zip(jp.problems, jp.sigmas)):
        S = np.zeros(p.sv().shape[:2] + (len(res.names),))
        S[..., jp.layout.columns(k)] = p.sv() / s
        out.append((S, p._need_rows().reshape(-1, 3) / s))
    return out


def test_hac_std_of_several_flights_are_newey_west_within_each_flight(two):
    """std='hac' with several flights: the sandwich (A^T A)^-1 Omega (A^T A)^-1 of the stacked whitened rows, Omega
    summed over the flights with lag products inside each flight only (built here with numpy, independently)."""
    from casep.noise.whiteness import default_lags

    a, b = two
    res, jp = _quiet(separate_flights, [a.flight, b.flight], a.model, "ols", noise="white", robust="none", std="hac")
    assert res.settings["std"] == "hac"
    blocks = _stacked(jp, res)
    A = np.concatenate([S.reshape(-1, S.shape[-1]) for S, _ in blocks])
    c = np.linalg.norm(A, axis=0)  # columns scaled: the regression is ill-conditioned (cond ~4e5)
    Rinv = np.linalg.inv(np.linalg.qr(A / c, mode="r"))
    Ainv = Rinv @ Rinv.T  # (Z^T Z)^-1 of the scaled columns Z = A / c
    omega = np.zeros_like(Ainv)
    for S, y in blocks:
        r = y - S @ res.estimate
        L = default_lags(S.shape[0])
        for ax in range(3):
            g = S[:, ax, :] * r[:, ax, None] / c
            omega += g.T @ g
            for lag in range(1, L + 1):
                G = g[lag:].T @ g[:-lag]
                omega += (1 - lag / (L + 1)) * (G + G.T)
    ref = Ainv @ omega @ Ainv / np.outer(c, c)
    np.testing.assert_allclose(res.std, np.sqrt(np.diag(ref)), rtol=1e-6)


def test_exclusion_flags_and_checks_of_one_flight_apply_to_each_flight(two):
    """exclude_outliers removes a gross glitch of flight 2 on its own rows (named there); outliers flags name the
    flight; each flight's residual checks run (a flight with a glitch and no robust fit is warned about by name)."""
    a, b = two
    dv = b.flight.dv.copy()
    dv[300, 2] += 40 * 0.2  # one sample 40 sigma off in flight 2
    bad = dataclasses.replace(b.flight, dv=dv, source="bad.csv")
    spec = casep.FitSpec.build("ols", noise="white", robust="none", exclude_outliers=0.01, outliers=0.01)
    res, jp = _quiet(separate_flights, [a.flight, bad], a.model, spec=spec)
    label = jp.layout.labels[1]
    excluded = res.diagnostics["noise"][label]["excluded"]["samples"]
    assert [r["sample"] for r in excluded] == [300]
    assert res.diagnostics["noise"][jp.layout.labels[0]]["excluded"]["samples"] == []  # flight 1's own rows: none
    assert res.diagnostics["outliers_studentized"]["rows"] == []  # removed before the joint fit: none left
    flag = casep.FitSpec.build("ols", noise="white", robust="none", outliers=0.01)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        flagged, _ = separate_flights([a.flight, bad], a.model, spec=flag)
    assert any(issubclass(w.category, casep.OutlierWarning) and "bad.csv" in str(w.message) for w in caught)
    rows = flagged.diagnostics["outliers_studentized"]["rows"]
    assert (rows[0]["flight"], rows[0]["flight_sample"], rows[0]["axis"]) == (label, 300, "z")


def test_several_pairs_model_a_time_offset_by_the_rule_of_one_flight():
    """A pair of files whose tracking is 40 ms late among several: the residual test that makes one flight's
    fit add dt_trk (refit_on_offset) does the same for several flights, each flight with its own dt_trk; the
    offset recovered within 4 std. Without it the offset is left to the noise model and the std."""
    from scipy.interpolate import CubicSpline

    from casep.io.pair import pair_flight
    from casep.simulation.simulate import simulate_two_rate

    flights = []
    for k, (sc, off) in enumerate((("paper", 0.0), ("paper-azimuth", 0.04))):
        d = simulate_two_rate(sc, seed=k + 1, telemetry_rate=10.0, tracking_rate=5.0, time_offset=off)
        acc = CubicSpline(d.t_tel, d.v_tel, axis=0).derivative()(d.t_tel)  # as read_flight_pair: d v_tel / dt
        flights.append(pair_flight(d.t_tel, d.f, d.v_tel, d.t_trk, d.v_trk, source=f"tel{k} + trk{k}",
                                   signals={f"a_{a}": acc[:, i] for i, a in enumerate("xyz")}))
    res, _ = _quiet(separate_flights, flights, "platform36", "ols", noise="white", robust=None)
    assert "tracking time offset modelled" in res.message
    j = [i for i, n in enumerate(res.names) if n.startswith("dt_trk") and "tel1" in n]
    assert len(j) == 1, res.names
    assert abs(res.estimate[j[0]] - 40.0) < 4.0 * res.std[j[0]], (res.estimate[j[0]], res.std[j[0]])


def test_a_flight_with_its_own_tracking_offset_fuses_with_one_without():
    """`--imu` and Earth-fixed tracking add the flight's own dt_trk (model ``platform36+dt_trk``): its result fuses
    with a ``platform36`` result on the shared coefficients (dt_trk marginalised: its covariance block dropped), as
    the information sum written out here; a result of another instrument model is still refused."""
    from casep.estimators.map import per_flight_names
    from casep.estimators.result import EstimateResult
    from casep.workflows.fusion import fuse

    base = casep.load_model("platform36")
    rng = np.random.default_rng(5)

    def result(model, names, units):
        n = len(names)
        A = rng.normal(size=(n, n))
        C = A @ A.T / n + 0.1 * np.eye(n)
        return EstimateResult(method="ols", names=tuple(names), units=tuple(units), estimate=rng.normal(size=n),
                              std=np.sqrt(np.diag(C)), covariance=C, reasons={}, residuals=np.zeros((0, 3)),
                              sigma=0.1, rank=n, status=1, message="", success=True, si_factors=np.ones(n),
                              model=model)

    a = result("platform36+dt_trk", [*base.names, "dt_trk"], [*base.units, "ms"])
    b = result("platform36", base.names, base.units)
    assert per_flight_names(a) == per_flight_names(a, "platform36") == {"dt_trk"}
    for pair in ((a, b), (b, a)):
        fused = fuse(list(pair), labels=["1", "2"])
        assert fused.names == tuple(base.names) and fused.model == "platform36"
        n = len(base.names)
        Ia, Ib = np.linalg.inv(a.covariance[:n, :n]), np.linalg.inv(b.covariance)
        cov = np.linalg.inv(Ia + Ib)
        np.testing.assert_allclose(fused.covariance, cov, rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose(fused.estimate, cov @ (Ia @ a.estimate[:n] + Ib @ b.estimate), rtol=1e-8,
                                   atol=1e-10)
    other = result("platform36_leverarm", casep.load_model("platform36_leverarm").names,
                   casep.load_model("platform36_leverarm").units)
    with pytest.raises(ValueError, match="results of different models"):
        fuse([a, other])
