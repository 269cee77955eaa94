"""Late start: a flight whose telemetry begins after lift-off.

The model puts dv(t0) = 0 and phi(t0) = 0 at the first telemetry sample; a flight cut after
lift-off breaks that unless the model has the initial terms dv0 and phi0.
:func:`late_start_evidence` looks for it (the telemetry speed at the first sample, and dv
extrapolated back to the first sample); :func:`warn_late_start` warns
(:class:`~casep.io.flight.LateStartWarning`) when the model lacks the terms.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

from casep.checks.plausibility import setup_problems
from casep.exceptions import SetupWarning
from casep.frames import OMEGA_EARTH
from casep.gravity import WGS84_A
from casep.io.flight import FlightData, LateStartWarning

__all__ = ["late_start_evidence", "warn_late_start", "START_WINDOW_S", "START_DEGREE", "START_MIN_SAMPLES",
           "START_CHI2", "START_DV_FLOOR", "PAD_SPEED", "INITIAL_TERMS", "EARTH_ROTATION_SPEED",
           "frame_unknown_message"]

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


#: The largest speed the Earth's rotation gives a point at rest on the surface in an inertial frame, m/s
#: (``omega_E a``, the equator at sea level, 465.1 m/s; 1 % more for the pad's height).
EARTH_ROTATION_SPEED = 1.01 * OMEGA_EARTH * WGS84_A


def frame_unknown_message(source: str, speed: float) -> str:
    """What a first-sample speed within :data:`EARTH_ROTATION_SPEED` means when no header names the telemetry's
    frame: the pad carried by the Earth's rotation in casep's launch-inertial frame (``casep navigate``'s
    telemetry, whose ``#`` lines name the frame and the site), or a flight that started after lift-off."""
    lat = math.degrees(math.acos(min(1.0, speed / (OMEGA_EARTH * WGS84_A))))
    return (f"{source}: the telemetry speed at the first sample is {speed:.4g} m/s and no header names its frame: "
            f"in casep's launch-inertial frame (casep navigate's telemetry) a pad at rest moves with the Earth's "
            f"rotation, {OMEGA_EARTH * WGS84_A:.4g} cos(lat) m/s, and {speed:.4g} m/s is that of a pad at about "
            f"latitude +-{lat:.3g} deg; or the flight started after lift-off. The frame is unknown, so casep cannot "
            f"tell (nor take the gravitation at the launch site). Missing: the header casep navigate writes (`# casep "
            f"navigate ...: strapdown telemetry, launch-inertial frame` and `# launch site LAT LON H azimuth AZ deg, "
            f"launch time T0 s`). Use: the telemetry with its header as casep navigate wrote it (or those two lines "
            f"put back), or Earth-fixed tracking (--tracking-frame ecef or geodetic with --launch-site and "
            f"--launch-time), which measures the speed relative to the pad")


#: Initial terms a late start needs: (model.numeric key, what it is, the platform models that add it, the strapdown
#: models that add it, smallest first; none: no shipped strapdown model has dv0). A model is suggested only when
#: it keeps every coefficient of the model in use (:func:`_models`).
INITIAL_TERMS = (
    ("dv0", "initial velocity error dv0 (dv0x, dv0y, dv0z, m/s)", ("platform36_dv0",), ()),
    ("phi0", "initial platform misalignment phi0 (phi0x, phi0y, phi0z, arcsec)", ("platform39_misalignment",),
     ("strapdown15_phi0", "strapdown42_extended")),
)


def _is_strapdown(flight: FlightData, model: Any) -> bool:
    """Whether the flight is a strapdown one: its model reads the INS attitude, or the flight carries it."""
    from casep.io.strapdown import QUATERNION_COLUMNS

    return any(c in tuple(getattr(model, "signals", ()) or ()) or c in flight.signals for c in QUATERNION_COLUMNS)



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
    observed = np.asarray(flight.observed)  # a mask after FlightData's checks
    if observed[0]:
        run = int(np.argmin(observed)) if not observed.all() else flight.n_samples
        est = _dv_at_start(flight.t[:run], flight.dv[:run])
        if est is not None:
            dv0, sd, window = est
            z = np.divide(dv0, sd, out=np.where(dv0 != 0, np.inf, 0.0), where=sd > 0)
            chi2 = float(np.sum(z**2))
            if chi2 > START_CHI2 and np.linalg.norm(dv0) > START_DV_FLOOR:
                out.update(dv0=dv0, dv0_std=sd, chi2=chi2, window_s=window)
    return out


def _compared(suggested: str, model: Any) -> tuple[list[str], list[str]] | None:
    """The coefficients of `model` the shipped model `suggested` lacks, and those it adds; ([], []) for a model
    without names (nothing to compare); None when `suggested` is not shipped."""
    from casep.model.loader import shipped_model

    names = getattr(model, "names", None)
    if names is None:
        return [], []
    other = shipped_model(suggested)
    if other is None:
        return None
    return [n for n in names if n not in set(other.names)], [n for n in other.names if n not in set(names)]


def _models(missing: Sequence[tuple[str, Sequence[str]]], model: Any) -> str:
    """The models that add the missing initial terms, said: the first shipped one that keeps every coefficient of
    `model` (a model with fewer would trade the terms the data may need for the initial ones); when none does, the
    term added to a copy of `model` (the shipped file showing how); a term no shipped model of the flight's kind has."""
    have, copy, lack = [], [], []
    for term, candidates in missing:
        what = term.split(" (")[0]
        if not candidates:
            lack.append(what)
            continue
        compared = {c: _compared(c, model) for c in candidates}
        keeper = next((c for c, d in compared.items() if d is not None and not d[0]), None)
        if keeper is not None:
            added = (compared[keeper] or ([], []))[1]
            have.append(keeper + (f" (the {len(model.names)} terms of `{model.name}` and {', '.join(added)})"
                                  if getattr(model, "names", None) is not None else ""))
            continue
        first, dropped = candidates[0], (compared[candidates[0]] or ([], []))[0]
        copy.append(f"the {what} ({first}.py in models/ shows how: its declare and set_initial_* lines; --model "
                    f"{first} would drop {len(dropped)} of the {len(getattr(model, 'names', ()))} terms of "
                    f"`{model.name}`: {', '.join(dropped[:6])}{' ...' if len(dropped) > 6 else ''})")
    out = f"--model {' or '.join(dict.fromkeys(have))}" if have else ""
    if copy:
        out += ("; " if out else "") + f"add to a copy of `{model.name}` " + " and ".join(copy)
    if lack:
        out += ("; " if out else "") + f"no shipped model of this kind has the {' and '.join(lack)}: add it to a copy"
    return out


def warn_late_start(flight: FlightData, model: Any) -> dict:
    """Warn (:class:`LateStartWarning`) when the flight starts after lift-off and `model`
    lacks the initial velocity error dv0 or the initial misalignment phi0.

    A first-sample speed within :data:`EARTH_ROTATION_SPEED` in a telemetry whose header does not name its
    frame (``meta["start_frame_unnamed"]``, :func:`casep.io.files.frame_unnamed`) is no late start said as
    one: a :class:`SetupWarning` says the frame is unknown and both readings (:func:`frame_unknown_message`).

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
    speed = ev.get("speed_m_s")
    if speed is not None and flight.meta.get("start_frame_unnamed") and speed <= EARTH_ROTATION_SPEED:
        # the speed may be the pad's in an inertial frame: say what is unknown instead of a late start
        warnings.warn(frame_unknown_message(flight.source, speed), SetupWarning, stacklevel=3)
        return ev
    strapdown = _is_strapdown(flight, model)
    missing = [(term, sd if strapdown else platform) for key, term, platform, sd in INITIAL_TERMS
               if not np.any(model.numeric(key))]
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
    offset = ("the term a(t) dt_trk of models/platform36_timeoffset.py, added to a copy of the strapdown model"
              if strapdown else "--model platform36_timeoffset")
    warnings.warn(LateStartWarning(
        f"{flight.source}: the flight seems to start after lift-off{maybe} (t0 = {flight.t[0]:.6g} s): "
        f"{'; '.join(what)}. Model `{model.name}` has no {' and no '.join(m[0] for m in missing)}: errors "
        f"accumulated before t0 will bias the estimates. Use data from lift-off, or a model with the initial "
        f"terms: {_models(missing, model)} (models/README.md shows how to combine them). "
        f"A tracking time offset also gives dv(t0) != 0 (dv = a(t) dt_trk): `casep separate` (casep.check_fit) "
        f"tests the residuals for one; if it finds one, model the offset instead ({offset})."),
        stacklevel=3)
    return ev

