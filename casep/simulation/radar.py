"""Simulated radar tracking of a simulated flight: stations, injected station errors, noise.

The flight is the rotating-Earth boost of a scenario (:func:`casep.simulation.simulate.scenario_setup`,
launch site with t0 = 0 at lift-off). Telemetry is the navigated state with the instrument errors::

    v_tel = v + S_V D,      r_tel = r + S_P D,      S_P = cumulative trapezoid of S_V

(:func:`casep.model.sv.cumulative_sp`, the same S_P the separation uses). Each station measures at
its own rate, on times inside the flight::

    z(t) = h(r(t - tau), v(t - tau)) + T(g) theta + n,    n ~ N(0, sigma_type^2)

(tags whose instant ``t - tau`` falls outside the flight are not written, nor samples whose true
elevation is below the station's elevation mask ``min_elevation_deg``: :attr:`RadarSimulation.masked`
counts them). A measured elevation pushed above 90 deg by its bias and noise near the zenith is
written as the same line of sight seen over the top, ``(azimuth + 180 deg, 180 deg - elevation)``,
as an azimuth-elevation mount reports it (:attr:`RadarSimulation.over_zenith` counts them); the
separation compares such a sample with its prediction across the zenith
(:meth:`casep.radar.regression.RadarRegression.assemble`).

with ``h`` the geometric measurement (:class:`casep.radar.geometry.RadarGeometry`), ``g`` the
geometry it gives, ``T`` the tracking model's Jacobian and ``theta`` the station's true errors.
A tracking-model term named ``time_bias`` (unit ``ms``) is applied exactly as a late time tag
(the true state sampled at ``t - tau``, the trajectory's dense output) instead of through its
first-order ``T`` column; every other term enters through ``T`` (exact for biases and scale
factors). All randomness from ``numpy.random.default_rng(seed)``.
"""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from casep.frames import LaunchSite
from casep.model.error_model import ErrorModel
from casep.model.sv import build_sv, cumulative_sp
from casep.model.tracking import TrackingModel, load_tracking_model
from casep.radar.geometry import RadarGeometry
from casep.radar.regression import Telemetry
from casep.radar.stations import RadarMeasurements, Station, check_station_names
from casep.units import ARCSEC

__all__ = ["RadarSimulation", "simulate_radar", "write_radar_simulation", "DEFAULT_NOISE"]

#: Default noise std per measurement type, natural units: 3 m, 8 arcsec, 8 arcsec, 0.05 m/s.
DEFAULT_NOISE = {"range": 3.0, "azimuth": 8.0, "elevation": 8.0, "range_rate": 0.05}
_SI = {"range": 1.0, "azimuth": ARCSEC, "elevation": ARCSEC, "range_rate": 1.0}


@dataclass(frozen=True)
class RadarSimulation:
    """A simulated flight tracked by radar stations, with its truth."""

    telemetry: Telemetry
    radars: tuple[RadarMeasurements, ...]
    site: LaunchSite
    model: ErrorModel
    tracking: TrackingModel
    truth: np.ndarray  # instrument, natural units
    tracking_truth: dict  # station -> {term: value}, natural units
    noise: dict  # type -> std, natural units: the default for a station whose file gives none
    seed: int
    scenario: str
    station_noise: dict = dataclasses.field(default_factory=dict)  # station -> {type: std} used, natural units
    masked: dict = dataclasses.field(default_factory=dict)  # station -> samples below its elevation mask, dropped
    over_zenith: dict = dataclasses.field(default_factory=dict)  # station -> samples written over the top
    gauss_markov: dict = dataclasses.field(default_factory=dict)  # type -> std of the Gauss-Markov part, natural units
    gm_tau: float | None = None  # its correlation time, s

    def truth_vector(self, launch_time: bool | None = None) -> np.ndarray:
        """Truth in the order of a :class:`~casep.radar.regression.RadarRegression`'s names.

        With `launch_time` (default: as the separation's default, with two stations or more) the
        launch-time correction ``dt_launch`` comes last: 0, the simulated launch time is the site's ``t0``.
        """
        launch_time = len(self.radars) > 1 if launch_time is None else launch_time
        parts = [self.truth] + [np.array([self.tracking_truth[m.station.name].get(n, 0.0)
                                          for n in self.tracking.names]) for m in self.radars]
        return np.concatenate(parts + [np.zeros(1 if launch_time else 0)])

    def truth_dict(self) -> dict:
        return {"model": self.model.name, "coefficients": dict(zip(self.model.names, map(float, self.truth))),
                "units": dict(zip(self.model.names, self.model.units)),
                "tracking_model": self.tracking.name,
                "tracking": {s: {k: float(v) for k, v in d.items()} for s, d in self.tracking_truth.items()},
                "tracking_units": dict(zip(self.tracking.names, self.tracking.units)),
                "radar_noise": dict(self.noise), "radar_noise_gauss_markov": dict(self.gauss_markov),
                "radar_noise_gm_tau_s": self.gm_tau,
                "station_noise": {k: dict(v) for k, v in self.station_noise.items()},
                "seed": self.seed, "scenario": self.scenario,
                "launch_site": self.site.to_dict(),
                "stations": [m.station.to_dict() for m in self.radars]}


def simulate_radar(stations: Sequence[Station], site: LaunchSite, *, scenario="paper", seed: int = 0,
                   telemetry_rate: float = 100.0, radar_rate: float = 20.0, model=None, truth: Mapping | None = None,
                   tracking: "str | TrackingModel" = "radar_biases", tracking_truth: Mapping | None = None,
                   noise: Mapping | None = None, range_rate: bool = False, gauss_markov: Mapping | None = None,
                   gm_tau: float = 1.0) -> RadarSimulation:
    """Simulate telemetry and the measurements of each station.

    Parameters
    ----------
    stations : sequence of Station
    site : LaunchSite
        Launch point and azimuth; ``t0`` must be 0 (lift-off).
    scenario, telemetry_rate, model, truth
        As :func:`casep.simulation.simulate.simulate_flight` (truth: instrument coefficients, natural units).
    radar_rate : float
        Hz; a divisor of `telemetry_rate` puts the radar times on telemetry samples.
    tracking : str or TrackingModel
    tracking_truth : mapping, optional
        ``{station: {term: value}}``, natural units (missing: 0).
    noise : mapping, optional
        Std per type, natural units (:data:`DEFAULT_NOISE`); 0 for noise-free. A station whose
        file gives ``sigma_range`` / ``sigma_angle`` / ``sigma_range_rate`` is simulated with those
        (the station file written declares them, so they must be what the data have).
    range_rate : bool
        Also write range rate.
    gauss_markov : mapping, optional
        Std per type of a first-order Gauss-Markov measurement noise added to the white one, natural
        units (``{"range": 2.0, "azimuth": 6.0, "elevation": 6.0}``): per station and type
        ``g_k = a_k g_(k-1) + sqrt(1 - a_k^2) sigma n_k``, ``a_k = exp(-(t_k - t_(k-1)) / gm_tau)``,
        stationary from the first sample (:func:`casep._kernels.ar1_terms`), drawn from the same `rng`
        after the white noise.
    gm_tau : float
        Its correlation time, s.
    """
    from casep.simulation.scenarios import get_scenario
    from casep.simulation.simulate import check_seed, scenario_setup

    seed = check_seed(seed)
    stations = list(stations)
    check_station_names(stations)
    sc = get_scenario(scenario)
    if model is not None or truth is not None:
        sc = dataclasses.replace(sc, model=sc.model if model is None else os.fspath(model),
                                 truth=sc.truth if truth is None else dict(truth))
    sc, traj, mdl, D = scenario_setup(sc, telemetry_rate, rotating_earth=True, site=site)
    trk = load_tracking_model(tracking)
    noise = _check_stds("noise", {**DEFAULT_NOISE, **dict(noise or {})})
    gm = _check_stds("gauss_markov", dict(gauss_markov or {}))
    if gm and not (np.isfinite(gm_tau) and gm_tau > 0):
        raise ValueError(f"`gm_tau` must be a finite correlation time > 0 s, got {gm_tau!r}")
    tt = {s.name: dict((tracking_truth or {}).get(s.name, {})) for s in stations}
    for s, d in (tracking_truth or {}).items():
        if s not in tt:
            raise ValueError(f"`tracking_truth` names station `{s}`, which is not simulated ({', '.join(tt)})")
        for k in d:
            if k not in trk.names:
                raise ValueError(f"`tracking_truth` of `{s}`: unknown term `{k}`; the model has {', '.join(trk.names)}")
    from casep.simulation.simulate import trajectory_signals

    sig = trajectory_signals(traj)
    SV = build_sv(mdl, traj.t, traj.specific_force, signals=sig)
    SP = cumulative_sp(SV, traj.t)
    v_tel = traj.velocity + SV @ D  # v_tel = v + S_V D
    r_tel = traj.position + SP @ D  # r_tel = r + S_P D
    # a_*: kinematic acceleration; r_*, v_*: the true state (the range's best trajectory; casep impact's burnout)
    keep_sig = {k: v for k, v in sig.items() if k[:2] in ("a_", "r_", "v_")}
    tel = Telemetry(traj.t, traj.specific_force, v_tel, r_tel, "r_tel columns", keep_sig,
                    f"simulated:{sc.name}:seed{seed}")
    rng = np.random.default_rng(seed)
    t_end = traj.t[-1]
    t_r = np.arange(0, int(np.floor(t_end * radar_rate + 1e-9)) + 1) / radar_rate
    types = ("range", "azimuth", "elevation") + (("range_rate",) if range_rate else ())
    idx_time = trk.names.index("time_bias") if "time_bias" in trk.names else None
    radars, used, masked, over_zenith = [], {}, {}, {}
    for st in stations:
        # the station file's noise when given (it is written out, and separate trusts it), else `noise`
        nz = {ty: (st.sigma[ty] / _SI[ty] if ty in st.sigma else noise[ty]) for ty in types}
        used[st.name] = nz
        th = np.array([tt[st.name].get(n, 0.0) for n in trk.names], dtype=float)
        tau = 0.0
        if idx_time is not None:
            tau = th[idx_time] * trk.si_factors[idx_time]  # s
            th[idx_time] = 0.0  # applied exactly below
        inside = (t_r - tau >= traj.t[0]) & (t_r - tau <= t_end)  # tags whose instant t - tau was flown
        t_tag = t_r[inside]
        t_meas = t_tag - tau  # measured at t - tau
        k = traj.kinematics(t_meas)
        geo, _ = RadarGeometry(site, st).evaluate(t_meas, k["position"], k["velocity"], k["acceleration"])
        seen = geo[:, 2] >= np.radians(st.min_elevation_deg)  # the station's elevation mask
        masked[st.name] = int((~seen).sum())
        if not seen.any():
            raise ValueError(f"station `{st.name}`: the flight never rises above its elevation mask "
                             f"{st.min_elevation_deg:g} deg (highest {np.degrees(geo[:, 2].max()):.3g} deg)")
        t_tag, geo = t_tag[seen], geo[seen]
        T = trk.jacobian(np.column_stack([geo, t_tag - t_tag[0]]))
        z = geo[:, :4] + T @ th  # h + T theta
        for j, ty in enumerate(types):
            if nz[ty] > 0:
                z[:, j] += rng.normal(0.0, nz[ty] * _SI[ty], t_tag.size)
        for j, ty in enumerate(types):
            if gm.get(ty, 0.0) > 0:
                z[:, j] += _gauss_markov(t_tag, gm[ty] * _SI[ty], gm_tau, rng)
        over = z[:, 2] > np.pi / 2  # the same line of sight over the top: (az + pi, pi - el)
        z[over, 1] += np.pi
        z[over, 2] = np.pi - z[over, 2]
        over_zenith[st.name] = int(over.sum())
        radars.append(RadarMeasurements(st, t_tag, z[:, 0], z[:, 1] % (2 * np.pi), z[:, 2],
                                        z[:, 3] if range_rate else None, f"simulated:{st.name}"))
    return RadarSimulation(tel, tuple(radars), site, mdl, trk, D, tt, {k: noise[k] for k in types}, seed, sc.name,
                          used, masked, over_zenith, gm, gm_tau if gm else None)


def _check_stds(what: str, stds: dict) -> dict:
    """`stds` (type -> std, natural units), each type known and each std finite and >= 0, else an error naming it."""
    for k, v in stds.items():
        if k not in DEFAULT_NOISE or not np.isfinite(v) or v < 0:
            raise ValueError(f"`{what}`: `{k}` must be one of {', '.join(DEFAULT_NOISE)} with a finite std >= 0, "
                             f"got {v!r}")
    return stds


def _gauss_markov(t: np.ndarray, sigma: float, tau: float, rng: np.random.Generator) -> np.ndarray:
    """A stationary first-order Gauss-Markov sequence of std `sigma` and correlation time `tau` on the times `t`."""
    from casep._kernels import ar1_terms

    a, b = ar1_terms(np.diff(t), tau)  # a_k, 1 - a_k^2
    n = rng.normal(0.0, sigma, t.size)
    g = np.empty(t.size)
    g[0] = n[0]
    for k in range(1, t.size):
        g[k] = a[k - 1] * g[k - 1] + np.sqrt(b[k - 1]) * n[k]  # g_k = a g_(k-1) + sqrt(1 - a^2) sigma n_k
    return g


def write_radar_simulation(sim: RadarSimulation, telemetry: str | os.PathLike,
                           folder: str | os.PathLike | None = None) -> list[Path]:
    """Write the telemetry file, one station JSON and one measurement CSV per station, and the truth.

    Telemetry: ``t, f_*, v_tel_*, r_tel_*`` and the signals ``a_*`` (kinematic acceleration) and
    ``r_*, v_*`` (the true state: what ``casep impact`` reads as the burnout state). Stations:
    ``<stem>.<S>.json`` and ``<stem>.<S>.csv`` beside it (or in `folder`); truth: ``<stem>.truth.json``.
    Angles in degrees.
    """
    from casep.io._atomic import atomic_open
    from casep.io.files import write_table
    from casep.simulation.simulate import truth_path

    telemetry = Path(telemetry)
    folder = telemetry.parent if folder is None else Path(folder)
    tel = sim.telemetry
    cols = {"t": tel.t, **{f"f_{a}": tel.f[:, i] for i, a in enumerate("xyz")},
            **{f"v_tel_{a}": tel.v[:, i] for i, a in enumerate("xyz")},
            **{f"r_tel_{a}": tel.r[:, i] for i, a in enumerate("xyz")}, **tel.signals}
    write_table(telemetry, cols, comments=[f"casep simulated telemetry (radar), scenario {sim.scenario}, seed "
                                           f"{sim.seed}; launch site {sim.site.to_dict()} (t0: lift-off)"])
    out = [telemetry]
    for m in sim.radars:
        js = folder / f"{telemetry.stem}.{m.station.name}.json"
        with atomic_open(js) as fh:
            fh.write(json.dumps(m.station.to_dict(), indent=2) + "\n")
        csv = folder / f"{telemetry.stem}.{m.station.name}.csv"
        c = {"t": m.t, "range": m.range, "azimuth": np.degrees(m.azimuth), "elevation": np.degrees(m.elevation)}
        if m.range_rate is not None:
            c["range_rate"] = m.range_rate
        write_table(csv, c, comments=[f"casep simulated radar, station {m.station.name}: range m, azimuth and "
                                      "elevation deg, range_rate m/s"])
        out += [js, csv]
    side = truth_path(telemetry)
    with atomic_open(side) as fh:
        fh.write(json.dumps(sim.truth_dict(), indent=2) + "\n")
    return out + [side]
