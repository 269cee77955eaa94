"""The noise of the radar rows: the velocity domain's noise layer, per station and measurement type.

A station's range, azimuth and elevation are three time series on the station's sample times, as
the three axes of a flight's velocity error are on the flight's. So each station is one
:class:`~casep.regression.problem.Problem` ``(N, 3, n)`` whose axes are its types (the rows divided by
the group's std from the linearisation, :class:`~casep.radar.linearised.LinearisedRadar`, so that the
three are commensurate), and its noise model, robust weights and removed samples are those of
:func:`casep.regression.rows.prepare_rows`: white, Gauss-Markov or Gauss-Markov plus white per type
(chosen by REML and the nested likelihood-ratio tests under ``auto``, or as asked, ``tau`` given
per type as for the axes), whitened by the one kernel (:func:`casep.noise.model.whiten`:
the AR(1) difference, the innovations filter of the mixture, exact on uneven times and across
gaps), the robust filter on the innovations. Each station's REML profiles out every coefficient
its own rows see (the instrument terms, its own terms, ``dt_launch``).

The rows every method then solves are the whitened rows of every station, each divided by its
noise std (the REML std of its range, or the robust fit's M-estimator std), stacked as sample
triples in time order (:meth:`RadarNoise.problem`): least squares on them is the GLS estimate of
the joint regression, and the common scale the method estimates is 1 when the noise models are
right.

- A station whose noise std are given (station file, ``sigma``) has known white noise: its rows
  are divided by them and nothing is fitted (a correlated noise asked for it is an error); their
  level is tested by the residual check, not their whiteness.
- The whitened residuals of every other station are tested for whiteness (Ljung-Box per type, as
  a flight's axes, :meth:`RadarNoise.whiteness`): still correlated, a warning naming the station.
- Range-rate rows (a fourth type) stay white per group, std from the linearisation.
- The samples in a station's keyhole (telemetry above 85 deg elevation: the azimuth left out of
  the fit) are left out of its series (a gap, whitened across exactly), range and elevation too:
  one type cannot have a gap the others do not have.
- A method with a noise model of its own (``gls``) takes the rows divided by the group std alone.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from casep.noise.model import NoiseModel, whiten
from casep.radar.linearised import TYPE_UNITS
from casep.regression.rows import Rows, prepare_rows

__all__ = ["RadarNoise", "StationRows", "fit_radar_noise", "SERIES_TYPES"]

#: The measurement types that form a station's three series (the axes of its Problem), in that order.
SERIES_TYPES = ("range", "azimuth", "elevation")


@dataclass
class StationRows:
    """One station's three series: rows of the linearised regression, times, and their noise.

    Attributes
    ----------
    name : str
    index : (N, 3) int ndarray
        Row of the linearised regression of each sample's range, azimuth, elevation (keyhole out).
    t : (N,) ndarray
    sigma : (3,) ndarray
        The group std the rows were divided by (SI; from the linearisation, or given).
    rows : Rows or None
        :func:`~casep.regression.rows.prepare_rows` of the station's Problem; None: noise given (white).
    std : float
        Std of the station's whitened rows (what they are divided by before stacking).
    problem : Problem
        The station's rows (before whitening).
    """

    name: str
    index: np.ndarray
    t: np.ndarray
    sigma: np.ndarray
    rows: Rows | None
    std: float
    problem: Any = None

    @property
    def noise(self) -> NoiseModel:
        return self.rows.noise if self.rows is not None else NoiseModel.white()

    @property
    def keep(self) -> np.ndarray:
        return self.rows.keep if self.rows is not None else np.ones(self.t.size, dtype=bool)

    def whiten(self, X: np.ndarray) -> np.ndarray:
        """Whitened sample triples ``(K, 3, k)`` of the regression rows ``X`` (m, k) of this station (kept samples)."""
        keep = self.keep
        Xs = X[self.index[keep]] / self.sigma[None, :, None]  # (K, 3, k), rows divided by the group std
        w = None if self.rows is None or self.rows.weights is None else self.rows.weights[keep]
        Xw, _ = whiten(Xs, np.zeros(Xs.shape[:2]), self.t[keep], self.noise, w)
        return Xw / self.std


@dataclass
class RadarNoise:
    """The noise of the joint radar regression (module notes): per station its series, range rate white."""

    lin: Any  # casep.radar.linearised.LinearisedRadar
    stations: list[StationRows]
    asked: str
    rate_index: np.ndarray  # (M, 3) range-rate rows grouped three to a triple (-1: a zero pad)
    rate_t: np.ndarray
    rate_sigma: np.ndarray  # (M, 3) their group std (1 at the pads)

    def whiten(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(Xw (M, 3, k), t (M,))``: the regression rows ``X`` (m, k) whitened, sample triples in time order."""
        parts = [s.whiten(X) for s in self.stations]
        ts = [s.t[s.keep] for s in self.stations]
        if self.rate_index.size:
            Xp = np.vstack([X, np.zeros((1, X.shape[1]))])  # row -1: the zero pad
            parts.append(Xp[self.rate_index] / self.rate_sigma[:, :, None])
            ts.append(self.rate_t)
        Xw, t = np.concatenate(parts), np.concatenate(ts)
        order = np.argsort(t, kind="stable")  # whitened rows are independent: time order for recursive methods
        return Xw[order], t[order]

    def problem(self):
        """The whitened joint regression as an ``(M, 3, n)`` Problem (what every method solves)."""
        from casep.regression.problem import Problem

        reg = self.lin.regression
        Xw, t = self.whiten(np.column_stack([self.lin.S, self.lin.y]))
        return Problem.from_arrays(Xw[:, :, :-1], Xw[:, :, -1], t, names=reg.names, units=reg.units,
                                   si_factors=reg.si_factors, model=reg.model.name)

    def fit_spec(self, spec: Any, sigma: float | None) -> Any:
        """The request `spec` as the rows of :meth:`problem` take it, for :func:`casep.estimators.solve.fit`.

        The noise layer's work is done on those rows (each station whitened by its noise model, its
        glitches weighted or removed), so they are white to a method without a noise model of its own and
        no robust filter runs on them again; a method with its own (GLS) fits it on the rows divided by the
        group std. `sigma`: 1 when every group's std is given (the rows are divided by them), else None
        (the method estimates the common scale).
        """
        from casep.estimators.registry import METHODS

        own = METHODS[spec.method].own_noise_model is not None
        noise = dataclasses.replace(spec.noise, kind=spec.noise.kind if own else "white", tau=None, robust=None)
        return dataclasses.replace(spec, sigma=sigma, noise=noise)

    def accounts(self) -> dict[str, Any]:
        """``{station: noise record}`` (the noise model and what the robust fit did), each from
        :func:`casep.estimators.solve.noise_account` (the one place), as a several-flight result holds them."""
        from casep.estimators.solve import noise_account

        note = ("axes x, y, z are the station's range, azimuth, elevation; std in units of the group std "
                "(radar.noise gives them in natural units)")
        out = {}
        for s in self.stations:
            acc = noise_account(s.rows, self.asked, s.noise,
                                note=note if s.rows is not None else "noise given in the station file: white")
            out[s.name] = {**acc["noise"], **({"robust": acc["robust"]} if "robust" in acc else {})}
        return out

    def group_records(self) -> list[dict]:
        """Per group (station and type): the noise kind, its std in natural units (Gauss-Markov and white
        parts), the correlation time, and how it was had."""
        out = []
        groups = {(st, ty): g for g, (st, ty) in enumerate(self.lin.regression.groups)}
        by_name = {s.name: s for s in self.stations}
        for row in self.lin.noise_table():
            s = by_name.get(row["station"])
            if s is None or row["type"] not in SERIES_TYPES:
                out.append({**row, "kind": "white"})
                continue
            j = SERIES_TYPES.index(row["type"])
            nm = s.noise
            kind = nm.axis_kinds()[j]
            # the series' stationary std: the group std x the axis scale x the std of the whitened rows
            sd = float(self.lin.sigma[groups[(row["station"], row["type"])]] * nm.scale[j] * s.std)
            f = TYPE_UNITS[row["type"]][1]
            how = "" if s.rows is None or (kind == "white" and nm.rule == "given") else \
                ", tau given" if nm.rule == "given" else f", {nm.rule.replace('reml', 'REML')}"
            d = {**row, "kind": kind, "sigma": sd / f, "source": row["source"] + how}
            if kind != "white":
                d["tau_s"] = float(nm.tau[j])
                d["sigma_gm"] = sd / f * float(np.sqrt(1.0 - nm.share[j]))
                d["sigma_white"] = sd / f * float(np.sqrt(nm.share[j]))
            out.append(d)
        return out

    def whiteness(self, x: np.ndarray) -> dict[str, Any]:
        """Per station, the Ljung-Box test of its whitened residuals at the estimate `x`; a
        :class:`~casep.exceptions.NoiseNotWhiteWarning` naming the station where they are still correlated."""
        from casep.exceptions import NoiseNotWhiteWarning
        from casep.noise.whiteness import ALPHA_FITTED, whiteness_test

        r = self.lin.y - self.lin.S @ x
        out = {}
        for s in self.stations:
            keep = s.keep
            # rounding: no noise whose whiteness to test; given std: the user's statement, their level tested by
            # the residual check (LinearisedRadar.residual_check)
            if keep.sum() < 10 or s.rows is None or s.problem.is_noise_free():
                continue
            e = s.whiten(r[:, None])[:, :, 0]
            # as for a flight: white noise asked at 1 %, a fitted model's residuals at 0.1 %
            alpha = 0.01 if self.asked == "white" else ALPHA_FITTED
            wt = dataclasses.replace(whiteness_test(e, s.t[keep], alpha=alpha), kind=s.noise.kind)
            if wt.rejected:
                axes = dict(zip("xyz", SERIES_TYPES))
                text = wt.text()
                for a, ty in axes.items():
                    text = text.replace(f"{a} Q ", f"{ty} Q ")
                warnings.warn(f"station `{s.name}`: {text}", NoiseNotWhiteWarning, stacklevel=3)
            out[s.name] = wt.to_dict()
        return out


def _station_problem(lin, i: int, first_group: int):
    """Station `i`'s rows of range, azimuth, elevation as a Problem ``(N, 3, n)`` (keyhole samples out),
    divided by the group std: ``(problem, index, t, sigma)``."""
    from casep.regression.problem import Problem

    reg = lin.regression
    st = reg.stations[i]
    rows = reg.group_rows(all_rows=True)
    index = np.stack([rows[first_group + j] for j in range(3)], axis=1)  # (N, 3)
    ok = ~st.keyhole if st.keyhole is not None else np.ones(st.t.size, dtype=bool)
    index, t = index[ok], st.t[ok]
    sigma = lin.sigma[first_group:first_group + 3]
    pb = Problem.from_arrays(lin.S[index] / sigma[None, :, None], lin.y[index] / sigma[None, :], t,
                             names=reg.names, units=reg.units, si_factors=reg.si_factors, model=reg.model.name)
    pb.source = f"station {st.meas.station.name} ({st.meas.source})"  # named in the noise fit's messages
    return pb, index, t, sigma


def fit_radar_noise(lin, spec) -> RadarNoise:
    """The noise of every station's series as `spec` (a :class:`~casep.estimators.spec.FitSpec`) asks (module notes).

    Raises
    ------
    ValueError
        A correlated noise (``gm``, ``gmw`` or a ``tau``) asked for a station whose noise std are given.
    """
    from casep.estimators.registry import METHODS

    reg = lin.regression
    ns = spec.noise
    own = METHODS[spec.method].own_noise_model is not None  # gls: its own noise model on the rows
    stations, g = [], 0
    for i, st in enumerate(reg.stations):
        pb, index, t, sigma = _station_problem(lin, i, g)
        given = bool(lin.sigma_given[g:g + 3].any())
        name = st.meas.station.name
        if given and (ns.kind in ("gm", "gmw") or ns.tau is not None):
            raise ValueError(f"noise {ns.kind!r} asked, but station `{name}` ({st.meas.station.source}) gives its "
                             "noise std (sigma_range / sigma_angle, or `sigma`): given std are white noise. Remove "
                             "them to have the noise fitted, or use noise 'auto' or 'white'")
        if given or own:
            stations.append(StationRows(name, index, t, sigma, None, 1.0, pb))
        else:
            rows = prepare_rows(pb, ns.kind, ns.tau, ns.robust, ns.exclude_outliers)
            std = rows.sigma if rows.sigma is not None else rows.noise.sigma
            stations.append(StationRows(name, index, t, sigma, rows, float(std) if std and np.isfinite(std) else 1.0,
                                        pb))
        g += len(st.types)
    # range rate: white, its rows grouped three to a triple as the estimators' sample layout has them
    index, t = lin.sample_layout()
    group_sigma = np.ones(lin.y.size + 1)  # the last place: the zero pad (-1)
    is_rate = np.zeros(lin.y.size + 1, dtype=bool)
    for gi, ((_, ty), r) in enumerate(zip(reg.groups, reg.group_rows(all_rows=True))):
        group_sigma[r] = lin.sigma[gi]
        is_rate[r] = ty == "range_rate"
    rate = is_rate[index[:, 0]]
    return RadarNoise(lin, stations, "white" if own else ns.kind, index[rate], t[rate], group_sigma[index[rate]])
