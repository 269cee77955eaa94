"""The inputs of a campaign: option checks, one's own trajectory instead of the scenario's, truth priors."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from casep._cores import usable_cores
from casep.exceptions import IllConditionedWarning, option_label
from casep.montecarlo.methods import MethodSpec, parse_method
from casep.simulation.scenarios import Scenario

__all__ = ["TRUTH_PRIOR_LIMIT", "check_options", "check_truth_prior", "own_trajectory"]


def check_options(runs: Any, seed: Any, methods: Sequence[str], workers: Any, noise: str, tau: Any,
                  robust: str | None) -> tuple[int, int, list[MethodSpec], int, Any]:
    """The options of :func:`casep.montecarlo.run_montecarlo` checked before any work: runs, seed,
    the parsed methods, the number of workers (None: the cores this process may use,
    :func:`casep._cores.usable_cores`) and the noise request every method
    assumes (a :class:`~casep.estimators.spec.NoiseSpec`, checked by the fit request's own rules; noise
    "white" without a robust fit asked runs the methods as they are: robust "auto" is then none)."""
    from casep.estimators.spec import NoiseSpec

    ns = NoiseSpec(kind=noise, tau=tau, robust=robust)  # the fit request's rules for the noise kind, tau, robust
    if ns.kind == "white" and ns.robust == "auto":
        ns = NoiseSpec(kind="white", robust=None)
    specs = [parse_method(m) for m in methods]
    if isinstance(runs, bool) or not isinstance(runs, (int, np.integer)) or runs < 1:
        raise ValueError(f"{option_label('runs')} must be an int >= 1, got {runs!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"{option_label('seed')} must be an int >= 0, got {seed!r}")
    if not specs:
        raise ValueError("`methods` is empty")
    if len({s.text for s in specs}) != len(specs):
        raise ValueError(f"`methods` names a method twice: {', '.join(methods)}")
    n_workers = usable_cores() if workers is None else int(workers)
    if n_workers < 1:
        raise ValueError(f"{option_label('workers')} must be >= 1, got {workers!r}")
    return int(runs), int(seed), specs, n_workers, ns

#: A truth prior may reach this many declared magnitudes (mean + 6 std): wide priors of poorly known
#: second-order terms (the demo's: 1e4 x) pass, 1e308 does not.
TRUTH_PRIOR_LIMIT = 1e6


def check_truth_prior(tp: tuple[np.ndarray, np.ndarray], model: Any, source: str) -> None:
    """Refuse a truth prior whose draws (mean +- 6 std) reach beyond :data:`TRUTH_PRIOR_LIMIT` times a
    coefficient's declared magnitude (no instrument is that far off its spec sheet), or overflow (std 1e308)."""
    mu, sd = tp
    scales = model.scales
    for j, name in enumerate(model.names):
        if not np.isfinite(sd[j]):
            continue  # not drawn
        reach = abs(float(mu[j])) + 6.0 * float(sd[j])
        limit = TRUTH_PRIOR_LIMIT * scales[name] if name in scales else np.finfo(float).max / 1e10
        if not reach <= limit:
            raise ValueError(f"{source}: `{name}`: draws reach |mean| + 6 std = {reach:.4g} {model.units[j]}, beyond "
                             + (f"{TRUTH_PRIOR_LIMIT:g} x its declared magnitude {scales[name]:g} (no instrument is "
                                "that far off its spec sheet)" if name in scales else "what a flight can hold"))


def own_trajectory(scenario: str | Scenario, flight: Any, truth: Mapping) -> dict[str, Any]:
    """The scenario of a Monte Carlo on one's own flight: its times, specific force, signal columns (a strapdown
    flight's ``q_*``, ``fb_*``, ``w_*``: every extra column of the flight, as ``casep separate`` reads them), model,
    truth and noise."""
    import dataclasses

    from casep.checks.flight import flight_problem
    from casep.io.files import read_flight
    from casep.io.flight import FlightData
    from casep.io.provenance import file_record
    from casep.model import ErrorModel
    from casep.model.loader import load_model, load_recorded_model
    from casep.simulation.noise import NoiseModel
    from casep.simulation.scenarios import get_scenario
    from casep.simulation.simulate import truth_vector

    sc = get_scenario(scenario)
    fl = flight if isinstance(flight, FlightData) else read_flight(flight)
    if not isinstance(truth, Mapping):
        raise ValueError(f"`truth` must be a mapping {{name: value}} or a truth file's dict, got "
                         f"{type(truth).__name__}")
    coefs = truth["coefficients"] if isinstance(truth.get("coefficients"), Mapping) else truth
    named = truth.get("model", sc.model)  # a model the caller loaded, or one shipped with casep by its name
    model = load_model(named) if isinstance(named, ErrorModel) else load_recorded_model(
        str(named), where="`truth`", option="truth['model'] = casep.load_model('FILE.py')")
    vec = truth_vector(model, {k: v for k, v in coefs.items() if k not in ("model", "noise")}, "`truth`")
    if isinstance(truth.get("noise"), Mapping):
        try:
            noise = NoiseModel(**truth["noise"])
        except (TypeError, ValueError) as exc:
            raise ValueError(f"`truth`: `noise` must be a noise model of casep simulate ({exc})") from None
        how = "the truth file's"
    else:  # the flight's own least-squares residual std: its tracking noise
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IllConditionedWarning)
            pb = flight_problem(fl, model)
        noise = NoiseModel("white", float(np.sqrt(pb.ls_rss() / max(pb.m - pb.rank().rank, 1))))
        how = "the flight's least-squares residual std"
    rate = float(1.0 / np.median(np.diff(fl.t)))
    name = f"flight {Path(fl.source).name}"
    sc = dataclasses.replace(sc, name=name, description=f"own trajectory {fl.source}; noise: {how}", rate=rate,
                             model=model.name, truth=dict(zip(model.names, vec.tolist())), noise=noise)
    record = file_record(fl.source, "flight") if Path(fl.source).is_file() else {"file": fl.source}
    return {"scenario": sc, "model": model, "truth": vec, "t": np.asarray(fl.t), "f": np.asarray(fl.f),
            "signals": dict(fl.signals),
            "record": {**record, "noise": noise.to_dict(), "noise_from": how}}
