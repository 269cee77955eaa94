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
estimators as a :class:`casep.regression.problem.Problem`. ``D0`` is re-set to the least-squares
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

import copy
import dataclasses
import math
import warnings
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from casep.exceptions import CasepWarning, NoiseFreeWarning
from casep.frames import LaunchSite
from casep.model.error_model import ErrorModel
from casep.model.sv import build_sv, cumulative_sp
from casep.model.tracking import TrackingModel
from casep.radar.geometry import RadarGeometry, wrap_angle
from casep.radar.groups import estimate_group_sigmas, group_reductions
from casep.radar.linearised import PLAUSIBLE_SIGMA, RESIDUAL_RATIO_LIMIT, TYPE_UNITS, LinearisedRadar
from casep.radar.stations import RadarMeasurements, check_station_names
from casep.radar.telemetry import Telemetry, hermite, interp_linear, read_telemetry
from casep.regression.problem import is_rounding_level, rounding_level
from casep.units import ARCSEC

__all__ = ["Telemetry", "read_telemetry", "RadarRegression", "estimate_group_sigmas", "FIRST_RANGE_LIMIT",
           "LAUNCH_TIME", "LAUNCH_TIME_SCALE",
           "TYPE_UNITS", "RadarCoverageWarning", "RadarConvergenceWarning", "RadarResidualWarning",
           "PLAUSIBLE_SIGMA", "RESIDUAL_RATIO_LIMIT", "LinearisedRadar"]

#: The launch-time correction estimated with the station terms (ms): true launch time = given + dt_launch. An error
#: of the launch epoch (the launch-inertial frame turned about the Earth's axis), not a time-tag delay: a station's
#: delay is its own ``time_bias``, the twin of a velocity pair's ``dt_trk`` (:func:`casep.io.pair.fits_time_offset`
#: says why the two are not one rule).
LAUNCH_TIME = "dt_launch"
#: Its declared magnitude (ms): a launch time known to about 10 ms (the diagnostics' scale).
LAUNCH_TIME_SCALE = 10.0
#: Elevation above which a station's azimuth is left out of the fit, rad (85 deg): near the zenith the
#: azimuth's sensitivity to the position, 1 / (range cos E), makes it far from linear over the position's
#: uncertainty (the Gauss-Newton steps then crawl), and a tracking mount's azimuth there (the keyhole) is
#: not to be trusted either. The elevation rows there are kept.
KEYHOLE = math.radians(85.0)
#: Passes whose start re-sets the geometry of ``T`` and ``dt_launch``; later passes hold it (near the zenith
#: the launch-time column changes fast with the trajectory and re-setting it for ever moves D by about 0.5 std
#: a pass without end; after 4 passes the point is within a fraction of a std, where T's change is negligible).
T_PASSES = 4
#: A full Gauss-Newton step below this (std of D) is taken without the line search.
SMALL_STEP = 0.1
#: A pass of the Gauss-Newton fit whose first full step (std and T re-set) is below this (std of D) settles it.
PASS_TOL = 0.05
#: Elevation above which a measured line of sight may be reported over the top of the zenith, rad (80 deg).
ZENITH_FOLD = math.radians(80.0)
#: A first predicted range further than this from the first measured one is a wrong site, not a bias, m.
FIRST_RANGE_LIMIT = 1000.0
#: ... and the same for the angles, rad (1 deg).
FIRST_ANGLE_LIMIT = math.radians(1.0)
#: Starting noise std per type (SI) before they are estimated: 1 m, 5 arcsec, 0.1 m/s.
_START_SIGMA = {"range": 1.0, "azimuth": 5 * ARCSEC, "elevation": 5 * ARCSEC, "range_rate": 0.1}


def over_the_top(z: np.ndarray, geo: np.ndarray) -> np.ndarray:
    """Measured angles near the zenith carried across it to the side of their prediction.

    A line of sight near the zenith is reported either way: ``(A, E)`` or ``(A + pi, pi - E)``
    over the top. A sample measured above :data:`ZENITH_FOLD` elevation whose azimuth is more
    than 90 deg from the predicted one is compared as ``(A - pi, pi - E)`` (an elevation above
    90 deg), so that its residual is continuous through the zenith.
    """
    flip = (z[:, 2] > ZENITH_FOLD) & (np.abs(wrap_angle(z[:, 1] - geo[:, 1])) > math.pi / 2)
    if not flip.any():
        return z
    z = z.copy()
    z[flip, 1] -= math.pi
    z[flip, 2] = math.pi - z[flip, 2]
    return z


def _unit_ratio(a: np.ndarray, b: np.ndarray, what_a: str, what_b: str, big: str, small: str) -> None:
    """Raise when ``median a / median b`` (two speeds, m/s) is outside [0.1, 10], naming the likely unit mix-up."""
    ma, mb = float(np.median(a)), float(np.median(b))
    if ma <= 1.0 or mb <= 1.0 or 0.1 < ma / mb < 10.0:
        return
    ratio = ma / mb
    likely = big if 300 < ratio < 3000 else small if 300 < 1 / ratio < 3000 else "different units"
    raise ValueError(f"{what_a} a median {ma:.4g} m/s but {what_b} {mb:.4g} m/s (ratio {ratio:.4g}): {likely}? "
                     "casep reads m, m/s (and deg for the angles)")


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
    keyhole: np.ndarray | None = None  # (N,) bool: azimuth left out, the telemetry above KEYHOLE elevation


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
    fit_launch_time : bool, optional
        Estimate the launch-time offset :data:`LAUNCH_TIME` (ms, one for all stations) with the
        other terms (default). The launch time ties the telemetry's launch-inertial frame to the
        Earth (``theta = omega_E (t - t0)``); an offset ``dt0`` turns the flight about the Earth's
        axis by ``omega_E dt0`` (21 m at the test site for 50 ms), which the station terms and the
        instrument terms would otherwise absorb. Its column is ``d h / d t0`` (central differences,
        :meth:`RadarGeometry.setup_jacobian`). With the stations' ``time_bias`` terms it also spans
        an offset of the telemetry clock against the range clock (the same time shift for every
        station, minus the Earth's turn that ``dt0`` holds).
    """

    def __init__(self, telemetry: Telemetry, radars: Sequence[RadarMeasurements], model: ErrorModel,
                 tracking: TrackingModel, site: LaunchSite, *, check: bool = True,
                 fit_launch_time: bool = True) -> None:
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
            geo, _ = st.geometry.evaluate(st.t, st.r, st.v)
            st.keyhole = geo[:, 2] > KEYHOLE  # the azimuth is not linear in the position there
            st.z = over_the_top(st.z, geo)  # decided once, at the telemetry: the residuals stay continuous in D
            self.stations.append(st)
        self.launch_shift = 0.0  # s: the stations' geometry at site.t0 + launch_shift (at_launch_shift)
        self.nD = model.n_coefficients
        self.nT = tracking.n_coefficients
        self.common = (LAUNCH_TIME,) if fit_launch_time else ()  # terms shared by all stations, last columns
        self.names = tuple(model.names) + tuple(f"{s.meas.station.name}.{n}" for s in self.stations
                                                 for n in tracking.names) + self.common
        self.units = tuple(model.units) + tuple(tracking.units) * len(self.stations) + ("ms",) * len(self.common)
        self.si_factors = np.concatenate([model.si_factors] + [tracking.si_factors] * len(self.stations)
                                         + [np.full(len(self.common), 1e-3)])
        self.groups = [(s.meas.station.name, ty) for s in self.stations for ty in s.types]
        if check:
            self.check_units()
            self.check_first_sample()

    # ------------------------------------------------------------------ checks
    def check_units(self) -> None:
        """Refuse telemetry whose velocity, position or radar range are in other units than m/s and m.

        Two speed ratios, each near 1 for consistent units (medians over the samples, central
        differences): the telemetered position's rate ``|d r_tel/dt|`` against ``|v_tel|``, and
        each station's measured range rate ``|d range/dt|`` against the one the telemetry
        predicts. A ratio outside [0.1, 10] is an error; near 1000 (or 1/1000) it names km/s or km.
        """
        tel = self.telemetry
        if tel.r_source == "r_tel columns" and tel.t.size >= 3:
            _unit_ratio(np.linalg.norm(np.gradient(tel.r, tel.t, axis=0), axis=1), np.linalg.norm(tel.v, axis=1),
                        f"{tel.source}: the telemetered position r_tel changes at", "the telemetered velocity v_tel is",
                        "v_tel in km/s", "r_tel in km")
        for s in self.stations:
            if s.t.size < 3:
                continue
            geo, _ = s.geometry.evaluate(s.t, s.r, s.v, s.a)
            _unit_ratio(np.abs(np.gradient(s.z[:, 0], s.t)), np.abs(geo[:, 3]),
                        f"station `{s.meas.station.name}` ({s.meas.source}): the measured range changes at",
                        f"the range rate the telemetry ({tel.source}) predicts is",
                        "the telemetry velocity in km/s (and its position from it)", "the range in km")

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
            z0 = over_the_top(s.z[:1], geo[:1])[0]
            for j, ty in ((1, "azimuth"), (2, "elevation")):
                d = float(wrap_angle(z0[j] - geo[0, j]))
                if abs(d) > FIRST_ANGLE_LIMIT:
                    raise ValueError(
                        f"station `{name}` ({s.meas.source}): first measured {ty} {math.degrees(z0[j]):.6g} deg vs "
                        f"predicted {math.degrees(geo[0, j]):.6g} deg at t = {s.t[0]:g} s (difference "
                        f"{math.degrees(d):.4g} deg > 1 deg): a wrong station position or launch site, a radar time "
                        "scale other than the telemetry's (--launch-time: the launch time in the radar files' time "
                        "scale), or angles not in degrees")

    # ------------------------------------------------------------------ rows
    @property
    def n(self) -> int:
        return len(self.names)

    def group_rows(self, *, all_rows: bool = False) -> list[np.ndarray]:
        """Row indices of each group (:attr:`groups` order) in the stacked regression.

        The azimuth rows in a station's keyhole (:data:`KEYHOLE`) are zero rows of the regression and
        are not among their group's rows unless `all_rows`.
        """
        out, k0 = [], 0
        for s in self.stations:
            for ty in s.types:
                idx = np.arange(k0, k0 + s.t.size)
                out.append(idx if all_rows or ty != "azimuth" or s.keyhole is None else idx[~s.keyhole])
                k0 += s.t.size
        return out

    @property
    def keyhole_counts(self) -> dict[str, int]:
        """Azimuth samples left out per station (the telemetry above :data:`KEYHOLE` elevation)."""
        return {s.meas.station.name: int(s.keyhole.sum()) if s.keyhole is not None else 0 for s in self.stations}

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
            resid = s.z[:, :k] - geo[:, :k]
            resid[:, 1] = wrap_angle(resid[:, 1])  # azimuth across north
            yk = resid + A @ D0  # y = z - h(lin) + A D0
            if tracking_at is not None:  # T at another point's geometry (the damped steps keep T fixed)
                geo_T, _ = s.geometry.evaluate(s.t, s.r - s.SP @ tracking_at, s.v - s.SV @ tracking_at, s.a)
            else:
                geo_T = geo
            T = self.tracking.jacobian(np.column_stack([geo_T, s.t - s.t[0]]))[:, :k, :]
            if self.common:
                C = self._launch_time_column(s, D0 if tracking_at is None else tracking_at)
            c0 = self.nD + i * self.nT
            for j in range(k):
                rows = slice(k0, k0 + s.t.size)
                S[rows, :self.nD] = A[:, j, :]
                S[rows, c0:c0 + self.nT] = T[:, j, :]
                if self.common:
                    S[rows, -1] = C[:, j]
                y[rows] = yk[:, j]
                if s.types[j] == "azimuth" and s.keyhole is not None and s.keyhole.any():
                    S[k0 + np.flatnonzero(s.keyhole)] = 0.0  # keyhole: a zero row (left out of its group)
                    y[k0 + np.flatnonzero(s.keyhole)] = 0.0
                t[rows] = s.t
                k0 += s.t.size
        return S, y, t

    def group_scales(self) -> np.ndarray:
        """Largest measured magnitude of each group (:attr:`groups` order), SI: the scale of its rounding."""
        return np.array([float(np.max(np.abs(s.z[:, j]))) if s.t.size else 0.0
                         for s in self.stations for j in range(len(s.types))])

    @staticmethod
    def _launch_time_column(s: _Station, D: np.ndarray) -> np.ndarray:
        """``d h / d t0`` of station `s`'s measurements at the trajectory of D, per ms (the term's unit): (N, k)."""
        k = len(s.types)
        return s.geometry.setup_jacobian(s.t, s.r - s.SP @ D, s.v - s.SV @ D, s.a, station=False)[:, :k, 0] * 1e-3

    def launch_time_rows(self, D: np.ndarray) -> np.ndarray:
        """The column of :data:`LAUNCH_TIME` in the stacked rows at the trajectory of D (m,), also when the
        term is not in the regression (one station: :func:`casep.radar.setup.check_setup` tests it)."""
        return self._stacked([self._launch_time_column(s, D) for s in self.stations])

    def launch_time_remainder(self, D: np.ndarray, dt_ms: float) -> np.ndarray:
        """What the linear :data:`LAUNCH_TIME` column leaves out of a launch-time correction `dt_ms` (ms), stacked
        rows at the trajectory of D (SI)::

            h(t0 + dt) - h(t0) - (d h / d t0) dt        (azimuth differences wrapped; keyhole rows 0)

        ``t0`` the launch time the geometry is at (the site's plus :attr:`launch_shift`)."""
        out = []
        for s in self.stations:
            k, r, v = len(s.types), s.r - s.SP @ D, s.v - s.SV @ D
            g = s.geometry
            x, acc = np.hstack([r, v]), np.asarray(s.a, dtype=float)
            h1 = g._evaluate(s.t, x, acc, g._parameters(1e-3 * dt_ms, np.zeros(3)), False, jacobian=False)[0][:, :k]
            d = h1 - g._evaluate(s.t, x, acc, g._parameters(0.0, np.zeros(3)), False, jacobian=False)[0][:, :k]
            if "azimuth" in s.types:
                d[:, 1] = wrap_angle(d[:, 1])
            out.append(d - self._launch_time_column(s, D) * dt_ms)
        return self._stacked(out)

    def at_launch_shift(self, shift: float) -> RadarRegression:
        """This regression with the stations' geometry at the launch time ``site.t0 + shift`` (s): the rows
        then carry a launch-time correction ``shift`` exactly, and :data:`LAUNCH_TIME` estimates the rest.
        The site, the rows' selection (keyhole, angles over the top) and the columns' order are kept."""
        out = copy.copy(self)
        at = dataclasses.replace(self.site, t0=self.site.t0 + shift)
        out.stations = [dataclasses.replace(s, geometry=RadarGeometry(at, s.meas.station)) for s in self.stations]
        out.launch_shift = float(shift)
        return out

    def _stacked(self, per_station: Sequence[np.ndarray]) -> np.ndarray:
        """Per station ``(N, k)`` values -> the stacked rows' (m,), station by station, type by type; the
        keyhole's azimuth rows 0 (as :meth:`assemble`'s zero rows)."""
        out = np.zeros(sum(s.t.size * len(s.types) for s in self.stations))
        k0 = 0
        for s, C in zip(self.stations, per_station):
            for j in range(len(s.types)):
                if not (s.types[j] == "azimuth" and s.keyhole is not None):
                    out[k0:k0 + s.t.size] = C[:, j]
                else:
                    out[k0:k0 + s.t.size] = np.where(s.keyhole, 0.0, C[:, j])  # the keyhole's zero rows
                k0 += s.t.size
        return out

    def given_sigmas(self) -> dict[tuple[str, str], float]:
        """Noise std given in the station files, SI, per group."""
        out = {}
        for s in self.stations:
            for ty in s.types:
                if ty in s.meas.station.sigma:
                    out[(s.meas.station.name, ty)] = float(s.meas.station.sigma[ty])
        return out

    def solve(self, sigma: dict | None = None, *, iterations: int = 60, tol: float = 1e-3):
        """Gauss-Newton on the linearisation point, the group noise std and ``T`` re-set between passes.

        Each pass holds the group std and the geometry of the station-term columns ``T`` (and of
        ``dt_launch``) at the pass's starting point, so that it minimises one function of D,
        ``F(D) = min_theta |W (z - h(D) - T theta)|^2``, whose Jacobian ``A = dh/dD`` is exact:
        the Gauss-Newton step of the joint problem is then a descent direction and is halved
        until F does not grow (a backtracking line search), so F falls monotonically and the pass
        converges also where h is far from linear (a flight through a station's zenith, where the
        azimuth's position sensitivity is ``range cos E``). A pass ends when the full step is
        below `tol` std; the next re-estimates the std and (in the first :data:`T_PASSES` passes)
        ``T`` there; the fit is settled when a
        pass's first full step is already below :data:`PASS_TOL` (0.05 std: re-setting the std and
        the station columns' geometry moves D by a negligible part of its std; this outer
        fixed-point iteration converges only linearly near the zenith).

        Parameters
        ----------
        sigma : dict, optional
            ``{(station, type): std}`` SI, known std (also read from the station files); the
            others are estimated (:func:`estimate_group_sigmas`).
        iterations : int
            At most this many Gauss-Newton steps over all passes. Not converged: a
            :class:`RadarConvergenceWarning`, and the returned ``converged`` false with the
            numbers in ``convergence_message``.
        tol : float
            Stop when the change of D is below `tol` times its least-squares std (Gauss-Newton
            converges quadratically away from the zenith: 2.8, 0.76, 2.4e-4 std on the test flight).

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
        # an estimated std is floored at the rounding level of its group's measurements (the noise-free rule):
        # on noise-free data the steps and the convergence test are then measured against that level, not zero
        scale = self.group_scales()
        floor = rounding_level(scale)
        D0 = np.zeros(self.nD)
        history: list[float] = []
        settled, why, step = False, "", math.inf
        T_at, passes = D0, 0
        while len(history) < iterations and not why:
            T_at = D0 if passes < T_PASSES else T_at  # then held: F is one function of D from there on
            passes += 1
            S, y, _ = self.assemble(D0, tracking_at=T_at)
            sig = estimate_group_sigmas(S, y, rows, sig, fixed, floor=floor)[0]
            D0, steps, why = self._gauss_newton_pass(D0, T_at, sig, tol, iterations - len(history))
            history += steps
            step = steps[-1] if steps else step
            if len(steps) == 1 and steps[0] < PASS_TOL:  # re-setting the std and T here moves D by < 0.05 std
                settled = True
                break
        msg = ""
        if not settled:
            why = why or f"not settled in {iterations} Gauss-Newton steps"
            msg = (f"radar separation: the linearisation did not converge: {why} (last step {step:.3g} std, "
                   f"steps taken {', '.join(f'{h:.3g}' for h in history)}): the telemetered trajectory is far from "
                   "the measured one, or a station, the launch site or the launch time is wrong; the estimate is "
                   "that of the last linearisation and is not to be used")
            warnings.warn(msg, RadarConvergenceWarning, stacklevel=2)
        S, y, t = self.assemble(D0, tracking_at=T_at)
        if not fixed.all() and all(is_rounding_level(sig[g], scale[g]) for g in np.flatnonzero(~fixed)):
            warnings.warn("radar residuals at the rounding level: the noise std are floored at the rounding of the "
                          "measurements (a noise-free simulation?); give the noise in the station files",
                          NoiseFreeWarning, stacklevel=2)
        return LinearisedRadar(self, S, y, t, sig, fixed, D0, history, group_reductions(S, y, rows), settled, msg)

    def _gauss_newton_pass(self, D0: np.ndarray, T_at: np.ndarray, sig: np.ndarray, tol: float,
                           budget: int) -> tuple[np.ndarray, list[float], str]:
        """Damped Gauss-Newton steps on ``F(D)`` with the std `sig` and ``T`` held at `T_at`: ``(D, steps, why)``.

        ``steps`` are the steps taken in std of D (the last one below `tol` when the pass ended
        there); ``why`` says why a pass stopped without converging (no step lowers F), else "".
        """
        rows = self.group_rows()
        w = np.ones(self.group_rows(all_rows=True)[-1][-1] + 1)  # the keyhole's zero rows keep 1
        for g, r in enumerate(rows):
            w[r] = 1.0 / sig[g]
        steps: list[float] = []
        S, y, _ = self.assemble(D0, tracking_at=T_at)
        for _ in range(budget):
            _, x, std = estimate_group_sigmas(S, y, rows, sig, np.ones(len(rows), dtype=bool), floor=sig)
            dD = x[:self.nD] - D0
            with np.errstate(invalid="ignore", divide="ignore"):
                step = float(np.nanmax(np.where(std[:self.nD] > 0, np.abs(dD) / std[:self.nD], 0.0)))
            if step < tol:  # the full step is below tol std: a stationary point of this pass's F
                steps.append(step)
                return x[:self.nD], steps, ""
            f0, alpha = self._profile_cost(S, y, D0, w), 1.0
            # backtracking: halve until F does not grow. A full step below SMALL_STEP std changes F by about its
            # square (<= 0.01 chi-square, far inside F's own spread), where F's rounding can defeat the comparison:
            # it is taken as it is (Gauss-Newton's last, quadratically converging steps)
            while step >= SMALL_STEP and alpha >= 2.0**-30:
                Dt = D0 + alpha * dD
                St, yt, _ = self.assemble(Dt, tracking_at=T_at)
                if self._profile_cost(St, yt, Dt, w) <= f0 * (1.0 + 1e-12):
                    break
                alpha *= 0.5
            if step < SMALL_STEP:
                Dt = D0 + dD
                St, yt, _ = self.assemble(Dt, tracking_at=T_at)
            elif alpha < 2.0**-30:
                steps.append(step)
                return D0, steps, ("no step along the Gauss-Newton direction lowers the weighted residual sum "
                                   f"({f0:.6g})")
            steps.append(alpha * step)
            D0, S, y = Dt, St, yt
        return D0, steps, ""

    def _profile_cost(self, S: np.ndarray, y: np.ndarray, D: np.ndarray, w: np.ndarray) -> float:
        """Weighted residual sum at D with the station terms profiled out (``S, y = assemble(D)``).

        ``F(D) = min_theta |W (z - h(D) - T theta)|^2`` and ``z - h(D) = y - A D`` (:meth:`assemble`).
        """
        r = (y - S[:, :self.nD] @ D) * w
        Q, _ = np.linalg.qr(S[:, self.nD:] * w[:, None])  # the projection on T's columns, none truncated
        return float(np.sum((r - Q @ (Q.T @ r)) ** 2))
