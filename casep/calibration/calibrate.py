"""The regression of a ground test and :func:`calibrate`.

Rows. Each sensor triad (accelerometer, gyro) is its own regression ``y = S D + e`` over the
coefficients of its output, solved by the registered estimators (:mod:`casep.estimators`, on a
:class:`casep.Problem`), so the noise level, the std, outlier handling and the collinearity
diagnostics are those of a flight. With readings ``u`` and the model's reading
``u = y0(f, omega) + J(f, omega) D``:

- static segment k (specific force ``f_k = g e_k``, rate ``omega_k``): one row per axis, the segment
  mean ``mean(u) - y0(f_k, omega_k) = J(f_k, omega_k) D`` (``weighting="samples"``: one row per
  sample and axis);
- rotation segment k (gyro only; by angle ``theta`` about axis ``a`` along gravity, over ``T_k =
  sum_i dt_i``, ``dt_i = t_{i+1} - t_i`` the recorded steps, the last 1 / rate): the integral
  ``int u dt = sum_i u_i dt_i`` (evenly sampled: imucal's sum / rate). The reading is affine in omega
  (checked by the model's setup), so
  ``int u dt = T_k y0(f_k, 0) + [y0(f_k, Theta) - y0(f_k, 0)] + (T_k J(f_k, 0) + [J(f_k, Theta) -
  J(f_k, 0)]) D`` exactly, ``Theta = theta a`` in rad, whatever the rate profile of the turn.

Weighting. A hand-held or fixture position is never exactly the nominal one: its error is shared by
every sample of the segment, so the means misfit the model far above the sample noise (imucal's
session: up to 25 raw units against 0.2). ``positions`` (default): the static means whitened by the
covariance a tilt ``phi ~ N(0, tilt^2 I)`` of the position gives,
``V_k = tilt^2 g^2 J_f P_k J_f^T + g^2 tilt^4 (J_f e)(J_f e)^T + diag(s_i^2 / n_k)`` with
``J_f = dy/df`` (the model's, at an equal-weight first estimate) and ``P_k = I - e e^T`` (a tilt
moves the readings across gravity, not along it), the turns by their white-noise std
``s_i sqrt(n_k) / rate`` (``s_i``: pooled within-segment sample std of axis i); ``tilt`` is where the
whitened least-squares residual std is 1, estimated on the accelerometer and used for the gyro. A tilted
position senses on average ``g cos|phi x e| ~ g (1 - tilt^2)`` along e (``E |phi x e|^2 / 2 = tilt^2``):
the static rows are taken at ``f_k = g (1 - tilt^2) e_k`` (tilt and rows by a few fixed-point steps).
``segments``: the means with equal weight and the noise level from their misfit (the turns scaled to
that level); ``samples``: every static sample a row, the white-noise GLS (exact positions only).
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from casep.calibration.model import CalibrationModel
from casep.calibration.session import ACC_UNITS, GYR_UNITS, RAW_UNIT, Segment, Session
from casep.exceptions import CasepWarning
from casep.units import G0

__all__ = ["Calibration", "calibrate", "load_calibration_model", "calibration_models",
           "calibration_model_dirs", "calibrate_files", "RotationSignWarning", "PositionMisfitWarning",
           "TimeGapWarning", "WEIGHTINGS", "ACC_UNITS", "GYR_UNITS"]

#: Row weighting of the static segments (module notes).
WEIGHTINGS = ("positions", "segments", "samples")
#: A static segment's |mean specific force| may differ from gravity by this fraction (physical units).
GRAVITY_TOLERANCE = 0.10
_SENSOR = {"accel_reading": "accelerometer", "gyro_reading": "gyro"}
#: Methods whose noise model runs along time (AR(1), MA): meaningless on segment rows.
TIME_SERIES_METHODS = ("gls", "rels")
#: A studentized segment misfit above this is warned about.
MISFIT_Z = 4.0


class RotationSignWarning(CasepWarning):
    """A rotation's gyro reading has the opposite sign of the expected angle (segment and numbers)."""


class PositionMisfitWarning(CasepWarning):
    """A static segment misfits the model far more than the others (segment and numbers)."""


class TimeGapWarning(CasepWarning):
    """Samples are missing inside a turn (segment, gaps, samples missing): integrated over the recorded times."""


# ------------------------------------------------------------------ models
def calibration_model_dirs() -> list[Path]:
    """Folders searched for a calibration model by name: ``calibration/`` under each model folder."""
    from casep.model.loader import model_dirs

    return [d / "calibration" for d in model_dirs() if (d / "calibration").is_dir()]


def calibration_models() -> list[str]:
    """Names of the calibration models found (``ferraris``, ``platform36_ground``, ...)."""
    seen: list[str] = []
    for d in calibration_model_dirs():
        for p in sorted(d.glob("*.py")):
            if not p.name.startswith("_") and p.stem not in seen:
                seen.append(p.stem)
    return seen


def load_calibration_model(model: str | os.PathLike | CalibrationModel) -> CalibrationModel:
    """A calibration model by name (``models/calibration/NAME.py``), path or object, set up.

    Model files are loaded as the flight models' (:mod:`casep.model.loader`: one ``build()``,
    errors of one line naming the file and the line).
    """
    from casep.model._model import ModelDefinitionError
    from casep.model.loader import ModelFileError, _where

    if isinstance(model, CalibrationModel):
        return model.setup()
    text = os.fspath(model)
    if text.endswith(".py") or os.sep in text:
        path = Path(text)
        if not path.is_file():
            raise ValueError(f"model file `{text}` does not exist")
    else:
        found = next((d / f"{text}.py" for d in calibration_model_dirs() if (d / f"{text}.py").is_file()), None)
        if found is None:
            raise ValueError(f"unknown calibration model `{text}`. Use one of: {', '.join(calibration_models())}; "
                             "or a path to a .py file whose build() returns a casep.calibration.CalibrationModel")
        path = found
    import importlib.util

    spec = importlib.util.spec_from_file_location(f"casep_calibration_model_{path.stem}", path)
    if spec is None or spec.loader is None:  # as casep.model.loader
        raise ModelFileError(f"model file {path}: cannot be loaded as Python")
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
        built = module.build()
    except ModelFileError:
        raise
    except (Exception, SystemExit) as exc:  # one line naming the file and line
        raise ModelFileError(f"{_where(path, exc)}: {type(exc).__name__}: {exc}") from exc
    if not isinstance(built, CalibrationModel):
        raise ModelFileError(f"model file {path}: build() returned {type(built).__name__}, not "
                             "casep.calibration.CalibrationModel (a flight model is used by casep separate)")
    try:
        return built.setup()
    except ModelDefinitionError as exc:
        raise ModelFileError(f"model file {path}: {exc}") from exc


# ------------------------------------------------------------------ result
@dataclass
class Calibration:
    """The outcome of :func:`calibrate`.

    Attributes
    ----------
    result : EstimateResult
        Every coefficient in model order: estimate, std, covariance (block diagonal: the two
        sensors are independent regressions), natural units; ``sigma`` NaN (each sensor has its
        own, :attr:`sensors`).
    sensors : dict
        ``"accelerometer"`` / ``"gyro"`` -> that regression's EstimateResult (its sigma in the
        reading unit, its diagnostics).
    segments : list of dict
        Per segment: name, kind, rows, samples, and per sensor the misfit of the segment's row
        (reading units), the noise std of that row from the sample scatter, their ratio.
    model : CalibrationModel
    settings : dict
    """

    result: Any
    sensors: dict
    segments: list
    model: CalibrationModel
    settings: dict = field(default_factory=dict)

    @property
    def names(self) -> tuple[str, ...]:
        return self.result.names

    def value(self, name: str) -> float:
        return float(self.result.estimate[self.model.index(name)])

    def std(self, name: str) -> float:
        return float(self.result.std[self.model.index(name)])

    def to_dict(self) -> dict:
        """The calibration JSON: a casep result (``coefficients``, ``covariance``, ... usable as
        ``--prior``) plus ``calibration`` (model, flight model, per-sensor fits, segments)."""
        d = self.result.to_dict()
        d["calibration"] = {
            "model": self.model.name, "flight_model": self.model.flight_model, "readings": self.model.readings,
            "settings": self.settings,
            "sensors": {k: {"sigma": _f(r.sigma), "sigma_source": r.sigma_source, "status": r.status,
                            "message": r.message, "names": list(r.names), "diagnostics": r.diagnostics}
                        for k, r in self.sensors.items()},
            "segments": self.segments,
        }
        return d

    def report(self) -> str:
        """Readable terminal report: coefficients, per-sensor fit, misfit per segment."""
        from casep.estimators.result import format_number

        lines = [f"{'coefficient':<12} {'unit':<14} {'estimate':>14} {'std':>12}  note"]
        for row in self.result.coefficient_rows():
            lines.append(f"{row['name']:<12} {row['unit']:<14} {format_number(row['estimate'], 14)} "
                         f"{format_number(row['std'])}  {row.get('reason', '')}".rstrip())
        lines.append("")
        s = self.settings
        lines.append(f"model {self.model.name}, method {self.result.method}, weighting {s['weighting']}, "
                     f"g {s['gravity']:.6g} m/s^2, {s['rate_hz']:.6g} Hz, readings {s['acc_unit']} / {s['gyr_unit']}")
        for k, r in self.sensors.items():
            unit = s["acc_unit"] if k == "accelerometer" else s["gyr_unit"]
            cn = r.diagnostics.get("condition_number_equilibrated")
            whitened = s["weighting"] == "positions"
            what = "(rows whitened: 1 = the position and noise model)" if whitened else unit
            lines.append(f"{k}: sigma {r.sigma:.4g} {what} "
                         f"({r.sigma_source}, {r.diagnostics.get('rows', '?')} rows, rank {r.rank}/{len(r.names)})"
                         + (f", condition number {cn:.3g} (equilibrated)" if cn else "") + f"; {r.message}")
            if "position_error_deg" in r.diagnostics and k == "accelerometer":
                dof = r.diagnostics.get("position_error_dof")
                lines.append(f"  position error {r.diagnostics['position_error_deg']:.3g} deg rms (estimated from the "
                             f"misfit of the positions, {dof} degrees of freedom"
                             + ("; few: the std of the coefficients it drives are themselves uncertain)"
                                if dof is not None and dof < 10 else ")"))
            if r.diagnostics.get("groups"):
                lines.append("  near-dependencies: " + "; ".join("[" + ", ".join(g) + "]"
                                                                for g in r.diagnostics["groups"]))
        lines.append("")
        lines.append("misfit per segment (row residual per axis; noise: std of the row from the sample scatter)")
        for seg in self.segments:
            for sensor, m in seg.get("misfit", {}).items():
                res = ", ".join(f"{v:+.4g}" for v in m["residual"])
                noise = ", ".join(f"{v:.3g}" for v in m["noise_std"])
                lines.append(f"  {seg['name']:<8} {seg['kind']:<8} {sensor:<13} residual [{res}]  noise [{noise}]"
                             f"  ratio {m['ratio']:.3g}")
        return "\n".join(lines)


def _f(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


# ------------------------------------------------------------------ rows
def _readings(session: Session, model: CalibrationModel) -> tuple[np.ndarray, np.ndarray, str, str]:
    """Readings as the model wants them, and their units."""
    if model.readings == "raw":
        return session.acc, session.gyr, session.acc_unit, session.gyr_unit
    out = []
    for what, unit, table, arr in (("accelerometer", session.acc_unit, ACC_UNITS, session.acc),
                                   ("gyro", session.gyr_unit, GYR_UNITS, session.gyr)):
        if unit not in table:
            raise ValueError(f"model `{model.name}` reads SI; the session's {what} unit is `{unit}`. Use: "
                             f"--{'acc' if what == 'accelerometer' else 'gyr'}-unit one of {', '.join(table)} "
                             "(or a raw-readings model such as ferraris)")
        out.append(arr * table[unit])
    return out[0], out[1], "m/s^2", "rad/s"


def _noise(segs: Sequence[Segment], u: np.ndarray) -> np.ndarray:
    """Pooled within-segment sample std per axis over the static segments, (3,)."""
    ss, dof = np.zeros(3), 0
    for s in segs:
        x = u[s.rows]
        ss += ((x - x.mean(axis=0)) ** 2).sum(axis=0)
        dof += len(s.rows) - 1
    return np.sqrt(ss / max(dof, 1))


def _steps(seg: Segment, t: np.ndarray, rate: float) -> np.ndarray:
    """The time each sample of a segment stands for, s: the step to the next sample, the last one 1 / rate."""
    return np.append(np.diff(t[seg.rows]), 1.0 / rate)


def _rotation_row(model, slot, seg: Segment, u: np.ndarray, g: float, rate: float, t: np.ndarray):
    """(y, J, T, dt) of a rotation segment: the integral over the turn (module notes)."""
    assert seg.angle_deg is not None and seg.axis is not None  # a rotation segment has both
    f = g * seg.gravity
    theta = np.deg2rad(seg.angle_deg) * seg.axis  # rad
    # int u dt by the rectangle rule on the recorded times: u_i (t_{i+1} - t_i), the last sample 1 / rate
    # (evenly sampled: imucal's sum / rate; samples missing inside the turn do not shorten it)
    dt = _steps(seg, t, rate)
    T = float(dt.sum())
    z = np.zeros(3)
    integral = (u[seg.rows] * dt[:, None]).sum(axis=0)
    y0 = T * model.known(slot, f, z) + (model.known(slot, f, theta) - model.known(slot, f, z))
    J0 = model.jacobian(slot, f, z)
    J = T * J0 + (model.jacobian(slot, f, theta) - J0)
    return integral - y0, J, T, dt


def _unit_text(model: CalibrationModel, session: Session) -> list[str]:
    """The coefficients' unit text: a raw-readings model's ``a.u.`` is the session's unit of that sensor."""
    units = list(model.units)
    if model.readings != "raw":
        return units
    for slot, unit in (("accel_reading", session.acc_unit), ("gyro_reading", session.gyr_unit)):
        if slot in model.slots and unit != RAW_UNIT:
            for j in model.columns(slot):
                units[j] = units[j].replace(RAW_UNIT, unit)
    return units


def _check_gravity(segs: Sequence[Segment], session: Session, gravity: float) -> None:
    """Refuse readings in a physical unit whose static |mean| is off gravity by more than GRAVITY_TOLERANCE.

    A static accelerometer senses ``|f| = g``; a mean far from it in the declared unit is a unit mistake
    (raw counts declared as m/s^2, g as m/s^2, ...): the units that would give g are named.
    """
    unit = session.acc_unit
    if unit not in ACC_UNITS:
        return  # raw counts: any scale
    for s in segs:
        if s.kind != "static":
            continue
        raw = float(np.linalg.norm(session.acc[s.rows].mean(axis=0)))  # |mean|, declared unit
        m = raw * ACC_UNITS[unit]  # m/s^2
        if abs(m / gravity - 1.0) <= GRAVITY_TOLERANCE:
            continue
        fits = [u for u, k in ACC_UNITS.items() if u != unit and abs(raw * k / gravity - 1.0) <= GRAVITY_TOLERANCE]
        hint = (f"the readings look like {' or '.join(fits)}: --acc-unit {fits[0]}" if fits else
                f"raw counts? Use: --acc-unit {RAW_UNIT} with a raw-readings model (ferraris)")
        si = "" if unit == "m/s^2" else f" = {m:.6g} m/s^2"
        raise ValueError(f"{session.source}: {s.where}: the static accelerometer mean has |f| = {raw:.6g} {unit}"
                         f"{si}, {m / gravity:.4g} x gravity ({gravity:.6g} m/s^2; more than "
                         f"{GRAVITY_TOLERANCE:.0%} off): {hint}")


def _check_gaps(rots: Sequence[Segment], t: np.ndarray, rate: float) -> None:
    """TimeGapWarning for a turn whose time steps exceed 1.5 / rate (samples missing)."""
    for s in rots:
        step = np.diff(t[s.rows])
        gaps = step > 1.5 / rate
        if gaps.any():
            missing = int(np.round(step[gaps] * rate).sum()) - int(gaps.sum())
            warnings.warn(f"{s.where}: {int(gaps.sum())} gap(s) in time inside the turn (largest {step.max():.4g} s "
                          f"against the {1.0 / rate:.4g} s step; about {missing} samples missing): the turn is "
                          "integrated over the recorded times", TimeGapWarning, stacklevel=3)


def _check_positions(segs: Sequence[Segment], acc: np.ndarray, unit: str) -> None:
    """Refuse a static segment whose accelerometer mean points away from its stated gravity.

    The means are centred on their average when the stated directions balance (a Ferraris set),
    so a raw bias does not count; a segment whose centred mean makes more than 45 deg with its
    stated direction is mislabelled (the nearest axis is named).
    """
    st = [s for s in segs if s.kind == "static"]
    if len(st) < 2:
        return
    means = np.array([acc[s.rows].mean(axis=0) for s in st])
    dirs = np.array([s.gravity for s in st])
    centre = means.mean(axis=0) if np.linalg.norm(dirs.sum(axis=0)) < 1e-9 else np.zeros(3)
    for s, m, e in zip(st, means, dirs):
        v = m - centre
        nv = float(np.linalg.norm(v))
        if nv == 0:
            continue
        cos = float(v @ e) / nv
        if cos < math.cos(math.radians(45.0)):
            k = int(np.argmax(np.abs(v)))
            looks = f"{'+' if v[k] > 0 else '-'}{'xyz'[k]}"
            raise ValueError(f"{s.where}: the accelerometer mean [{', '.join(f'{x:.4g}' for x in m)}] {unit} points "
                             f"{math.degrees(math.acos(max(-1.0, min(1.0, cos)))):.0f} deg away from the stated "
                             f"gravity {e.round(3).tolist()} (it looks like gravity along {looks}): a mislabelled "
                             "position? Fix the label or the segment's gravity")


def _split_table(table: Mapping | None, names: Sequence[str]) -> dict | None:
    """The entries of a prior/bounds mapping for `names` (a correlation block restricted to them)."""
    if table is None:
        return None
    out = {k: v for k, v in table.items() if k in names}
    corr = table.get("correlation")
    if isinstance(corr, Mapping) and "names" in corr:
        idx = [i for i, n in enumerate(corr["names"]) if n in names]
        if idx:
            mat = np.asarray(corr["matrix"], dtype=float)[np.ix_(idx, idx)]
            out["correlation"] = {"names": [corr["names"][i] for i in idx], "matrix": mat.tolist()}
    return out or None


def _positive(v: float, fallback: float) -> float:
    return float(v) if np.isfinite(v) and v > 0 else float(fallback)


def calibrate(session: Session, segments: Sequence[Segment], model: str | os.PathLike | CalibrationModel = "ferraris",
              method: str = "ols", *, gravity: float = G0, weighting: str = "positions", sigma: float | None = None,
              options: Mapping[str, Any] | None = None):
    """Identify the error coefficients of a ground test.

    Parameters
    ----------
    session : Session
    segments : sequence of Segment
        Static positions and rotations (:mod:`casep.calibration.session`).
    model : str, path or CalibrationModel
        ``"ferraris"`` (raw readings, imucal's parameters) or ``"platform36_ground"`` (SI readings,
        the flight model's names and units), or a model file.
    method : str
        A registered estimator (``casep methods``); its options in `options` (``prior`` and
        ``bounds`` mappings cover both sensors: each regression takes its own names).
    gravity : float
        Magnitude of the specific force in the static positions, m/s^2 (default standard
        gravity; imucal uses 9.81; give the local value).
    weighting : {"positions", "segments", "samples"}
        Row weighting (module notes).
    sigma : float, optional
        Noise std of the (weighted) rows, reading units; default estimated per sensor.

    Returns
    -------
    Calibration

    Raises
    ------
    ValueError
        A mislabelled position, a model that needs SI readings from raw ones, an unknown option.

    Warns
    -----
    RotationSignWarning
        A turn whose gyro reading has the opposite sign of its expected angle.
    PositionMisfitWarning
        A static segment whose row misfits the model far more than the noise level explains.
    """
    import dataclasses

    from casep.analysis.problem import Problem
    from casep.estimators.registry import METHODS, check_method_options, run_method
    from casep.estimators.result import EstimateResult

    if weighting not in WEIGHTINGS:
        raise ValueError(f"`weighting` must be one of {', '.join(WEIGHTINGS)}, got {weighting!r}")
    if not (np.isfinite(gravity) and 9.7 < gravity < 9.9):
        raise ValueError(f"`gravity` must be the local gravity in m/s^2 (9.7 .. 9.9), got {gravity}")
    model = load_calibration_model(model)
    options = dict(options or {})
    check_method_options(method, {k: v for k, v in options.items() if v is not None})
    if METHODS[method].needs_time or method in TIME_SERIES_METHODS:
        raise ValueError(f"method `{method}` models noise correlated in time; the rows of a ground test (segment "
                         "means, turn integrals) have no time order. Use: another method")
    acc, gyr, acc_unit, gyr_unit = _readings(session, model)
    _check_gravity(segments, session, gravity)
    _check_positions(segments, acc, acc_unit)
    static = [s for s in segments if s.kind == "static"]
    rots = [s for s in segments if s.kind == "rotation"]
    rate = session.rate
    _check_gaps(rots, session.t, rate)
    units = _unit_text(model, session)
    seg_info: dict[str, dict[str, Any]] = {
        s.name: {"name": s.name, "kind": s.kind, "rows": [int(s.rows[0]), int(s.rows[-1])], "samples": len(s.rows),
                 "misfit": {}} for s in segments}
    sensors: dict[str, EstimateResult] = {}
    n = model.n_coefficients
    # the two sensors are independent regressions: zero covariance between their blocks
    est, cov = np.full(n, np.nan), np.zeros((n, n))
    reasons: dict[str, str] = {}
    tilt = None  # position error, rad rms (weighting "positions")
    tilt_dof = 0  # the residual degrees of freedom it is estimated from
    for slot in model.slots:
        sensor = _SENSOR[slot]
        u = acc if slot == "accel_reading" else gyr
        cols = model.columns(slot)
        names = [model.names[j] for j in cols]
        s_i = _noise(static, u)  # sample noise per axis
        rows_S, rows_y, rows_seg, rows_t = [], [], [], []
        rows_sd: list[np.ndarray | None] = []  # None: the static level, estimated
        for s in static:
            f = gravity * s.gravity
            w = np.deg2rad(s.omega_dps)
            J = model.jacobian(slot, f, w)[:, cols]
            y0 = model.known(slot, f, w)
            if weighting in ("positions", "segments"):
                rows_S.append(J)
                rows_y.append(u[s.rows].mean(axis=0) - y0)
                rows_sd.append(None)  # the static level, estimated
                rows_seg.append((s.name, 1))
                rows_t.append(session.t[s.rows].mean())
            else:
                k = len(s.rows)
                rows_S.append(np.broadcast_to(J, (k, 3, len(cols))).reshape(-1, len(cols)))
                rows_y.append((u[s.rows] - y0).reshape(-1))
                rows_sd.append(np.tile(s_i, k))
                rows_seg.append((s.name, k))
                rows_t.extend(session.t[s.rows])
        n_static = len(rows_S)
        if slot == "gyro_reading":
            for s in rots:
                y, J, T, dt = _rotation_row(model, slot, s, u, gravity, rate, session.t)
                rows_S.append(J[:, cols])
                rows_y.append(y)
                rows_sd.append(s_i * math.sqrt(float(dt @ dt)))  # white noise integrated: s sqrt(sum dt^2)
                rows_seg.append((s.name, 1))
                rows_t.append(session.t[s.rows].mean())
        S = np.vstack([np.atleast_2d(x).reshape(-1, len(cols)) for x in rows_S])
        y = np.concatenate([np.ravel(x) for x in rows_y])
        # Row std: the static level (segments: sigma_s of the static rows alone) and the rotation rows'.
        if weighting in ("positions", "segments"):
            Sst = np.vstack(rows_S[:n_static]).reshape(-1, len(cols))
            yst = np.concatenate(rows_y[:n_static])
            pst = Problem.from_arrays(Sst, yst)
            dof = pst.m - pst.rank().rank
            noise_mean = float(np.sqrt(np.mean(s_i**2) / np.mean([len(s.rows) for s in static])))
            level = math.sqrt(pst.ls_rss() / dof) if dof > 0 else noise_mean
            level = _positive(level, _positive(noise_mean, 1.0))
            sd = np.concatenate([np.full(3, level) if v is None else np.asarray(v) for v in rows_sd])
        else:
            level = _positive(float(np.sqrt(np.mean(s_i**2))), 1.0)
            sd = np.concatenate([np.asarray(v) for v in rows_sd])
        sd = np.where(sd > 0, sd, level)
        wgt = level / sd  # rows scaled to the static level: sigma comes out in reading units
        Sw, yw = S * wgt[:, None], y * wgt
        if weighting == "positions" and n_static:
            x0 = np.linalg.lstsq(Sw, yw, rcond=None)[0]  # equal-weight fit: the reading's slope in f
            D0 = np.zeros(model.n_coefficients)
            D0[cols] = x0
            Jf = [model.reading_df(slot, gravity * s.gravity, np.deg2rad(s.omega_dps), D0) for s in static]
            ybar = np.concatenate(rows_y[:n_static])
            # the turns' white-noise std, floored (like the means) at 1e-12 of the row: a noise-free session
            y_rot = y[3 * n_static:]
            sd_rot = np.concatenate([np.asarray(v) for v in rows_sd[n_static:]]) if len(rows_sd) > n_static \
                else np.zeros(0)
            sd_rot = np.maximum(sd_rot, 1e-12 * np.max(np.abs(y_rot), initial=0.0) + 1e-300)
            floor = (1e-12 * float(np.max(np.abs(ybar)))) ** 2 + 1e-300
            # a tilted position senses on average f = g (1 - tilt^2) e (module notes): the static rows there
            args = (model, slot, cols, static, u, gravity, n_static, Jf, s_i, floor, y_rot, sd_rot)
            if tilt is None:  # estimated on the first sensor (the accelerometer): the same tilts move both
                # degrees of freedom: rows minus the rank of S (the six axis positions leave some
                # coefficients undetermined, so the rank, not the number of columns, counts)
                tilt_dof = S.shape[0] - int(np.linalg.matrix_rank(Sw))
                tilt = 0.0
                for _ in range(4):  # the mean shortfall moves the misfit by O(tilt^2): a fixed point in a few steps
                    tilt = _solve_tilt(_tilted_rows(tilt, S, y, *args), S.shape[0], S.shape[0] - tilt_dof)
            whiten = _tilted_rows(tilt, S, y, *args)
            Sst, yst = S[:3 * n_static], y[:3 * n_static]
            Sw, yw = whiten(tilt)
            level = _ls_sigma(Sw, yw)
        m3 = S.shape[0] // 3  # observations of three rows (x, y, z) each
        pb = Problem.from_arrays(Sw.reshape(m3, 3, len(cols)), yw.reshape(m3, 3),
                                 np.asarray(rows_t, dtype=float), names=names, units=[units[j] for j in cols],
                                 si_factors=model.si_factors[cols], model=model.name)
        opts = {k: v for k, v in options.items() if v is not None}
        for key in ("prior", "bounds"):
            if key in opts:
                part = _split_table(opts[key], names)
                if part is None:
                    opts.pop(key)
                    if key in METHODS[method].required:
                        raise ValueError(f"--{key} names none of the {sensor}'s coefficients ({', '.join(names)}); "
                                         f"method `{method}` needs one for each sensor")
                else:
                    opts[key] = part
        # Huber's MAD scale is biased low on a few rows of high leverage (6 dof; the turns are fitted
        # exactly): it takes the least-squares sigma of the weighted rows as its scale instead
        use_sigma = sigma if sigma is not None or method != "huber" else _positive(_ls_sigma(Sw, yw), 1.0)
        res = run_method(method, pb, None, None, opts, sigma=use_sigma)
        res = dataclasses.replace(res, diagnostics={**res.diagnostics, "rows": int(S.shape[0]),
                                                    "static_level": level, "sample_noise": s_i.tolist(),
                                                    **({"position_error_deg": math.degrees(tilt),
                                                        "position_error_dof": tilt_dof}
                                                       if tilt is not None else {})})
        sensors[sensor] = res
        est[cols] = res.estimate
        # a method that defines no covariance: none for its coefficients either
        cov[np.ix_(cols, cols)] = res.covariance if res.covariance is not None else np.nan
        reasons.update(res.reasons)
        # misfit per segment: residual of the segment's row (unweighted), and its noise std
        x = np.where(np.isfinite(res.estimate), res.estimate, 0.0)
        r = y - S @ x
        k0 = 0
        for (name, k), sdv in zip(rows_seg, rows_sd):
            rr = r[k0:k0 + 3 * k].reshape(k, 3)
            k0 += 3 * k
            seg = next(s for s in segments if s.name == name)
            if seg.kind == "static":
                noise = s_i / math.sqrt(len(seg.rows))
                resid = rr.mean(axis=0)
            else:
                noise = np.asarray(sdv)
                resid = rr[0]
            ratio = float(np.sqrt(np.mean(resid**2)) / max(float(np.sqrt(np.mean(noise**2))), 1e-300))
            seg_info[name]["misfit"][sensor] = {"residual": resid.tolist(), "noise_std": noise.tolist(),
                                                "ratio": ratio, "unit": acc_unit if sensor == "accelerometer"
                                                else (gyr_unit if seg.kind == "static" else f"{gyr_unit} s")}
        if weighting in ("positions", "segments") and n_static and dof > 0:
            # the positions judged on the least-squares fit of the rows (whatever the method): static rows alone
            # (equal weight), or all rows whitened by the position and noise model
            A, b = (Sw, yw) if weighting == "positions" else (Sst, yst)
            xs = np.linalg.lstsq(A, b, rcond=None)[0]
            rr = b - A @ xs
            # residuals at the rounding level of the readings (a noise-free session) are no misfit
            rounding = np.abs(yst - Sst @ xs) <= 1e-12 * float(np.max(np.abs(u)))
            rr[:3 * n_static][rounding] = 0.0
            _warn_misfit(static, A[:3 * n_static], rr[:3 * n_static], level, sensor,
                         "(whitened)" if weighting == "positions" else
                         (acc_unit if sensor == "accelerometer" else gyr_unit),
                         1.0 if weighting == "positions" else float(np.max(np.abs(u))), A)
        if slot == "gyro_reading":
            _check_rotation_signs(model, rots, gyr, gravity, rate, est, gyr_unit)
    und = ~np.isfinite(est)
    cov[und, :] = np.nan
    cov[:, und] = np.nan
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    parts = list(sensors.values())
    # worst of the two: a failure (<= 0) if either failed, else 2 (some not identifiable) over 1
    status = min(r.status for r in parts) if any(r.status <= 0 for r in parts) else max(r.status for r in parts)
    res_all = EstimateResult(
        method=method, names=model.names, units=tuple(units), estimate=est, std=std, covariance=cov,
        reasons=reasons, residuals=np.zeros((0, 3)), sigma=math.nan, rank=sum(r.rank for r in parts),
        status=status, message="; ".join(f"{k}: {r.message}" for k, r in sensors.items()),
        success=all(r.success for r in parts), si_factors=model.si_factors,
        settings={"method_settings": {k: r.settings for k, r in sensors.items()}},
        diagnostics={k: r.diagnostics for k, r in sensors.items()}, model=model.name,
        n_samples=int(sum(len(s.rows) for s in segments)), sigma_source="estimated" if sigma is None else "given",
        stored_residual_rms={a: None for a in "xyz"}, std_kind=parts[0].std_kind, extras=None)
    settings = {"weighting": weighting, "gravity": float(gravity), "rate_hz": float(rate),
                "acc_unit": session.acc_unit if model.readings == "raw" else acc_unit,
                "gyr_unit": session.gyr_unit if model.readings == "raw" else gyr_unit,
                "session_units": [session.acc_unit, session.gyr_unit], "source": session.source,
                "rotation_angles_deg": {s.name: s.angle_deg for s in rots}}
    return Calibration(res_all, sensors, [seg_info[s.name] for s in segments], model, settings)


def _tilted_rows(tilt, S, y, model, slot, cols, static, u, gravity, n_static, Jf, s_i, floor, y_rot, sd_rot):
    """The static rows of `S`, `y` (in place) at the mean specific force of positions tilted by `tilt` rad rms,
    ``g (1 - tilt^2) e``, and their ``whiten`` (:func:`_position_whitening`)."""
    S[:3 * n_static], y[:3 * n_static] = _static_rows(model, slot, cols, static, u, gravity * (1.0 - tilt**2))
    return _position_whitening(static, Jf, s_i, gravity, floor, S[:3 * n_static], y[:3 * n_static],
                               S[3 * n_static:], y_rot, sd_rot)


def _static_rows(model, slot, cols, static, u: np.ndarray, g: float) -> tuple[np.ndarray, np.ndarray]:
    """The static means' rows at specific force ``g e_k``: ``S`` (3 per segment) and ``mean(u) - y0``."""
    S, y = [], []
    for s in static:
        f, w = g * s.gravity, np.deg2rad(s.omega_dps)
        S.append(model.jacobian(slot, f, w)[:, cols])
        y.append(u[s.rows].mean(axis=0) - model.known(slot, f, w))
    return np.vstack(S), np.concatenate(y)


def _ls_sigma(S: np.ndarray, y: np.ndarray) -> float:
    """Least-squares residual std ``sqrt(RSS / (m - rank))`` (0 without degrees of freedom)."""
    x, _, rank, _ = np.linalg.lstsq(S, y, rcond=None)
    dof = S.shape[0] - rank
    r = y - S @ x
    return float(np.sqrt(r @ r / dof)) if dof > 0 else 0.0


def _position_whitening(static, Jf, s_i, g, floor, S_st, y_st, S_rot, y_rot, sd_rot):
    """``whiten(tilt) -> (S_w, y_w)``: the rows whitened by the position-error and noise covariance.

    A static position tilted by a small rotation ``phi ~ N(0, tilt^2 I)`` senses ``f = g (e + phi x e
    - |phi x e|^2 e / 2)``: the mean reading of segment k moves by ``J_f (g phi x e)`` (``J_f = dy/df``),
    whose covariance is ``tilt^2 g^2 J_f P J_f^T``, ``P = I - e e^T`` (tilts do not move the reading
    along gravity to first order), plus the second-order shortfall along e (variance ``g^2 tilt^4``)
    and the sample noise of the mean ``diag(s_i^2 / n_k)``:
    ``V_k = tilt^2 g^2 J_f P J_f^T + g^2 tilt^4 (J_f e)(J_f e)^T + diag(s_i^2 / n_k)``. Rows of segment
    k are multiplied by ``L_k^-1`` (``V_k = L_k L_k^T``); the turns by 1 / their white-noise std.
    """
    blocks = []
    for s, J in zip(static, Jf):
        e = s.gravity
        P = np.eye(3) - np.outer(e, e)
        Je = J @ e
        blocks.append((g**2 * J @ P @ J.T, g**2 * np.outer(Je, Je), np.diag(s_i**2 / len(s.rows)) + floor * np.eye(3)))
    rot_w = 1.0 / sd_rot

    def whiten(tilt: float):
        Sw, yw = [], []
        for k, (A, B, N) in enumerate(blocks):
            L = np.linalg.cholesky(tilt**2 * A + tilt**4 * B + N)
            Sw.append(np.linalg.solve(L, S_st[3 * k:3 * k + 3]))
            yw.append(np.linalg.solve(L, y_st[3 * k:3 * k + 3]))
        return np.vstack(Sw + [S_rot * rot_w[:, None]]), np.concatenate(yw + [y_rot * rot_w])

    return whiten


def _solve_tilt(whiten, m: int, n: int) -> float:
    """The position error (rad rms) at which the whitened least-squares residual std is 1.

    `m` rows, `n` the rank of the rows (not the number of coefficients: the six axis positions leave
    some undetermined). 0 when the sample noise alone explains the misfit (or no degree of freedom is
    left); capped at 0.5 rad.
    """
    from scipy.optimize import brentq

    if m <= n:
        return 0.0

    def excess(log_tilt: float) -> float:
        return _ls_sigma(*whiten(math.exp(log_tilt))) - 1.0

    if _ls_sigma(*whiten(0.0)) <= 1.0:
        return 0.0
    lo, hi = math.log(1e-9), math.log(0.5)
    if excess(lo) <= 0.0:
        return math.exp(lo)
    if excess(hi) > 0.0:
        return 0.5
    return math.exp(brentq(excess, lo, hi, xtol=1e-10))


def _warn_misfit(static, S_static, r, level, sensor, unit, reading_scale, S_fit) -> None:
    """PositionMisfitWarning for a static segment whose studentized row residual exceeds MISFIT_Z.

    `S_static`, `r`: the static rows and their residuals in the fit of the rows `S_fit` (the static
    rows first); leverage ``h = diag(S (S^T S)^+ S^T)`` of the fit.
    """
    U, sv, _ = np.linalg.svd(S_fit, full_matrices=False)
    keep = sv > sv[0] * 1e-10 if sv.size else sv > 0
    h = np.sum(U[:, keep] ** 2, axis=1)[:S_static.shape[0]]
    # residuals at the rounding level of the rows (a noise-free session) are no misfit
    floor = 1e-12 * reading_scale
    z = np.where(np.abs(r) <= floor, 0.0, r / (max(level, floor, 1e-300) * np.sqrt(np.clip(1.0 - h, 1e-12, None))))
    for k, s in enumerate(static):
        zk = z[3 * k:3 * k + 3]
        if np.max(np.abs(zk)) > MISFIT_Z:
            i = int(np.argmax(np.abs(zk)))
            warnings.warn(f"{s.where}: the {sensor} mean misfits the model by {r[3 * k + i]:+.4g} {unit} "
                          f"on {'xyz'[i]}, {abs(zk[i]):.3g} x its std from the other positions' level ({level:.4g} "
                          f"{unit}): a bad position or a wrong label?", PositionMisfitWarning, stacklevel=3)


def _check_rotation_signs(model, rots, gyr, gravity, rate, est, unit) -> None:
    """RotationSignWarning where the fitted sensitivity about a turn's axis is negative."""
    x = np.where(np.isfinite(est), est, 0.0)
    for s in rots:
        f = gravity * s.gravity
        a = s.axis
        z = np.zeros(3)
        # d reading / d omega along the axis, per rad/s: [y(f, a) - y(f, 0)] . a (the reading is affine in omega)
        dy = (model.known("gyro_reading", f, a) - model.known("gyro_reading", f, z)
              + (model.jacobian("gyro_reading", f, a) - model.jacobian("gyro_reading", f, z)) @ x)
        sens = float(dy @ a) * math.pi / 180.0  # per deg/s
        if sens < 0:
            integral = float(gyr[s.rows].sum(axis=0) @ a / rate)
            warnings.warn(
                f"{s.where}: the gyro reading about {np.round(a, 3).tolist()} integrates to {integral:+.5g} {unit} s, "
                f"the opposite sign of the expected angle {s.angle_deg:+g} deg: the fitted scale about that axis is "
                f"{sens:.5g} {unit} per deg/s. The turn went the other way (--angle {-s.angle_deg:+g}) or the gyro "
                "axis is inverted", RotationSignWarning, stacklevel=3)


def calibrate_files(session: str | os.PathLike, *, rate: float | None = None, segments: str | os.PathLike | None = None,
                    label_column: str | None = None, model: str | os.PathLike = "ferraris", method: str = "ols",
                    options: Mapping[str, Any] | None = None, acc_columns=None, gyr_columns=None,
                    acc_unit: str = "a.u.", gyr_unit: str = "a.u.", gravity: float = G0, angle_deg: float = -360.0,
                    weighting: str = "positions", sigma: float | None = None,
                    prior_rel_std: float | None = None) -> Calibration:
    """:func:`calibrate` from files: the session, and its segments from `segments` (JSON) or `label_column`.

    A ``prior`` option may be a path: a map-format JSON, a casep calibration/result JSON (its
    estimate and covariance), or an imucal calibration JSON (with `prior_rel_std`, imucal states no
    std: :func:`casep.calibration.imucal.imucal_prior`). ``bounds`` may be a path of a JSON table.
    """
    from casep.calibration.session import ACC_COLUMNS, GYR_COLUMNS, read_segments, read_session, segments_from_labels

    if (segments is None) == (label_column is None):
        raise ValueError("give the segments as --segments FILE or --label-column NAME (one of the two)")
    ses = read_session(session, rate=rate, acc_columns=acc_columns or ACC_COLUMNS,
                       gyr_columns=gyr_columns or GYR_COLUMNS, acc_unit=acc_unit, gyr_unit=gyr_unit,
                       label_column=label_column)
    segs = (read_segments(segments, ses, angle_deg=angle_deg) if segments is not None
            else segments_from_labels(ses, angle_deg=angle_deg))
    options = dict(options or {})
    for key in ("prior", "bounds"):
        v = options.get(key)
        if isinstance(v, (str, os.PathLike)):
            options[key] = _table_file(v, key, prior_rel_std)
    return calibrate(ses, segs, model, method, gravity=gravity, weighting=weighting, sigma=sigma, options=options)


def _table_file(path, key: str, prior_rel_std: float | None) -> dict:
    """A --prior/--bounds JSON file as a mapping (prior: map format, a casep result, an imucal calibration)."""
    from casep.io.files import read_json_table

    data = read_json_table(path, f"--{key}")
    if key != "prior":
        return data
    if "cal_type" in data:  # imucal
        from casep.calibration.imucal import imucal_prior

        if prior_rel_std is None:
            raise ValueError(f"--prior {path} is an imucal calibration, which states no std. Use: --prior-rel-std R "
                             "(e.g. 0.01 for 1 %)")
        return imucal_prior(data, prior_rel_std)
    if "coefficients" in data and "covariance" in data:  # a casep result or calibration: its estimate and covariance
        from casep.calibration.consistency import as_gaussian

        names, _, mean, C, _ = as_gaussian(data)
        keep = [j for j in range(len(names)) if np.isfinite(mean[j]) and np.isfinite(C[j, j]) and C[j, j] > 0]
        sd = np.sqrt(np.diag(C)[keep])
        out: dict = {names[j]: {"mean": float(mean[j]), "std": float(s)} for j, s in zip(keep, sd)}
        out["correlation"] = {"names": [names[j] for j in keep],
                              "matrix": (C[np.ix_(keep, keep)] / np.outer(sd, sd)).tolist()}
        return out
    return data
