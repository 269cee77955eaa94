"""Strapdown telemetry with errors too large for the linear model (casep.workflows.telemetry_iterate): the corrected
record re-navigated against an independent INS, the remainder rule, the iterated separation and its std.

The flights come from the INS simulation of ``tests/conftest.py`` (:func:`ins_telemetry`: written there, not
casep's), with MEMS-grade gyro biases (600-1000 deg/h: the attitude is off by ~15 deg after 60 s).
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest
from conftest import ins_telemetry

import casep
from casep.io.files import write_table

#: MEMS-grade errors (strapdown12, natural units).
MEMS = {"ba_x": 1.05, "ba_y": 1.78, "ba_z": -2.55, "sa_x": -41.0, "sa_y": 304.0, "sa_z": 406.0,
        "bg_x": 1000.0, "bg_y": -800.0, "bg_z": 600.0, "sg_x": 400.0, "sg_y": -350.0, "sg_z": 300.0}


def _pair(tmp_path_factory, name, dur=30.0, **kw):
    """The telemetry + tracking files of :func:`ins_telemetry` (`dur` s, tracking at 2 Hz), read as casep separate
    reads them; the truth and the tables."""
    tel, trk, D, _ = ins_telemetry(growth=0.0, dur=dur, trk_rate=2.0, **kw)
    d = tmp_path_factory.mktemp(name)
    write_table(d / "tel.csv", tel)
    write_table(d / "trk.csv", trk)
    return casep.read_flight_pair(d / "tel.csv", d / "trk.csv"), D, tel, trk


@pytest.fixture(scope="module")
def model():
    return casep.load_model("strapdown12")


@pytest.fixture(scope="module")
def noise_free(tmp_path_factory):
    """The MEMS flight, noise-free (tracking and written IMU alike): the attitude ~8 deg off after 30 s."""
    return _pair(tmp_path_factory, "nf", errors=MEMS, noise=0.0, imu_noise=False)


def test_corrected_telemetry_is_the_true_navigation(noise_free, model):
    """The telemetry's record corrected at the true coefficients and re-navigated from its own first state gives the
    true velocity: to 1e-4 of the INS's own error (tens of m/s)."""
    from casep.workflows.telemetry_iterate import corrected_telemetry, strapdown_arrays

    flight, D, tel, trk = noise_free
    q, fb, w = strapdown_arrays(flight.meta["pair_inputs"])
    v_tel = np.column_stack([tel[f"v_tel_{a}"] for a in "xyz"])
    c = corrected_telemetry(model, tel["t"], q, fb, w, v_tel, np.array([D[n] for n in model.names]))
    on = np.isin(tel["t"], trk["t"])
    v_true = np.column_stack([trk[f"v_trk_{a}"] for a in "xyz"])[np.isin(trk["t"], tel["t"])]
    ins_error = np.abs(v_tel[on] - v_true).max()
    assert ins_error > 5.0  # MEMS: far beyond the linear model
    assert np.abs(c.v[on] - v_true).max() < 1e-4 * ins_error, np.abs(c.v[on] - v_true).max()
    assert np.allclose(np.linalg.norm(c.q, axis=1), 1.0, atol=1e-12)


def test_noise_free_mems_flight_is_iterated_to_the_truth(noise_free, model):
    """Iterated by default (the remainder rule), every coefficient within 0.01 CRLB std at 0.1 m/s, where the linear
    pass was more than one off (``--no-iterate``: the CLI test below)."""
    flight, D, *_ = noise_free
    truth = np.array([D[n] for n in model.names])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # noise-free: conditioning and magnitude warnings
        res = casep.separate(flight, model, method="ols", noise="white", robust="none", sigma=0.1)
    lin = res.diagnostics["linearisation"]
    assert lin["iterated"] and lin["shift_std"] > 100 * lin["tol"], lin
    crlb = np.array([res.diagnostics["crlb_std"][n] for n in model.names])
    err = np.abs(res.estimate - truth) / crlb
    assert res.success and err.max() <= 0.01, dict(zip(model.names, err.round(4)))
    first = res.diagnostics["iterations"]["passes"][0]["estimate"]  # the linear pass
    linear = np.array([first[n] for n in model.names])
    assert (np.abs(linear - truth) / crlb).max() > 1  # what the rule is about (the iterated: < 0.01)


def test_noisy_mems_flights_iterated_with_honest_std(tmp_path_factory, model):
    """Seeded 20 s flights, white tracking noise 0.02 m/s, fitted as white: iterated, every coefficient within 4 std,
    RMS z of the 24 (two flights) in [0.5, 1.6], the INS's noise term in the std (what the record's second
    differences read: motion only, this IMU is noise-free); ``benchmarks/mc_telemetry_iterate.py`` runs more flights
    for the figures."""
    z = []
    for seed in (11, 12):
        flight, D, *_ = _pair(tmp_path_factory, f"mems{seed}", 20.0, seed=seed, errors=MEMS, imu_noise=False)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the estimates are 100s of their declared (navigation-grade) magnitudes
            res = casep.separate(flight, model, noise="white", robust="none")
        assert res.success and res.diagnostics["linearisation"]["iterated"], res.message
        assert res.diagnostics["noise"]["imu"]["std_factor_max"] >= 1.0  # the INS's noise term (here: motion only)
        # strapdown33's further terms tested on the last pass (casep.workflows.omitted_terms): the truth is the model's
        assert res.diagnostics["omitted_terms"]["p_value"] > 1e-3
        z.extend((res.estimate - np.array([D[n] for n in model.names])) / res.std)
    z = np.array(z)
    assert np.abs(z).max() < 4.0 and 0.5 <= math.sqrt(np.mean(z**2)) <= 1.6, z.round(2)


def test_navigation_grade_telemetry_stays_linear_and_silent(tmp_path_factory, model):
    """Navigation-grade errors (bg ~ 3 deg/h): the remainder is far below a tenth of a std; no iteration, no
    warning, the result the linear one."""
    flight, D, *_ = _pair(tmp_path_factory, "nav", seed=5, imu_noise=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = casep.separate(flight, model, noise="white", robust="none")
    lin = res.diagnostics["linearisation"]
    assert res.success and not lin["iterated"] and lin["shift_std"] < lin["tol"], lin
    assert res.diagnostics["omitted_terms"]["p_value"] > 1e-3  # the linear result that stands: tested, silent


def test_cli_no_iterate_on_telemetry_fails_the_curved_linear_pass(noise_free, capsys):
    """``casep separate TEL --tracking TRK --no-iterate``: the linear pass kept, said (NonlinearityWarning with the
    shift) and failed, exit 1; ``--iterate`` with two flights is refused (exit 2) rather than ignored."""
    from casep.cli.app import main

    flight, *_ = noise_free
    tel, trk = flight.source.split(" + ")  # the files the pair was read from
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["separate", tel, "--tracking", trk, "--model", "strapdown12", "--noise", "white", "--robust",
                     "none", "--sigma", "0.1", "--no-iterate"]) == 1
    assert "the linear model does not hold on this strapdown record" in capsys.readouterr().err
    assert main(["separate", tel, tel, "--tracking", trk, "--iterate"]) == 2
    assert "--iterate is used with --imu IMU.csv or one strapdown telemetry file" in capsys.readouterr().err


def test_earth_fixed_tracking_is_judged_as_the_launch_frame_one(noise_free, model, tmp_path):
    """The MEMS flight's tracking written in ECEF (casep's own conversion, the pad's inertial velocity added to
    telemetry and tracking alike so that the pad is at rest on the Earth) and read with ``tracking_frame="ecef"``:
    the remainder is judged as on the launch-frame tracking (both with ``dt_trk`` and the site's gravitation, which
    the launch-frame pair is given as a ``casep navigate`` header would: the same shift to 1e-6 relative, above the
    tolerance), and the linear pass kept (``iterate=False``) is said and failed, not a plain success."""
    from casep.estimators.registry import STATUS_MISFIT
    from casep.exceptions import NonlinearityWarning
    from casep.frames import LaunchSite, launch_to_ecef

    flight, _, tel, trk = noise_free
    site = LaunchSite(67.89, 21.10, 330.0, 30.0, 0.0)
    _, pad = launch_to_ecef(site, [0.0], np.zeros((1, 3)), np.zeros((1, 3)))  # v_E of a launch-inertial point at rest
    c = -site.C.T @ pad[0]  # the pad's launch-inertial velocity at t0
    v = np.column_stack([trk[f"v_trk_{a}"] for a in "xyz"]) + c
    t = np.asarray(trk["t"])
    r = np.vstack([np.zeros((1, 3)), np.cumsum((v[1:] + v[:-1]) / 2 * np.diff(t)[:, None], axis=0)])  # trapezoid
    r_e, v_e = launch_to_ecef(site, t, r, v)
    write_table(tmp_path / "tel.csv", {**tel, **{f"v_tel_{a}": tel[f"v_tel_{a}"] + c[i] for i, a in enumerate("xyz")}})
    write_table(tmp_path / "trk.csv", {"t": t, **{f"r_ecef_{a}": r_e[:, i] for i, a in enumerate("xyz")},
                                      **{f"v_ecef_{a}": v_e[:, i] for i, a in enumerate("xyz")}})
    earth = casep.read_flight_pair(tmp_path / "tel.csv", tmp_path / "trk.csv", tracking_frame="ecef", site=site)
    assert "state_from" in earth.meta
    launch = dataclasses.replace(flight, meta={**flight.meta, "telemetry_site": site.to_dict()})
    got = {}
    for name, fl in (("launch", launch), ("ecef", earth)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")  # noise-free: conditioning and magnitude warnings besides
            got[name] = casep.separate(fl, model, method="ols", noise="white", robust="none", sigma=0.1,
                                       iterate=False, fit_time_offset=True)  # dt_trk: Earth-fixed tracking's default
        said = [str(w.message) for w in caught if issubclass(w.category, NonlinearityWarning)]
        assert any("does not hold on this strapdown record" in m for m in said), (name, said)
    lin, ref = got["ecef"].diagnostics["linearisation"], got["launch"].diagnostics["linearisation"]
    assert lin["shift_std"] > 100 * lin["tol"] and not lin["iterated"], lin
    assert lin["shift_std"] == pytest.approx(ref["shift_std"], rel=1e-6)
    assert not got["ecef"].success and got["ecef"].status == STATUS_MISFIT


def test_the_time_offset_term_of_a_pass_takes_the_corrected_trajectorys_acceleration(noise_free, model, tmp_path):
    """The noise-free MEMS flight with the tracking's tags 20 ms late: the offset's row ``a(t) dt_trk`` of each pass
    is the re-navigated trajectory's acceleration: iterated, every coefficient and dt_trk within 0.05 CRLB std at
    0.1 m/s (about 0.005 measured). With the raw telemetry's acceleration (off by ~1 m/s^2 here) they were up to
    0.11 CRLB std off, and on a MEMS boost with 0.02 m/s tracking RMS z 2.6 against the truth."""
    _, D, tel, trk = noise_free
    write_table(tmp_path / "tel.csv", tel)
    write_table(tmp_path / "trk.csv", {**trk, "t": trk["t"] + 0.02})
    flight = casep.read_flight_pair(tmp_path / "tel.csv", tmp_path / "trk.csv")
    truth = np.array([D[n] for n in model.names])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # noise-free: conditioning and magnitude warnings
        res = casep.separate(flight, model, method="ols", noise="white", robust="none", sigma=0.1,
                             fit_time_offset=True)
    assert res.diagnostics["linearisation"]["iterated"]
    names = list(res.names)
    crlb = np.array([res.diagnostics["crlb_std"][n] for n in names])
    err = np.abs(res.estimate - np.append(truth, 20.0 if res.estimate[-1] > 0 else -20.0)) / crlb
    assert names[-1] == "dt_trk" and err.max() <= 0.05, dict(zip(names, err.round(4)))


@pytest.fixture(scope="module")
def launch_frame_ins():
    """A 20 s boost at 20 Hz in the launch-inertial frame of a site, navigated by casep's navigator from a given
    state twice: the clean record (the truth) and the record with ``MEMS`` (the model's own forward law,
    :func:`casep.model.strapdown.body_errors`), the INS 31 m off after 20 s. Gravitation: the site's
    (:func:`casep.navigation.strapdown.launch_gravitation`), evaluated by each navigation at its own position."""
    from scipy.spatial.transform import Rotation

    from casep.frames import LaunchSite, ecef_to_launch
    from casep.model.strapdown import body_errors
    from casep.navigation import ImuData, check_imu
    from casep.navigation.navigator import navigate_from

    site = LaunchSite(67.89, 21.1, 330.0, 30.0, 0.0)
    t = np.arange(0.0, 20.0 + 1e-9, 0.05)
    f = np.column_stack([30.0 + 15.0 * np.sin(0.4 * t), 2.0 * np.sin(0.7 * t), 1.5 * np.cos(0.45 * t)])
    w = np.column_stack([np.minimum(t / 3.0, 1.0) * np.cos(0.2 * t), -0.02 + 0.1 * np.sin(0.5 * t),
                         0.08 * np.sin(0.3 * t)])
    q0 = Rotation.from_euler("zx", [80.0, 10.0], degrees=True).as_quat()[[3, 0, 1, 2]]
    r0, v0 = ecef_to_launch(site, t[:1], site.r_site[None, :], np.zeros((1, 3)))  # on the pad at t0
    clean = navigate_from(check_imu(ImuData(t, w, f)), site, q0, r0[0], v0[0])
    model = casep.load_model("strapdown12")
    D = np.array([MEMS[n] for n in model.names])
    df, dw = body_errors(model, clean.q, f, w, t, D)
    ins = navigate_from(check_imu(ImuData(t, w + dw, f + df)), site, q0, r0[0], v0[0])
    return site, clean, ins, model, D


def test_corrected_telemetry_carries_the_gravitation_along_the_corrected_path(launch_frame_ins):
    """The INS's record corrected at the true coefficients re-navigates onto the clean navigation to rounding (1e-9
    m/s; ~5e-13 measured: the same mechanisation, the gravitation difference integrated by the navigator's own rule
    along the corrected position). Without the term (the gravitation kept at the INS's position, 31 m off) it is
    5e-4 m/s off: first order in the position error, ``int Gamma (r_c - r_tel) dt``; with ``r_tel`` integrated from
    ``v_tel`` instead of given, within 1e-7 m/s of the given one (the gradient barely changes over the distance)."""
    from casep.navigation.strapdown import launch_gravitation
    from casep.workflows.telemetry_iterate import corrected_telemetry

    site, clean, ins, model, D = launch_frame_ins
    G = launch_gravitation(site)
    args = (model, ins.t, ins.q, ins.fb, ins.w, ins.v, D)
    assert np.abs(ins.r - clean.r).max() > 30.0 and np.abs(ins.v - clean.v).max() > 3.0
    exact = corrected_telemetry(*args, gravity=G, r=ins.r)
    assert np.abs(exact.v - clean.v).max() < 1e-9, np.abs(exact.v - clean.v).max()
    assert np.abs(corrected_telemetry(*args).v - clean.v).max() > 2e-4  # the term left out
    assert np.abs(corrected_telemetry(*args, gravity=G).v - exact.v).max() < 1e-7


def test_a_navigated_telemetry_pass_takes_its_sites_gravitation(launch_frame_ins, tmp_path):
    """The INS written as ``casep navigate`` writes it (header with the site, ``r_tel_*``) and read as a pair: its
    site in ``meta["telemetry_site"]``, and a pass of the iteration at the true coefficients gives the clean
    navigation to 1e-9 m/s. The site of Earth-fixed tracking, its launch time in the tracking's scale, serves
    (``time_shift_s``) when the telemetry names none; with no site, no gravitation (None)."""
    from casep.estimators.spec import FitSpec
    from casep.navigation.strapdown import launch_gravitation
    from casep.workflows.telemetry_iterate import _TelemetryRun, telemetry_gravitation

    site, clean, ins, model, D = launch_frame_ins
    write_table(tmp_path / "tel.csv", ins.columns(), comments=ins.comments("imu.csv"))
    k = slice(None, None, 4)
    write_table(tmp_path / "trk.csv", {"t": clean.t[k], **{f"v_trk_{a}": clean.v[k, i] for i, a in enumerate("xyz")}})
    flight = casep.read_flight_pair(tmp_path / "tel.csv", tmp_path / "trk.csv")
    assert flight.meta["telemetry_site"] == site.to_dict()
    run = _TelemetryRun(flight, model, "strapdown12", FitSpec.build("ols", noise="white", robust="none"), False)
    assert np.abs(run.navigate(D).v - clean.v).max() < 1e-9
    r = ins.r[::50]
    shifted = {"tracking_frame": {"site": {**site.to_dict(), "t0": 100.0}}, "time_shift_s": 100.0}
    G = telemetry_gravitation(dataclasses.replace(flight, meta=shifted))
    assert G is not None and np.allclose(G(ins.t[::50], r), launch_gravitation(site)(ins.t[::50], r), rtol=0,
                                         atol=1e-12)
    assert telemetry_gravitation(dataclasses.replace(flight, meta={})) is None


def test_a_linear_estimate_that_does_not_invert_is_said_with_its_reason(noise_free, model, monkeypatch):
    """The MEMS flight with the record made not to invert at the linear estimate (the check's one call of the rows:
    the refusal of :func:`casep.model.strapdown.corrected_imu`, which names the columns and coefficients): the
    iterated result says that the linear estimate could not be checked and why, in its message and in
    ``diagnostics["linearisation"]["why"]``, not an infinite shift ("moved it by inf std")."""
    from casep.workflows.telemetry_iterate import _TelemetryRun

    flight, *_ = noise_free
    rows, calls = _TelemetryRun.rows, [0]
    reason = "model `strapdown12`: the sensor errors at the coefficients given do not invert: w_z by 3.2"

    def first_refused(self, D):
        calls[0] += 1
        if calls[0] == 1:
            raise ValueError(reason)
        return rows(self, D)

    monkeypatch.setattr(_TelemetryRun, "rows", first_refused)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = casep.separate(flight, model, method="ols", noise="white", robust="none", sigma=0.1)
    lin = res.diagnostics["linearisation"]
    assert lin["iterated"] and lin["shift_std"] is None, lin
    assert lin["why"] == f"the record does not invert at the estimate: {reason}", lin
    assert ("iterated: the linear estimate could not be checked for its second order: the record does not invert at "
            f"the estimate: {reason}; the record re-navigated") in res.message, res.message
    assert "inf std" not in res.message
