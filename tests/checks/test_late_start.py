"""The late-start check (casep.checks.late_start): a flight whose telemetry begins after lift-off."""

from __future__ import annotations

import numpy as np
import pytest

import casep
from casep.checks.late_start import late_start_evidence
from casep.exceptions import CasepWarning
from casep.io.flight import LateStartWarning
from casep.simulation.simulate import simulate_flight


def _cut(fl, t0):
    k = fl.t >= t0
    return casep.FlightData(fl.t[k], fl.f[k], fl.dv[k], source=f"cut at {t0:g} s")


def _late_start_said(cut, model, rate: float) -> list[str]:
    """The LateStartWarning messages of separating `cut` with `model`: at 20 Hz ``casep.separate`` whole; at 100 Hz
    the checks it runs before estimating (:func:`casep.checks.flight.check_before_estimation`, which issues the
    warning from the flight and the model alone: what depends on the rate, the evidence, is the flight's), without
    the fit of 18000 rows (the warning said once by the whole path is the 20 Hz case's)."""
    from casep.checks.flight import check_before_estimation

    with pytest.warns(CasepWarning) as rec:
        if rate == 20.0:
            casep.separate(cut, model)
        else:
            check_before_estimation(cut, casep.load_model(model) if isinstance(model, str) else model)
    return [str(w.message) for w in rec if w.category is LateStartWarning]


@pytest.mark.parametrize("rate", [20.0, 100.0])
def test_late_start_warning_on_flight_cut_at_20s(rate, platform36):
    fl = simulate_flight("paper", seed=3, rate=rate).flight
    assert late_start_evidence(fl) == {}
    cut = _cut(fl, 20.0)
    ev = late_start_evidence(cut)
    # dv(20 s) of the paper truth is (-0.36, -0.20, 0.21) m/s against 0.1 m/s noise.
    np.testing.assert_allclose(ev["dv0"], [-0.36, -0.20, 0.21], atol=0.1)
    # (the unmodelled dv0 and phi0 also leave residuals the time-offset check may flag)
    late = _late_start_said(cut, platform36, rate)
    assert len(late) == 1
    msg = late[0]
    assert "cut at 20 s: the flight seems to start after lift-off (t0 = 20 s)" in msg
    assert "initial velocity error dv0" in msg and "initial platform misalignment phi0" in msg
    assert "platform36_dv0" in msg and "platform39_misalignment" in msg and "chi-square" in msg
    late = _late_start_said(cut, "platform36_dv0", rate)
    assert len(late) == 1 and "has no initial platform misalignment phi0" in late[0] and "dv0 (" not in late[0]
    assert "or it starts at lift-off with an initial velocity error" in late[0]  # dv evidence alone


@pytest.mark.parametrize("scenario", ["paper", "paper-pitch", "paper-ar1"])
def test_no_late_start_alarm_on_flights_from_liftoff(scenario):
    for seed in range(6):
        fl = simulate_flight(scenario, seed=seed, rate=20.0 if seed % 2 else 100.0).flight
        assert late_start_evidence(fl) == {}, (scenario, seed)


def _navigate_like_csv(path, site, speed_rel, header=True):
    """A launch-inertial telemetry (casep navigate's header and columns) of a vehicle moving at `speed_rel` m/s
    relative to the Earth (east) at its first sample; the tracking the same velocity."""
    from casep.frames import ecef_to_launch, geodetic_to_ecef
    from casep.io.files import write_table

    t = np.arange(0.0, 30.0, 0.1)
    r_e, v_e = geodetic_to_ecef(np.full(t.size, site.lat_deg), np.full(t.size, site.lon_deg), np.full(t.size, site.h_m),
                                np.full(t.size, speed_rel), np.zeros(t.size), np.zeros(t.size))
    r, v = ecef_to_launch(site, t, r_e, v_e)
    cols = {"t": t, "f_x": np.zeros(t.size), "f_y": np.full(t.size, 9.8), "f_z": np.zeros(t.size),
            **{f"v_tel_{a}": v[:, i] for i, a in enumerate("xyz")},
            **{f"r_tel_{a}": r[:, i] for i, a in enumerate("xyz")},
            **{f"v_trk_{a}": v[:, i] for i, a in enumerate("xyz")}}
    write_table(path, cols, comments=["casep navigate imu.csv: strapdown telemetry, launch-inertial frame",
                                      f"launch site {site.lat_deg:g} {site.lon_deg:g} {site.h_m:g} azimuth "
                                      f"{site.azimuth_deg:g} deg, launch time {site.t0:g} s"] if header else None)
    return float(np.linalg.norm(v[0]))


@pytest.mark.parametrize("speed_rel", [0.0, 100.0])
def test_start_speed_of_a_launch_inertial_telemetry_is_relative_to_the_earth(tmp_path, speed_rel):
    """A pad at rest in casep navigate's launch-inertial frame moves at the Earth's rotation speed (~160 m/s at
    69 deg): the late-start speed is the Earth-relative one (0, no alarm; 100 m/s: said), not |v_tel| (> 30 m/s)."""
    from casep.frames import LaunchSite
    from casep.io.files import read_flight

    site = LaunchSite(69.29, 16.02, 20.0, 340.0, 8.0)
    path = tmp_path / "nav.csv"
    inertial = _navigate_like_csv(path, site, speed_rel)
    assert inertial > 150.0  # what the check took for flying
    flight = read_flight(path)
    assert flight.meta["start_speed_m_s"] == pytest.approx(speed_rel, abs=1e-6)
    assert ("speed_m_s" in late_start_evidence(flight)) == (speed_rel > 30.0)


def test_a_strapdown_flight_is_never_told_to_use_a_platform_model(tmp_path):
    """A strapdown flight (its model reads the INS attitude) flying at its first sample: the warning recommends
    strapdown15_phi0 for phi0 and says no shipped strapdown model has dv0, never a platform model."""
    from casep.checks.late_start import warn_late_start
    from casep.frames import LaunchSite
    from casep.io.files import read_flight

    class Strapdown:  # the set-up model's answers the check reads
        name = "strapdown15_axial"
        signals = ("q_w", "q_x", "q_y", "q_z", "fb_x", "fb_y", "fb_z")

        @staticmethod
        def numeric(key):
            return np.zeros((3, 0)) if key == "velocity_columns" else np.zeros((3, 15))

    _navigate_like_csv(tmp_path / "nav.csv", LaunchSite(69.29, 16.02, 20.0, 340.0, 8.0), 100.0)
    with pytest.warns(LateStartWarning) as rec:
        warn_late_start(read_flight(tmp_path / "nav.csv"), Strapdown())
    text = str(rec[0].message)
    assert "--model strapdown15_phi0" in text and "--model platform" not in text and "platform39" not in text
    assert "no shipped model of this kind has the initial velocity error dv0" in text


def test_the_late_start_advice_never_drops_the_terms_of_the_model_in_use(tmp_path):
    """strapdown33 lacking phi0: the advice is strapdown42_extended (its 33 terms and phi0, named with what else it
    adds), never strapdown15_phi0, which would drop 21 of them; strapdown12: strapdown15_phi0 (12 + phi0). A model
    with a term no shipped model has: add phi0 to a copy, naming how many terms the shipped one would drop."""
    import casep
    from casep.checks.late_start import warn_late_start
    from casep.frames import LaunchSite
    from casep.io.files import read_flight

    _navigate_like_csv(tmp_path / "nav.csv", LaunchSite(69.29, 16.02, 20.0, 340.0, 8.0), 100.0)
    flight = read_flight(tmp_path / "nav.csv")

    def advice(model) -> str:
        with pytest.warns(LateStartWarning) as rec:
            warn_late_start(flight, model)
        return str(rec[0].message)

    text = advice(casep.load_model("strapdown33"))
    assert "--model strapdown42_extended (the 33 terms of `strapdown33` and ka2_x" in text and "phi0_x" in text
    assert "strapdown15_phi0" not in text
    assert "--model strapdown15_phi0 (the 12 terms of `strapdown12` and phi0_x, phi0_y, phi0_z)" in advice(
        casep.load_model("strapdown12"))

    class Custom:  # a user's model: strapdown12's terms and one of its own
        name = "mine"
        names = casep.load_model("strapdown12").names + ("k_own",)
        signals = ("q_w", "q_x", "q_y", "q_z", "fb_x", "fb_y", "fb_z")

        @staticmethod
        def numeric(key):
            return np.zeros((3, 0)) if key == "velocity_columns" else np.zeros((3, 13))

    text = advice(Custom())
    assert ("add to a copy of `mine` the initial platform misalignment phi0 (strapdown15_phi0.py in models/ shows "
            "how: its declare and set_initial_* lines; --model strapdown15_phi0 would drop 1 of the 13 terms of "
            "`mine`: k_own)") in text and "with the initial terms: add to a copy of `mine`" in text


def test_a_parquet_telemetry_names_its_frame_in_its_metadata(tmp_path):
    """casep navigate -o TEL.parquet keeps its header lines as the file's metadata: read back, the frame and the
    launch site are known, and a pad at rest starts at 0 m/s relative to the Earth (|v_tel| is 163 m/s)."""
    pytest.importorskip("pyarrow")
    from casep.frames import LaunchSite
    from casep.io.files import read_flight

    site = LaunchSite(69.29, 16.02, 20.0, 340.0, 8.0)
    assert _navigate_like_csv(tmp_path / "nav.parquet", site, 0.0) > 150.0
    flight = read_flight(tmp_path / "nav.parquet")
    assert flight.meta["start_speed_m_s"] == pytest.approx(0.0, abs=1e-6)
    assert flight.meta["start_frame_unnamed"] is False and late_start_evidence(flight) == {}


class _Strapdown:  # the set-up model's answers the check reads
    name = "strapdown15_axial"
    signals = ("q_w", "q_x", "q_y", "q_z", "fb_x", "fb_y", "fb_z")

    @staticmethod
    def numeric(key):
        return np.zeros((3, 0)) if key == "velocity_columns" else np.zeros((3, 15))


def test_a_telemetry_whose_header_was_dropped_is_said_to_have_an_unknown_frame(tmp_path):
    """casep navigate's telemetry of a pad at rest with its `#` header dropped: |v_tel(t0)| = 163 m/s is the pad's
    Earth rotation at 69.3 deg, not a late start. The warning says the frame is unknown, both readings, and
    Missing: / Use:; no late-start warning. Faster than the Earth's rotation can carry a pad: a late start still."""
    import warnings

    from casep.checks.late_start import EARTH_ROTATION_SPEED, warn_late_start
    from casep.exceptions import SetupWarning
    from casep.frames import LaunchSite
    from casep.io.files import read_flight

    site = LaunchSite(69.29, 16.02, 20.0, 340.0, 8.0)
    speed = _navigate_like_csv(tmp_path / "nav.csv", site, 0.0, header=False)
    flight = read_flight(tmp_path / "nav.csv")
    assert flight.meta["start_frame_unnamed"] is True and flight.meta["start_speed_m_s"] == pytest.approx(speed)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        warn_late_start(flight, _Strapdown())
    assert [w.category for w in rec] == [SetupWarning]
    text = str(rec[0].message)
    assert f"the telemetry speed at the first sample is {speed:.4g} m/s and no header names its frame" in text
    assert "a pad at about latitude +-69.2 deg" in text and "or the flight started after lift-off" in text
    assert "Missing: the header casep navigate writes" in text and "Use: the telemetry with its header" in text
    # with the header: the Earth-relative speed, 0, no warning
    _navigate_like_csv(tmp_path / "nav.csv", site, 0.0)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        warn_late_start(read_flight(tmp_path / "nav.csv"), _Strapdown())
    assert not rec
    # beyond what the Earth's rotation gives (465.1 m/s at the equator): flying at the first sample, whatever the frame
    _navigate_like_csv(tmp_path / "nav.csv", site, 400.0, header=False)
    flight = read_flight(tmp_path / "nav.csv")
    assert flight.meta["start_speed_m_s"] > EARTH_ROTATION_SPEED
    with pytest.warns(LateStartWarning, match="the flight seems to start after lift-off"):
        warn_late_start(flight, _Strapdown())


def test_start_speed_of_a_table_without_a_file_is_its_own(tmp_path):
    """A telemetry table held in memory (separate --imu's navigated one) has no header to read: |v_tel(t0)|."""
    from casep.io.files import start_speed
    from casep.io.tables import Table

    cols = {"t": np.arange(3.0), **{f"v_tel_{a}": np.full(3, 2.0) for a in "xyz"},
            **{f"r_tel_{a}": np.zeros(3) for a in "xyz"}}
    tab = Table.from_columns(cols, str(tmp_path / "imu.csv (navigated)"))
    assert start_speed(tab, cols["t"], np.full((3, 3), 2.0)) == pytest.approx(np.sqrt(12.0), rel=1e-12)
