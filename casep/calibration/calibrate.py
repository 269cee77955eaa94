"""The regression of a ground test: :func:`calibrate` and :func:`calibrate_files`.

Each sensor triad (accelerometer, gyro) is its own regression ``y = S D + e`` over the
coefficients of its output, solved by the registered estimators (:mod:`casep.estimators`, on a
:class:`casep.Problem`), so the noise level, the std, outlier handling and the collinearity
diagnostics are those of a flight. The rows (segment means, turn integrals) and their weighting
are described in :mod:`casep.calibration.rows`; the checks of the session against its pattern
in :mod:`casep.calibration.checks`; the result is a :class:`casep.calibration.result.Calibration`.
"""

from __future__ import annotations

import dataclasses
import math
import os
from typing import Any, Mapping, Sequence

import numpy as np

from casep.calibration.checks import (
    GRAVITY_TOLERANCE,
    MISFIT_Z,
    PositionMisfitWarning,
    RotationSignWarning,
    TimeGapWarning,
    check_gaps,
    check_gravity,
    check_positions,
    check_rotation_signs,
    check_turn_angles,
    segment_misfits,
    warn_misfit,
)
from casep.calibration.model import (
    CalibrationModel,
    calibration_model_dirs,
    calibration_models,
    load_calibration_model,
)
from casep.calibration.result import Calibration
from casep.calibration.rows import (
    ls_sigma,
    readings_for,
    sample_noise,
    sensor_rows,
    solve_tilt,
    tilted_rows,
    unit_text,
)
from casep.calibration.session import ACC_UNITS, GYR_UNITS, Segment, Session
from casep.regression.linalg import covariance_std, undetermined_nan
from casep.regression.problem import rounding_level
from casep.units import G0

# The result type, the model loaders and the warnings of a calibration are names of this module too.
__all__ = ["Calibration", "calibrate", "load_calibration_model", "calibration_models",
           "calibration_model_dirs", "calibrate_files", "RotationSignWarning", "PositionMisfitWarning",
           "TimeGapWarning", "WEIGHTINGS", "ACC_UNITS", "GYR_UNITS", "GRAVITY_TOLERANCE", "MISFIT_Z"]

#: Row weighting of the static segments (:mod:`casep.calibration.rows`).
WEIGHTINGS = ("positions", "segments", "samples")
_SENSOR = {"accel_reading": "accelerometer", "gyro_reading": "gyro"}


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



def _row_std(S: np.ndarray, y: np.ndarray, rows_sd: Sequence[Any], static: Sequence[Segment], s_i: np.ndarray,
             n_static: int, weighting: str) -> tuple[np.ndarray, float, int]:
    """Each row's std, the static level the rows are scaled to, and the static rows' residual dof.

    The static level: the least-squares residual std of the static rows alone (``positions``,
    ``segments``; the sample noise of a segment mean without dof), else the sample noise.
    """
    from casep.regression.problem import Problem

    dof = 0
    # Row std: the static level (segments: sigma_s of the static rows alone) and the rotation rows'.
    if weighting in ("positions", "segments"):
        Sst, yst = S[:3 * n_static], y[:3 * n_static]  # three rows per static segment
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
    return sd, level, dof


def _position_rows(model: Any, slot: str, cols: Sequence[int] | np.ndarray, static: Sequence[Segment], u: np.ndarray,
                   gravity: float, n_static: int, s_i: np.ndarray, S: np.ndarray, y: np.ndarray, Sw: np.ndarray,
                   yw: np.ndarray, rows_sd: Sequence[Any], tilt: float | None,
                   tilt_dof: int) -> tuple[np.ndarray, np.ndarray, float, float, int]:
    """Weighting ``positions``: the rows whitened by the position-error model (:mod:`casep.calibration.rows`),
    their level, and the position error (rad rms; estimated on the first sensor, the accelerometer,
    since the same tilts move both) with its residual dof."""
    x0 = np.linalg.lstsq(Sw, yw, rcond=None)[0]  # equal-weight fit: the reading's slope in f
    D0 = np.zeros(model.n_coefficients)
    D0[cols] = x0
    Jf = [model.reading_df(slot, gravity * s.gravity, np.deg2rad(s.omega_dps), D0) for s in static]
    ybar = y[:3 * n_static]
    # the turns' white-noise std, floored (like the means) at the rounding level of the rows (casep's noise-free
    # rule, rounding_level): a noise-free session is weighted, not divided by zero
    y_rot = y[3 * n_static:]
    sd_rot = np.concatenate([np.asarray(v) for v in rows_sd[n_static:]]) if len(rows_sd) > n_static \
        else np.zeros(0)
    sd_rot = np.maximum(sd_rot, rounding_level(np.max(np.abs(y_rot), initial=0.0)) + 1e-300)
    floor = rounding_level(float(np.max(np.abs(ybar)))) ** 2 + 1e-300
    # a tilted position senses on average f = g (1 - tilt^2) e (casep.calibration.rows): the static rows there
    args = (model, slot, cols, static, u, gravity, n_static, Jf, s_i, floor, y_rot, sd_rot)
    if tilt is None:  # estimated on the first sensor (the accelerometer): the same tilts move both
        # degrees of freedom: rows minus the rank of S (the six axis positions leave some
        # coefficients undetermined, so the rank, not the number of columns, counts)
        tilt_dof = S.shape[0] - int(np.linalg.matrix_rank(Sw))
        tilt = 0.0
        for _ in range(4):  # the mean shortfall moves the misfit by O(tilt^2): a fixed point in a few steps
            tilt = solve_tilt(tilted_rows(tilt, S, y, *args), S.shape[0], S.shape[0] - tilt_dof)
    whiten = tilted_rows(tilt, S, y, *args)
    Sw, yw = whiten(tilt)
    level = ls_sigma(Sw, yw)
    return Sw, yw, level, tilt, tilt_dof


def _sensor_options(options: Mapping[str, Any], names: Sequence[str], method: str, sensor: str) -> dict[str, Any]:
    """The method's options for one sensor's regression: ``prior``/``bounds`` cut to its coefficients."""
    from casep.estimators.registry import METHODS

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
    return opts


def _judge_positions(static: Sequence[Segment], weighting: str, Sw: np.ndarray, yw: np.ndarray, Sst: np.ndarray,
                     yst: np.ndarray, u: np.ndarray, level: float, sensor: str, unit: str) -> None:
    """Warn of static positions that misfit: judged on the least-squares fit of the rows (whatever the
    method), the static rows alone (equal weight, ``segments``) or all rows whitened by the position and
    noise model (``positions``); residuals at the rounding level of the readings are no misfit."""
    n3 = Sst.shape[0]
    A, b = (Sw, yw) if weighting == "positions" else (Sst, yst)
    xs = np.linalg.lstsq(A, b, rcond=None)[0]
    rr = b - A @ xs
    # the noise-free rule of casep (rounding_level), residual by residual: a noise-free session misfits nowhere
    rounding = np.abs(yst - Sst @ xs) <= rounding_level(float(np.max(np.abs(u))))
    rr[:n3][rounding] = 0.0
    warn_misfit(static, A[:n3], rr[:n3], level, sensor, "(whitened)" if weighting == "positions" else unit,
                1.0 if weighting == "positions" else float(np.max(np.abs(u))), A)


def _combined(method: str, model: Any, units: Sequence[str], est: np.ndarray, cov: np.ndarray,
              reasons: dict[str, str], sensors: Mapping[str, Any], segments: Sequence[Segment],
              sigma: float | None) -> Any:
    """The EstimateResult over both sensors' coefficients (block-diagonal covariance; the worse status)."""
    from casep.estimators.result import EstimateResult

    std = covariance_std(undetermined_nan(cov, ~np.isfinite(est)))
    parts = list(sensors.values())
    # worst of the two: a failure (<= 0) if either failed, else 2 (some not identifiable) over 1
    status = min(r.status for r in parts) if any(r.status <= 0 for r in parts) else max(r.status for r in parts)
    return EstimateResult(
        method=method, names=model.names, units=tuple(units), estimate=est, std=std, covariance=cov,
        reasons=reasons, residuals=np.zeros((0, 3)), sigma=math.nan, rank=sum(r.rank for r in parts),
        status=status, message="; ".join(f"{k}: {r.message}" for k, r in sensors.items()),
        success=all(r.success for r in parts), si_factors=model.si_factors,
        settings={"method_settings": {k: r.settings for k, r in sensors.items()}},
        diagnostics={k: r.diagnostics for k, r in sensors.items()}, model=model.name,
        n_samples=int(sum(len(s.rows) for s in segments)), sigma_source="estimated" if sigma is None else "given",
        stored_residual_rms={a: None for a in "xyz"}, std_kind=parts[0].std_kind, extras=None)


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
        Row weighting (:mod:`casep.calibration.rows`).
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

    from casep.estimators.registry import METHODS
    from casep.estimators.result import EstimateResult
    from casep.estimators.solve import fit
    from casep.estimators.spec import FitSpec, NoiseSpec
    from casep.regression.problem import Problem

    if weighting not in WEIGHTINGS:
        raise ValueError(f"`weighting` must be one of {', '.join(WEIGHTINGS)}, got {weighting!r}")
    if not (np.isfinite(gravity) and 9.7 < gravity < 9.9):
        raise ValueError(f"`gravity` must be the local gravity in m/s^2 (9.7 .. 9.9), got {gravity}")
    model = load_calibration_model(model)
    if method in METHODS and (METHODS[method].needs_time or METHODS[method].noise_in_time):  # no time order here
        raise ValueError(f"method `{method}` models noise correlated in time; the rows of a ground test (segment "
                         "means, turn integrals) have no time order. Use: another method")
    # the request checked once, as every fit's: white rows (the weighting is the calibration's own), no robust filter
    options = dict(FitSpec.build(method, options=options, noise="white", robust=None).options)
    acc, gyr, acc_unit, gyr_unit = readings_for(session, model)
    check_gravity(segments, session, gravity)
    check_turn_angles(segments, session)
    check_positions(segments, acc, acc_unit)
    static = [s for s in segments if s.kind == "static"]
    rots = [s for s in segments if s.kind == "rotation"]
    rate = session.rate
    check_gaps(rots, session.t, rate)
    units = unit_text(model, session)
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
        s_i = sample_noise(static, u)  # sample noise per axis
        S, y, rows_sd, rows_seg, _times, n_static = sensor_rows(model, slot, cols, static, rots, u, session.t,
                                                                gravity, rate, weighting, s_i)
        sd, level, dof = _row_std(S, y, rows_sd, static, s_i, n_static, weighting)
        wgt = level / sd  # rows scaled to the static level: sigma comes out in reading units
        Sw, yw = S * wgt[:, None], y * wgt
        if weighting == "positions" and n_static:  # a tilted position senses on average f = g (1 - tilt^2) e
            Sw, yw, level, tilt, tilt_dof = _position_rows(model, slot, cols, static, u, gravity, n_static, s_i, S, y,
                                                           Sw, yw, rows_sd, tilt, tilt_dof)
        m3 = S.shape[0] // 3  # observations of three rows (x, y, z) each
        # no sample times: segment means and turn integrals are no time series (no gaps, no correlation in time)
        pb = Problem.from_arrays(Sw.reshape(m3, 3, len(cols)), yw.reshape(m3, 3), None, names=names,
                                 units=[units[j] for j in cols], si_factors=model.si_factors[cols], model=model.name,
                                 row_unit=acc_unit if sensor == "accelerometer" else gyr_unit)
        opts = _sensor_options(options, names, method, sensor)
        # Huber's MAD scale is biased low on a few rows of high leverage (6 dof; the turns are fitted
        # exactly): it takes the least-squares sigma of the weighted rows as its scale instead
        use_sigma = sigma if sigma is not None or not METHODS[method].own_scale else _positive(ls_sigma(Sw, yw), 1.0)
        # The linear step: one checked request per sensor (the method, its options cut to this sensor's
        # coefficients, sigma) through the one entry point of every fit. White rows and no robust filter: their
        # noise model is the weighting above; the residual checks of a flight's time series do not apply (the
        # misfits per segment and the positions are judged below).
        spec = FitSpec(method, opts, use_sigma, NoiseSpec("white", robust=None))
        res = fit(pb, spec, checks=False)
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
        unit = pb.row_unit
        for name, misfit in segment_misfits(segments, rows_seg, rows_sd, y - S @ x, s_i, unit).items():
            seg_info[name]["misfit"][sensor] = misfit
        if weighting in ("positions", "segments") and n_static and dof > 0:
            _judge_positions(static, weighting, Sw, yw, S[:3 * n_static], y[:3 * n_static], u, level, sensor,
                             acc_unit if sensor == "accelerometer" else gyr_unit)
        if slot == "gyro_reading":
            check_rotation_signs(model, rots, gyr, gravity, rate, est, gyr_unit)
    res_all = _combined(method, model, units, est, cov, reasons, sensors, segments, sigma)
    settings = {"weighting": weighting, "gravity": float(gravity), "rate_hz": float(rate),
                "acc_unit": session.acc_unit if model.readings == "raw" else acc_unit,
                "gyr_unit": session.gyr_unit if model.readings == "raw" else gyr_unit,
                "session_units": [session.acc_unit, session.gyr_unit], "source": session.source,
                "rotation_angles_deg": {s.name: s.angle_deg for s in rots}}
    return Calibration(res_all, sensors, [seg_info[s.name] for s in segments], model, settings)


def calibrate_files(session: str | os.PathLike, *, rate: float | None = None, segments: str | os.PathLike | None = None,
                    label_column: str | None = None, model: str | os.PathLike = "ferraris", method: str = "ols",
                    options: Mapping[str, Any] | None = None, acc_columns=None, gyr_columns=None,
                    acc_unit: str = "a.u.", gyr_unit: str = "a.u.", gravity: float = G0, angle_deg: float = -360.0,
                    weighting: str = "positions", sigma: float | None = None,
                    prior_rel_std: float | None = None, window_s: float = 0.5, init_s: float = 5.0,
                    min_static_s: float = 0.5) -> Calibration:
    """:func:`calibrate` from files: the session, and its segments from `segments` (JSON) or `label_column`.

    ``segments="auto"``: the six static poses and three turns of a Ferraris session found without labels
    (:func:`casep.calibration.ferrarisauto.find_ferraris_segments` with `window_s`, `init_s`,
    `min_static_s`); the result carries what was found (:attr:`Calibration.segmentation`).

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
    found = None
    if segments == "auto":
        from casep.calibration.ferrarisauto import find_ferraris_segments

        found = find_ferraris_segments(ses, angle_deg=angle_deg, window_s=window_s, init_s=init_s,
                                       min_static_s=min_static_s)
        segs = found.segments
    else:
        segs = (read_segments(segments, ses, angle_deg=angle_deg) if segments is not None
                else segments_from_labels(ses, angle_deg=angle_deg))
    options = dict(options or {})
    for key in ("prior", "bounds"):
        v = options.get(key)
        if isinstance(v, (str, os.PathLike)):
            options[key] = _table_file(v, key, prior_rel_std)
    cal = calibrate(ses, segs, model, method, gravity=gravity, weighting=weighting, sigma=sigma, options=options)
    return cal if found is None else dataclasses.replace(cal, segmentation=found)


def _table_file(path, key: str, prior_rel_std: float | None) -> dict:
    """A --prior/--bounds JSON file as a mapping (prior: map format, a casep result, an imucal calibration)."""
    from casep.io.files import read_json_table

    if key == "prior" and str(path).endswith(".calib"):  # imu_tk's PREFIX_acc.calib (and PREFIX_gyro.calib)
        from casep.calibration.imutk import imu_tk_prior

        if prior_rel_std is None:
            raise ValueError(f"--prior {path} is an imu_tk calibration, which states no std. Use: --prior-rel-std R")
        return imu_tk_prior(path, prior_rel_std)
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
