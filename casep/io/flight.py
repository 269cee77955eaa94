"""Flight data: the :class:`FlightData` type and its error.

A flight is sample times ``t`` (s, strictly increasing, need not be uniform), the platform
specific force ``f`` (N x 3, m/s^2, from telemetry) and the velocity error ``dv`` (N x 3, m/s,
telemetry minus tracking). Files are read and written by :mod:`casep.io.files`.

Telemetry and tracking need not cover the same time: S_V is integrated from the first
telemetry sample (where the model puts dv = 0 and phi = 0), while the regression uses dv
only at the ``observed`` samples, where tracking exists (:meth:`FlightData.observed_rows`).

A flight whose telemetry begins after lift-off breaks the model's dv(t0) = 0, phi(t0) = 0
unless the model has the initial terms dv0 and phi0: :func:`warn_late_start` tests for it.

Set-up checks (:func:`setup_evidence`, recorded by the pair reader for Earth-fixed tracking;
:func:`setup_problems` judges, :func:`warn_setup` warns): the launch site, azimuth, launch time and
time scales the user states tie the tracking to the platform frame, and a mistake in them leaves
a fit that looks fine (a 4000 km site error: sigma 0.1 m/s). Two numbers betray it:

- the telemetry velocity at its first sample against the **pad velocity** of the stated site and
  azimuth. On the pad the platform moves with the Earth: ``v_pad = C^T Rz(theta) (w x r_s)``
  (409 m/s due east in Florida). While the tracking shows the vehicle (nearly) at rest relative to
  the Earth, ``|v_tel(t0) - v_pad|`` must equal that Earth-relative speed: a 0.1 deg azimuth error
  turns v_pad by 0.1 deg (0.71 m/s in Florida), a 10 deg one by 71 m/s;
- the **first tracked position** against the site: the vehicle cannot be further from the pad
  than its speed times the time since launch (a boost speeds up monotonically).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from casep.exceptions import CasepWarning

__all__ = ["FlightData", "FlightDataError", "LateStartWarning", "min_samples", "check_enough_samples",
           "check_dv_not_zero", "late_start_evidence", "warn_late_start", "MAX_ABS_VALUE", "setup_evidence",
           "setup_problems", "warn_setup"]

AXES = ("x", "y", "z")
FORCE_COLUMNS = tuple(f"f_{a}" for a in AXES)
DV_COLUMNS = tuple(f"dv_{a}" for a in AXES)

#: Largest magnitude accepted in any flight column (t, f, W, dv, v_tel, v_trk), SI units.
#: S_V holds products up to third order in f (the [f x] Phi term with Phi ~ int W^2 dt) and
#: least squares squares them: |f|^6 must stay far below the float limit 1.8e308 after
#: sums over samples and time factors. 1e30^6 = 1e180 leaves 1e128 of margin, and no
#: quantity of a boost flight in SI units comes within twenty orders of magnitude of it.
#: Larger values would end in inf or NaN deep inside the computation.
MAX_ABS_VALUE = 1e30

#: Late-start test (:func:`late_start_evidence`): dv is fitted by a polynomial of degree
#: ``START_DEGREE`` over the first ``START_WINDOW_S`` seconds (at least ``START_MIN_SAMPLES``
#: samples) and extrapolated to t0.
START_WINDOW_S = 20.0
START_DEGREE = 3
START_MIN_SAMPLES = 20
#: Chi-square (3 dof) of dv(t0) against its std above which dv(t0) = 0 is rejected. For white
#: noise p = 1e-6 would be 30.7; the correlation correction is approximate (on 150 flights of
#: the paper-ar1 scenario the chi-square averaged 4.2 instead of 3, at most 27.7), so 50 keeps
#: false alarms below about 1e-6 for such noise too. A flight of the paper scenario cut at
#: 20 s gives 600 (20 Hz) to 2800 (100 Hz) with white noise, 40 to 80 with Gauss-Markov noise.
START_CHI2 = 50.0
#: ... and |dv(t0)| must exceed this, m/s: below any tracking noise (>= 0.01 m/s), so that
#: noise-free data, whose quadratic-fit residuals are not noise, never raise a false alarm.
START_DV_FLOOR = 1e-3
#: Telemetry speed at the first sample above which the vehicle is already flying, m/s (about
#: 4 s after lift-off at 0.8 g net acceleration; the launch-inertial frame has the pad at rest).
PAD_SPEED = 30.0


#: Initial terms a late start needs: (model.numeric key, what it is, a model that adds it).
_INITIAL_TERMS = (
    ("dv0", "initial velocity error dv0 (dv0x, dv0y, dv0z, m/s)", "platform36_dv0"),
    ("phi0", "initial platform misalignment phi0 (phi0x, phi0y, phi0z, arcsec)", "platform39_misalignment"),
)


class LateStartWarning(CasepWarning):
    """The flight seems to start after lift-off and the model lacks the initial terms."""


class FlightDataError(ValueError):
    """Bad flight data. Attributes `source`, `column` and `row` locate the problem.

    Parameters
    ----------
    source : str
        File name (or ``"<memory>"``).
    message : str
        What is wrong.
    column : str, optional
        Offending column.
    row : int or str, optional
        1-based data row (after the header), or ``"header"``.
    line : int, optional
        1-based line of the file.
    """

    def __init__(self, source: str, message: str, column: str | None = None,
                 row: int | str | None = None, line: int | None = None) -> None:
        self.source, self.column, self.row, self.line = source, column, row, line
        where = []
        if column is not None:
            where.append(f"column `{column}`")
        if row is not None:
            where.append((f"row {row}" if row != "header" else "header")
                         + (f" (line {line})" if line is not None else ""))
        super().__init__(f"{source}: {', '.join(where) + ': ' if where else ''}{message}")


def _first_bad_row(values: np.ndarray) -> int | None:
    bad = np.flatnonzero(~np.isfinite(values))
    return int(bad[0]) if bad.size else None


def too_large(values: np.ndarray) -> tuple[int, str] | None:
    """First (0-based row, message) of a finite value above :data:`MAX_ABS_VALUE`, or None."""
    big = np.flatnonzero(np.abs(values) > MAX_ABS_VALUE)
    if not big.size:
        return None
    r = int(big[0])
    return r, (f"value {values[r]:g} exceeds the magnitude limit {MAX_ABS_VALUE:g} "
               "(SI units; the computation would overflow)")


def _check_column(src: str, col: str, values: np.ndarray, rows: np.ndarray | None = None) -> None:
    """Finite and within :data:`MAX_ABS_VALUE` (only at `rows`, a boolean mask, when given)."""
    sel = values if rows is None else np.where(rows, values, 0.0)
    r = _first_bad_row(sel)
    if r is not None:
        raise FlightDataError(src, f"value {values[r]:g} is not finite", col, r + 1)
    big = too_large(sel)
    if big is not None:
        raise FlightDataError(src, big[1], col, big[0] + 1)


@dataclass(frozen=True)
class FlightData:
    """One flight: time, specific force and velocity error, validated on creation.

    Parameters
    ----------
    t : (N,) array_like
        Time, s, strictly increasing.
    f : (N, 3) array_like
        Platform specific force, m/s^2 (x downrange, y up, z cross-range).
    dv : (N, 3) array_like
        Velocity error telemetry minus tracking, m/s.
    source : str, optional
        Where the data came from (used in error messages and reports).
    meta : dict, optional
        What the reader recorded (format, columns used, spans, ``start_speed_m_s``).
    observed : (N,) array_like of bool, optional
        Samples where dv is observed (tracking exists); default all. S_V is integrated over
        every sample, the regression uses the observed ones. dv may be NaN elsewhere.
    signals : dict of str -> (N,) array_like, optional
        Other numeric flight columns by name, in the file's unit (``a_*``, ``r_*``, ``v_*``,
        attitude, temperature, ...): what model files read with ``m.signal(name)``. Stored
        as read (NaN allowed); checked when a model uses them (:meth:`model_signals`).
    """

    t: np.ndarray
    f: np.ndarray
    dv: np.ndarray
    source: str = "<memory>"
    meta: dict = field(default_factory=dict, compare=False)
    observed: np.ndarray | None = None
    signals: dict = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        src = self.source
        t = np.array(self.t, dtype=float)
        f = np.array(self.f, dtype=float)
        dv = np.array(self.dv, dtype=float)
        if t.ndim != 1:
            raise FlightDataError(src, f"`t` must be 1-D, got shape {t.shape}", "t")
        obs = self._observed_mask(t.size)
        for name, arr, cols in (("f", f, FORCE_COLUMNS), ("dv", dv, DV_COLUMNS)):
            if arr.shape != (t.size, 3):
                raise FlightDataError(src, f"`{name}` must have shape ({t.size}, 3), got {arr.shape}", name)
            for i, col in enumerate(cols):
                _check_column(src, col, arr[:, i], obs if name == "dv" else None)
        _check_column(src, "t", t)
        step = np.flatnonzero(np.diff(t) <= 0)
        if step.size:
            k = int(step[0]) + 1
            raise FlightDataError(src, f"time {t[k]:.10g} s does not increase (previous row: {t[k - 1]:.10g} s)",
                                  "t", k + 1)
        for name, arr in (("t", t), ("f", f), ("dv", dv), ("observed", obs)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "signals", self._checked_signals(t.size))

    def _checked_signals(self, n: int) -> dict[str, np.ndarray]:
        if not isinstance(self.signals, dict):
            raise FlightDataError(self.source, f"`signals` must be a dict of column name -> array, got "
                                               f"{type(self.signals).__name__}", "signals")
        out = {}
        for name, values in self.signals.items():
            arr = np.array(values, dtype=float)
            if not isinstance(name, str) or arr.shape != (n,):
                raise FlightDataError(self.source, f"signal must be a named array of shape ({n},), got "
                                                   f"{arr.shape}", str(name))
            arr.setflags(write=False)
            out[name] = arr
        return out

    def model_signals(self, names: tuple[str, ...], model: str) -> dict[str, np.ndarray]:
        """The columns `names` that model `model` uses, checked: present and finite.

        Raises
        ------
        FlightDataError
            Naming the file, the model and the column that is missing, or the first row where
            a column is not finite.
        """
        out = {}
        for c in names:
            if c not in self.signals:
                have = ", ".join(self.signals) or "none"
                raise FlightDataError(self.source, f"missing column that model `{model}` needs (the flight's "
                                                   f"extra columns: {have})", c)
            values = self.signals[c]
            r = _first_bad_row(values)
            if r is not None:
                raise FlightDataError(self.source, f"value {values[r]:g} is not finite (a signal that model "
                                                   f"`{model}` uses)", c, r + 1)
            out[c] = values
        return out

    def _observed_mask(self, n: int) -> np.ndarray:
        if self.observed is None:
            return np.ones(n, dtype=bool)
        obs = np.array(self.observed)
        if obs.dtype != bool or obs.shape != (n,):
            raise FlightDataError(self.source, f"`observed` must be a boolean array of shape ({n},), got "
                                               f"{obs.dtype} of shape {obs.shape}", "observed")
        if n and not obs.any():
            raise FlightDataError(self.source, "no sample is observed (tracking covers none)", "observed")
        return obs

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(self.t.size)

    @property
    def n_observed(self) -> int:
        """Number of samples where dv is observed."""
        return int(np.count_nonzero(self.observed))

    def _observed_index(self) -> slice | np.ndarray:
        """The observed rows: a slice when they are contiguous (numpy views, no copy)."""
        idx = np.flatnonzero(self.observed)
        if idx.size and idx[-1] - idx[0] + 1 == idx.size:
            return slice(int(idx[0]), int(idx[-1]) + 1)
        return idx

    def observed_rows(self, S: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(S[obs], dv[obs], t[obs])``: the regression rows of an S_V built on all samples.

        Parameters
        ----------
        S : (N, 3, n) ndarray
            S_V integrated over every sample (from the first telemetry sample).
        """
        S = np.asarray(S)
        if S.shape[:1] != (self.n_samples,):
            raise ValueError(f"`S` must have {self.n_samples} samples, got shape {S.shape}")
        k = self._observed_index()
        return S[k], self.dv[k], self.t[k]


def min_samples(n_coefficients: int) -> int:
    """Fewest samples that leave one degree of freedom for the noise estimate.

    The first sample carries no information (S_V(t0) = 0 for a model without initial
    terms), so 3 (N - 1) > n is needed: N >= n // 3 + 2.
    """
    return n_coefficients // 3 + 2


def check_enough_samples(flight: FlightData, n_coefficients: int, model_name: str) -> None:
    """Raise :class:`FlightDataError` when `flight` has too few observed samples for a model."""
    need = min_samples(n_coefficients)
    n = flight.n_observed
    if n < need:
        part = "" if n == flight.n_samples else f" observed (tracking covers {n} of {flight.n_samples})"
        raise FlightDataError(
            flight.source,
            f"{n} samples{part} are too few for model `{model_name}` with "
            f"{n_coefficients} coefficients: need at least {need}",
            "t", int(np.flatnonzero(flight.observed)[-1]) + 1 if n else flight.n_samples,
        )


def _dv_columns(flight: FlightData) -> str:
    return "v_tel_* - v_trk_*" if str(flight.meta.get("dv", "dv")).startswith("v_tel") else ", ".join(DV_COLUMNS)


def check_dv_not_zero(flight: FlightData) -> None:
    """Refuse a flight whose velocity error is exactly zero at every observed sample.

    Such a dv carries no information (no error and no tracking noise): the fit would report
    sigma 0 and std 0. It is nearly always an unfilled column or telemetry compared with
    itself. One rule for ``separate`` and ``diagnose``.
    """
    dv = flight.dv[flight._observed_index()]
    if not np.any(dv):
        raise FlightDataError(flight.source, f"the velocity error (columns {_dv_columns(flight)}) is exactly 0 at "
                                             f"all {dv.shape[0]} observed samples: nothing to estimate (an unfilled "
                                             "column, or telemetry compared with itself?)")


def _dv_at_start(t: np.ndarray, dv: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
    """dv(t0) from a cubic fit over the first seconds, its std, and the window length (s).

    For noise with lag-1 correlation rho (from the residuals; AR(1)-like tracking noise) the
    m samples are worth n_eff = m (1 - rho) / (1 + rho) independent ones: the least-squares
    variance of c0 is multiplied by m / n_eff, and the residual sum of squares is divided by
    m - p m / n_eff (p = degree + 1), since a fit absorbs slow noise. None when n_eff is too
    small for the test (dof below m / 4).
    """
    m = max(int(np.searchsorted(t, t[0] + START_WINDOW_S, side="right")), START_MIN_SAMPLES)
    m = min(m, t.size)
    if m < START_MIN_SAMPLES:
        return None
    x = (t[:m] - t[0]) / (t[m - 1] - t[0])
    A = np.vander(x, START_DEGREE + 1, increasing=True)  # dv ~ c0 + c1 x + ..., c0 = dv(t0)
    coef, *_ = np.linalg.lstsq(A, dv[:m], rcond=None)
    r = dv[:m] - A @ coef
    rss = np.sum(r**2, axis=0)
    rho = np.divide(np.sum(r[1:] * r[:-1], axis=0), rss, out=np.zeros(3), where=rss > 0)
    infl = (1 + np.clip(rho, 0.0, 0.999)) / (1 - np.clip(rho, 0.0, 0.999))  # m / n_eff
    dof = m - A.shape[1] * infl  # E[RSS] ~ s^2 (m - p m / n_eff): the fit absorbs slow noise
    if np.any(dof < m / 4):
        return None  # too few independent samples in the window to judge dv(t0)
    var0 = rss / dof * np.linalg.inv(A.T @ A)[0, 0] * infl  # Var(c0) ~ s^2 [(A^T A)^-1]_00 m / n_eff
    return coef[0], np.sqrt(var0), float(t[m - 1] - t[0])


def late_start_evidence(flight: FlightData) -> dict:
    """Evidence that the flight's data begin after lift-off; empty when there is none.

    Two tests, each with its numbers in the returned dict:

    - ``speed_m_s``: the telemetry speed at the first sample (``meta["start_speed_m_s"]``,
      recorded by the readers when velocity columns exist) exceeds :data:`PAD_SPEED`;
    - ``dv0`` (with ``dv0_std``, ``chi2``, ``window_s``): when dv is observed from the first
      sample, dv extrapolated to t0 is not 0 (chi-square > :data:`START_CHI2` and
      ``|dv0| >`` :data:`START_DV_FLOOR`), whereas S_V(t0) = 0 makes the model predict 0.

    The specific force is not used: the simulator's and many real flights start at full
    thrust (hold-down), so no single "pad value" separates a pad start from a late one.
    """
    out: dict = {}
    speed = flight.meta.get("start_speed_m_s")
    if speed is not None and speed > PAD_SPEED:
        out["speed_m_s"] = float(speed)
    if flight.observed[0]:
        run = np.argmin(flight.observed) if not flight.observed.all() else flight.n_samples
        est = _dv_at_start(flight.t[:run], flight.dv[:run])
        if est is not None:
            dv0, sd, window = est
            z = np.divide(dv0, sd, out=np.where(dv0 != 0, np.inf, 0.0), where=sd > 0)
            chi2 = float(np.sum(z**2))
            if chi2 > START_CHI2 and np.linalg.norm(dv0) > START_DV_FLOOR:
                out.update(dv0=dv0, dv0_std=sd, chi2=chi2, window_s=window)
    return out


def warn_late_start(flight: FlightData, model) -> dict:
    """Warn (:class:`LateStartWarning`) when the flight starts after lift-off and `model`
    lacks the initial velocity error dv0 or the initial misalignment phi0.

    Parameters
    ----------
    flight : FlightData
    model : ErrorModel
        Set up; its ``numeric("dv0")`` and ``numeric("phi0")`` Jacobians show which initial
        terms it has.

    Returns
    -------
    dict
        The evidence (:func:`late_start_evidence`); empty when there is none.
    """
    ev = late_start_evidence(flight)
    missing = [(term, use) for key, term, use in _INITIAL_TERMS if not np.any(model.numeric(key))]
    if not ev or not missing or setup_problems(flight):  # a failed set-up check explains dv(t0): said there
        return ev
    if "speed_m_s" not in ev and np.size(model.numeric("velocity_columns")):
        return ev  # dv(t0) != 0 at lift-off is what a direct velocity term (a time offset: a(t0) dt) gives
    what = []
    if "speed_m_s" in ev:
        what.append(f"the telemetry speed at the first sample is {ev['speed_m_s']:.4g} m/s (> {PAD_SPEED:g} m/s)")
    if "dv0" in ev:
        vec = ", ".join(f"{v:.4g}" for v in ev["dv0"])
        sd = ", ".join(f"{v:.2g}" for v in ev["dv0_std"])
        what.append(f"dv at the first sample, extrapolated from the first {ev['window_s']:.3g} s, is ({vec}) m/s "
                    f"+- ({sd}) (chi-square {ev['chi2']:.3g}, 3 dof), where the model has dv(t0) = 0")
    # dv(t0) != 0 alone with dv0 in the model: an initial velocity error at lift-off looks the same.
    maybe = (" (or it starts at lift-off with an initial velocity error, which the model's dv0 terms take; "
             "then ignore this)" if "speed_m_s" not in ev and np.any(model.numeric("dv0")) else "")
    warnings.warn(LateStartWarning(
        f"{flight.source}: the flight seems to start after lift-off{maybe} (t0 = {flight.t[0]:.6g} s): "
        f"{'; '.join(what)}. Model `{model.name}` has no {' and no '.join(m[0] for m in missing)}: errors "
        f"accumulated before t0 will bias the estimates. Use data from lift-off, or a model with the initial "
        f"terms: --model {' or '.join(m[1] for m in missing)} (models/README.md shows how to combine them). "
        f"A tracking time offset also gives dv(t0) != 0 (dv = a(t) dt_trk): `casep separate` (casep.check_fit) "
        f"tests the residuals for one; if it finds one, model the offset instead (platform36_timeoffset)."),
        stacklevel=3)
    return ev


# ------------------------------------------------------------------------------ set-up checks
#: ``| |v_tel(t0) - v_pad| - s_trk |`` above this (m/s), or 5 std of the tracking's Earth-relative speed
#: ``s_trk`` if larger: the stated site, azimuth or launch time does not match the telemetry. An INS
#: aligned on the pad starts within mm/s of v_pad; 0.2 m/s is a 0.03 deg azimuth error in Florida.
PAD_VELOCITY_TOL = 0.2
#: Tracking Earth-relative speed below which the vehicle is taken to be on (or just leaving) the pad, m/s.
PAD_REST_SPEED = 30.0
#: Seconds of tracking after the first telemetry sample used to estimate its Earth-relative velocity there.
PAD_FIT_WINDOW = 2.0
#: First tracked position farther from the site than (time since launch x speed) + this, m: wrong site.
POSITION_TOL = 2000.0
#: First telemetry sample this far (s) from the stated launch time: the time scales or the launch time are off.
LAUNCH_GAP_TOL = 60.0


def _velocity_at(t: np.ndarray, v: np.ndarray, t0: float) -> tuple[np.ndarray, float] | None:
    """Earth-relative tracking velocity at `t0` from a straight-line fit over :data:`PAD_FIT_WINDOW` s of
    samples from `t0` on, and the std of one component; None when the tracking does not cover `t0`."""
    period = float(np.median(np.diff(t))) if t.size > 1 else np.inf
    if not (t[0] <= t0 + period and t[-1] >= t0):
        return None
    use = (t >= t0 - period) & (t <= t0 + max(PAD_FIT_WINDOW, 4 * period))
    if use.sum() < 4:
        return None
    A = np.column_stack([np.ones(use.sum()), t[use] - t0])  # v ~ c0 + c1 (t - t0): c0 = v(t0)
    coef, *_ = np.linalg.lstsq(A, v[use], rcond=None)
    r = v[use] - A @ coef
    s2 = float(np.sum(r**2) / max(3 * (use.sum() - 2), 1))
    return coef[0], float(np.sqrt(s2 * np.linalg.inv(A.T @ A)[0, 0]))


def setup_evidence(site, t_tel: np.ndarray, v_tel: np.ndarray, t_trk: np.ndarray, r_ecef: np.ndarray,
                   v_ecef: np.ndarray, *, time_shift: float = 0.0) -> dict:
    """The numbers of the set-up checks of an Earth-fixed telemetry + tracking pair (module notes).

    Parameters
    ----------
    site : casep.frames.LaunchSite
        As stated by the user (launch time in the tracking time scale).
    t_tel, v_tel : (N,), (N, 3) arrays
        Telemetry times (telemetry time scale) and launch-inertial velocity, s and m/s.
    t_trk, r_ecef, v_ecef : (M,), (M, 3), (M, 3) arrays
        Tracking times (tracking time scale), ECEF position and Earth-relative velocity, s, m, m/s.
    time_shift : float
        Tracking time minus telemetry time, s.

    Returns
    -------
    dict
        ``spans`` (telemetry and tracking, both time scales), ``pad`` (pad velocity, the telemetry's,
        their difference, the tracking's Earth-relative speed at the first telemetry sample and its
        std, the rotation about the vertical and the speed ratio between v_tel and v_pad),
        ``first_tracked`` (time since launch, distance from the site, reach), and ``problems``: the
        messages of the checks that fail (empty when all pass).
    """
    from casep.frames import ecef_to_launch

    t_tel, v_tel, t_trk = (np.asarray(a, dtype=float) for a in (t_tel, v_tel, t_trk))
    r_ecef, v_ecef = np.asarray(r_ecef, dtype=float), np.asarray(v_ecef, dtype=float)
    t_start = float(t_tel[0] + time_shift)  # the first telemetry sample in the tracking time scale
    v_pad = ecef_to_launch(site, [t_start], [site.r_site], [[0.0, 0.0, 0.0]])[1][0]
    e = v_tel[0] - v_pad
    fit = _velocity_at(t_trk, v_ecef, t_start)
    s_trk, s_std = (float(np.linalg.norm(fit[0])), fit[1]) if fit is not None else (None, None)
    # horizontal (x, z) parts in launch axes: the turn of v_tel(t0) from v_pad about the vertical y
    h_tel, h_pad = v_tel[0][[0, 2]], v_pad[[0, 2]]
    turn = float(np.degrees(np.arctan2(h_pad[0] * h_tel[1] - h_pad[1] * h_tel[0], h_pad @ h_tel)))
    pad = {"t_s": t_start, "pad_velocity_m_s": v_pad.tolist(), "telemetry_velocity_m_s": v_tel[0].tolist(),
           "speed_relative_m_s": float(np.linalg.norm(e)), "tracking_speed_m_s": s_trk, "tracking_speed_std_m_s": s_std,
           "turn_about_vertical_deg": turn,
           "speed_ratio": float(np.linalg.norm(v_tel[0]) / np.linalg.norm(v_pad)) if np.any(v_pad) else None}
    since = float(t_trk[0] - site.t0)
    dist = float(np.linalg.norm(r_ecef[0] - site.r_site))
    reach = max(since, 0.0) * float(np.linalg.norm(v_ecef[0]))  # a boost speeds up: mean speed <= current
    first = {"t_s": float(t_trk[0]), "since_launch_s": since, "distance_from_site_m": dist, "reach_m": reach,
             "tolerance_m": POSITION_TOL}
    spans = {"telemetry_s": [float(t_tel[0]), float(t_tel[-1])], "tracking_s": [float(t_trk[0]), float(t_trk[-1])],
             "time_shift_s": float(time_shift), "launch_time_s": float(site.t0),
             "telemetry_start_after_launch_s": t_start - site.t0}
    where = (f"site ({site.lat_deg:.8g} deg, {site.lon_deg:.8g} deg, {site.h_m:.6g} m), azimuth {site.azimuth_deg:.8g} "
             f"deg, launch time {site.t0:.10g} s")
    problems = []
    if dist > reach + POSITION_TOL:
        problems.append(f"the first tracked position (t = {t_trk[0]:.10g} s, {since:.4g} s after the launch time) is "
                        f"{dist / 1e3:.6g} km from the stated launch site, where the vehicle could be at most "
                        f"{reach / 1e3:.4g} km away (its speed then times the time since launch) + "
                        f"{POSITION_TOL / 1e3:g} km: the stated {where} is wrong")
    if s_trk is not None and s_trk < PAD_REST_SPEED:
        tol = max(PAD_VELOCITY_TOL, 5.0 * s_std)
        gap = abs(float(np.linalg.norm(e)) - s_trk)
        pad["tolerance_m_s"] = tol
        if gap > tol:
            hint = ""
            if s_trk < 1.0:
                hint = (f"; v_tel is v_pad turned by {turn:.4g} deg about the vertical"
                        + (f" (azimuth {site.azimuth_deg - turn:.6g} deg, not {site.azimuth_deg:.6g}?)"
                           if abs(turn) > 1e-3 else "")
                        + f", speed ratio {pad['speed_ratio']:.6g}"
                        + (" (a latitude or height error?)" if abs(pad["speed_ratio"] - 1) > 1e-3
                           else ""))
            problems.append(f"at the first telemetry sample (t = {t_tel[0]:.10g} s) the telemetry velocity differs by "
                            f"{np.linalg.norm(e):.4g} m/s from the pad velocity ({np.linalg.norm(v_pad):.6g} m/s) "
                            "of the "
                            f"stated {where}, while the tracking shows the vehicle at {s_trk:.3g} +- {s_std:.2g} m/s "
                            f"relative to the Earth: the two differ by {gap:.4g} m/s (> {tol:.3g} m/s){hint}. The "
                            "launch site, azimuth or launch time does not match the telemetry's frame")
    if abs(t_start - site.t0) > LAUNCH_GAP_TOL:
        problems.append(f"the telemetry starts {t_start - site.t0:.6g} s after the stated launch time "
                        f"{site.t0:.10g} s (tracking time scale; time_shift {time_shift:g} s): more than "
                        f"{LAUNCH_GAP_TOL:g} s. State the "
                        "launch time in the tracking file's time scale and how the time scales relate (time_shift)")
    return {"spans": spans, "pad": pad, "first_tracked": first, "problems": problems}


def setup_problems(flight: FlightData) -> list[str]:
    """The failed set-up checks of a flight (``meta["setup"]["problems"]``, :func:`setup_evidence`)."""
    ev = flight.meta.get("setup") if isinstance(flight.meta, dict) else None
    return list(ev.get("problems", [])) if isinstance(ev, dict) else []


def warn_setup(flight: FlightData) -> list[str]:
    """Warn (:class:`~casep.exceptions.SetupWarning`) once per failed set-up check; returns their messages."""
    from casep.exceptions import SetupWarning

    problems = setup_problems(flight)
    for msg in problems:
        warnings.warn(SetupWarning(f"{flight.source}: set-up check failed: {msg}."), stacklevel=3)
    return problems
