"""The joint measurement-domain regression: instrument coefficients and station errors together.

Telemetry gives the navigated position and velocity ``r_tel, v_tel`` (launch-inertial); the
instrument errors D make them ``r_tel = r + S_P D``, ``v_tel = v + S_V D`` with
``S_P = int S_V dt`` (:func:`casep.model.sv.cumulative_sp`, trapezoid from the first telemetry
sample). Station ``s`` measures ``z = h_s(r, v) + T_s(g) theta_s + noise`` (range, azimuth,
elevation, optionally range rate; :mod:`casep.radar.geometry`; ``T_s`` from the tracking model).
Linearised about ``(r_lin, v_lin) = (r_tel - S_P D0, v_tel - S_V D0)``::

    z - h(r_lin, v_lin) = -H_r S_P (D - D0) - H_v S_V (D - D0) + T(g_lin) theta + noise

so with ``A = -(H_r S_P + H_v S_V)`` the regression in the absolute coefficients is::

    y = z - h(r_lin, v_lin) + A D0 = A D + T theta + noise           (per station, per type)

Rows are grouped by station and measurement type (azimuth residuals wrapped to [-pi, pi)),
each group divided by its noise std (given, or estimated: :func:`estimate_group_sigmas`), and
stacked into one ``(m, n_D + n_stations n_T)`` regression ``[A | T_1 | T_2 ...]`` handed to the
estimators as a :class:`casep.analysis.problem.Problem`. ``D0`` is re-set to the least-squares
estimate a few times (Gauss-Newton) so that the linearisation point is the estimated true
trajectory: on the test flight (370 m of position error at burnout, 70-290 km range) the
linearisation at the telemetered trajectory alone is off by 1.5-3 std of the estimate; the steps
then shrink quadratically (2.8, 0.76, 2.4e-4 std). Each step is damped: it is halved until the
weighted residual sum ``F(D) = min_theta |W (z - h(D) - T theta)|^2`` (``T`` kept at the geometry of
the current point) does not grow. Near a station's zenith the azimuth, and the azimuth rate in the
time-bias column of ``T``, are far from linear in the position (position sensitivity
``range cos E``), and the full step diverges there (a flight passing at 89 deg elevation: steps of
20, 359, 793, ... 1e5 std); damped, it converges (12 steps). A linearisation that does not
converge is reported (:attr:`LinearisedRadar.converged`) and makes a failed result.

Telemetry quantities are carried to each station's times by :mod:`casep.radar.telemetry`; the
group noise is estimated by :mod:`casep.radar.groups`; the result of the linearisation is a
:class:`casep.radar.linearised.LinearisedRadar`.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from casep.exceptions import CasepWarning, NoiseFreeWarning
from casep.frames import LaunchSite
from casep.model._model import ErrorModel
from casep.model.sv import build_sv, cumulative_sp
from casep.model.tracking import TrackingModel
from casep.radar.geometry import RadarGeometry, wrap_angle
from casep.radar.groups import estimate_group_sigmas, group_reductions
from casep.radar.linearised import PLAUSIBLE_SIGMA, RESIDUAL_RATIO_LIMIT, TYPE_UNITS, LinearisedRadar
from casep.radar.stations import RadarMeasurements, check_station_names
from casep.radar.telemetry import Telemetry, hermite, interp_linear, read_telemetry
from casep.units import ARCSEC

__all__ = ["Telemetry", "read_telemetry", "RadarRegression", "estimate_group_sigmas", "FIRST_RANGE_LIMIT",
           "TYPE_UNITS", "RadarCoverageWarning", "RadarConvergenceWarning", "RadarResidualWarning",
           "PLAUSIBLE_SIGMA", "RESIDUAL_RATIO_LIMIT", "LinearisedRadar"]

#: A first predicted range further than this from the first measured one is a wrong site, not a bias, m.
FIRST_RANGE_LIMIT = 1000.0
#: ... and the same for the angles, rad (1 deg).
FIRST_ANGLE_LIMIT = math.radians(1.0)
#: Starting noise std per type (SI) before they are estimated: 1 m, 5 arcsec, 0.1 m/s.
_START_SIGMA = {"range": 1.0, "azimuth": 5 * ARCSEC, "elevation": 5 * ARCSEC, "range_rate": 0.1}
#: Floor of an estimated group std (SI): the rounding of the measurements, not noise.
_SIGMA_FLOOR = {"range": 1e-9, "azimuth": 1e-15, "elevation": 1e-15, "range_rate": 1e-10}


class RadarConvergenceWarning(CasepWarning):
    """The Gauss-Newton relinearisation did not settle: the message gives the steps (in std)."""


class RadarResidualWarning(CasepWarning):
    """Residuals significantly above the given noise (chi-square, p < 1e-6), but within 1.5 times it."""


class RadarCoverageWarning(CasepWarning):
    """Radar samples outside the telemetry time span were left out: the message gives how many."""


@dataclass
class _Station:
    """One station's data carried to its own times (rows inside the telemetry span)."""

    meas: RadarMeasurements
    geometry: RadarGeometry
    t: np.ndarray
    z: np.ndarray  # (N, k) measured, SI
    r: np.ndarray
    v: np.ndarray
    SP: np.ndarray  # (N, 3, n)
    SV: np.ndarray
    types: tuple[str, ...]
    a: np.ndarray  # (N, 3) kinematic acceleration, m/s^2 (the range-acceleration input of T only)


class RadarRegression:
    """The stacked regression of one flight tracked by one or several radar stations.

    Parameters
    ----------
    telemetry : Telemetry
    radars : sequence of RadarMeasurements
        One per station (names unique).
    model : ErrorModel
        Instrument model, set up.
    tracking : TrackingModel
        Tracking model, set up; every station gets its own coefficients ``<station>.<term>``.
    site : LaunchSite
        Launch point, azimuth and launch time (in the radar files' time scale).
    check : bool, optional
        Refuse a station whose first predicted range (angle) differs from the measured one by
        more than :data:`FIRST_RANGE_LIMIT` (1 deg): a wrong site or station, not a bias.
    """

    def __init__(self, telemetry: Telemetry, radars: Sequence[RadarMeasurements], model: ErrorModel,
                 tracking: TrackingModel, site: LaunchSite, *, check: bool = True) -> None:
        if not radars:
            raise ValueError("no radar station given: at least one station and its measurements are needed")
        check_station_names([m.station for m in radars])
        self.telemetry, self.model, self.tracking, self.site = telemetry, model, tracking, site
        tel = telemetry
        signals = {k: tel.signals[k] for k in model.signals if k in tel.signals}
        if len(signals) < len(model.signals):
            missing = [k for k in model.signals if k not in tel.signals]
            raise ValueError(f"{tel.source}: model `{model.name}` needs column(s) {', '.join(missing)}")
        SV = build_sv(model, tel.t, tel.f, signals=signals)
        SP = cumulative_sp(SV, tel.t)
        acols = ("a_x", "a_y", "a_z")  # kinematic acceleration: the file's, else d v_tel / dt (2nd order)
        acc = (np.column_stack([tel.signals[c] for c in acols]) if all(c in tel.signals for c in acols)
               else np.gradient(tel.v, tel.t, axis=0, edge_order=2) if tel.t.size >= 3 else np.zeros_like(tel.v))
        self.stations: list[_Station] = []
        for m in radars:
            inside = (m.t >= tel.t[0]) & (m.t <= tel.t[-1])
            if not inside.any():
                raise ValueError(f"station `{m.station.name}` ({m.source}): no sample inside the telemetry time span "
                                 f"[{tel.t[0]:g}, {tel.t[-1]:g}] s (radar {m.t[0]:g}..{m.t[-1]:g} s): are the two "
                                 "in the same time scale (--launch-time)?")
            if not inside.all():
                warnings.warn(f"station `{m.station.name}` ({m.source}): {int((~inside).sum())} of {m.t.size} samples "
                              f"outside the telemetry span [{tel.t[0]:g}, {tel.t[-1]:g}] s left out",
                              RadarCoverageWarning, stacklevel=2)
            t = m.t[inside]
            st = _Station(m, RadarGeometry(site, m.station), t, m.values()[inside],
                          hermite(tel.t, tel.r, tel.v, t), interp_linear(tel.t, tel.v, t),
                          hermite(tel.t, SP, SV, t), interp_linear(tel.t, SV, t), m.types, interp_linear(tel.t, acc, t))
            self.stations.append(st)
        self.nD = model.n_coefficients
        self.nT = tracking.n_coefficients
        self.names = tuple(model.names) + tuple(f"{s.meas.station.name}.{n}" for s in self.stations
                                                 for n in tracking.names)
        self.units = tuple(model.units) + tuple(tracking.units) * len(self.stations)
        self.si_factors = np.concatenate([model.si_factors] + [tracking.si_factors] * len(self.stations))
        self.groups = [(s.meas.station.name, ty) for s in self.stations for ty in s.types]
        if check:
            self.check_first_sample()

    # ------------------------------------------------------------------ checks
    def check_first_sample(self) -> None:
        """A station whose first predicted measurement is far from the measured one: a wrong site (error)."""
        for s in self.stations:
            geo, _ = s.geometry.evaluate(s.t[:1], s.r[:1], s.v[:1], s.a[:1])
            d_rng = float(s.z[0, 0] - geo[0, 0])
            name = s.meas.station.name
            if abs(d_rng) > FIRST_RANGE_LIMIT:
                raise ValueError(
                    f"station `{name}` ({s.meas.station.source}, {s.meas.source}): first measured range "
                    f"{s.z[0, 0]:.6g} m vs predicted {geo[0, 0]:.6g} m at t = {s.t[0]:g} s (difference "
                    f"{d_rng:.4g} m > {FIRST_RANGE_LIMIT:g} m): a wrong station position, launch site or launch "
                    "time, not a bias" + (f" (or a navigation error above 1 km already: this radar starts "
                                          f"{s.t[0] - self.telemetry.t[0]:.4g} s into the telemetry)"
                                          if s.t[0] - self.telemetry.t[0] > 10.0 else ""))
            for j, ty in ((1, "azimuth"), (2, "elevation")):
                d = float(wrap_angle(s.z[0, j] - geo[0, j]))
                if abs(d) > FIRST_ANGLE_LIMIT:
                    raise ValueError(
                        f"station `{name}` ({s.meas.source}): first measured {ty} {math.degrees(s.z[0, j]):.6g} deg vs "
                        f"predicted {math.degrees(geo[0, j]):.6g} deg at t = {s.t[0]:g} s (difference "
                        f"{math.degrees(d):.4g} deg > 1 deg): a wrong station position or launch site, a radar time "
                        "scale other than the telemetry's (--launch-time: the launch time in the radar files' time "
                        "scale), or angles not in degrees")

    # ------------------------------------------------------------------ rows
    @property
    def n(self) -> int:
        return len(self.names)

    def group_rows(self) -> list[np.ndarray]:
        """Row indices of each group (:attr:`groups` order) in the stacked regression."""
        out, k0 = [], 0
        for s in self.stations:
            for _ in s.types:
                out.append(np.arange(k0, k0 + s.t.size))
                k0 += s.t.size
        return out

    def assemble(self, D0: np.ndarray | None = None, *,
                 tracking_at: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(S, y, t)`` of the stacked regression linearised about ``D0`` (unweighted, SI rows).

        Rows: station by station, type by type (range, azimuth, elevation, range rate), in time
        order; columns: the instrument coefficients, then each station's tracking terms.
        """
        D0 = np.zeros(self.nD) if D0 is None else np.asarray(D0, dtype=float)
        m = sum(s.t.size * len(s.types) for s in self.stations)
        S = np.zeros((m, self.n))
        y = np.empty(m)
        t = np.empty(m)
        k0 = 0
        for i, s in enumerate(self.stations):
            k = len(s.types)
            r_lin = s.r - s.SP @ D0  # r = r_tel - S_P D0
            v_lin = s.v - s.SV @ D0
            geo, H = s.geometry.evaluate(s.t, r_lin, v_lin, s.a)
            # A = -(H_r S_P + H_v S_V): (N, k, n_D)
            A = -(np.einsum("kij,kjn->kin", H[:, :k, :3], s.SP) + np.einsum("kij,kjn->kin", H[:, :k, 3:], s.SV))
            resid = s.z - geo[:, :k]
            resid[:, 1] = wrap_angle(resid[:, 1])  # azimuth across north
            yk = resid + A @ D0  # y = z - h(lin) + A D0
            if tracking_at is not None:  # T at another point's geometry (the damped steps keep T fixed)
                geo_T, _ = s.geometry.evaluate(s.t, s.r - s.SP @ tracking_at, s.v - s.SV @ tracking_at, s.a)
            else:
                geo_T = geo
            T = self.tracking.jacobian(np.column_stack([geo_T, s.t - s.t[0]]))[:, :k, :]
            c0 = self.nD + i * self.nT
            for j in range(k):
                rows = slice(k0, k0 + s.t.size)
                S[rows, :self.nD] = A[:, j, :]
                S[rows, c0:c0 + self.nT] = T[:, j, :]
                y[rows] = yk[:, j]
                t[rows] = s.t
                k0 += s.t.size
        return S, y, t

    def given_sigmas(self) -> dict[tuple[str, str], float]:
        """Noise std given in the station files, SI, per group."""
        out = {}
        for s in self.stations:
            for ty in s.types:
                if ty in s.meas.station.sigma:
                    out[(s.meas.station.name, ty)] = float(s.meas.station.sigma[ty])
        return out

    def solve(self, sigma: dict | None = None, *, iterations: int = 30, tol: float = 1e-3):
        """Gauss-Newton on the linearisation point with group noise std re-estimated at each step.

        Parameters
        ----------
        sigma : dict, optional
            ``{(station, type): std}`` SI, known std (also read from the station files); the
            others are estimated (:func:`estimate_group_sigmas`).
        iterations : int
            At most this many relinearisations (each a Gauss-Newton step halved until the weighted
            residual sum does not grow). Not converged: a :class:`RadarConvergenceWarning`, and
            the returned ``converged`` false with the numbers in ``convergence_message``.
        tol : float
            Stop when the change of D is below `tol` times its least-squares std. Gauss-Newton
            converges quadratically here (steps of 2.8, 0.76, 2.4e-4, 1.4e-7 std on the test
            flight), and the estimator's solve is one more step, so the default 1e-3 leaves an
            error far below 1e-6 std.

        Returns
        -------
        LinearisedRadar
            The weighted regression at the final linearisation point.
        """
        known = {**self.given_sigmas(), **dict(sigma or {})}
        for g, v in known.items():
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) or not 0 < v < math.inf:
                raise ValueError(f"noise std of {g[0]}.{g[1]} must be a finite number > 0 (SI: m, rad, m/s), "
                                 f"got {v!r}")
        for g in known:
            if g not in self.groups:
                raise ValueError(f"noise given for {g[0]}.{g[1]}, which is not a measurement group here "
                                 f"({', '.join(f'{a}.{b}' for a, b in self.groups)})")
        sig = np.array([known.get(g, _START_SIGMA[g[1]]) for g in self.groups])
        fixed = np.array([g in known for g in self.groups])
        rows = self.group_rows()
        floor = np.array([_SIGMA_FLOOR[g[1]] for g in self.groups])
        D0 = np.zeros(self.nD)
        S, y, t = self.assemble(D0)
        history: list[float] = []
        step, settled, why = math.inf, False, ""
        for _ in range(iterations):
            sig, x, std = estimate_group_sigmas(S, y, rows, sig, fixed, floor=floor)
            dD = x[:self.nD] - D0
            with np.errstate(invalid="ignore", divide="ignore"):
                step = float(np.nanmax(np.where(std[:self.nD] > 0, np.abs(dD) / std[:self.nD], 0.0)))
            if step < tol:  # the full Gauss-Newton step is below tol std: a stationary point
                history.append(step)
                D0 = x[:self.nD]
                settled = True
                break
            # damped step: halve it until the weighted nonlinear residual sum F(D) (theta profiled out)
            # does not grow; near a station's zenith the azimuth is far from linear in the position
            w = np.empty(y.size)
            for g, r in enumerate(rows):
                w[r] = 1.0 / sig[g]
            f0 = self._profile_cost(S, y, D0, w)
            alpha = 1.0
            while True:
                Dt = D0 + alpha * dD
                St, yt, t = self.assemble(Dt, tracking_at=D0)
                ft = self._profile_cost(St, yt, Dt, w)
                if ft <= f0 * (1.0 + 1e-12):
                    break
                alpha *= 0.5
                if alpha < 2.0**-30:
                    break
            if alpha < 2.0**-30:
                why = f"no step along the Gauss-Newton direction lowers the weighted residual sum ({f0:.6g})"
                history.append(step)
                break
            history.append(alpha * step)
            D0 = Dt
            S, y, t = self.assemble(D0)
        if not settled:
            why = why or f"not settled in {iterations} Gauss-Newton steps"
            msg = (f"radar separation: the linearisation did not converge: {why} (last full step {step:.3g} std, "
                   f"steps taken {', '.join(f'{h:.3g}' for h in history)}): the telemetered trajectory is far from "
                   "the measured one, or a station, the launch site or the launch time is wrong; the estimate is "
                   "that of the last linearisation and is not to be used")
            warnings.warn(msg, RadarConvergenceWarning, stacklevel=2)
        else:
            msg = ""
        S, y, t = self.assemble(D0)
        if np.all(sig <= floor * 1.0001) and not fixed.all():
            warnings.warn("radar residuals at the rounding level: the noise std are floored at the rounding of the "
                          "measurements (a noise-free simulation?); give the noise in the station files",
                          NoiseFreeWarning, stacklevel=2)
        return LinearisedRadar(self, S, y, t, sig, fixed, D0, history, group_reductions(S, y, rows), settled, msg)

    def _profile_cost(self, S: np.ndarray, y: np.ndarray, D: np.ndarray, w: np.ndarray) -> float:
        """Weighted residual sum at D with the station terms profiled out (``S, y = assemble(D)``).

        ``F(D) = min_theta |W (z - h(D) - T theta)|^2`` and ``z - h(D) = y - A D`` (:meth:`assemble`).
        """
        r = (y - S[:, :self.nD] @ D) * w
        T = S[:, self.nD:] * w[:, None]
        theta = np.linalg.lstsq(T, r, rcond=None)[0]
        return float(np.sum((r - T @ theta) ** 2))
