"""A bound (``casep diagnose``) of a telemetry ``casep navigate`` levelled on the pad, for a strapdown model without
an initial attitude error, is refused where ``casep separate`` fails its result (status -4): one rule,
:func:`casep.checks.plausibility.levelling_problem`, applied by :func:`casep.checks.flight.check_bound_describes`.

The flight: a rail launch (84 deg rail, 20 s on the pad levelled over [0, 19.5] s with the heading given, a 6 g boost,
a weaving coast; 30 s in the air, 10 Hz) with strapdown12 biases of 1 mg and 1 deg/h, navigated as ``casep navigate``
does and written with its header, tracked at 5 Hz. The independent figure is the levelling's closed form: at rest the
INS makes its specific force vertical, so a body accelerometer bias ``b`` leaves the start tilt
``phi0 = u x (C0 b) / g`` (``u`` the pad's vertical, launch-inertial), and the velocity error of a levelled telemetry
is ``S_b b + S_phi0 phi0(b)``: the regression's accelerometer-bias columns with the tilt's added, whose bound is the
levelled telemetry's own.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import casep
from casep.checks.diagnostics import diagnose
from casep.checks.flight import flight_problem
from casep.cli import main
from casep.frames import LaunchSite
from casep.io.files import read_flight_pair, write_table
from casep.io.flight import FlightDataError
from casep.model.strapdown import body_errors
from casep.navigation import ImuData, check_imu, navigate
from casep.navigation.imu import split_steps
from casep.navigation.strapdown import quat_to_dcm
from casep.regression.problem import Problem
from casep.simulation.noise import white_noise
from casep.simulation.strapdown import rail_launch
from casep.units import G0

SITE = LaunchSite(28.46, -80.53, 3.0, 95.0, 20.0)  # lift-off at t = 20 s
ALIGN, HEADING, SIGMA = (0.0, 19.5), 95.0, 0.03
ARCSEC = 180.0 / np.pi * 3600.0


@pytest.fixture(scope="module")
def levelled(tmp_path_factory):
    """(telemetry file, tracking file, the INS's navigation, the pair read): strapdown12 biases, levelled on the
    pad."""
    t = np.round(np.arange(0.0, 50.0, 0.1), 10)
    w, f = rail_launch(SITE, t, elevation_deg=84.0, boost_g=6.0, burn_s=10.0, coast_g=-0.3, lateral=(3.0, 0.4),
                       roll=(1.5, 3.0))
    w, f = split_steps(t, w, f)
    clean = navigate(check_imu(ImuData(t, w, f)), SITE, ALIGN, heading_deg=HEADING)
    model = casep.load_model("strapdown12")
    biases = {"ba_x": 1.0, "ba_y": -1.0, "ba_z": 1.0, "bg_x": 1.0, "bg_y": -1.0, "bg_z": 1.0}
    df, dw = body_errors(model, clean.q, f, w, t - t[0], np.array([biases.get(n, 0.0) for n in model.names]))
    ins = navigate(check_imu(ImuData(t, w + dw, f + df)), SITE, ALIGN, heading_deg=HEADING)
    directory = tmp_path_factory.mktemp("levelled")
    tel, trk = directory / "tel.csv", directory / "trk.csv"
    write_table(tel, ins.columns(), comments=ins.comments("imu.csv"))
    k = slice(None, None, 2)
    v = clean.v[k] + white_noise(t[k].size, SIGMA, np.random.default_rng(0))
    write_table(trk, {"t": t[k], **{f"v_trk_{a}": v[:, i] for i, a in enumerate("xyz")}})
    return tel, trk, ins, read_flight_pair(tel, trk)


def test_diagnose_refuses_a_model_without_phi0_on_a_levelled_telemetry(levelled, capsys):
    """``casep diagnose --model strapdown12`` of the levelled telemetry: exit 2, naming the levelling's window and
    what to run instead, no table; the Python bound refuses it too (one flight and several), a model with phi0 is
    bounded, and the same telemetry without casep navigate's header line is not judged by the rule."""
    tel, trk, _, flight = levelled
    assert main(["diagnose", str(tel), "--tracking", str(trk), "--model", "strapdown12"]) == 2
    out = capsys.readouterr()
    assert "CRLB" not in out.out and "identifiable" not in out.out
    assert "levelled this telemetry on the pad over [0, 19.5] s" in out.err, out.err
    assert "use strapdown15_phi0" in out.err and "casep separate --imu" in out.err, out.err
    with pytest.raises(FlightDataError, match=r"over \[0, 19.5\] s"):
        flight_problem(flight, casep.load_model("strapdown12"), bound=True)
    with pytest.raises(FlightDataError, match="use strapdown15_phi0"):
        casep.diagnose_flights([flight, flight], "strapdown12", sigma=SIGMA)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # conditioning: said by the bound
        assert flight_problem(flight, casep.load_model("strapdown15_phi0"), bound=True).n == 15
        other = dataclasses.replace(flight, meta={**flight.meta, "levelled": None})  # another INS: not casep's
        assert flight_problem(other, casep.load_model("strapdown12"), bound=True).n == 12


def test_the_refused_bound_is_wrong_and_the_one_named_is_not_optimistic(levelled):
    """Against the levelling's closed form (module notes): the tilt's columns cancel the horizontal biases' pad rows
    (body z, across the pad's vertical, to 1e-3; body y, 6 deg off the horizontal, to its sin 6 deg = 0.104), which
    checks the closed form against S_V's own phi0 columns. The strapdown12 bound that diagnose used to print is that
    of a telemetry not levelled: for ``ba_y`` 0.69 of the levelled telemetry's std (the pad rows seem to determine
    it), for ``ba_z`` 5e5 times it (``ba_z`` and ``sa_z`` are one column here: the flight's body z force is a
    constant, and the levelling's tilt is what tells them apart). The bound the refusal names instead
    (strapdown15_phi0, phi0 free) is at or above the levelled telemetry's own for every coefficient: a free phi0
    only relaxes ``phi0 = phi0(b)``."""
    _, _, ins, flight = levelled
    m12, m15 = casep.load_model("strapdown12"), casep.load_model("strapdown15_phi0")
    p12, p15 = Problem.from_flight(flight, m12, keep_sv=True), Problem.from_flight(flight, m15, keep_sv=True)
    S = p15.sv()
    assert list(m15.names[:12]) == list(m12.names) and np.array_equal(p12.sv(), S[:, :, :12])
    sel = ins.t <= ALIGN[1]
    up = np.einsum("nij,nj->ni", quat_to_dcm(ins.q[sel]), ins.fb[sel]).mean(axis=0)  # launch-inertial, m/s^2
    C0 = quat_to_dcm(ins.q[0])
    tilt = np.column_stack([np.cross(up, C0[:, j]) / (up @ up) * 1e-3 * G0 * ARCSEC for j in range(3)])  # arcsec/mg
    lev = S[:, :, :12].copy()
    lev[:, :, :3] += np.einsum("nkp,pj->nkj", S[:, :, 12:], tilt)
    pad = p15.t <= ALIGN[1]
    left = np.abs(lev[pad][:, :, 1:3]).max(axis=(0, 1)) / np.abs(S[pad][:, :, 1:3]).max(axis=(0, 1))
    assert left[0] == pytest.approx(np.sin(np.radians(6.0)), rel=0.01) and left[1] < 2e-3, left
    X = lev.reshape(-1, 12)
    own = SIGMA * np.sqrt(np.diag(np.linalg.inv(X.T @ X)))  # the levelled telemetry's bound
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # conditioning: said by the bound
        naive, named = diagnose(p12, sigma=SIGMA).crlb_std, diagnose(p15, sigma=SIGMA).crlb_std[:12]
    assert naive[1] < 0.75 * own[1] and naive[2] > 1e4 * own[2], (naive[:3], own[:3])
    assert np.all(named >= own * (1.0 - 1e-6)), (named, own)


def test_diagnose_says_the_imu_noise_its_bound_leaves_out(levelled, tmp_path, capsys):
    """A telemetry navigated from a noisy IMU (white, 2e-3 m/s^2 and 2e-5 rad/s per sample): diagnose's bound holds
    the tracking noise only, and it says so with the IMU's noise measured on the samples (each sensor's largest
    within 15 % of the noise added: 500 samples), in its text and JSON; the noise-free telemetry gets no such line."""
    import json
    import re

    tel, trk, ins, _ = levelled
    assert main(["diagnose", str(tel), "--tracking", str(trk), "--model", "strapdown15_phi0",
                 "--sigma", str(SIGMA)]) == 0
    assert "bound holds the tracking noise only" not in capsys.readouterr().out
    rng = np.random.default_rng(5)
    acc, gyr = 2e-3, 2e-5
    noisy = navigate(check_imu(ImuData(ins.t, ins.w + rng.normal(0, gyr, ins.w.shape),
                                       ins.fb + rng.normal(0, acc, ins.fb.shape))), SITE, ALIGN, heading_deg=HEADING)
    path = tmp_path / "noisy.csv"
    write_table(path, noisy.columns(), comments=noisy.comments("imu.csv"))
    assert main(["diagnose", str(path), "--tracking", str(trk), "--model", "strapdown15_phi0", "--sigma",
                 str(SIGMA), "--json", str(tmp_path / "d.json")]) == 0
    out = capsys.readouterr().out
    said = json.loads((tmp_path / "d.json").read_text())["imu_noise_not_in_bound"]
    assert said and said in out, out
    a, g = (float(x) for x in re.search(r"up to ([0-9.e+-]+) m/s\^2 and ([0-9.e+-]+) rad/s", said).groups())
    assert abs(a / acc - 1) < 0.15 and abs(g / gyr - 1) < 0.15, said
