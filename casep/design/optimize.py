"""``casep design``: the attitude manoeuvre that minimises a Cramer-Rao objective, by IPOPT.

:func:`design` builds the :class:`~casep.design.objective.DesignProblem` of a scenario's nominal
flight, solves it with IPOPT (``casadi.nlpsol``, exact gradient and Hessian by CasADi's AD: the limited-memory
approximation stalls at the bang-bang optima, measured) from
several seeded starts, keeps the best solved one, and checks the design by re-simulating the
designed flight at the scenario's rate (``simulate_boost`` with the offsets): the exact CRLB of
that flight (``crlb_after``), the prediction error of the design model, and the constraints as
flown.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any, Mapping, Sequence

import numpy as np

from casep.design.maneuver import AXES_OF, Maneuver
from casep.design.objective import OBJECTIVES, DesignProblem, fisher_information, objective_value
from casep.design.result import DesignResult
from casep.exceptions import option_label

__all__ = ["design", "DEFAULTS"]

#: Defaults of :func:`design` (and ``casep design``).
DEFAULTS: dict[str, Any] = {"maneuver": "yaw", "objective": "A", "max_angle": 5.0, "max_rate": 2.0, "max_lateral": 1.0,
            "knots": 10, "design_rate": 2.0, "starts": 4, "seed": 0, "max_iter": 150}


#: Keywords of :func:`design` that ``casep design`` has no flag for: named as keywords only.
_API_ONLY = ("design_rate", "max_iter")


def _label(name: str) -> str:
    """The one form of an option's name in a message (:func:`casep.exceptions.option_label`)."""
    return f"`{name}`" if name in _API_ONLY else option_label(name)


def _positive(name: str, v, hi: float = math.inf) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not np.isfinite(v) \
            or not 0 < v <= hi:
        raise ValueError(f"{_label(name)} must be a number > 0" + (f" and <= {hi:g}" if np.isfinite(hi) else "")
                         + f", got {v!r}")
    return float(v)


def _count(name: str, v, lo: int) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
        raise ValueError(f"{_label(name)} must be an int >= {lo}, got {v!r}")
    return int(v)


def _solve(problem: DesignProblem, kind: str, max_angle: float, max_rate: float, max_lateral: float,
           starts: int, seed: int, max_iter: int) -> tuple[np.ndarray, dict]:
    import casadi as ca

    from casep.units import G0

    mv = problem.maneuver
    x = problem.x
    R = mv.rate_matrix()
    g = [ca.mtimes(ca.DM(R), x)]
    lbg, ubg = [-max_rate] * R.shape[0], [max_rate] * R.shape[0]
    gamma = knot_angle_limits(mv, problem.t, np.abs(problem.axial) / G0, max_lateral)  # deg, free knots
    ub = np.minimum(max_angle, gamma)
    ub = np.tile(ub, len(mv.axes))
    if len(mv.axes) == 2:  # sqrt(d_pitch^2 + d_yaw^2) <= gamma at every free knot
        m = mv.n_free
        bind = np.flatnonzero(gamma < math.sqrt(2.0) * max_angle)
        if bind.size:
            g.append(x[bind.tolist()] ** 2 + x[(bind + m).tolist()] ** 2)
            lbg += [0.0] * bind.size
            ubg += (gamma[bind] ** 2).tolist()
    nlp = {"x": x, "f": problem.objective_expr(kind), "g": ca.vertcat(*g)}
    opts = {"print_time": False, "error_on_fail": False,
            "ipopt": {"print_level": 0, "sb": "yes", "hessian_approximation": "exact",
                      "max_iter": max_iter, "tol": 1e-8, "acceptable_tol": 1e-6}}
    solver = ca.nlpsol("casep_design", "ipopt", nlp, opts)  # type: ignore[arg-type]  # CasADi's stubs: SX only
    rng = np.random.default_rng(seed)
    nv = mv.n_variables
    runs = []
    for k in range(starts):
        x0 = np.zeros(nv) if k == 0 else rng.uniform(-max_angle, max_angle, nv)
        t0 = time.perf_counter()
        sol = solver(x0=np.clip(x0, -ub, ub), lbx=-ub, ubx=ub, lbg=lbg, ubg=ubg)
        st = solver.stats()
        xs = np.clip(np.array(sol["x"]).ravel(), -ub, ub)
        runs.append({"start": k, "x0": "zero (nominal)" if k == 0 else f"uniform(+-max_angle), seed {seed}",
                     "return_status": st["return_status"], "success": bool(st["success"]),
                     "iterations": int(st["iter_count"]), "objective": float(sol["f"]),
                     "seconds": time.perf_counter() - t0, "x": xs})
    ok = [r for r in runs if r["success"]] or runs
    best = min(ok, key=lambda r: r["objective"])
    info = {"name": "ipopt (casadi.nlpsol), exact gradient and Hessian (CasADi AD)",
            "starts": [{k: v for k, v in r.items() if k != "x"} for r in runs],
            "best_start": best["start"], "return_status": best["return_status"], "success": best["success"],
            "knot_angle_limit_deg": gamma.tolist(), "rate_constraints": int(R.shape[0])}
    return best["x"], info


def knot_angle_limits(mv: Maneuver, t: np.ndarray, f_g: np.ndarray, max_lateral: float) -> np.ndarray:
    """Largest offset angle (deg) at each free knot that keeps ``|f| sin(angle) <= max_lateral`` everywhere.

    On a segment the offset (pitch, yaw) is a convex combination of its end knots' offsets, so its size
    is at most the larger of theirs; the angle between the designed and the nominal body axis is at most
    ``sqrt(d_pitch^2 + d_yaw^2)`` (the sphere's metric ``cos^2(psi) d theta^2 + d psi^2``). Hence limiting
    each knot's offset size to ``asin(max_lateral / max |f|)`` over the segments next to it (the design grid's
    samples) guarantees the lateral limit at every time (conservative: the limit may be met inside).
    """
    k = np.asarray(mv.knots)
    out = np.full(k.size, 90.0)
    for i in range(1, k.size):
        lo, hi = k[i - 1], k[i + 1] if i + 1 < k.size else k[i]
        sel = (t >= lo) & (t <= hi)
        fmax = float(np.max(f_g[sel], initial=0.0))
        if fmax > max_lateral:
            out[i] = math.degrees(math.asin(max_lateral / fmax))
    return out[1:]


def _burnout_miss_sensitivity(traj, S) -> np.ndarray:
    """``G = -J [S_P; S_V]`` at burnout (m per natural unit), from a trajectory and its full S_V."""
    from casep.impact.ballistic import impact_jacobian

    sp = np.trapezoid(S, traj.t, axis=0)  # S_P(t_b), trapezoid from the first sample (casep.impact)
    J = impact_jacobian(traj.position[-1], traj.velocity[-1])
    return -J @ np.vstack([sp, S[-1]])


def _flown(traj_nom, traj, names) -> dict:
    """The offsets as flown (designed minus nominal attitude) and the lateral acceleration, on the simulated flight."""
    from casep.units import G0

    d = traj.attitude[:, :2] - traj_nom.attitude[:, :2]
    rate = np.gradient(d, traj.t, axis=0)
    th, ps = traj_nom.attitude[:, 0], traj_nom.attitude[:, 1]
    e0 = np.column_stack([np.cos(ps) * np.cos(th), np.cos(ps) * np.sin(th), np.sin(ps)])
    f = traj.specific_force
    lat = np.linalg.norm(np.cross(f, e0), axis=1) / G0  # |f| sin(angle to the nominal body axis)
    return {"max_pitch_offset_deg": float(np.degrees(np.max(np.abs(d[:, 0])))),
            "max_yaw_offset_deg": float(np.degrees(np.max(np.abs(d[:, 1])))),
            "max_pitch_rate_deg_s": float(np.degrees(np.max(np.abs(rate[:, 0])))),
            "max_yaw_rate_deg_s": float(np.degrees(np.max(np.abs(rate[:, 1])))),
            "max_lateral_g": float(np.max(lat))}


def design(scenario="paper", *, maneuver: str = DEFAULTS["maneuver"], objective: str = DEFAULTS["objective"],
           max_angle: float = DEFAULTS["max_angle"], max_rate: float = DEFAULTS["max_rate"],
           max_lateral: float = DEFAULTS["max_lateral"], prior: Mapping | None = None,
           knots: int = DEFAULTS["knots"], start: float | None = None, design_rate: float = DEFAULTS["design_rate"],
           starts: int = DEFAULTS["starts"], seed: int = DEFAULTS["seed"], max_iter: int = DEFAULTS["max_iter"],
           model=None, rate: float | None = None, verify: bool = True,
           coefficients: list[str] | tuple[str, ...] | None = None, flight=None,
           sigma: float | None = None) -> DesignResult:
    """Design the attitude manoeuvre of a scenario's flight that minimises a Cramer-Rao objective.

    Parameters
    ----------
    scenario : str or Scenario
        The nominal flight (vehicle, rate, noise std, model).
    maneuver : {"yaw", "pitch", "both"}
        Attitude axes the manoeuvre moves.
    objective : {"A", "D", "miss"}
        See :mod:`casep.design.objective`.
    max_angle : float
        Largest offset from the nominal attitude, deg.
    max_rate : float
        Largest offset rate, deg/s.
    max_lateral : float
        Largest lateral specific force the offset implies, ``|f| sin(angle)``, g.
    prior : mapping, optional
        ``{name: {"mean", "std"}}`` (MAP format, natural units): the Bayesian covariance.
    knots : int
        Knots of the piecewise-linear offset (the first held at zero).
    start : float, optional
        First knot, s (default: the end of the pitch-over kick); the last is burnout.
    design_rate : float
        Rate of the design grid, Hz (S_V integrated on it; the information counts the samples of the
        flight at the scenario's rate).
    starts, seed, max_iter : int
        IPOPT starts (the first from the nominal flight, the others uniform in the angle box, seeded)
        and iterations per start.
    model : str or ErrorModel, optional
        Default: the scenario's.
    rate : float, optional
        Sample rate of the flight, Hz (default: the scenario's).
    verify : bool
        Re-simulate the designed flight at the flight's rate for the exact CRLB and the constraints
        as flown (default True).
    coefficients : sequence of str, optional
        The coefficients that matter: objective A sums only their scaled variances (default: all).
    flight : FlightData or path, optional
        One's own trajectory instead of the scenario's vehicle: its specific force (every sample, at its
        own rate) is the nominal flight, the body axis taken along it (no angle of attack), and the
        manoeuvre turns it (the design model's approximation). Objectives A and D only (``miss`` needs
        the burnout state of a flown vehicle); there is no vehicle to re-fly, so ``crlb_before`` is the
        flight's exact CRLB and ``crlb_after`` the design model's prediction (no ``verification``).
    sigma : float, optional
        White tracking-noise std, m/s (default: the scenario's; with `flight`, the flight's own
        least-squares residual std).

    Returns
    -------
    DesignResult
    """
    from casep.estimators.map import prior_information as prior_rows
    from casep.model.loader import load_model
    from casep.model.sv import build_sv
    from casep.simulation.scenarios import get_scenario
    from casep.simulation.trajectory import simulate_boost

    t_start = time.perf_counter()
    max_angle, max_rate, max_lateral, design_rate = _checked_limits(objective, maneuver, max_angle, max_rate,
                                                                    max_lateral, design_rate)
    knots, starts, max_iter = _count("knots", knots, 2), _count("starts", starts, 1), _count("max_iter", max_iter, 1)
    seed = _count("seed", seed, 0)
    sc = get_scenario(scenario).with_rate(rate)
    model = load_model(sc.model if model is None else model)
    names = model.names
    own = None
    if flight is not None:
        if objective == "miss":
            raise ValueError("objective `miss` on one's own trajectory is not available (it needs the burnout state "
                             "of a flown vehicle); use A or D")
        own = _flight_nominal(flight, model, design_rate)
        sc = dataclasses.replace(sc, name=f"flight {own['name']}", rate=own["rate"],
                                 description=f"own trajectory {own['source']}")
        verify = False
    sigma = _design_sigma(sigma, own, sc)
    scales = np.array([model.scales.get(nm, 1.0) for nm in names])
    weights = _objective_weights(coefficients, names, objective)
    info_prior = W = None  # the prior's square-root information rows, W^T W its information
    if prior is not None:
        W = prior_rows(prior, names, "--prior")[0]
        info_prior = W.T @ W
    timing = {}
    t0 = time.perf_counter()
    coarse = None if own is not None else simulate_boost(sc.vehicle, design_rate)
    t_grid, att_grid, f_grid, default_start = _nominal_grid(sc, coarse, own)
    t_end = float(t_grid[-1])
    first = default_start if start is None else float(start)
    if not float(t_grid[0]) <= first < t_end:
        raise ValueError(f"`start` must be in [{float(t_grid[0]):g}, {t_end:g}) s (burnout), got {first!r}")
    mv = Maneuver(maneuver, tuple(np.linspace(first, t_end, knots)))
    full = S_nom = G_miss = None
    if own is not None:
        S_nom = build_sv(model, own["t_full"], own["f_full"])  # the flight as flown: its exact CRLB
    elif verify or objective == "miss":
        full = simulate_boost(sc.vehicle, sc.rate)
        S_nom = build_sv(model, full.t, full.specific_force)
        G_miss = _burnout_miss_sensitivity(full, S_nom)
    timing["nominal_trajectory"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    problem = DesignProblem(model, t_grid, att_grid, f_grid, mv, rate=sc.rate, sigma=sigma,
                            scales=scales, prior_information=info_prior, miss_sensitivity=G_miss, weights=weights)
    timing["build"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    x_best, solver = _solve(problem, objective, max_angle, max_rate, max_lateral, starts, seed, max_iter)
    timing["solve"] = time.perf_counter() - t0
    x_nom = np.zeros(mv.n_variables)
    pred_before = np.sqrt(np.diag(problem.covariance(x_nom)))
    pred_after = np.sqrt(np.diag(problem.covariance(x_best)))
    before, after = problem.value(objective, x_nom), problem.value(objective, x_best)
    vehicle = sc.vehicle if own is not None else _designed_vehicle(sc.vehicle, coarse, mv, x_best)
    designed = dataclasses.replace(sc, name=f"{sc.name}-designed", vehicle=vehicle,
                                   description=f"{sc.description}; designed {maneuver} manoeuvre ({objective}-optimal, "
                                               f"max {max_angle:g} deg, {max_rate:g} deg/s, {max_lateral:g} g)")
    constraints = {"max_angle_deg": max_angle, "max_rate_deg_s": max_rate, "max_lateral_g": max_lateral,
                   "design": {"max_offset_deg": float(np.max(np.abs(x_best), initial=0.0)),
                              "max_rate_deg_s": float(np.max(np.abs(mv.rate_matrix() @ x_best), initial=0.0)),
                              "max_lateral_g": float(np.max(problem.lateral_g(x_best)))}}
    crlb_before, crlb_after = pred_before, pred_after
    if own is not None:
        from casep.checks.diagnostics import crlb_covariance

        assert S_nom is not None  # built from the flight above
        crlb_before = np.sqrt(np.diag(crlb_covariance(S_nom, sigma, prior_information=W)))
    verification: dict = {}
    if verify:
        t0 = time.perf_counter()
        assert full is not None and S_nom is not None  # verify: the nominal flight was simulated above
        crlb_before, crlb_after, verification = _verify(model, sc, vehicle, full, S_nom, sigma, W, objective,
                                                        scales, info_prior, G_miss, weights, pred_after, constraints)
        timing["verify"] = time.perf_counter() - t0
    timing["total"] = time.perf_counter() - t_start
    return DesignResult(objective=objective, maneuver=mv, x=x_best, names=names, units=model.units, scales=scales,
                        before=before, after=after, crlb_before=crlb_before, crlb_after=crlb_after,
                        predicted_before=pred_before, predicted_after=pred_after, constraints=constraints,
                        solver=solver, scenario=designed, prior=prior is not None, timing=timing,
                        coefficients=None if coefficients is None else tuple(coefficients),
                        verification=verification, nominal=scenario if isinstance(scenario, str) else None,
                        own_flight=None if flight is None else str(getattr(flight, "source", flight)))


def _checked_limits(objective: str, maneuver: str, max_angle: float, max_rate: float, max_lateral: float,
                    design_rate: float) -> tuple[float, float, float, float]:
    """The objective and manoeuvre names checked, and the limits and design rate as positive floats."""
    if objective not in OBJECTIVES:
        raise ValueError(f"unknown objective `{objective}`: use one of {', '.join(OBJECTIVES)}")
    if maneuver not in AXES_OF:
        raise ValueError(f"unknown maneuver `{maneuver}`: use one of {', '.join(AXES_OF)}")
    return (_positive("max_angle", max_angle, 45.0), _positive("max_rate", max_rate),
            _positive("max_lateral", max_lateral), _positive("design_rate", design_rate))


def _nominal_grid(sc: Any, coarse: Any, own: dict | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Times, attitude and specific force of the nominal flight on the design grid, and the default first knot
    (the end of the pitch-over kick; on one's own flight, after its first tenth)."""
    if own is None:
        p = sc.vehicle.pitch
        return coarse.t, coarse.attitude, coarse.specific_force, p.vertical + p.kick
    t_grid = own["t"]
    return t_grid, own["attitude"], own["force"], float(t_grid[0] + 0.1 * (t_grid[-1] - t_grid[0]))


def _designed_vehicle(vehicle: Any, coarse: Any, mv: Maneuver, x: np.ndarray) -> Any:
    """The vehicle that flies the designed manoeuvre.

    It flies the nominal pitch programme open loop (as a function of time, from the design grid) plus
    the offsets: the attitude is then the one the design assumed, not the gravity-turn law's reaction
    to the manoeuvre. (No vehicle flies one's own trajectory: that is not re-flown.)
    """
    assert coarse.attitude is not None  # a simulated flight has its attitude
    after_first = coarse.t > mv.knots[0] + 1e-9  # the spline starts at the first knot (no kink of the kick)
    base_t = np.concatenate([[mv.knots[0]], coarse.t[after_first]])
    base_theta = np.concatenate([coarse.kinematics(np.array([mv.knots[0]]))["attitude"][:, 0],
                                 coarse.attitude[after_first, 0]])
    return dataclasses.replace(vehicle, attitude=mv.profile(x, base_t, base_theta))


def _design_sigma(sigma: float | None, own: dict | None, sc: Any) -> float:
    """The tracking-noise std of the design, m/s: given (the noise std's one declared rule), else the own
    flight's least-squares residual std, else the scenario's; ValueError when it is not > 0."""
    if sigma is not None:
        from casep.estimators.registry import SIGMA

        sigma = float(SIGMA.check(sigma))
    elif own is not None and own["sigma"] is not None:
        sigma = own["sigma"]  # the flight's own tracking noise
    else:
        sigma = float(sc.noise.sigma)
    if not sigma > 0:
        raise ValueError(f"scenario `{sc.name}` has no tracking noise (sigma {sigma}): the bound is zero")
    return sigma


def _objective_weights(coefficients: Sequence[str] | None, names: Sequence[str], objective: str) -> np.ndarray | None:
    """0/1 weights of the coefficients objective A sums (None: all of them)."""
    if coefficients is None:
        return None
    from casep.model.error_model import unknown_coefficient_message

    chosen = list(coefficients)
    for nm in chosen:
        if nm not in names:
            raise ValueError(unknown_coefficient_message(nm, names, "`coefficients`"))
    if not chosen:
        raise ValueError("`coefficients` is empty: name one or more, or leave it out (all)")
    if objective != "A":
        raise ValueError(f"`coefficients` selects the terms of objective A, not of `{objective}`")
    return np.array([1.0 if nm in chosen else 0.0 for nm in names])


def _verify(model: Any, sc: Any, vehicle: Any, full: Any, S_nom: np.ndarray, sigma: float, W: Any, objective: str,
            scales: np.ndarray, info_prior: Any, G_miss: Any, weights: Any, pred_after: np.ndarray,
            constraints: dict) -> tuple[np.ndarray, np.ndarray, dict]:
    """The designed flight re-simulated at the flight's rate: exact CRLB before and after, the objective as
    flown, the design model's prediction error, the burnout change (``constraints["flown"]`` set here)."""
    from casep.checks.diagnostics import crlb_covariance
    from casep.model.sv import build_sv
    from casep.simulation.trajectory import simulate_boost

    names = model.names
    traj = simulate_boost(vehicle, sc.rate)
    S = build_sv(model, traj.t, traj.specific_force)
    crlb_before = np.sqrt(np.diag(crlb_covariance(S_nom, sigma, prior_information=W)))
    crlb_after = np.sqrt(np.diag(crlb_covariance(S, sigma, prior_information=W)))
    F_after = fisher_information(S, sigma)
    F_before = fisher_information(S_nom, sigma)
    both = np.isfinite(pred_after) & np.isfinite(crlb_after)
    rel = np.abs(pred_after[both] / crlb_after[both] - 1.0)
    constraints["flown"] = _flown(full, traj, names)
    verification = {
        "rate_hz": sc.rate, "samples": int(traj.t.size),
        "before": objective_value(objective, F_before, scales, info_prior, G_miss, weights),
        "after": objective_value(objective, F_after, scales, info_prior, G_miss, weights),
        "crlb_prediction_error_max": float(np.max(rel, initial=0.0)),
        "crlb_prediction_error_median": float(np.median(rel)) if rel.size else None,
        "burnout_change": {"speed_m_s": float(np.linalg.norm(traj.velocity[-1])
                                              - np.linalg.norm(full.velocity[-1])),
                           "altitude_m": float(traj.altitude[-1] - full.altitude[-1]),
                           "crossrange_m": float(traj.position[-1, 2] - full.position[-1, 2])},
        "note": "designed flight re-simulated (simulate_boost with the offsets) and its S_V built at the flight's "
                "rate: crlb_after is exact for it; crlb_prediction_error compares the design model's prediction",
    }
    return crlb_before, crlb_after, verification


def _flight_nominal(flight, model, design_rate: float) -> dict:
    """One's own flight as the design's nominal: the design grid (``design_rate``), the attitude of the
    specific force (body axis along f: pitch ``atan2(f_y, f_x)``, yaw ``asin(f_z / |f|)``), the flight's
    rate, the flight at its own samples and its least-squares residual std (None without dv)."""
    import warnings

    from casep.checks.flight import flight_problem
    from casep.exceptions import IllConditionedWarning
    from casep.io.files import read_flight
    from casep.io.flight import FlightData

    fl = flight if isinstance(flight, FlightData) else read_flight(flight)
    t, f = np.asarray(fl.t), np.asarray(fl.f)
    norm = np.linalg.norm(f, axis=1)
    if np.any(norm <= 0):
        k = int(np.flatnonzero(norm <= 0)[0])
        raise ValueError(f"{fl.source}: row {k + 1}: zero specific force, no body axis to turn (the design needs "
                         "powered flight throughout)")
    grid = np.arange(t[0], t[-1] + 1e-9, 1.0 / design_rate)
    fg = np.column_stack([np.interp(grid, t, f[:, i]) for i in range(3)])
    ng = np.linalg.norm(fg, axis=1)
    attitude = np.column_stack([np.arctan2(fg[:, 1], fg[:, 0]), np.arcsin(np.clip(fg[:, 2] / ng, -1, 1)),
                                np.zeros(grid.size)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IllConditionedWarning)
        pb = flight_problem(fl, model)
    sigma = float(np.sqrt(pb.ls_rss() / max(pb.m - pb.rank().rank, 1)))
    from pathlib import Path

    return {"t": grid, "attitude": attitude, "force": fg, "rate": float(1.0 / np.median(np.diff(t))),
            "t_full": t, "f_full": f, "sigma": sigma if sigma > 0 else None, "source": fl.source,
            "name": Path(fl.source).name}
