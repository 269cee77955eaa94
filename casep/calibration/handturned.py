"""A hand-turned session calibrated without labels or turntable: segmentation, then model ``multiposition``.

:func:`calibrate_multiposition` chains :func:`casep.calibration.segment.detect_static` (the static
poses and the motions between them), :func:`casep.calibration.multiposition.fit_accelerometer`
(the pose means against the magnitude of gravity), the gyro bias (the mean of the poses' mean
gyro readings; std: their scatter over sqrt(poses), widened by the drift they show, :mod:`casep.calibration.drift`) and
:func:`casep.calibration.multiposition.fit_gyro` (the motions against the change of the gravity
direction). :class:`MultipositionCalibration` holds every coefficient with its std in imu_tk's
convention and, beside it, in casep's ``ferraris`` names (``Ma_ij``, ``ba_i``, ``Mg_ij``, ``bg_i``).

Units: readings declared in a physical unit are converted to SI first (scales are then
dimensionless, near 1, biases in m/s^2 and rad/s); raw counts (``a.u.``) are fitted as they are
(scales in SI per count, ~1e-3; biases in counts, ~32768 for an unsigned 16-bit converter).
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field

import numpy as np

from casep.calibration.checks import check_acc_scale, check_gyro_scale
from casep.calibration.drift import DriftFit
from casep.calibration.multiposition import (
    ACC_NAMES,
    GYRO_NAMES,
    AccFit,
    GyroFit,
    acc_matrix,
    fit_accelerometer,
    fit_gyro,
    gyro_matrix,
)
from casep.calibration.saturation import (
    SaturationWarning,
    check_gyro_saturation,
    clipped_poses,
    implied_full_scale,
    warn_implied_full_scale,
)
from casep.calibration.segment import Segmentation, detect_static
from casep.calibration.session import ACC_UNITS, GYR_UNITS, RAW_UNIT, Session
from casep.estimators.result import EstimateResult
from casep.exceptions import CasepWarning
from casep.fullscale import beyond_declared
from casep.regression.linalg import covariance_std
from casep.results import OfEstimate

__all__ = ["MultipositionCalibration", "calibrate_multiposition", "calibrate_multiposition_file", "ferraris_view",
           "FitWarning", "SaturationWarning", "DriftWarning", "CONVENTION"]

#: Poses whose gravity directions lie within this angle of their mean direction (deg) are a narrow session.
CONE_DEG = 60.0

#: A gyro fit with an RMS gravity-direction misfit above this (deg) is checked for swapped columns.
SWAP_MISFIT_DEG = 1.0

CONVENTION = ("imu_tk: a_cal = T_a K_a (a - b_a), T_a = [[1, -a_yz, a_zy], [0, 1, -a_zx], [0, 0, 1]] (upper "
              "triangular); w_cal = T_g K_g (w - b_g), T_g = [[1, -g_yz, g_zy], [g_xz, 1, -g_zx], [-g_xy, g_yx, 1]]; "
              "K = diag(s). casep ferraris: y = M f + b, M_a = (T_a K_a)^-1, M_g = (T_g K_g)^-1")


class FitWarning(CasepWarning):
    """An iterative fit did not converge, or its misfit is large: the result is probably wrong."""


def _unit(unit: str, table: dict, si: str) -> tuple[float, str, str]:
    """(SI factor applied to the readings, scale unit, bias unit) of a declared unit."""
    if unit == RAW_UNIT:
        return 1.0, f"{si}/a.u.", "a.u."
    return table[unit], "1", si


def ferraris_view(M_of_x, x: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``M = M_of_x(x)^-1`` (casep's ferraris matrix) and its std by the delta method (central differences)."""
    M = np.linalg.inv(M_of_x(x))
    G = np.empty((9, len(x)))
    for i in range(len(x)):
        h = 1e-6 * max(abs(x[i]), 1e-3)  # misalignments ~1e-3 rad, scales ~1 (SI) or ~1e-3 (counts)
        e = np.zeros(len(x))
        e[i] = h
        G[:, i] = (np.linalg.inv(M_of_x(x + e)) - np.linalg.inv(M_of_x(x - e))).ravel() / (2 * h)
    C = np.where(np.isfinite(C), C, 0.0)
    return M, covariance_std(G @ C @ G.T).reshape(3, 3)


@dataclass(frozen=True)
class MultipositionCalibration(OfEstimate):
    """The outcome of :func:`calibrate_multiposition` (the result protocol, :mod:`casep.results`).

    Attributes
    ----------
    result : EstimateResult
        ACC_NAMES, GYRO_NAMES and ``bg_x, bg_y, bg_z``: estimate, std, covariance (block diagonal).
    segmentation : Segmentation
    acc : AccFit
    gyro : GyroFit
    settings : dict
    """

    result: EstimateResult
    segmentation: Segmentation
    acc: AccFit
    gyro: GyroFit
    settings: dict = field(default_factory=dict)

    def value(self, name: str) -> float:
        return float(self.result.estimate[list(self.result.names).index(name)])

    def std(self, name: str) -> float:
        return float(self._std()[list(self.result.names).index(name)])

    def _std(self) -> np.ndarray:
        assert self.result.std is not None  # both fits give a covariance
        return self.result.std

    def ferraris(self) -> dict:
        """casep's ferraris names: ``Ma_ij`` (reading unit per m/s^2), ``ba_i``, ``Mg_ij`` (per rad/s), ``bg_i``."""
        out = {}
        Ma, sMa = ferraris_view(acc_matrix, self.acc.x, self.acc.covariance)
        Mg, sMg = ferraris_view(gyro_matrix, self.gyro.x, self.gyro.covariance)
        for pre, M, sM in (("Ma", Ma, sMa), ("Mg", Mg, sMg)):
            for i, a in enumerate("xyz"):
                for j, b in enumerate("xyz"):
                    out[f"{pre}_{a}{b}"] = {"estimate": float(M[i, j]), "std": float(sM[i, j])}
        for i, a in enumerate("xyz"):
            out[f"ba_{a}"] = {"estimate": float(self.acc.x[6 + i]), "std": float(self.acc.std[6 + i])}
            out[f"bg_{a}"] = {"estimate": float(self.gyro.bias[i]), "std": float(self.gyro.bias_std[i])}
        return out

    def to_dict(self) -> dict:
        d = self.result.to_dict()
        d["calibration"] = {"model": "multiposition", "convention": CONVENTION, "settings": self.settings,
                            "segmentation": self.segmentation.to_dict(), "ferraris": self.ferraris(),
                            "accelerometer": {"rms_misfit_m_s2": _rms(self.acc.residuals), "sigma": self.acc.sigma,
                                              "iterations": self.acc.iterations, "converged": self.acc.converged},
                            "gyro": {"rms_misfit_rad": _rms(self.gyro.residuals), "sigma": self.gyro.sigma,
                                     "iterations": self.gyro.iterations, "converged": self.gyro.converged}}
        return d

    def text(self) -> str:
        from casep.estimators.result import format_number

        r = self.result
        lines = [self.segmentation.text(), "", f"model multiposition ({CONVENTION})",
                 f"{'coefficient':<12} {'unit':<16} {'estimate':>14} {'std':>12}"]
        sd = self._std()
        for j, name in enumerate(r.names):
            lines.append(f"{name:<12} {r.units[j]:<16} {format_number(r.estimate[j], 14)} {format_number(sd[j])}")
        s = self.settings
        lines += ["", f"g {s['gravity']:.7g} m/s^2 ({s['gravity_source']}); accelerometer: RMS | |a_cal| - g | "
                  f"{_rms(self.acc.residuals):.3g} m/s^2 over {len(self.acc.residuals)} poses, "
                  f"{self.acc.iterations} iterations; gyro: RMS gravity-direction misfit "
                  f"{math.degrees(_rms(self.gyro.residuals)):.3g} deg over {len(self.gyro.residuals)} motions, "
                  f"{self.gyro.iterations} iterations"]
        lines += _full_scale_lines(self.settings)
        lines += drift_lines(self.settings.get("drift"))
        for sensor, d in self.result.diagnostics.items():
            cn = d["condition_number_equilibrated"]
            lines.append(f"{sensor}: condition number {cn:.3g} (equilibrated)" if cn else f"{sensor}: rank deficient")
            if d["groups"]:
                lines[-1] += "; near-dependencies: " + "; ".join("[" + ", ".join(g) + "]" for g in d["groups"])
        lines += ["", "casep ferraris view (y = M f + b):"]
        fv = self.ferraris()
        for pre in ("Ma", "Mg"):
            for a in "xyz":
                lines.append(f"  {pre}_{a}. " + "  ".join(f"{fv[f'{pre}_{a}{b}']['estimate']:+.6g} "
                                                          f"({fv[f'{pre}_{a}{b}']['std']:.2g})" for b in "xyz"))
        return "\n".join(lines)


def _full_scale_lines(settings: dict) -> list[str]:
    """The full scale raw counts imply (:func:`casep.calibration.saturation.implied_full_scale`), a line a sensor."""
    out = []
    for key, sensor in (("acc_full_scale", "accelerometer"), ("gyr_full_scale", "gyro")):
        fs = settings.get(key)
        if not fs or "full_scale" not in fs:
            continue
        u = fs["unit"]
        line = (f"{sensor} raw counts: full scale +-{fs['full_scale']:.4g} {u} over +-{fs['half_range_counts']:.0f} "
                f"counts (a {fs['bits']}-bit converter), {fs['ratio']:.4g} x the "
                f"{'declared' if fs.get('declared') else 'nominal'} +-{fs['nominal']:g} {u}")
        if sensor == "gyro":
            line += (f"; at {'the t column' if settings.get('t_column') else 'the assumed --rate'} "
                     f"{settings['rate_hz']:.6g} Hz" + ("" if settings.get("t_column") else
                                                        " (no t column: a wrong rate scales it by assumed / true)"))
        out.append(line)
        if "bias_si" in fs:  # the bias in SI beside the counts, natural units in brackets
            b = fs["bias_si"]
            nat = "mg" if sensor == "accelerometer" else "deg/s"
            k = 1.0 / {**ACC_UNITS, **GYR_UNITS}[nat]
            out.append(f"{sensor} bias in SI, T K (b - {b['zero_counts']:.0f}) (the reading at zero input): "
                       + ", ".join(f"{'xyz'[i]} {v:+.4g} +- {sd:.2g} {b['unit']} ({v * k:+.4g} {nat})"
                                   for i, (v, sd) in enumerate(zip(b["estimate"], b["std"]))))
    return out


def _floats(v) -> str:
    return ", ".join(f"{x:.3g}" for x in v)


def _drift_shown(sensor: str, v: dict) -> str:
    """One sensor's part of the drift line: share, std (also in natural units), -2 ln Lambda and, below the
    threshold (:attr:`casep.calibration.drift.DriftFit.shown`), that the session neither shows nor excludes one."""
    from casep.noise.model import AUTO_LR

    text = f"{sensor} {100 * v['share']:.0f} %, {_floats(v['sigma_d'])} {v['unit']}"
    if "natural" in v:
        text += f" ({_floats(v['natural']['sigma_d'])} {v['natural']['unit']})"
    if "lr_stat" in v:
        text += f", {v['lr_stat']:.3g}"
        if not v["shown"]:
            text += (f" (below the 1 % point {AUTO_LR:g} of white noise: a drift neither shown nor excluded; "
                     "the slow-drift bound below)")
    return text


def drift_lines(dr: dict | None) -> list[str]:
    """The report's lines on the bias drift (:func:`drift_report`'s dict): what the session shows, and the prior
    the biases' std carries or, without one, the slow drift the session cannot exclude and the std it would give."""
    if not dr:
        return []
    out = ["drift beyond white noise (share of a pose mean's variance, std, -2 ln Lambda against white noise; "
           "casep.calibration.drift): " + "; ".join(_drift_shown(k, v) for k, v in dr.items())]
    for k, v in dr.items():
        if "prior" in v:
            p = v["prior"]
            out.append(f"  {k} bias std with the drift prior (std {_floats(p['sigma_d'])} {v['unit']}, "
                       f"tau {p['tau_s']:.3g} s): {_floats(v['bias_std'])} {v['bias_unit']}")
        elif "slow_bound" in v:
            b = v["slow_bound"]
            out.append(f"  {k} bias std {_floats(v['bias_std'])} {v['bias_unit']}: no drift prior, holds for a drift "
                       f"correlation time up to about a quarter of the session; a drift of correlation time "
                       f"{b['tau_s']:.3g} s (the session) up to std {'>= ' if b['at_grid_end'] else ''}"
                       f"{_floats(b['sigma_d'])} {v['unit']} is consistent with it (95 %) and would make it "
                       f"{_floats(b['bias_std'])} {v['bias_unit']}; the sensor's drift: "
                       f"{'--acc-drift MG,TAU' if k == 'accelerometer' else '--gyr-drift DEG_H,TAU'}")
    return out


def _jacobian(fit: AccFit | GyroFit) -> np.ndarray:
    """The Jacobian a converged fit keeps at its solution."""
    assert fit.jacobian is not None  # every fit returned by multiposition keeps it
    return fit.jacobian


def _rms(r) -> float:
    return float(np.sqrt(np.mean(np.asarray(r) ** 2)))


def _propagate(gfit: GyroFit, afit: AccFit, means: np.ndarray, gyr: np.ndarray, rate: float, motions,
               dt: np.ndarray) -> GyroFit:
    """The gyro covariance with the errors of what its fit takes as known: the accelerometer's
    coefficients (through the gravity directions) and the gyro bias.

    At the minimum, a change ``dp`` of those moves the solution by ``dx = -(J^T J)^-1 J^T (dr/dp) dp``
    (J: the gyro Jacobian at the solution), so ``C_x += G C_p G^T``, ``G = -(J^T J)^-1 J^T dr/dp``,
    dr/dp by central differences.
    """
    from dataclasses import replace

    from casep.calibration.multiposition import gyro_residuals

    def r_of(pa, b):
        return gyro_residuals(gfit.x, gyr, rate, motions, *_dirs(replace(afit, x=pa), means), b, dt)

    p0 = np.concatenate([afit.x, gfit.bias])
    Cp = np.zeros((12, 12))
    Cp[:9, :9] = afit.covariance
    Cp[9:, 9:] = np.diag(np.where(np.isfinite(gfit.bias_std), gfit.bias_std, 0.0) ** 2)
    if not np.any(Cp):
        return gfit
    D = np.empty((3 * len(motions), 12))
    for i in range(12):
        h = 1e-6 * max(abs(p0[i]), 1e-3)
        e = np.zeros(12)
        e[i] = h
        D[:, i] = (r_of((p0 + e)[:9], (p0 + e)[9:]) - r_of((p0 - e)[:9], (p0 - e)[9:])) / (2 * h)
    Jx = np.empty((3 * len(motions), 9))
    r0 = gyro_residuals(gfit.x, gyr, rate, motions, *_dirs(afit, means), gfit.bias, dt)
    for i in range(9):
        h = 1e-7 * max(abs(gfit.x[i]), 1e-3)
        e = np.zeros(9)
        e[i] = h
        Jx[:, i] = (gyro_residuals(gfit.x + e, gyr, rate, motions, *_dirs(afit, means), gfit.bias, dt) - r0) / h
    G = -np.linalg.lstsq(Jx, D, rcond=None)[0]
    return replace(gfit, covariance=gfit.covariance + G @ Cp @ G.T)


def _dirs(afit: AccFit, means: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit gravity directions of the calibrated pose means: (before each motion, after it)."""
    u = afit.calibrate(means)
    u /= np.linalg.norm(u, axis=1)[:, None]
    return u[:-1], u[1:]


def separation(J: np.ndarray, names: tuple[str, ...]) -> dict:
    """What a fit's final linearisation can separate: the equilibrated condition number and the
    near-dependency groups (condition index > 30, variance proportions > 0.5), as ``casep diagnose``
    (:func:`casep.checks.diagnostics.collinearity` of the column-scaled Jacobian)."""
    from casep.checks.diagnostics import collinearity
    from casep.regression.linalg import analyze_rank, condition_numbers, reduce_qr

    red = reduce_qr(J, np.zeros(len(J)))
    ra = analyze_rank(red)
    col = collinearity(red, ra)
    return {"condition_number_equilibrated": condition_numbers(red, ra)["condition_number_equilibrated"],
            "groups": [[names[j] for j in g] for g in col["groups"]]}


def _result(acc: AccFit, gyro: GyroFit, units: tuple, n: int, message: str, success: bool):
    """The EstimateResult of both fits (block-diagonal covariance)."""

    names = ACC_NAMES + GYRO_NAMES + ("bg_x", "bg_y", "bg_z")
    est = np.concatenate([acc.x, gyro.x, gyro.bias])
    C = np.zeros((21, 21))
    C[:9, :9], C[9:18, 9:18] = acc.covariance, gyro.covariance
    C[18:, 18:] = np.diag(gyro.bias_std ** 2)
    return EstimateResult(method="levenberg-marquardt", names=names, units=units, estimate=est,
                          std=covariance_std(C), covariance=C, reasons={},
                          residuals=np.zeros((0, 3)), sigma=math.nan, rank=21, status=1 if success else 0,
                          message=message, success=success, si_factors=np.ones(21), model="multiposition",
                          diagnostics={"accelerometer": separation(_jacobian(acc), ACC_NAMES),
                                       "gyro": separation(_jacobian(gyro), GYRO_NAMES)},
                          n_samples=n, stored_residual_rms={a: None for a in "xyz"})


def _reissue(held: list[warnings.WarningMessage]) -> None:
    """Issue held warnings again, as they were."""
    for w in held:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def calibrate_multiposition(session: Session, segmentation: Segmentation | None = None, *,
                            gravity: float | None = None, latitude: float | None = None, height: float = 0.0,
                            window_s: float = 0.5, init_s: float = 5.0,
                            min_static_s: float = 0.5, acc_full_scale: float | None = None,
                            gyr_full_scale: float | None = None, acc_drift: tuple[float, float] | None = None,
                            gyr_drift: tuple[float, float] | None = None) -> MultipositionCalibration:
    """Calibrate a hand-turned session (module notes).

    Parameters
    ----------
    session : Session
        Its ``acc_unit`` / ``gyr_unit`` say how to read the columns (``a.u.``: raw counts).
    segmentation : Segmentation, optional
        Default: :func:`detect_static` on the session.
    gravity : float, optional
        Local gravity, m/s^2; else from `latitude` (deg) and `height` (m) by
        :func:`casep.calibration.gravity.normal_gravity`; else 9.80665.
    window_s, init_s, min_static_s : float
        Of :func:`detect_static`.
    acc_full_scale, gyr_full_scale : float, optional
        The sensors' full scale ``+-F``, m/s^2 and rad/s (``casep calibrate --acc-range G --gyr-range DPS``):
        readings held at it are saturated (:mod:`casep.calibration.saturation`). Default: a nominal range for a
        physical unit, the converter's limit for raw counts; raw counts also say the full scale their fitted
        scale implies, and warn (FullScaleWarning) when it is off the declared one.
    acc_drift, gyr_drift : (float, float), optional
        A prior on the bias drift (a datasheet's): a first-order Gauss-Markov process's stationary std (m/s^2,
        rad/s) and correlation time (s). The biases' std then carries what the session cannot show, a drift as
        slow as the session or slower (:func:`casep.calibration.drift.fit_drift_prior`); without it the std
        carries the drift the session shows and is honest for correlation times up to about a quarter of the
        session (DriftWarning when the session shows a slower one).
    """
    from casep.calibration.gravity import normal_gravity
    from casep.calibration.saturation import check_full_scale, declared_range
    from casep.units import G0

    for v, name, flag, u in ((acc_full_scale, "acc_full_scale", "--acc-range", "m/s^2"),
                             (gyr_full_scale, "gyr_full_scale", "--gyr-range", "rad/s")):
        if v is not None:
            check_full_scale(v, name, flag, u)
    for dp, flag, u in ((acc_drift, "--acc-drift", "m/s^2"), (gyr_drift, "--gyr-drift", "rad/s")):
        if dp is not None and not (len(dp) == 2 and all(math.isfinite(x) and x > 0 for x in dp)):
            raise ValueError(f"{flag} {dp}: a bias drift prior is a positive std ({u}) and a positive correlation "
                             "time (s)")
    acc_range = declared_range(acc_full_scale, session.acc_unit, "accelerometer")
    gyr_range = declared_range(gyr_full_scale, session.gyr_unit, "gyro")

    if gravity is not None and latitude is not None:
        raise ValueError("give --gravity or --latitude (with --height), not both")
    g, g_src = ((float(gravity), "given") if gravity is not None else
                (normal_gravity(latitude, height), f"WGS84 normal gravity at {latitude:g} deg, {height:g} m")
                if latitude is not None else (G0, "standard gravity"))
    if not (math.isfinite(g) and 9.7 <= g <= 9.9):
        raise ValueError(f"--gravity {g} m/s^2: the Earth's is 9.78..9.84")
    fa, sa_unit, ba_unit = _unit(session.acc_unit, ACC_UNITS, "m/s^2")
    fg, sg_unit, bg_unit = _unit(session.gyr_unit, GYR_UNITS, "rad/s")
    acc, gyr = session.acc * fa, session.gyr * fg
    _refuse_beyond_declared(session, acc, gyr, acc_range, gyr_range)
    held: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as held:
            # held until the gyro's unit is checked: a wrong unit also makes the poses' noise look like turns
            warnings.simplefilter("always")
            seg = segmentation or detect_static(acc, gyr, session.rate, gravity=g, window_s=window_s,
                                                init_s=init_s, min_static_s=min_static_s, source=session.source,
                                                gyr_si=None if session.gyr_unit == RAW_UNIT else 1.0)
    except ValueError:
        _reissue(held)  # no fit to check the unit by: the segmentation's warnings go with its error
        raise
    seg = _drop_clipped(seg, session, acc_range)
    saturated = check_gyro_saturation(session.gyr, seg.motions, session.gyr_unit, session.source, gyr_range)
    means = np.array([acc[a:b].mean(axis=0) for a, b in seg.poses])
    physical = session.acc_unit != RAW_UNIT
    # a physical unit is near its truth: start there (the extremes' half-range of a narrow session is not)
    afit = fit_accelerometer(means, g, counts=np.array([b - a for a, b in seg.poses]),
                             x0=np.array([0, 0, 0, 1, 1, 1, 0, 0, 0.0]) if physical else None)
    t_pose = np.array([session.t[a:b].mean() for a, b in seg.poses])
    n_pose = np.array([b - a for a, b in seg.poses])
    afit, acc_free = acc_drift_covariance(afit, means, t_pose, n_pose, session.rate)
    u0, u1 = _dirs(afit, means)
    gm = np.array([gyr[a:b].mean(axis=0) for a, b in seg.poses])
    bias, bias_std, gyr_free = pose_mean_bias(gm, t_pose, n_pose, session.rate)
    # each sample's rate held until the next sample's time (the last: one nominal interval)
    dt = np.diff(session.t, append=session.t[-1] + 1.0 / session.rate)
    gfit = fit_gyro(gyr, session.rate, seg.motions, u0, u1, bias, bias_std=bias_std,
                    scale0=None if session.gyr_unit == RAW_UNIT else 1.0, dt=dt)
    # the gyro's scale and misalignment see the bias and the gravity directions where the motions are: their errors
    # are the session's own drift (a prior's slow part is common to the bias and every motion's readings)
    gfit = _propagate(gfit, afit, means, gyr, session.rate, seg.motions, dt)
    afit, gfit, fits = _drift_priors(afit, acc_free, gfit, gyr_free, means, gm, (t_pose, n_pose, session.rate),
                                     acc_drift, gyr_drift)
    bias_std = gfit.bias_std
    check_acc_fit(afit, means, session)  # the units and the rate first: they explain everything else
    check_gyro_swap(gfit, gyr, session, seg.motions, (u0, u1), dt)
    check_gyro_scale(gfit.x[6:9], session)
    _reissue(held)
    drift = drift_report(fits, afit.std[6:9], bias_std, float(np.ptp(t_pose)), (ba_unit, bg_unit), session.source,
                         np.abs(gfit.x[6:9]) if session.gyr_unit == RAW_UNIT else np.ones(3))
    if session.gyr_unit == RAW_UNIT:  # the turn inside each pose, now that the counts' scale is known
        from dataclasses import replace

        from casep.calibration.segment import MAX_TURN_DEG, warn_turns

        wc = (gyr - bias) @ gyro_matrix(gfit.x).T
        turns = [math.degrees(float(np.linalg.norm((wc[a:b] * dt[a:b, None]).sum(axis=0)))) for a, b in seg.poses]
        warn_turns(seg.poses, turns, MAX_TURN_DEG, session.source)
        seg = replace(seg, turns_deg=turns)
    ok = afit.converged and gfit.converged and not saturated and not gyro_misfit(gfit, seg.motions, session,
                                                                                 bool(saturated))
    if not (afit.converged and gfit.converged):
        warnings.warn(f"{session.source}: the fit did not converge (accelerometer {afit.iterations} iterations, gyro "
                      f"{gfit.iterations}): the coefficients are probably wrong", FitWarning, stacklevel=2)
    units = ("rad",) * 3 + (sa_unit,) * 3 + (ba_unit,) * 3 + ("rad",) * 6 + (sg_unit,) * 3 + (bg_unit,) * 3
    res = _result(afit, gfit, units, session.n_samples,
                  f"{len(seg.poses)} poses, {len(seg.motions)} motions"
                  + ("" if afit.converged and gfit.converged else "; fit not converged")
                  + ("; the sensor saturates in a motion" if saturated else "")
                  + ("" if acc_drift and gyr_drift else f"; no {'gyro ' if acc_drift else ''}"
                     f"{'accelerometer ' if gyr_drift else ''}drift prior: the biases' std holds for a drift "
                     f"correlation time up to ~{0.25 * float(np.ptp(t_pose)):.0f} s (settings.drift)"), ok)
    settings = {"gravity": g, "gravity_source": g_src, "rate_hz": session.rate, "source": session.source,
                "acc_unit": session.acc_unit, "gyr_unit": session.gyr_unit, "t_column": session.t_column,
                "drift": drift}
    settings.update(_full_scales(session, afit, gfit, acc_full_scale, gyr_full_scale))
    return MultipositionCalibration(res, seg, afit, gfit, settings)


def _full_scales(session: Session, afit: AccFit, gfit: GyroFit, acc_fs: float | None, gyr_fs: float | None) -> dict:
    """The settings' full scales: raw counts' implied one (warned of when off the declared one), or the declared."""
    out: dict = {}
    for key, unit, sc, b, fs_si, sensor, raw in (
            ("acc_full_scale", session.acc_unit, afit.x[3:6], afit.x[6:9], acc_fs, "accelerometer", session.acc),
            ("gyr_full_scale", session.gyr_unit, gfit.x[6:9], gfit.bias, gyr_fs, "gyro", session.gyr)):
        if unit == RAW_UNIT:
            out[key] = implied_full_scale(sc, b, sensor, fs_si, raw)
            warn_implied_full_scale(out[key], sensor, session.source, not session.t_column)
            out[key]["bias_si"] = bias_si(afit if sensor == "accelerometer" else gfit, out[key]["zero_counts"])
        elif fs_si is not None:
            out[key] = {"declared": True, "full_scale_si": fs_si}
    return out


def bias_si(fit: AccFit | GyroFit, zero: float) -> dict:
    """Raw counts' bias in SI: ``T K (b - zero)`` (m/s^2 or rad/s; ``zero`` the count the converter reads at zero
    input, :func:`casep.calibration.saturation.converter`), what the sensor reads at zero input, as a datasheet's
    zero-g or zero-rate offset; std by the delta method from the fit's covariance (the gyro's bias independent of
    its scale and misalignment: its own pose means)."""
    if isinstance(fit, AccFit):
        x, C = fit.x, fit.covariance
    else:
        x = np.r_[fit.x, fit.bias]
        C = np.zeros((12, 12))
        C[:9, :9] = fit.covariance
        C[9:, 9:] = np.diag(np.where(np.isfinite(fit.bias_std), fit.bias_std, 0.0) ** 2)
    M_of_x = acc_matrix if isinstance(fit, AccFit) else gyro_matrix

    def off(p: np.ndarray) -> np.ndarray:
        return M_of_x(p[:9]) @ (p[-3:] - zero)

    G = np.empty((3, len(x)))
    for i in range(len(x)):  # central differences, steps relative to each coefficient's size
        h = 1e-6 * max(abs(x[i]), 1e-3)
        e = np.zeros(len(x))
        e[i] = h
        G[:, i] = (off(x + e) - off(x - e)) / (2 * h)
    C = np.where(np.isfinite(C), C, 0.0)
    return {"estimate": off(x).tolist(), "std": covariance_std(G @ C @ G.T).tolist(),
            "unit": "m/s^2" if isinstance(fit, AccFit) else "rad/s", "zero_counts": zero}


def check_acc_fit(afit: AccFit, means: np.ndarray, session: Session) -> None:
    """Refuse an accelerometer fit a unit mistake or the poses' spread explains (numbers in the message).

    Fitted scales off 1 by more than GRAVITY_TOLERANCE (physical unit) or a fit that did not converge, with
    the poses' gravity directions inside a cone narrower than CONE_DEG
    (:func:`casep.calibration.segment.pose_cone_deg`: the scale and bias along the cone's axis are then
    barely separable) and, in a physical unit, the pose means' median magnitude within GRAVITY_TOLERANCE
    of gravity (the unit is right): the spread is named. Else :func:`casep.calibration.checks.check_acc_scale`
    (the unit).
    """
    from casep.calibration.checks import GRAVITY_TOLERANCE, scale_off
    from casep.calibration.segment import pose_cone_deg, pose_spread

    unit, s, g = session.acc_unit, afit.x[3:6], afit.gravity
    physical = unit != RAW_UNIT
    unit_right = not physical or abs(float(np.median(np.linalg.norm(means, axis=1))) / g - 1.0) <= GRAVITY_TOLERANCE
    dirs = means if physical else afit.calibrate(means)
    cone = pose_cone_deg(dirs)
    off = scale_off(s, GRAVITY_TOLERANCE) if physical else None
    if (off is not None or not afit.converged) and cone < CONE_DEG and unit_right:
        src = "" if physical else " (from the fit)"
        raise ValueError(f"{session.source}: the {len(means)} poses' gravity directions{src} lie within "
                         f"{cone:.3g} deg of one direction (smallest singular value / sqrt(n) "
                         f"{pose_spread(dirs):.3g}; 0.577: spread evenly): the accelerometer's scale and bias along "
                         "it cannot be separated (fitted scales "
                         f"{', '.join(f'{v:.4g}' for v in s)}"
                         f"{'' if afit.converged else f', not converged in {afit.iterations} iterations'}). Use: "
                         "turn the sensor so that each axis points up and down")
    check_acc_scale(s, session)


def gyro_misfit(gfit: GyroFit, motions: list, session: Session, saturated: bool) -> bool:
    """FitWarning, and True, when the gyro's RMS gravity-direction misfit is above SWAP_MISFIT_DEG (hand-turned
    sessions fit to ~0.1 deg) and no saturation already explains it: the worst motions' rows and misfits, and the
    likely causes."""
    rms = math.degrees(_rms(gfit.residuals))
    if rms <= SWAP_MISFIT_DEG or saturated or not gfit.converged:
        return False
    per = np.degrees(np.linalg.norm(np.asarray(gfit.residuals).reshape(len(motions), -1), axis=1))
    worst = np.argsort(per)[::-1][:3]
    warnings.warn(f"{session.source}: the gyro fit leaves an RMS gravity-direction misfit of {rms:.3g} deg over "
                  f"{len(motions)} motions (a hand-turned session fits to ~0.1 deg; > {SWAP_MISFIT_DEG:g} deg is a "
                  "bad fit), worst " + ", ".join(f"rows {motions[i][0]}-{motions[i][1] - 1}: {per[i]:.3g} deg"
                                                  for i in worst)
                  + ". The turns are misread: a gyro that saturates below its converter's limits (a range narrower "
                  "than the counts), a gyro sampled at another time or rate than the accelerometers, or motion in "
                  "the poses. The coefficients are probably wrong", FitWarning, stacklevel=3)
    return True


def check_gyro_swap(gfit: GyroFit, gyr: np.ndarray, session: Session, motions: list,
                    dirs: tuple[np.ndarray, np.ndarray], dt) -> None:
    """Refuse a gyro whose columns are in another order than the accelerometer's (numbers and the order).

    A permutation of the axes is no small misalignment: the fit ends far off (scales off 1, a misfit of
    degrees, or no convergence) and would be read as a unit mistake. When the fit is bad in that way
    (not converged, RMS gravity-direction misfit above SWAP_MISFIT_DEG, or in a physical unit scales off 1
    by more than TURN_TOLERANCE), the five other orders of the columns are fitted; one that converges with
    a misfit under a tenth of the given order's (and scales within TURN_TOLERANCE in a physical unit) is named.
    """
    from itertools import permutations

    from casep.calibration.checks import TURN_TOLERANCE, scale_off

    physical = session.gyr_unit != RAW_UNIT

    def bad(f: GyroFit) -> bool:
        return (not f.converged or math.degrees(_rms(f.residuals)) > SWAP_MISFIT_DEG
                or (physical and scale_off(f.x[6:9], TURN_TOLERANCE) is not None))

    if not bad(gfit):
        return
    from casep.calibration.multiposition import gyro_start

    scale0 = 1.0 if physical else None
    # the order whose start fits best is fitted (a fit per order would cost five)
    u0, u1 = dirs
    order = min((o for o in permutations(range(3)) if o != (0, 1, 2)), key=lambda o: gyro_start(
        gyr[:, o], session.rate, motions, u0, u1, gfit.bias[list(o)], scale0, dt)[1])
    f = fit_gyro(gyr[:, order], session.rate, motions, u0, u1, gfit.bias[list(order)], scale0=scale0, dt=dt)
    rms = _rms(f.residuals)
    if bad(f) or rms > 0.1 * _rms(gfit.residuals):
        return
    names = ", ".join("xyz"[i] for i in order)
    raise ValueError(f"{session.source}: the gyro columns look swapped: taken in the order ({names}) the gyro fit "
                     f"converges with an RMS gravity-direction misfit of {math.degrees(rms):.3g} deg and scales "
                     f"{', '.join(f'{v:.4g}' for v in f.x[6:9])}; in the order given, "
                     f"{math.degrees(_rms(gfit.residuals)):.3g} "
                     f"deg and scales {', '.join(f'{v:.4g}' for v in gfit.x[6:9])}"
                     f"{'' if gfit.converged else f', not converged in {gfit.iterations} iterations'}. Use: "
                     f"--gyr-columns in the order {names} of the given ones (or the accelerometer's columns are "
                     "swapped: the gyro's axes must be the accelerometer's)")


def pose_mean_bias(gm: np.ndarray, t: np.ndarray, n: np.ndarray, rate: float,
                   prior: tuple[np.ndarray, float] | None = None) -> tuple[np.ndarray, np.ndarray, DriftFit]:
    """The gyro bias (the mean of the poses' mean readings `gm`, at times `t` s, of `n` samples at `rate` Hz)
    and its std with a drift (:mod:`casep.calibration.drift`).

    ``gm_k = b + d(t_k) + white_k``, white variance ``v0 nbar / n_k``: the bias's error is the mean of the
    drift over the poses plus the white noise's mean, ``var = v0 (1^T (W + rho D) 1) / m^2`` averaged over the
    drift grid (each axis its ``v0``); white noise alone gives the poses' scatter over sqrt(m). With `prior`
    (the drift's std per axis in the readings' unit, its correlation time in s) the drift is the prior's
    (:func:`casep.calibration.drift.fit_drift_prior`).
    """
    fit = _drift_fit(gm - gm.mean(axis=0), np.ones((len(gm), 1)), None, t, n, rate,
                     np.full((1, len(gm)), 1.0 / len(gm)), float(np.max(np.abs(gm))), prior)
    return gm.mean(axis=0), np.sqrt(fit.covariance[:, 0, 0]), fit


def _drift_fit(r, X, S, t, n, rate, A, scale, prior, W=None) -> DriftFit:
    """:func:`casep.calibration.drift.fit_drift` of pose rows (white shape ``nbar / n_k`` unless `W`), or
    :func:`casep.calibration.drift.fit_drift_prior` with `prior` ``(sigma_d, tau)``."""
    from casep.calibration.drift import drift_grid, fit_drift, fit_drift_prior

    n = np.asarray(n, dtype=float)
    m = len(n)
    W = np.diag(np.mean(n) / n) if W is None else W
    S = np.ones((m, m)) if S is None else S
    if prior is not None:
        return fit_drift_prior(r, X, W, S, t, A, prior[0], prior[1])
    return fit_drift(r, X, W, S, t, drift_grid(t, n / rate), A, scale)


class DriftWarning(CasepWarning):
    """The pose means drift slowly: without a drift prior the biases' std holds for a drift faster than about a
    quarter of the session; with one, the session shows more drift than the prior."""


def drift_report(fits: dict, acc_bias_std: np.ndarray, gyr_bias_std: np.ndarray, session_s: float,
                 units: tuple[str, str], source: str, gyr_si: np.ndarray) -> dict:
    """The drift each sensor's pose means show (:mod:`casep.calibration.drift`), warned of (DriftWarning, numbers)
    when it is most of their variance and slow, or, with a prior, when it is more than the prior's; a dict for the
    result's settings.

    `fits`: per sensor (``accelerometer``, ``gyro``) the session's own drift fit and the prior's (or None);
    `gyr_si`: rad/s per gyro reading unit, per axis (the drift also in natural units, mg and deg/h: ``natural``).
    """
    from casep.calibration.drift import drift_note, prior_note

    out = {}
    for (key, (fit, prior)), what, unit, bstd, bunit in zip(
            fits.items(), ("accelerometer's misfit", "gyro's pose means"), ("m/s^2", units[1]),
            (acc_bias_std, gyr_bias_std), units):
        out[key] = {"share": fit.drift_share, "lr_stat": fit.lr_stat, "shown": fit.shown,
                    "sigma_d": np.atleast_1d(fit.sigma_d).tolist(), "unit": unit,
                    "tau_s": float(np.exp(np.sum(fit.weights * np.log(fit.taus)))), "bias_unit": bunit,
                    "bias_std": np.atleast_1d(bstd).tolist()}
        to_nat = (1.0 / ACC_UNITS["mg"], "mg") if key == "accelerometer" else (gyr_si / GYR_UNITS["deg/h"], "deg/h")
        out[key]["natural"] = {"sigma_d": (np.atleast_1d(fit.sigma_d) * to_nat[0]).tolist(), "unit": to_nat[1]}
        if prior is None and fit.bound is not None:
            C = fit.bound["covariance"]
            var = np.diag(C[0])[6:9] if key == "accelerometer" else C[:, 0, 0]
            out[key]["slow_bound"] = {"tau_s": fit.bound["tau_s"], "at_grid_end": fit.bound["at_grid_end"],
                                      "sigma_d": np.atleast_1d(fit.bound["sigma_d"]).tolist(),
                                      "bias_std": np.sqrt(np.clip(var, 0, None)).tolist()}
        if prior is not None:
            out[key]["prior"] = {"sigma_d": np.atleast_1d(prior.sigma_d).tolist(), "tau_s": float(prior.taus[0]),
                                 "share": prior.drift_share}
        flag = "--acc-drift MG,TAU" if key == "accelerometer" else "--gyr-drift DEG_H,TAU"
        note = (drift_note(fit, what, unit, session_s, bstd, bunit, flag) if prior is None
                else prior_note(prior, fit, what, unit))
        if note:
            warnings.warn(f"{source}: {note}", DriftWarning, stacklevel=3)
    return out


def _drift_priors(afit: AccFit, acc_free: DriftFit, gfit: GyroFit, gyr_free: DriftFit, means: np.ndarray,
                  gm: np.ndarray, poses: tuple, acc_drift: tuple[float, float] | None,
                  gyr_drift: tuple[float, float] | None) -> tuple[AccFit, GyroFit, dict]:
    """The fits with the biases' std of the drift priors (each sensor's given, in the readings' unit: the std in SI
    over each axis's scale), and per sensor the session's own drift fit and the prior's (or None).

    `poses`: the poses' times (s), samples and the rate (Hz).
    """
    from dataclasses import replace

    t, n, rate = poses
    fits: dict = {"accelerometer": (acc_free, None), "gyro": (gyr_free, None)}
    if acc_drift is not None:
        ap = acc_drift_covariance(afit, means, t, n, rate, acc_drift)
        afit, fits["accelerometer"] = ap[0], (acc_free, ap[1])
    if gyr_drift is not None:
        _, bias_std, gp = pose_mean_bias(gm, t, n, rate, (gyr_drift[0] / np.abs(gfit.x[6:9]), gyr_drift[1]))
        gfit, fits["gyro"] = replace(gfit, bias_std=bias_std), (gyr_free, gp)
    return afit, gfit, fits


def acc_drift_covariance(afit: AccFit, means: np.ndarray, t: np.ndarray, n: np.ndarray, rate: float,
                         prior: tuple[float, float] | None = None) -> tuple[AccFit, DriftFit]:
    """The accelerometer fit with its covariance widened by the drift its misfit shows (:mod:`casep.calibration.drift`),
    or by the drift `prior` states (its std in m/s^2, its correlation time in s).

    Rows ``r_k = w_k (|T K (abar_k - b)| - g)``; a reading error ``e_k`` moves row k by ``w_k a_k . e_k``,
    ``a_k = (T K)^T u_k`` (``u_k`` the calibrated gravity direction); the drift, the same process on each axis
    in m/s^2 (``e_k = K^-1 d_k`` in the readings' unit), couples rows k, l by
    ``w_k w_l (K^-1 a_k) . (K^-1 a_l) exp(-|t_k - t_l| / tau)``; ``x - x_true = -J^+ r`` (J the fit's weighted
    Jacobian at its solution).
    """
    from dataclasses import replace

    J = _jacobian(afit)
    n = np.asarray(n, dtype=float)
    w = np.sqrt(n / np.mean(n))
    v = afit.calibrate(means)
    a = (v / np.linalg.norm(v, axis=1)[:, None]) @ acc_matrix(afit.x)  # a_k = (T K)^T u_k, one per row
    a = a / afit.x[3:6]  # per m/s^2 of drift (K: the scales, SI per reading unit)
    d = np.linalg.norm(J, axis=0)
    d[d == 0] = 1.0
    A = np.linalg.pinv(J / d) / d[:, None]
    fit = _drift_fit(w * afit.residuals, J, np.outer(w, w) * (a @ a.T), t, n, rate, A, afit.gravity,
                     None if prior is None else (np.atleast_1d(prior[0]), prior[1]), W=np.eye(len(J)))
    return replace(afit, covariance=fit.covariance[0]), fit


def _drop_clipped(seg: Segmentation, session: Session, acc_range) -> Segmentation:
    """The segmentation without the poses in which the accelerometer clips (warned of by
    :func:`casep.calibration.saturation.clipped_poses`), listed among its rejected intervals.

    Raises
    ------
    SegmentError
        Fewer than the accelerometer model's poses are left.
    """
    from dataclasses import replace

    from casep.calibration.segment import MIN_POSES
    from casep.calibration.session import SegmentError

    bad = clipped_poses(session.acc, seg.poses, session.acc_unit, session.source, acc_range)
    if not bad:
        return seg
    keep = [p for i, p in enumerate(seg.poses) if i not in bad]
    if len(keep) < MIN_POSES:
        raise SegmentError(f"{session.source}: the accelerometer saturates in {len(bad)} of {len(seg.poses)} static "
                           f"poses; {len(keep)} are left, fewer than the {MIN_POSES} the accelerometer model needs. "
                           "Use: a wider range, or poses that keep every axis inside it")
    return replace(seg, poses=keep, rejected=seg.rejected + [(seg.poses[i][0], seg.poses[i][1],
                                                              "the accelerometer saturates") for i in bad],
                   turns_deg=[t for i, t in enumerate(seg.turns_deg) if i not in bad])


def _refuse_beyond_declared(session: Session, acc: np.ndarray, gyr: np.ndarray, acc_range: float | None,
                            gyr_range: float | None) -> None:
    """A ValueError naming the file, the column, the row and the numbers when a sensor reads beyond
    :data:`casep.fullscale.DECLARED_EXCEEDED` times its declared full scale (`acc`, `gyr` and the ranges SI; the
    rule of the raw-IMU and telemetry paths, :func:`casep.fullscale.beyond_declared`): a sensor clipped at its range
    reads at it, so the declared range (or the column's unit) is wrong."""
    for k, (x, sensor, fs) in enumerate(((acc, "accelerometer", acc_range), (gyr, "gyro", gyr_range))):
        beyond = beyond_declared(x, sensor, fs)
        if beyond is not None:
            j, i, said = beyond
            raise ValueError(f"{session.source}: column `{session.columns[3 * k + j]}`, row {session.file_row(i)} "
                             f"(t = {session.t[i]:.10g} s): {said}")


def calibrate_multiposition_file(session: str | os.PathLike, *, rate: float | None = None, acc_columns=None,
                                 gyr_columns=None, acc_unit: str = "a.u.", gyr_unit: str = "a.u.",
                                 **kwargs) -> MultipositionCalibration:
    """:func:`calibrate_multiposition` of a session file (``casep calibrate --segments auto``).

    A text file without a header (``.log``, ``.txt``, gzipped or not: whitespace-separated ``ax ay az wx wy wz``,
    as imu_tk and the MPU-9150 sessions of Mikov et al. store them) is read too.
    """
    from casep.calibration.session import ACC_COLUMNS, GYR_COLUMNS, read_session

    plain = str(session).lower().endswith((".log", ".txt", ".log.gz", ".txt.gz"))
    ses = (_read_plain(session, rate, acc_unit, gyr_unit) if plain
           else read_session(session, rate=rate, acc_columns=acc_columns or ACC_COLUMNS,
                             gyr_columns=gyr_columns or GYR_COLUMNS, acc_unit=acc_unit, gyr_unit=gyr_unit))
    return calibrate_multiposition(ses, **kwargs)


def _read_plain(path, rate, acc_unit, gyr_unit) -> Session:
    """Whitespace-separated ``ax ay az wx wy wz`` rows, no header, no time (needs `rate`)."""
    if rate is None:
        raise ValueError(f"{path}: a text session has no time column. Use: --rate HZ")
    try:
        a = np.loadtxt(path, ndmin=2)
    except (OSError, ValueError) as exc:
        raise ValueError(f"session file {path}: cannot be read as whitespace-separated numbers ({exc})") from None
    if a.shape[1] != 6 or not np.all(np.isfinite(a)):
        bad = np.flatnonzero(~np.all(np.isfinite(a), axis=1))
        raise ValueError(f"session file {path}: needs 6 finite columns ax ay az wx wy wz, got {a.shape[1]}"
                         + (f" (row {bad[0] + 1} not finite)" if bad.size else ""))
    return Session(t=np.arange(len(a)) / float(rate), acc=a[:, :3], gyr=a[:, 3:], rate=float(rate), source=str(path),
                   acc_unit=acc_unit, gyr_unit=gyr_unit, columns=("ax", "ay", "az", "wx", "wy", "wz"), header_lines=0)
