"""The weighted radar regression at its final linearisation point: :class:`LinearisedRadar`.

What the estimators solve (:meth:`LinearisedRadar.problem`, :meth:`LinearisedRadar.estimation_problem`),
the noise per group and the check of the residuals against it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from casep.radar.stations import MEASUREMENT_TYPES
from casep.units import ARCSEC

__all__ = ["LinearisedRadar", "TYPE_UNITS", "PLAUSIBLE_SIGMA", "RESIDUAL_RATIO_LIMIT"]

#: Measurement type -> (natural unit, SI factor) for reporting noise and residuals.
TYPE_UNITS = {"range": ("m", 1.0), "azimuth": ("arcsec", ARCSEC), "elevation": ("arcsec", ARCSEC),
              "range_rate": ("m/s", 1.0)}
#: Largest plausible noise std of a tracking radar per type (SI): 100 m, 300 arcsec, 10 m/s. An estimated
#: noise above it is a misfit (time tags off, a wrong model), not noise: the result is failed.
PLAUSIBLE_SIGMA = {"range": 100.0, "azimuth": 300 * ARCSEC, "elevation": 300 * ARCSEC, "range_rate": 10.0}
#: A given noise std exceeded by the residual RMS by more than this factor (and a chi-square test at
#: p < 1e-6) is a failed result; exceeded less, but significantly (p < 1e-6), a warning.
RESIDUAL_RATIO_LIMIT = 1.5


@dataclass
class LinearisedRadar:
    """The weighted regression at the final linearisation point (what the estimators solve)."""

    # the casep.radar.regression.RadarRegression linearised (not imported: that module builds this one)
    regression: Any
    S: np.ndarray  # (m, n) unweighted, SI rows, natural-unit columns
    y: np.ndarray  # (m,) SI
    t: np.ndarray
    sigma: np.ndarray  # (G,) per group, SI
    sigma_given: np.ndarray  # (G,) bool
    D0: np.ndarray
    history: list
    reductions: list  # group_reductions(S, y) at this point, unweighted
    converged: bool = True
    convergence_message: str = ""

    def stacked(self, groups=None, columns=None) -> np.ndarray:
        """The whitened regression reduced to ``[R_g / sigma_g]`` over `groups` (indices; default all):
        the same information matrix as the full rows, on `columns` (default all)."""
        groups = range(len(self.sigma)) if groups is None else groups
        F = np.vstack([self.reductions[g][0] / self.sigma[g] for g in groups])
        return F if columns is None else F[:, columns]

    @property
    def weights(self) -> np.ndarray:
        w = np.ones(self.y.size)  # the keyhole's zero rows keep 1
        for g, r in enumerate(self.regression.group_rows()):
            w[r] = 1.0 / self.sigma[g]
        return w

    def problem(self, columns: np.ndarray | None = None, rows: np.ndarray | None = None):
        """The whitened :class:`~casep.regression.problem.Problem` (rows / sigma_group), optionally a subset."""
        from casep.regression.problem import Problem

        reg = self.regression
        w = self.weights
        Sw, yw, t = self.S * w[:, None], self.y * w, self.t
        names, units, si = reg.names, reg.units, reg.si_factors
        if rows is not None:
            Sw, yw, t = Sw[rows], yw[rows], t[rows]
        if columns is not None:
            Sw = Sw[:, columns]
            names = tuple(names[j] for j in columns)
            units = tuple(units[j] for j in columns)
            si = si[columns]
        return Problem.from_arrays(Sw, yw, t, names=names, units=units, si_factors=si,
                                   model=reg.model.name)

    def sample_layout(self) -> tuple[np.ndarray, np.ndarray]:
        """Rows grouped as ``(M, 3)`` "samples" for the estimators that need samples x 3 rows.

        Each station sample is one row triple (range, azimuth, elevation); range rates are grouped
        three consecutive ones to a triple (the last triple padded with zero rows: at most two per
        station, a negligible change of the degrees of freedom). Triples are sorted by time
        (stations interleaved), so recursive methods run in time order.

        Returns
        -------
        index : (M, 3) ndarray of int
            Row of the stacked regression for each place (-1: a zero pad row).
        t : (M,) ndarray
            Time of each triple, s.
        """
        reg = self.regression
        gr = reg.group_rows(all_rows=True)
        idx, ts, g = [], [], 0
        for s in reg.stations:
            idx.append(np.stack([gr[g + j] for j in range(3)], axis=1))
            ts.append(s.t)
            if len(s.types) == 4:
                rr = gr[g + 3]
                pad = (-rr.size) % 3
                idx.append(np.concatenate([rr, -np.ones(pad, dtype=np.intp)]).reshape(-1, 3))
                ts.append(s.t[np.minimum(np.arange(idx[-1].shape[0]) * 3 + 1, s.t.size - 1)])
            g += len(s.types)
        index, t = np.vstack(idx), np.concatenate(ts)
        order = np.argsort(t, kind="stable")
        return index[order], t[order]

    def estimation_problem(self):
        """The whitened regression as an ``(M, 3, n)`` Problem (rows as in :meth:`sample_layout`)."""
        from casep.regression.problem import Problem

        reg = self.regression
        w = self.weights
        Sw = np.vstack([self.S * w[:, None], np.zeros((1, reg.n))])  # row -1: the zero pad
        yw = np.append(self.y * w, 0.0)
        index, t = self.sample_layout()
        return Problem.from_arrays(Sw[index], yw[index], t, names=reg.names, units=reg.units,
                                   si_factors=reg.si_factors, model=reg.model.name)

    def noise_table(self) -> list[dict]:
        """Noise std per group in natural units, and whether given or estimated."""
        out = []
        for (st, ty), s, given, r in zip(self.regression.groups, self.sigma, self.sigma_given,
                                         self.regression.group_rows()):
            unit, f = TYPE_UNITS[ty]
            out.append({"station": st, "type": ty, "unit": unit, "sigma": float(s / f),
                        "source": "given" if given else "estimated", "n": int(r.size)})
        return out

    def group_residual_rms(self, x: np.ndarray) -> dict[str, float]:
        """RMS of ``y - S x`` per group, natural units (``"S1.range"`` -> m)."""
        x = np.where(np.isnan(x), 0.0, x)
        res = self.y - self.S @ x
        out = {}
        for (st, ty), r in zip(self.regression.groups, self.regression.group_rows()):
            out[f"{st}.{ty}"] = float(np.sqrt(np.mean(res[r] ** 2)) / TYPE_UNITS[ty][1])
        return out

    def residual_check(self, x: np.ndarray) -> tuple[list[str], list[str]]:
        """Residuals against the noise, per group: ``(failures, warnings)`` (messages with the numbers).

        Given noise: ``q = sum r_i^2 / sigma^2`` over the group's ``m`` rows is chi-square with about
        ``m`` degrees of freedom (the fitted parameters are few against thousands of samples); a
        significant excess (``P(chi2_m > q) < 1e-6``) with ``RMS > 1.5 sigma`` fails, a smaller
        significant excess warns. Estimated noise: above :data:`PLAUSIBLE_SIGMA` fails (the
        estimate then measures a misfit, not the sensor).
        """
        from scipy.stats import chi2

        x = np.where(np.isnan(x), 0.0, x)
        res = self.y - self.S @ x
        fail: list[str] = []
        warn: list[str] = []
        for (st, ty), r, s, given in zip(self.regression.groups, self.regression.group_rows(), self.sigma,
                                         self.sigma_given):
            unit, f = TYPE_UNITS[ty]
            rms = float(np.sqrt(np.mean(res[r] ** 2)))
            if given:
                m = r.size
                q = m * (rms / s) ** 2  # sum r^2 / sigma^2 ~ chi2(m)
                p = float(chi2.sf(q, m))
                if p < 1e-6:
                    txt = (f"{st}.{ty}: residual RMS {rms / f:.4g} {unit} is {rms / s:.3g} times the given noise "
                           f"{s / f:.4g} {unit} (chi-square {q:.4g} on {m} samples, p = {p:.2g})")
                    (fail if rms > RESIDUAL_RATIO_LIMIT * s else warn).append(txt)
            elif s > PLAUSIBLE_SIGMA[ty]:
                fail.append(f"{st}.{ty}: estimated noise {s / f:.4g} {unit} (residual RMS {rms / f:.4g} {unit}) is "
                            f"above any plausible radar noise ({PLAUSIBLE_SIGMA[ty] / f:g} {unit})")
        if fail or warn:
            hint = ("; a misfit, not noise: time tags off (time scale, --launch-time), a wrong station position, or "
                    "station errors outside the tracking model")
            fail = [f + hint for f in fail[:1]] + fail[1:] if fail else fail
            warn = [w + hint for w in warn[:1]] + warn[1:] if warn else warn
        return fail, warn

    @property
    def types(self) -> tuple[str, ...]:
        return MEASUREMENT_TYPES
