"""The joint measurement-domain regression: instrument coefficients and station errors together.

Telemetry gives the navigated position and velocity ``r_tel, v_tel`` (launch-inertial); the
instrument errors D make them ``r_tel = r + S_P D``, ``v_tel = v + S_V D`` with
``S_P = int S_V dt`` (:func:`casep.model.sv.cumulative_sp`, trapezoid from the first telemetry
sample). Station ``s`` measures ``z = h_s(r, v) + T_s(g) theta_s + noise`` (range, azimuth,
elevation, optionally range rate; :mod:`casep.tracking.geometry`; ``T_s`` from the tracking model).
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

Telemetry quantities are carried to each station's times by cubic Hermite interpolation (position
with velocity as its derivative, S_P with S_V), velocity and S_V linearly; at radar times that
are telemetry times this is exact.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from casep.exceptions import CasepWarning, NoiseFreeWarning
from casep.frames import LaunchSite
from casep.model._model import ErrorModel
from casep.model.sv import build_sv, cumulative_sp
from casep.model.tracking import TrackingModel
from casep.tracking.geometry import RadarGeometry, wrap_angle
from casep.tracking.stations import MEASUREMENT_TYPES, RadarMeasurements, check_station_names
from casep.units import ARCSEC

__all__ = ["Telemetry", "read_telemetry", "RadarRegression", "estimate_group_sigmas", "FIRST_RANGE_LIMIT",
           "TYPE_UNITS", "RadarCoverageWarning", "RadarConvergenceWarning", "RadarResidualWarning",
           "PLAUSIBLE_SIGMA", "RESIDUAL_RATIO_LIMIT"]

#: A first predicted range further than this from the first measured one is a wrong site, not a bias, m.
FIRST_RANGE_LIMIT = 1000.0
#: ... and the same for the angles, rad (1 deg).
FIRST_ANGLE_LIMIT = math.radians(1.0)
#: Measurement type -> (natural unit, SI factor) for reporting noise and residuals.
TYPE_UNITS = {"range": ("m", 1.0), "azimuth": ("arcsec", ARCSEC), "elevation": ("arcsec", ARCSEC),
              "range_rate": ("m/s", 1.0)}
#: Starting noise std per type (SI) before they are estimated: 1 m, 5 arcsec, 0.1 m/s.
_START_SIGMA = {"range": 1.0, "azimuth": 5 * ARCSEC, "elevation": 5 * ARCSEC, "range_rate": 0.1}
#: Floor of an estimated group std (SI): the rounding of the measurements, not noise.
_SIGMA_FLOOR = {"range": 1e-9, "azimuth": 1e-15, "elevation": 1e-15, "range_rate": 1e-10}
#: Largest plausible noise std of a tracking radar per type (SI): 100 m, 300 arcsec, 10 m/s. An estimated
#: noise above it is a misfit (time tags off, a wrong model), not noise: the result is failed.
PLAUSIBLE_SIGMA = {"range": 100.0, "azimuth": 300 * ARCSEC, "elevation": 300 * ARCSEC, "range_rate": 10.0}
#: A given noise std exceeded by the residual RMS by more than this factor (and a chi-square test at
#: p < 1e-6) is a failed result; exceeded less, but significantly (p < 1e-6), a warning.
RESIDUAL_RATIO_LIMIT = 1.5
#: Telemetry speed relative to the pad above which its first sample is not on the pad, m/s.
_PAD_SPEED = 5.0


class RadarConvergenceWarning(CasepWarning):
    """The Gauss-Newton relinearisation did not settle: the message gives the steps (in std)."""


class RadarResidualWarning(CasepWarning):
    """Residuals significantly above the given noise (chi-square, p < 1e-6), but within 1.5 times it."""


class RadarCoverageWarning(CasepWarning):
    """Radar samples outside the telemetry time span were left out: the message gives how many."""


@dataclass(frozen=True)
class Telemetry:
    """Telemetered navigation of a flight: times, specific force, velocity and position (launch-inertial).

    Attributes
    ----------
    t, f, v, r : ndarray
        s; m/s^2 (N, 3); m/s (N, 3); m (N, 3).
    r_source : str
        ``"r_tel columns"`` or ``"v_tel integrated from the launch point"``.
    signals : dict
        Other numeric columns (for model files that use signals).
    source : str
    """

    t: np.ndarray
    f: np.ndarray
    v: np.ndarray
    r: np.ndarray
    r_source: str
    signals: dict = field(default_factory=dict)
    source: str = "<memory>"


def integrate_position(t: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Position from the launch point (r(t_0) = 0) by the trapezoid rule on the velocity."""
    dt = np.diff(t)[:, None]
    return np.vstack([np.zeros((1, 3)), np.cumsum(0.5 * (v[1:] + v[:-1]) * dt, axis=0)])


def read_telemetry(path: str | os.PathLike, site: LaunchSite | None = None) -> Telemetry:
    """A telemetry file for the radar separation: ``t``, ``f_*`` or ``W_*``, ``v_tel_*``, optional ``r_tel_*``.

    Without ``r_tel_*`` the position is ``v_tel`` integrated from the launch point (the origin of
    the launch-inertial frame); that needs the first sample on the pad: with `site`, a first
    ``v_tel`` more than 5 m/s from the pad's inertial velocity (the Earth's rotation) is refused.
    """
    from casep.io.files import VTEL_COLUMNS, _force, _Table

    tab = _Table(path)
    tab.require(("t",) + VTEL_COLUMNS, ". A radar separation needs the telemetered velocity v_tel_x/y/z (m/s, "
                                       "launch-inertial) and optionally the position r_tel_x/y/z (m)")
    t = tab.time()
    f, _ = _force(tab, t)
    v = tab.vectors(VTEL_COLUMNS)
    rcols = ("r_tel_x", "r_tel_y", "r_tel_z")
    if tab.has(rcols):
        r, how = tab.vectors(rcols), "r_tel columns"
    else:
        if any(c in tab.columns for c in rcols):
            tab.require(rcols, ". Give all three r_tel_x/y/z or none (then v_tel is integrated)")
        if site is not None:
            pad = np.cross(site.earth_rate, -site.earth_centre)  # inertial velocity of the launch point
            off = float(np.linalg.norm(v[0] - pad))
            if off > _PAD_SPEED:
                raise tab.error(f"no r_tel_x/y/z columns, and the first v_tel is {off:.4g} m/s from the pad's "
                                "velocity: the telemetry starts in flight, so its position cannot be integrated from "
                                "the launch point. Give r_tel_x, r_tel_y, r_tel_z (m, launch-inertial)", "r_tel_x",
                                "header")
        r, how = integrate_position(t, v), "v_tel integrated from the launch point"
    sig = {k: val for k, val in tab.signals().items() if k not in rcols}
    return Telemetry(t, f, v, r, how, sig, tab.src)


def _hermite(t: np.ndarray, y: np.ndarray, dy: np.ndarray, tq: np.ndarray) -> np.ndarray:
    """Cubic Hermite interpolation of `y` (derivative `dy`) at `tq`, along axis 0 (exact at the nodes)."""
    k = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, t.size - 2)
    h = (t[k + 1] - t[k])
    s = (tq - t[k]) / h
    shape = (-1,) + (1,) * (y.ndim - 1)
    s, h = s.reshape(shape), h.reshape(shape)
    h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s  # Hermite basis on [0, 1]
    h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
    return h00 * y[k] + h10 * h * dy[k] + h01 * y[k + 1] + h11 * h * dy[k + 1]


def _linear(t: np.ndarray, y: np.ndarray, tq: np.ndarray) -> np.ndarray:
    k = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, t.size - 2)
    w = ((tq - t[k]) / (t[k + 1] - t[k])).reshape((-1,) + (1,) * (y.ndim - 1))
    return (1 - w) * y[k] + w * y[k + 1]


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
                          _hermite(tel.t, tel.r, tel.v, t), _linear(tel.t, tel.v, t),
                          _hermite(tel.t, SP, SV, t), _linear(tel.t, SV, t), m.types, _linear(tel.t, acc, t))
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


def estimate_group_sigmas(S: np.ndarray, y: np.ndarray, rows: list[np.ndarray], sigma: np.ndarray,
                          fixed: np.ndarray, *, floor: np.ndarray, iterations: int = 30,
                          rtol: float = 1e-5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Noise std per group from the weighted least-squares residuals, degrees of freedom corrected.

    Iterates ``sigma_g^2 = sum_{i in g} r_i^2 / (m_g - h_g)`` with ``r`` the residuals of the fit
    weighted by the current std and ``h_g = sum_{i in g} h_ii = trace(F_g^T F_g (F^T F)^+)`` the
    group's share of the leverages (``F`` the weighted S); at the fixed point the weighted residual
    sum of squares equals ``m - rank``, the REML condition for group variances of a linear model
    at these leverages.

    Each group is reduced once (casep's TSQR, :func:`casep.analysis.linalg.reduce_qr`:
    ``S_g = Q_g R_g``, ``q_g = Q_g^T y_g``, ``rho_g^2`` the rest); a weighting is then the
    least-squares problem of the stacked ``R_g / sigma_g`` (``G n`` rows), and the group's residual
    sum of squares is ``|q_g - R_g x|^2 + rho_g^2``: exact, and independent of the number of rows.

    Returns
    -------
    sigma : (G,) ndarray
        Per group, SI (the `fixed` ones as given).
    x : (n,) ndarray
        Weighted least-squares estimate at the final std.
    std : (n,) ndarray
        Its std (unit weighted noise).
    """
    sigma = np.array(sigma, dtype=float)
    red = group_reductions(S, y, rows)
    grams = [R.T @ R for R, _, _ in red]  # S_g^T S_g
    x = cov = None
    for _ in range(iterations):
        x, cov = _stacked_ls(red, sigma)
        new = sigma.copy()
        for g, (R, q, rho2) in enumerate(red):
            if fixed[g]:
                continue
            lev = float(np.sum(grams[g] * cov)) / sigma[g] ** 2  # trace(F_g^T F_g Cov), Cov symmetric
            dof = max(rows[g].size - lev, 1.0)
            rss = float(np.sum((q - R @ x) ** 2)) + rho2
            new[g] = max(math.sqrt(max(rss, 0.0) / dof), float(floor[g]))
        done = np.all(np.abs(new - sigma) <= rtol * sigma)
        sigma = new
        if done:
            break
    x, cov = _stacked_ls(red, sigma)
    return sigma, x, np.sqrt(np.clip(np.diag(cov), 0, None))


def group_reductions(S: np.ndarray, y: np.ndarray, rows: list[np.ndarray]) -> list[tuple]:
    """Per group ``(R_g, q_g, rho_g^2)`` with ``S_g = Q_g R_g``, ``q_g = Q_g^T y_g`` (casep's TSQR).

    ``|y_g - S_g x|^2 = |q_g - R_g x|^2 + rho_g^2`` for every x, and ``S_g^T S_g = R_g^T R_g``, also on
    any subset of the columns: every bound and fit of the stacked regression follows from these.
    """
    from casep.analysis.linalg import reduce_qr

    out = []
    for r in rows:
        rg = reduce_qr(S[r], y[r])
        out.append((rg.R * rg.scale[None, :], rg.qty, float(rg.rho2)))  # R of S_g itself (S_g = Q R diag(scale))
    return out


def _stacked_ls(red, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least squares of the stacked group reductions ``[R_g / sigma_g] x = [q_g / sigma_g]``, columns
    equilibrated, minimum norm on an exact null space: estimate and covariance (unit weighted noise)."""
    F = np.vstack([R / s for (R, _, _), s in zip(red, sigma)])
    f = np.concatenate([q / s for (_, q, _), s in zip(red, sigma)])
    c = np.linalg.norm(F, axis=0)
    c = np.where(c > 0, c, 1.0)
    U, sv, Vt = np.linalg.svd(F / c, full_matrices=False)
    keep = sv > sv[0] * max(F.shape) * np.finfo(float).eps
    Wm = Vt[keep].T / sv[keep]
    x = (Wm @ (U[:, keep].T @ f)) / c
    cov = (Wm @ Wm.T) / np.outer(c, c)
    return x, cov


@dataclass
class LinearisedRadar:
    """The weighted regression at the final linearisation point (what the estimators solve)."""

    regression: RadarRegression
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
        w = np.empty(self.y.size)
        for g, r in enumerate(self.regression.group_rows()):
            w[r] = 1.0 / self.sigma[g]
        return w

    def problem(self, columns: np.ndarray | None = None, rows: np.ndarray | None = None):
        """The whitened :class:`~casep.analysis.problem.Problem` (rows / sigma_group), optionally a subset."""
        from casep.analysis.problem import Problem

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
        gr = reg.group_rows()
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
        from casep.analysis.problem import Problem

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
