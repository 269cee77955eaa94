"""Several flights in one estimate.

Each flight becomes its own :class:`~casep.regression.problem.Problem` (its checks, its S_V, its QR);
its noise sigma is estimated from its own least-squares residuals (or given); the flights are
combined into one :class:`~casep.regression.joint.JointProblem`, a whitened reduced system over
``theta = [shared, per-flight(1), ..., per-flight(K)]`` (per-flight: the model's
``declare(..., per_flight=True)`` coefficients), which the reduction-based methods solve (OLS,
ridge, bounded, PCR, MAP). The same whitened problem also gives its rows flight after flight
(:meth:`~casep.regression.joint.JointProblem.blocks`, one segment per flight), so the recursive methods
(RLS, RELS) run the flights in sequence (the RELS noise memory restarts at each flight). What else a
method does with several flights is its own declaration
(:class:`~casep.estimators._options.SeveralFlights`): Huber estimates the scale of the stacked whitened
rows (about 1) and names each outlier's flight; GLS whitens each flight with its own Gauss-Markov
correlation time (REML per flight, or given) and solves the combined rows as least squares.
Residuals are each flight's own, divided by its sigma (the whitened system the joint fit minimises).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from casep.checks.flight import flight_problem
from casep.estimators.registry import METHODS, STATUS_DISAGREE
from casep.estimators.result import EstimateResult
from casep.estimators.solve import JointRows, fit, flight_sigmas, joint_rows
from casep.estimators.spec import FitSpec
from casep.regression.joint import Flights, JointLayout, JointProblem
from casep.regression.problem import Problem

# and JOINT_METHODS (module __getattr__: the registry's as it is now)
__all__ = ["separate_flights", "flights_summary", "flights_consistency", "judge_consistency", "diagnose_flights",
           "STATUS_DISAGREE", "JOINT_ROUNDING_MARGIN"]


def __getattr__(name: str) -> Any:
    # JOINT_METHODS: the methods that estimate several flights jointly (the registry's with hooks for it), as now
    if name == "JOINT_METHODS":
        return tuple(k for k, m in METHODS.items() if m.flights is not None)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _labels(problems: Sequence[Problem], given: Sequence[str | None] | None = None) -> tuple[str, ...]:
    """Each flight's name in per-flight coefficient names (``dt_trk[name]``): its label when `given` holds one
    (a manifest's ``label``), else its file names (a telemetry + tracking pair: both); file names that repeat
    gain ``#k``. Given labels that repeat are an error (:class:`~casep.regression.joint.JointLayout`)."""
    if given is not None and len(given) != len(problems):
        raise ValueError(f"`labels`: {len(given)} labels for {len(problems)} flights")
    names = [" + ".join(Path(part).name for part in p.source.split(" + ")) or f"flight{k + 1}"
             for k, p in enumerate(problems)]
    if len(set(names)) < len(names):
        names = [f"{n}#{k + 1}" for k, n in enumerate(names)]
    return tuple(lab if lab else n for lab, n in zip(given or [None] * len(names), names))


def separate_flights(flights: Sequence, model, method: str = "ols", *, sigma: float | Sequence[float] | None = None,
                     options: Mapping[str, Any] | None = None, noise: str = "auto", tau=None,
                     robust: str | None = "auto", std: str = "model",
                     exclude_outliers: float | None = None, fit_time_offset: bool | None = None,
                     spec: FitSpec | None = None,
                     labels: Sequence[str | None] | None = None) -> tuple[EstimateResult, JointProblem]:
    """One estimate of the shared coefficients from several flights; per-flight ones per flight.

    The flights become one :class:`~casep.regression.joint.Flights` fitted through the one entry point
    :func:`casep.estimators.solve.fit`, so every rule of the request (noise model per flight and axis, tau,
    robust fit, std kind, outlier exclusion and flags, de-noising) applies to each flight as to one alone. The
    time-offset rules of one flight too: with ``dt_trk`` (one per flight), each one-file flight's samples whose
    tracking straddles a step of the acceleration are left out (:func:`casep.workflows.separate.free_step_samples`,
    ``settings["step_samples_left_out"]``); pairs of files get ``dt_trk`` when their residuals show an offset
    and are re-paired at it (:func:`casep.workflows.separate.refit_on_offset`).

    Parameters
    ----------
    flights : sequence of FlightData, Problem or path
        Two or more flights of the same model.
    model : str, path or ErrorModel
    method : str
        A registered method with hooks for several flights (:data:`JOINT_METHODS`: every built-in one).
    sigma : float or sequence of float, optional
        Noise std per flight (one value for all), m/s; default: each flight's own least-squares
        residual std ``sqrt(RSS_k / (m_k - rank_k))``.
    options : mapping, optional
        The method's options (registry names).
    noise, tau, robust, std, exclude_outliers : optional
        As :func:`casep.separate`, each flight's own (its noise model fitted on the flight alone, its
        glitches removed and its rows weighted by a robust fit of the flight alone; HAC std with lags
        within each flight); the joint solve is then on every flight's whitened rows.
    fit_time_offset : bool, optional
        Add the tracking time offset ``dt_trk`` (per flight) to the model; default: when any flight read
        here asks for it by the one rule :func:`casep.io.pair.fits_time_offset` (tracking aligned
        automatically, Earth-fixed tracking), each flight then has its own offset.
    spec : FitSpec, optional
        The fit request as one value (:class:`casep.FitSpec`) instead of `method`, `options` and the
        noise keywords (its sigma, when set, is every flight's). Either way the request is checked once,
        by the FitSpec.
    labels : sequence of str or None, optional
        One per flight (a manifest's ``label``): the flight's name in per-flight coefficient names and in the
        result; None (or an entry None): its file names.

    Returns
    -------
    (EstimateResult, JointProblem)
        The result over the joint parameters (names ``name`` for shared, ``name[label]`` per flight;
        std from the whitened system, so ``sigma`` is 1 and ``sigma_source`` "whitened"); the problem
        (its ``sigmas``, ``layout`` and ``flight_estimates``). The flights' consistency
        (:func:`flights_consistency`) is in ``diagnostics["consistency"]`` and judges the result
        (:func:`judge_consistency`): flights that disagree fail it (status :data:`STATUS_DISAGREE`), the
        estimates kept for inspection.
    """
    if spec is None:
        spec = FitSpec.build(method, options=options, noise=noise, tau=tau, robust=robust, std=std,
                             exclude_outliers=exclude_outliers)  # the one check
    if METHODS[spec.method].flights is None:
        joint = [k for k, m in METHODS.items() if m.flights is not None]
        raise ValueError(f"method `{spec.method}` cannot be estimated jointly; use one of {', '.join(joint)}")
    if len(flights) < 2:
        raise ValueError(f"`flights` must hold two or more flights, got {len(flights)}")
    from casep.io.files import read_flight
    from casep.io.flight import FlightData
    from casep.model.loader import TIME_OFFSET
    from casep.workflows.separate import LOCATING_FIT, free_step_samples, refit_on_offset, repair_on_offset

    flights = [fl if isinstance(fl, (FlightData, Problem)) else read_flight(fl) for fl in flights]  # read once
    box: dict[str, Any] = {}

    def fit_freeing(fls: Sequence, fit_time_offset: bool | None) -> EstimateResult:
        # the rule of one flight: with dt_trk, each one-file flight's samples at a step of the acceleration left out
        def fit_at(f: Sequence) -> tuple[EstimateResult, JointRows]:
            return _joint_fit(f, model, fit_time_offset, spec, sigma, box, labels)(), box["rows"]

        res, box["rows"], _ = free_step_samples(fls, fit_at)
        return res

    def fit_at(fls: Sequence, quick: bool = False) -> EstimateResult:  # the fit with dt_trk of the flights given
        if quick:
            return _joint_fit(fls, model, True, LOCATING_FIT, sigma, {}, labels, checks=False)()
        return fit_freeing(fls, True)

    if fit_time_offset is not None and not fit_time_offset:  # the caller decided
        return fit_freeing(flights, False), box["rows"].joint
    if fit_time_offset:
        return repair_on_offset(flights, fit_at), box["rows"].joint
    # the rule of one flight (refit_on_offset): pairs of files whose residuals show an offset get dt_trk, re-paired
    # at the offset found when the linearised dt_trk does not hold it (repair_on_offset)
    res = refit_on_offset(lambda: fit_freeing(flights, None), lambda: fit_freeing(flights, True),
                          wanted=lambda: TIME_OFFSET not in box["model"].names and any(box["paired_files"]),
                          flights=lambda: flights, fit_at=fit_at)
    return res, box["rows"].joint


def _joint_fit(flights: Sequence, model: Any, fit_time_offset: bool | None, spec: FitSpec, sigma: Any,
               box: dict[str, Any], labels: Sequence[str | None] | None = None,
               checks: bool = True) -> Callable[[], EstimateResult]:
    """The joint fit of :func:`separate_flights` with `fit_time_offset`, as a call (what it read and its rows go
    into `box`: ``model``, ``rows``, ``paired_files``); `checks` as :func:`casep.estimators.solve.fit`'s."""
    def run() -> EstimateResult:
        m, problems, paired, read = _read(flights, model, fit_time_offset)
        box["model"], box["paired_files"] = m, [_is_pair(fl) for fl in read]
        _refuse_repeats(problems)
        for key in ("prior", "bounds"):  # on shared coefficients only (a per-flight one is refused, not dropped)
            per = [k for k in (spec.options.get(key) or {}) if k in m.names and m.per_flight[m.names.index(k)]]
            if per:
                raise ValueError(f"`{key}` names per-flight coefficient(s) {', '.join(per)}: not supported with "
                                 "several flights yet; give it for the shared coefficients only")
        layout = JointLayout(m.names, m.per_flight, _labels(problems, labels))
        several = Flights(tuple(problems), layout, tuple(paired))
        rows = joint_rows(several, spec, sigma)  # a sigma per flight, or the request's
        box["rows"] = rows
        res = fit(several, spec, rows=rows, checks=checks)  # the one entry point, as for one flight
        if checks:  # the flights' agreement first: flights that disagree explain any judgement after it
            cons = flights_consistency(rows.joint, res.method, denoised=bool(res.denoise))
            res = judge_consistency(dataclasses.replace(res, diagnostics={**res.diagnostics, "consistency": cons}),
                                    cons)
        from casep.model.loader import model_record
        from casep.workflows.separate import judge_setup

        res = dataclasses.replace(res, **model_record(m))
        for fl in read:  # a flight that failed a set-up check fails the joint result
            res = judge_setup(res, fl, None)
        return judge_setup(res, None, m, noise_free=all(p.is_noise_free() for p in problems))  # declared magnitudes

    return run


def _is_pair(flight: Any) -> bool:
    meta = getattr(flight, "meta", None)
    return isinstance(meta, dict) and meta.get("format") == "pair"


def _read(flights: Sequence, model: Any, fit_time_offset: bool | None) -> tuple[Any, list[Problem], list[bool], list]:
    """The model (with ``dt_trk`` when the time-offset rule asks for it), each flight's Problem (after the checks
    before estimation), whether its tracking was interpolated onto telemetry times, and the flights read."""
    from casep.io.files import read_flight
    from casep.io.flight import FlightData
    from casep.io.pair import fits_time_offset
    from casep.model.loader import load_model, with_time_offset

    read = [fl if isinstance(fl, (FlightData, Problem)) else read_flight(fl) for fl in flights]
    data = [fl for fl in read if isinstance(fl, FlightData)]
    if fit_time_offset is None:
        fit_time_offset = any(fits_time_offset(fl.meta) for fl in data)  # the one rule, as for one flight
    model = load_model(with_time_offset(model) if fit_time_offset else model)
    problems = [fl if isinstance(fl, Problem) else flight_problem(fl, model) for fl in read]
    paired = [isinstance(fl, FlightData) and fl.meta.get("format") == "pair" and fl.meta.get("grid") == "telemetry"
              for fl in read]  # interpolated tracking
    return model, problems, paired, data


def _refuse_repeats(problems: Sequence[Problem]) -> None:
    """The same flight twice would count its information twice (std too small by sqrt 2)."""
    seen: dict[str, int] = {}
    for k, p in enumerate(problems):
        key = " + ".join(os.path.realpath(part) if os.path.exists(part) else part for part in p.source.split(" + "))
        if key in seen and key != "<memory>":
            raise ValueError(f"flight {k + 1} ({p.source}) is flight {seen[key] + 1} again: its information would "
                             "count twice; give each flight once")
        seen[key] = k
        for j, q in enumerate(problems[:k]):
            if q.y is not None and p.y is not None and q.y.shape == p.y.shape and np.array_equal(q.y, p.y):
                raise ValueError(f"flights {j + 1} ({q.source}) and {k + 1} ({p.source}) hold the same data: its "
                                 "information would count twice; give each flight once")


#: Noise-free flights agree when the joint least-squares fit leaves each within this factor of its rounding level
#: (:meth:`Problem.is_noise_free` of the joint residual RMS / this). A pair of files' rounding level is its
#: interpolation floor, an estimate of a systematic error that each flight's own fit partly absorbs and a joint
#: fit cannot: two noise-free pairs of one truth, re-paired at 42 and 100 ms, leave 3.9 x theirs. Pure rounding
#: of one truth stays below 1e-6 x its level; noise-free flights of different instruments left 1.7e4 x and more.
JOINT_ROUNDING_MARGIN = 100.0


def flights_summary(res: EstimateResult, jp: JointProblem) -> dict[str, Any]:
    """The ``flights`` entries of the result JSON (``docs/reference/file-formats.md``, "Several flights") and the
    consistency of the flights on the shared coefficients.

    Per flight: file, samples, sigma, residual RMS per axis under the joint estimate, its per-flight
    coefficients. Consistency: :func:`flights_consistency` (the result's own, ``diagnostics["consistency"]``,
    when :func:`separate_flights` judged it).
    """
    lay = jp.layout
    x = res.fitted_coefficients()
    pf = np.flatnonzero(lay.per_flight)
    flights = []
    for k, (p, s) in enumerate(zip(jp.raw, jp.sigmas)):
        r = p.residuals(x[lay.columns(k)]).reshape(-1, 3)  # dv - S_V D: the flight's own residuals, m/s
        cols = lay.columns(k)[pf]
        flights.append({
            "file": p.source, "n_samples": int(p.n_samples), "sigma": s,
            "residual_rms": {a: float(np.sqrt(np.mean(r[:, i] ** 2))) for i, a in enumerate("xyz")},
            "coefficients": [{"name": lay.names[j], "unit": p.units[j], "estimate": _num(res.estimate[c]),
                              "std": _num(res.std[c]) if res.std is not None else None}
                             for j, c in zip(pf, cols)],
        })
    cons = res.diagnostics.get("consistency") or flights_consistency(jp, res.method, denoised=bool(res.denoise))
    return {"flights": flights, "consistency": cons}


def flights_consistency(jp: JointProblem, method: str = "ols", *, denoised: bool = False) -> dict[str, Any]:
    """Do the flights agree on the shared coefficients? (:mod:`casep.estimators.joint`)

    Noise-free flights (each at its rounding level, :meth:`Problem.is_noise_free`): they agree when the joint
    least-squares fit leaves every flight at its rounding level too (the same rule, on the joint fit's
    residuals, within :data:`JOINT_ROUNDING_MARGIN`); ``noise_free`` holds each flight's joint-fit residual RMS
    and rounding level, m/s. Otherwise:
    per shared coefficient, chi-square of the flights' own OLS estimates about their weighted mean (flights
    where it is estimable alone); overall, the Chow test of the joint least-squares fit against the separate
    fits (F form), with each flight's share of its statistic, ``(RSS_joint,k - RSS_k) / sigma_k^2 / s^2``.
    `denoised` (the flights' rows de-noised before the fit): their residuals understate the noise, so the Chow
    test is optimistic; it is reported with a note and ``judged`` False (:func:`judge_consistency` leaves it), as
    for tracking interpolated onto telemetry times fitted with white noise.
    """
    import warnings

    from casep.estimators.joint import coefficient_consistency, flight_rss, overall_consistency
    from casep.estimators.ols import solve_ols

    lay = jp.layout
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # conditioning: said by the result
        x_ls = solve_ols(jp, sigma=1.0).fitted_coefficients()  # the tests compare least-squares fits
    if all(p.is_noise_free() for p in jp.raw):  # rounding residuals: the joint fit must leave them so
        rms = [float(np.sqrt(np.mean(p.residuals(x_ls[lay.columns(k)]) ** 2))) for k, p in enumerate(jp.raw)]
        return {"overall": None, "per_coefficient": {}, "noise_free": {
            "agree": all(p.is_noise_free(r / JOINT_ROUNDING_MARGIN) for p, r in zip(jp.raw, rms)),
            "residual_rms": dict(zip(lay.labels, rms)), "rounding_level": {
                lab: p.rounding_floor() for lab, p in zip(lay.labels, jp.raw)}}}
    rss_joint, own = [], []
    for k, (w, s) in enumerate(zip(jp.problems, jp.sigmas)):
        rss_joint.append(float(np.sum(w.residuals(x_ls[lay.columns(k)]) ** 2)))  # as weighed (GLS: whitened)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # each flight alone: ill-conditioned, said by the joint result
            own.append(solve_ols(w, sigma=s))
    per = {}
    for j in lay.shared:
        var = np.array([np.nan if o.std is None else o.std[j] ** 2 for o in own])
        test = coefficient_consistency(np.array([o.estimate[j] for o in own]), var)
        if test is not None:
            per[lay.names[j]] = test.to_dict()
    own_rss = [flight_rss(p.red) for p in jp.problems]
    resid_dof = int(sum(p.m - o[1] for p, o in zip(jp.problems, own_rss)))
    overall = overall_consistency(rss_joint, [o[0] for o in own_rss], jp.sigmas, [o[1] for o in own_rss],
                                  jp.rank().rank, resid_dof=resid_dof)  # F form: a common error in the sigmas cancels
    cons: dict[str, Any] = {"overall": overall.to_dict() if overall else None, "per_coefficient": per}
    if overall is not None:
        s2 = sum(o[0] / s**2 for o, s in zip(own_rss, jp.sigmas)) / max(resid_dof, 1)  # the F form's scale
        cons["per_flight"] = {lab: float(max(rj - o[0], 0.0) / s**2 / s2)
                              for lab, rj, o, s in zip(lay.labels, rss_joint, own_rss, jp.sigmas)}
    paired = [lab for lab, pr in zip(lay.labels, jp.interpolated) if pr]
    own_noise = METHODS[method].own_noise_model is not None if method in METHODS else False
    cons["judged"] = not denoised and not (paired and not own_noise)  # an optimistic test does not fail a result
    if denoised:
        cons["note"] = ("de-noised flights: their residuals understate the noise, so this test is optimistic (false "
                        "alarms) and does not judge the result; fit without --denoise to test the flights' agreement")
    elif paired and not own_noise:  # a method with its own Gauss-Markov noise model (gls) models that correlation
        cons["note"] = (f"tracking interpolated onto telemetry times in {', '.join(paired)}: its noise is correlated, "
                        "so white-noise std and these tests are optimistic (false alarms) and do not judge the result; "
                        "use the tracking grid (--grid tracking, the default), or --method gls")
    return cons




def judge_consistency(res: EstimateResult, cons: Mapping[str, Any]) -> EstimateResult:
    """`res` judged by its flights' consistency (:func:`flights_consistency`): failed (:data:`STATUS_DISAGREE`)
    when noise-free flights are not all left at their rounding level by one joint fit, or when the Chow test
    gives p below :data:`casep.estimators.joint.FAIL_P`; a :class:`~casep.exceptions.ConsistencyWarning` below
    :data:`casep.estimators.joint.WARN_P`. The estimates stay, for inspection: no one set of shared coefficients
    describes flights that disagree."""
    import warnings

    from casep.estimators.joint import FAIL_P, WARN_P, largest_disagreements
    from casep.estimators.registry import failed
    from casep.exceptions import ConsistencyWarning

    nf = cons.get("noise_free")
    if nf is not None:
        if nf["agree"]:
            return res
        misfit = ", ".join(f"{lab} {nf['residual_rms'][lab]:.3g} m/s (rounding level {nf['rounding_level'][lab]:.2g})"
                           for lab in nf["residual_rms"])
        return failed(res, STATUS_DISAGREE, "failed: the flights disagree: noise-free flights, but no one set of "
                      f"shared coefficients fits them within {JOINT_ROUNDING_MARGIN:g} x their rounding level; joint "
                      "least-squares residual RMS "
                      f"{misfit}. An unmodelled error, another instrument or another model in one of them?")
    ov = cons.get("overall")
    if not ov or not cons.get("judged", True) or ov["p_value"] >= WARN_P:
        return res
    shares = cons.get("per_flight") or {}
    flights = ", ".join(f"{lab} {v:.4g}" for lab, v in sorted(shares.items(), key=lambda kv: -kv[1]))
    what = (f"the flights disagree: Chow test chi2 {ov['chi2']:.4g} on {ov['dof']} dof, p {ov['p_value']:.3g} (warn "
            f"below {WARN_P:g}, fail below {FAIL_P:g}); share of chi2 per flight: {flights}; largest per coefficient: "
            f"{largest_disagreements(cons['per_coefficient'])}. An unmodelled error in one flight, a unit or set-up "
            "mistake, or a noise model that understates the noise?")
    if ov["p_value"] < FAIL_P:
        return failed(res, STATUS_DISAGREE, "failed: " + what)
    warnings.warn(what, ConsistencyWarning, stacklevel=2)
    return res


def _verdict(diag, name: str, scales: Mapping, with_prior: bool) -> str:
    """The joint verdict. With a prior, diagnose's own yardstick is the prior std (is the data worth
    anything?); here the question is whether the coefficient is known to better than its declared
    magnitude, prior included: posterior std below `scales[name]`."""
    v = diag.identifiability[name]
    if not with_prior or v == "unidentifiable" or name not in scales:
        return v
    std = diag.crlb_std[list(diag.names).index(name)]
    return "identifiable" if std <= scales[name] else "weak"


def _num(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


def diagnose_flights(flights: Sequence, model, *, sigma: float | Sequence[float] | None = None,
                     prior_std: np.ndarray | None = None, scales: Mapping | None = None,
                     prior: Mapping | None = None, labels: Sequence[str | None] | None = None,
                     noise: str = "white") -> dict[str, Any]:
    """What each flight determines alone and what they determine together (flights named by `labels`, as
    :func:`separate_flights`).

    Without `sigma`, each flight's rows are first whitened for the noise model of kind `noise`
    (:func:`casep.regression.rows.prepare_rows`, separate's rule; ``"white"``: none), and its sigma
    is the std of the whitened residuals: the bound under the noise ``casep separate`` fits.

    Per shared coefficient: the CRLB std of each flight alone (its own sigma) and of the flights
    jointly (weighted by 1/sigma_k^2), and the verdicts (identifiable / weak / unidentifiable, as
    :func:`casep.checks.diagnostics.diagnose`, "weak" against the model's declared magnitudes);
    with `prior_std` (model order), the joint bound is Bayesian and its verdict asks whether the
    posterior std is below the declared magnitude. `prior` (the MAP format, correlations allowed,
    e.g. :func:`casep.estimators.map.prior_from_result` of earlier flights) is used instead of
    `prior_std`.

    Returns
    -------
    dict
        ``{"flights": [labels], "sigmas": [...], "coefficients": [{"name", "unit", "crlb_alone": [..],
        "verdict_alone": [..], "crlb_joint", "verdict_joint"}], "identifiable_alone": [counts],
        "identifiable_joint": count}``
    """
    from casep.checks.diagnostics import diagnose
    from casep.io.files import read_flight
    from casep.io.flight import FlightData
    from casep.model.loader import load_model

    model = load_model(model)
    Wp = None
    if prior is not None:
        from casep.estimators.map import prior_information

        if prior_std is not None:
            raise ValueError("give `prior` or `prior_std`, not both")
        Wp, _, _, prior_std = prior_information(prior, model.names)
    problems = [fl if isinstance(fl, Problem) else  # a model that cannot describe a flight refused (bound=True)
                flight_problem(fl if isinstance(fl, FlightData) else read_flight(fl), model, bound=True)
                for fl in flights]
    noise_lines = None
    if sigma is None and noise != "white":
        from casep.regression.rows import prepare_rows

        prepared = [prepare_rows(p, noise, robust=None) for p in problems]
        problems, noise_lines = [r.solved for r in prepared], [r.noise.line() for r in prepared]
    sig = flight_sigmas(problems, sigma)
    scales = dict(model.scales if scales is None else scales)
    alone = [diagnose(p, sigma=s, scales=scales) for p, s in zip(problems, sig)]
    out: dict[str, Any] = {"flights": list(_labels(problems, labels)), "sigmas": sig}
    if noise_lines is not None:
        out["noise"] = noise_lines
    if len(problems) >= 2:
        layout = JointLayout(model.names, model.per_flight, _labels(problems, labels))
        jp = JointProblem(problems, sig, layout)
        jscales = {n: scales[n.split("[")[0]] for n in layout.joint_names if n.split("[")[0] in scales}
        jprior = jrows = None
        if prior_std is not None:
            jprior = np.array(layout.expand(list(np.asarray(prior_std, dtype=float))), dtype=float)
        if Wp is not None:
            if np.any(Wp[:, layout.per_flight]):
                raise ValueError("a prior with correlations on per-flight coefficients is not supported with "
                                 "several flights; give it for the shared coefficients only")
            jrows = np.zeros((Wp.shape[0], layout.n_params))
            jrows[:, layout.columns(0)[layout.shared]] = Wp[:, layout.shared]  # shared columns
        joint = diagnose(jp, sigma=1.0, scales=jscales, prior_std=jprior, prior_information=jrows)  # whitened
    else:
        joint = diagnose(problems[0], sigma=sig[0], scales=scales, prior_information=Wp,
                         prior_std=None if prior_std is None else np.asarray(prior_std, dtype=float))
    rows = []
    for j in np.flatnonzero(~model.per_flight):
        name = model.names[j]
        rows.append({"name": name, "unit": model.units[j],
                     "crlb_alone": [_num(a.crlb_std[j]) for a in alone],
                     "verdict_alone": [a.identifiability[name] for a in alone],
                     "crlb_joint": _num(joint.crlb_std[list(joint.names).index(name)]),
                     "verdict_joint": _verdict(joint, name, scales, prior_std is not None)})
    out["coefficients"] = rows
    out["identifiable_alone"] = [sum(r["verdict_alone"][k] == "identifiable" for r in rows) for k in range(len(alone))]
    out["identifiable_joint"] = sum(r["verdict_joint"] == "identifiable" for r in rows)
    return out
