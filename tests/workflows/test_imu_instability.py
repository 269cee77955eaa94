"""The IMU's bias instability in a strapdown telemetry's std: a reduced seeded Monte Carlo.

The flights come from the independent INS of ``tests/conftest.py`` (:func:`ins_telemetry`) with a bias instability the
INS integrates (a first-order Gauss-Markov bias per body axis, 0.3 mg and 20 deg/h, correlation time 20 s) and white
tracking noise. ``benchmarks/mc_imu_instability.py`` runs the full Monte Carlo (and the Gauss-Markov tracking noise,
the white-only IMU) for the figures of ``docs/results/car-drive.md``.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from conftest import ins_telemetry
from scipy.stats import chi2

import casep
from casep.checks.tracking_quality import IMU_INSTABILITY_SIZE, IMU_INSTABILITY_TAU
from casep.io.files import write_table
from casep.units import G0
from casep.workflows.row_estimators import added_covariance

MEMS = {"ba_x": 1.05, "ba_y": 1.78, "ba_z": -2.55, "sa_x": -41.0, "sa_y": 304.0, "sa_z": 406.0,
        "bg_x": 1000.0, "bg_y": -800.0, "bg_z": 600.0, "sg_x": 400.0, "sg_y": -350.0, "sg_z": 300.0}
WANDER = (0.3e-3 * G0, math.radians(20.0 / 3600.0), 20.0)  # m/s^2, rad/s, s


def _separate(tmp_path, seed: int, bias_noise, tau, given=None):
    """One 30 s MEMS flight with tracking at 4 Hz (white, 0.02 m/s), separated with casep's defaults; `tau` the
    instability term's correlation time (None: not asked for), `given` its variances (None: fitted)."""
    tel, trk, D, _ = ins_telemetry(seed=seed, errors=MEMS, imu_noise=False, growth=0.0, noise=0.02, dur=30.0,
                                   trk_rate=4.0, bias_noise=bias_noise)
    write_table(tmp_path / "tel.csv", tel)
    write_table(tmp_path / "trk.csv", trk)
    flight = casep.read_flight_pair(tmp_path / "tel.csv", tmp_path / "trk.csv")
    if tau is not None:
        flight.meta[IMU_INSTABILITY_TAU] = tau
    if given is not None:
        flight.meta[IMU_INSTABILITY_SIZE] = given
    model = casep.load_model("strapdown12")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # MEMS estimates: 100s of their declared (navigation-grade) magnitudes
        res = casep.separate(flight, model)
    # z against the std without the omitted terms' consider part (the truth holds none of them): the instability
    # term alone is judged here
    E = added_covariance(res)
    std = res.std if E is None else np.sqrt(np.diag(np.asarray(res.covariance) - E))
    return res, (res.estimate - np.array([D[n] for n in model.names])) / std


def test_a_wandering_bias_needs_the_instability_term_and_the_term_finds_its_size(tmp_path):
    """One seed (12 z, against the std without the omitted terms' consider part, which at their declared magnitudes
    happen to cover the wander: the full Monte Carlo's RMS z 1.05 without the term, 0.73 with it): without the term
    the std are too small (RMS z 2.78 measured: a wander of 0.3 mg and 20 deg/h is far larger than what 0.02 m/s of
    tracking determines); with it the RMS z falls by more than 1.5 times to within the 0.1 % and 99.9 % points of the
    RMS of 12 standard normal z, [0.43, 1.66] (1.63 measured: 12 z of one flight scatter; the full Monte Carlo's 192 z
    give 1.08, 92.2 % within 1.96: ``benchmarks/mc_imu_instability.py --seeds 1 .. 16 --gm 0 --sa 0.3 --sg 20``),
    and the accelerometers' size fitted by the restricted likelihood is within a factor 3 of the truth's (0.48 mg),
    said in mg; the term is left out unless asked for."""
    res, z0 = _separate(tmp_path, 5, WANDER, None)
    assert res.success and res.diagnostics["noise"]["imu"]["instability"] is None
    res, z1 = _separate(tmp_path, 5, WANDER, 20.0)
    held = res.diagnostics["noise"]["imu"]["instability"]
    assert res.success and held["tau_s"] == 20.0, res.message
    rms0, rms1 = (math.sqrt(np.mean(z**2)) for z in (z0, z1))
    lo, hi = (math.sqrt(chi2.ppf(p, z1.size) / z1.size) for p in (1e-3, 1 - 1e-3))
    assert rms0 > hi and rms1 < rms0 / 1.5 and lo <= rms1 <= hi, (rms0, rms1, lo, hi)
    assert 0.1 <= held["accelerometer_mg"] <= 0.9 and held["gyro_deg_h"] >= 0.0, held
    # the size given back (as a size pooled over windows is: the one rule of the term's covariance), the tracking
    # noise refitted at it: the same std, to the searches' tolerance, and the record says it was given
    res2, _ = _separate(tmp_path, 5, WANDER, 20.0, tuple(held["variances"]))
    given = res2.diagnostics["noise"]["imu"]["instability"]
    assert given["given"] and given["variances"] == held["variances"] and "given" not in held
    np.testing.assert_allclose(res2.std, res.std, rtol=0.01)
    np.testing.assert_array_equal(res2.estimate, res.estimate)


def test_a_white_only_imu_keeps_its_std_with_the_term(tmp_path):
    """The INS's IMU without a wander (white tracking noise only): the term asked for finds next to nothing (below a
    tenth of the wander above) and the std stay within 2 % of those without it."""
    res0, _ = _separate(tmp_path, 2, None, None)
    res1, _ = _separate(tmp_path, 2, None, 20.0)
    held = res1.diagnostics["noise"]["imu"]["instability"]
    assert res1.success and held["accelerometer_mg"] < 0.03 and held["gyro_deg_h"] < 2.0, held
    np.testing.assert_allclose(res1.std, res0.std, rtol=0.02)


def test_the_correlation_time_asked_for_is_checked():
    """The flight's ``meta[IMU_INSTABILITY_TAU]``: None leaves the term out, a positive time is taken, zero, a
    negative or a non-finite time or a text is an error naming the value."""
    import pytest

    from casep.io.flight import FlightData
    from casep.workflows.imu_separate import instability_tau

    def flight(value):
        meta = {} if value is None else {IMU_INSTABILITY_TAU: value}
        return FlightData(np.arange(3.0), np.zeros((3, 3)), np.zeros((3, 3)), meta=meta)

    assert instability_tau(flight(None)) is None and instability_tau(flight(20)) == 20.0
    for bad in (0.0, -5.0, math.inf, "20"):
        with pytest.raises(ValueError, match="correlation time > 0 s"):
            instability_tau(flight(bad))


def test_the_size_given_is_checked():
    """The flight's ``meta[IMU_INSTABILITY_SIZE]``: two finite variances >= 0 with a correlation time, else an error;
    absent: fitted."""
    import pytest

    from casep.io.flight import FlightData
    from casep.workflows.imu_separate import instability_given

    def flight(q, tau=20.0):
        meta = {IMU_INSTABILITY_TAU: tau} if tau else {}
        if q is not None:
            meta[IMU_INSTABILITY_SIZE] = q
        return FlightData(np.arange(3.0), np.zeros((3, 3)), np.zeros((3, 3)), meta=meta)

    assert instability_given(flight(None)) is None and instability_given(flight((1e-6, 0))) == (1e-6, 0.0)
    for bad, said in (((1.0,), "two variances"), ((-1.0, 0.0), ">= 0"), ((math.nan, 0.0), ">= 0"), ("ab", "two")):
        with pytest.raises(ValueError, match=said):
            instability_given(flight(bad))
    with pytest.raises(ValueError, match="without its correlation time"):
        instability_given(flight((1e-6, 1e-8), tau=None))
