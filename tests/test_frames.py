"""Tracking frames: launch-inertial <-> ECEF <-> geodetic, Earth-fixed tracking files,
the rotating-Earth simulator.

References are closed forms (the distance of a point from the Earth's axis, the Coriolis and
centrifugal accelerations of a horizontal velocity) and round trips; the end-to-end test recovers
the truth from a noise-free rotating-Earth flight whose tracking went through an ECEF (or
geodetic) file.
"""

from __future__ import annotations

import dataclasses
import json
import math
import warnings

import numpy as np
import pytest

import casep
from casep.cli import main
from casep.exceptions import IllConditionedWarning
from casep.frames import (
    OMEGA_EARTH,
    LaunchSite,
    ecef_to_geodetic,
    ecef_to_launch,
    geodetic_to_ecef,
    geodetic_to_launch,
    launch_to_ecef,
    launch_to_geodetic,
)
from casep.io.flight import FlightDataError

A_WGS84, B_WGS84 = 6378137.0, 6356752.31424518
E2 = 1.0 - (B_WGS84 / A_WGS84) ** 2
SITE = LaunchSite(28.5, -80.6, 3.0, 90.0, 0.0)  # Florida, due east


def _prime_vertical(lat_deg: float) -> float:
    s = math.sin(math.radians(lat_deg))
    return A_WGS84 / math.sqrt(1.0 - E2 * s * s)


# ------------------------------------------------------------------ conversions
@pytest.mark.parametrize("site", [SITE, LaunchSite(-33.9, 151.2, 250.0, 200.0, 1234.5),
                                  LaunchSite(67.9, 21.1, 330.0, -10.0, -50.0)])
def test_launch_ecef_round_trip_exact(site):
    rng = np.random.default_rng(7)
    t = site.t0 + np.linspace(-10.0, 600.0, 400)
    r = rng.uniform(-1e6, 1e6, (400, 3))
    v = rng.uniform(-8e3, 8e3, (400, 3))
    r_e, v_e = launch_to_ecef(site, t, r, v)
    r2, v2 = ecef_to_launch(site, t, r_e, v_e)
    assert np.abs(r2 - r).max() <= 1e-9  # m: the rounding of |r_E| ~ 6.4e6 m (half an ulp 4.7e-10)
    assert np.abs(v2 - v).max() <= 1e-9  # m/s
    # and through geodetic + ENU velocity
    r3, v3 = geodetic_to_launch(site, t, *launch_to_geodetic(site, t, r, v))
    assert np.abs(r3 - r).max() < 1e-7 and np.abs(v3 - v).max() < 1e-9


def test_geodetic_round_trip():
    rng = np.random.default_rng(3)
    lat, lon = rng.uniform(-89.9, 89.9, 2000), rng.uniform(-180.0, 180.0, 2000)
    h = rng.uniform(-1e3, 1e6, 2000)
    ve, vn, vu = rng.uniform(-8e3, 8e3, (3, 2000))
    r, v = geodetic_to_ecef(lat, lon, h, ve, vn, vu)
    lat2, lon2, h2, ve2, vn2, vu2 = ecef_to_geodetic(r, v)
    assert np.abs(lat2 - lat).max() * 111e3 < 1e-7 and np.abs(lon2 - lon).max() * 111e3 < 1e-7  # m on the ground
    assert np.abs(h2 - h).max() < 1e-7
    for a, b in ((ve, ve2), (vn, vn2), (vu, vu2)):
        assert np.abs(a - b).max() < 1e-9
    # independent of pymap3d: the closed form of an ECEF point on the ellipsoid normal
    N = np.array([_prime_vertical(x) for x in lat])
    cl, sl = np.cos(np.radians(lat)), np.sin(np.radians(lat))
    ref = np.column_stack([(N + h) * cl * np.cos(np.radians(lon)), (N + h) * cl * np.sin(np.radians(lon)),
                           (N * (1 - E2) + h) * sl])
    assert np.abs(r - ref).max() < 1e-7


def test_launch_triad_and_earth_rotation_closed_form():
    lat, lon = math.radians(SITE.lat_deg), math.radians(SITE.lon_deg)
    C = SITE.C
    np.testing.assert_allclose(C.T @ C, np.eye(3), atol=1e-15)
    assert np.linalg.det(C) == pytest.approx(1.0, abs=1e-15)  # right-handed
    east = np.array([-math.sin(lon), math.cos(lon), 0.0])
    up = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    np.testing.assert_allclose(C[:, 0], east, atol=1e-15)  # azimuth 90 deg: x east
    np.testing.assert_allclose(C[:, 1], up, atol=1e-15)  # y: ellipsoid normal
    # the launch point at t0 is the origin; at rest on the Earth it moves at omega * (distance from the axis)
    r, v = ecef_to_launch(SITE, [0.0, 100.0], [SITE.r_site] * 2, np.zeros((2, 3)))
    assert np.abs(r[0]).max() < 1e-9
    rho = (_prime_vertical(SITE.lat_deg) + SITE.h_m) * math.cos(lat)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), OMEGA_EARTH * rho, rtol=1e-12)
    assert OMEGA_EARTH * rho == pytest.approx(409.05, abs=0.01)  # m/s at 28.5 deg
    np.testing.assert_allclose(v[0], OMEGA_EARTH * rho * C.T @ east, atol=1e-9)  # due east, all in x here
    np.testing.assert_allclose(SITE.earth_rate, OMEGA_EARTH * C.T @ [0.0, 0.0, 1.0], atol=1e-20)


@pytest.mark.parametrize("lat", [28.5, -45.0, 60.0])
def test_coriolis_and_centrifugal_closed_form(lat):
    """An inertially unaccelerated body passing the launch point at t0 with a horizontal east velocity v
    relative to the Earth: seen in ECEF it accelerates by -2 w x v - w x (w x r). Closed forms: north
    -2 omega v sin(lat) (Coriolis, to the right in the north) - omega^2 rho sin(lat); up
    +2 omega v cos(lat) (Eotvos) + omega^2 rho cos(lat) (rho = (N + h) cos(lat), distance from the axis)."""
    site = LaunchSite(lat, 10.0, 100.0, 30.0, 0.0)
    v_east = 2000.0
    C, r_s = site.C, site.r_site
    phi = math.radians(lat)
    east = np.array([-math.sin(math.radians(10.0)), math.cos(math.radians(10.0)), 0.0])
    w = np.array([0.0, 0.0, OMEGA_EARTH])
    v_l = C.T @ (v_east * east + np.cross(w, r_s))  # launch-inertial velocity of that body (transport theorem)
    h = 0.5
    t = np.array([-h, 0.0, h])
    r_e, v_e = launch_to_ecef(site, t, v_l * t[:, None], np.tile(v_l, (3, 1)))  # straight line, a_L = 0
    a_e = (v_e[2] - v_e[0]) / (2 * h)  # central difference: O(h^2) of the cubic terms, ~1e-9 m/s^2
    up = C[:, 1]
    north = np.cross(up, east)
    rho = (_prime_vertical(lat) + 100.0) * math.cos(phi)
    assert a_e @ north == pytest.approx(-2 * OMEGA_EARTH * v_east * math.sin(phi)
                                        - OMEGA_EARTH**2 * rho * math.sin(phi), abs=1e-8)
    assert a_e @ up == pytest.approx(2 * OMEGA_EARTH * v_east * math.cos(phi)
                                     + OMEGA_EARTH**2 * rho * math.cos(phi), abs=1e-8)
    assert abs(a_e @ east) < 1e-8
    assert abs(2 * OMEGA_EARTH * v_east * math.sin(phi)) > 0.1  # the Coriolis term is 0.14-0.25 m/s^2 here


# ------------------------------------------------------------------ rotating-Earth simulation
@pytest.fixture(scope="module")
def rotating():
    from casep.simulation.noise import NoiseModel
    from casep.simulation.scenarios import get_scenario
    from casep.simulation.simulate import simulate_two_rate

    quiet = dataclasses.replace(get_scenario("paper"), noise=NoiseModel("white", 0.0))
    return simulate_two_rate(quiet, seed=0, telemetry_rate=20.0, tracking_rate=20.0, rotating_earth=True, site=SITE)


def test_rotating_simulation_starts_at_rest_on_the_pad_and_obeys_the_rotating_frame(rotating):
    d = rotating
    r_e, v_e = launch_to_ecef(SITE, d.t_trk, d.r_trk, d.v_trk)
    assert np.abs(r_e[0] - SITE.r_site).max() < 1e-9 and np.abs(v_e[0]).max() < 1e-9  # at rest on the pad
    rho = (_prime_vertical(SITE.lat_deg) + SITE.h_m) * math.cos(math.radians(SITE.lat_deg))
    assert np.linalg.norm(d.v_trk[0]) == pytest.approx(OMEGA_EARTH * rho, rel=1e-12)
    # ECEF acceleration (central differences of the converted velocity) against the simulator's inertial
    # acceleration rotated into ECEF, minus Coriolis and centrifugal, in smooth flight (30-90 s)
    i = np.flatnonzero((d.t_trk > 30.0) & (d.t_trk < 90.0))
    a_fd = (v_e[i + 1] - v_e[i - 1]) / (d.t_trk[i + 1] - d.t_trk[i - 1])[:, None]
    th = OMEGA_EARTH * d.t_trk[i]
    c, s = np.cos(th), np.sin(th)
    a_i = d.acceleration[i] @ SITE.C.T  # launch -> inertial ECEF-at-t0 axes
    a_rot = np.column_stack([c * a_i[:, 0] + s * a_i[:, 1], -s * a_i[:, 0] + c * a_i[:, 1], a_i[:, 2]])  # Rz^T
    w = np.array([0.0, 0.0, OMEGA_EARTH])
    coriolis = -2 * np.cross(w, v_e[i])
    a_model = a_rot + coriolis - np.cross(w, np.cross(w, r_e[i]))
    assert np.abs(a_fd - a_model).max() < 2e-3  # m/s^2: the differences' own error
    assert np.linalg.norm(coriolis, axis=1).max() > 0.1  # what is checked is not negligible


def test_rotating_earth_bad_input():
    from casep.simulation.trajectory import DEFAULT_VEHICLE, simulate_boost

    with pytest.raises(ValueError, match="`rotating_earth` needs `site`"):
        simulate_boost(DEFAULT_VEHICLE, 1.0, rotating_earth=True)
    with pytest.raises(ValueError, match=r"`site.t0` must be 0"):
        simulate_boost(DEFAULT_VEHICLE, 1.0, rotating_earth=True, site=dataclasses.replace(SITE, t0=5.0))
    with pytest.raises(ValueError, match="only with `rotating_earth=True`"):
        simulate_boost(DEFAULT_VEHICLE, 1.0, site=SITE)
    for kw, what in (({"lat_deg": 91.0}, "lat_deg"), ({"h_m": float("nan")}, "h_m"), ({"t0": "0"}, "t0"),
                     ({"lat_deg": 90.0}, "pole")):
        with pytest.raises(ValueError, match=what):
            dataclasses.replace(SITE, **kw)


# ------------------------------------------------------------------ files, end to end
@pytest.mark.parametrize("frame", ["ecef", "geodetic"])
def test_earth_fixed_tracking_noise_free_recovers_truth(rotating, tmp_path, frame):
    """Rotating-Earth flight, tracking written in ECEF (geodetic), read back and separated: the truth to
    ~1e-12 of the CRLB std (measured 3e-12); no late-start warning although the launch-inertial
    speed at lift-off is 409 m/s (the pad's, removed from the check)."""
    from conftest import noise_free_errors

    d = rotating
    tel, trk = tmp_path / "tel.csv", tmp_path / f"trk_{frame}.csv"
    d.write(tel, trk, tracking_frame=frame)
    fl = casep.read_flight_pair(tel, trk, tracking_frame=frame, site=SITE)
    assert fl.meta["tracking_frame"]["frame"] == frame and fl.meta["start_speed_m_s"] < 1e-6
    res, err = noise_free_errors(fl, d.model, d.truth)
    assert err.max() < 1e-6, dict(zip(d.model.names, err))
    assert abs(res.estimate[res.names.index("dt_trk")]) < 1e-6  # ms: the range clock's offset, fitted by default


def test_ignoring_earth_rotation_biases_the_estimate(rotating, tmp_path):
    """The same ECEF file with its velocity only rotated into launch axes (no w x r, no turning of the Earth):
    dv is off by 409-452 m/s and the estimates by far more than their CRLB std."""
    from casep.checks.diagnostics import crlb_covariance
    from casep.io.pair import pair_flight
    from casep.workflows.separate import regression_rows

    d = rotating
    r_e, v_e = launch_to_ecef(SITE, d.t_trk, d.r_trk, d.v_trk)
    naive = v_e @ SITE.C  # C^T v_E: frames confused
    gap = np.linalg.norm(naive - d.v_trk, axis=1)
    assert 408.0 < gap[0] < 409.5 and gap.max() < 460.0
    fl = pair_flight(d.t_tel, d.f, d.v_tel, d.t_trk, naive)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", casep.LateStartWarning)  # 409 m/s at the first sample: the frames confused
        warnings.simplefilter("ignore", IllConditionedWarning)
        warnings.simplefilter("ignore", casep.exceptions.NoiseNotWhiteWarning)  # the misfit is not white
        warnings.simplefilter("ignore", casep.exceptions.MagnitudeWarning)  # a bias of 1.15 g: the frames confused
        # white noise, as the CRLB below (noise "auto" would take part of the misfit for Gauss-Markov noise)
        res = casep.separate(fl, "platform36", noise="white")
        S, _, _ = regression_rows(fl, d.model)
    crlb = np.sqrt(np.diag(crlb_covariance(S, 0.1)))
    assert np.nanmax(np.abs(res.estimate - d.truth) / crlb) > 1e3


def test_earth_fixed_tracking_bad_input(rotating, tmp_path):
    d = rotating
    tel, trk = tmp_path / "tel.csv", tmp_path / "trk.csv"
    d.write(tel, trk, tracking_frame="ecef")
    with pytest.raises(ValueError, match=r"trk\.csv: ecef tracking needs the launch site.*--launch-site LAT LON H AZ "
                                         r"--launch-time T0"):
        casep.read_flight_pair(tel, trk, tracking_frame="ecef")
    with pytest.raises(FlightDataError, match=r"column `v_trk_x`.*this file has ecef columns.*--tracking-frame ecef"):
        casep.read_flight_pair(tel, trk)  # default: launch frame, unchanged
    with pytest.raises(ValueError, match="`site` is used only with an Earth-fixed tracking_frame"):
        casep.read_flight_pair(tel, trk, site=SITE)
    with pytest.raises(ValueError, match="`tracking_frame` must be one of launch, ecef, geodetic"):
        casep.read_flight_pair(tel, trk, tracking_frame="eci", site=SITE)
    with pytest.raises(FlightDataError, match=r"column `lat`.*missing column.*Use \(deg, deg, m, m/s east/north/up\)"):
        casep.read_flight_pair(tel, trk, tracking_frame="geodetic", site=SITE)
    d.write(tel, trk, tracking_frame="geodetic")
    text = trk.read_text().splitlines()
    head = [i for i, line in enumerate(text) if line.startswith("t,")][0]
    row = text[head + 3].split(",")
    text[head + 3] = ",".join([row[0], "95.0"] + row[2:])
    trk.write_text("\n".join(text) + "\n")
    with pytest.raises(FlightDataError, match=r"column `lat`, row 3.*95 deg is outside \+-90 deg"):
        casep.read_flight_pair(tel, trk, tracking_frame="geodetic", site=SITE)
    with pytest.raises(ValueError, match="ecef tracking needs a rotating-Earth flight"):
        dataclasses.replace(d, site=None).write(tel, tmp_path / "x.csv", tracking_frame="ecef")


def test_cli_rotating_earth_geodetic_round_trip(tmp_path, capsys):
    tel, out = tmp_path / "tel.csv", tmp_path / "r.json"
    site = ["28.5", "-80.6", "3", "90"]
    assert main(["simulate", "--rotating-earth", "--launch-site", *site, "--tracking-frame", "geodetic",
                 "--rate", "10", "--tracking-rate", "5", "--seed", "3", "-o", str(tel)]) == 0
    trk = tmp_path / "tel.tracking.csv"
    assert trk.exists() and (tmp_path / "tel.truth.json").exists()
    assert "t,lat,lon,h,v_east,v_north,v_up" in trk.read_text()
    truth = json.loads((tmp_path / "tel.truth.json").read_text())
    assert truth["tracking"]["launch_site"]["lat_deg"] == 28.5 and truth["tracking"]["frame"] == "geodetic"
    assert main(["separate", str(tel), "--tracking", str(trk), "--tracking-frame", "geodetic", "--launch-site", *site,
                 "--launch-time", "0", "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    assert res["n_samples"] == 976 and 0.08 < res["residual_rms"]["x"] < 0.12  # the 0.1 m/s tracking noise
    capsys.readouterr()
    for argv, msg in (
        (["separate", str(tel), "--tracking", str(trk), "--tracking-frame", "geodetic"],
         "tracking needs the launch site"),
        (["separate", str(tel), "--tracking", str(trk), "--tracking-frame", "geodetic", "--launch-site", *site],
         "needs both --launch-site"),
        (["separate", str(tel), "--launch-site", *site, "--launch-time", "0"], "used only with --tracking-frame"),
        (["simulate", "--tracking-frame", "ecef", "-o", str(tmp_path / "x.csv")], "need --rotating-earth"),
        (["simulate", "--rotating-earth", "-o", str(tmp_path / "x.csv")], "needs --launch-site"),
        (["simulate", "--rotating-earth", "--launch-site", "95", "0", "0", "90", "-o", str(tmp_path / "x.csv")],
         "lat_deg"),
    ):
        assert main(argv) == 2
        assert msg in capsys.readouterr().err
