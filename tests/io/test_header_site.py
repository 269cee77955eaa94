"""The stated launch site against the one a navigated telemetry's header names (casep.io.setup.header_site_problem).

A telemetry written by ``casep navigate`` is in the launch-inertial frame of the site its header names; Earth-fixed
tracking is turned into the frame of the site stated on the command line. An azimuth 3 deg off turns a 4 km/s velocity
by 210 m/s: before this check the fit failed on estimates beyond any instrument's, naming no set-up value."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import ins_telemetry

import casep
from casep.frames import LaunchSite, launch_to_ecef
from casep.io.files import write_table
from casep.io.setup import header_site_problem

SITE = LaunchSite(67.89, 21.10, 330.0, 30.0, 0.0)


def test_the_rule_on_sites():
    """Equal sites (to the header's 12 digits) pass; each value off is named with both numbers and the difference;
    the launch times (each file's own time scale) are not compared; no header, no check."""
    assert header_site_problem(SITE, SITE) is None
    assert header_site_problem(SITE, dataclasses.replace(SITE, lat_deg=float(f"{SITE.lat_deg + 1e-13:.12g}"))) is None
    assert header_site_problem(SITE, dataclasses.replace(SITE, t0=100.0)) is None
    # stated to 5 decimals and the height to the metre: the same frame to well below any tracking's noise
    assert header_site_problem(SITE, dataclasses.replace(SITE, lat_deg=SITE.lat_deg + 4e-6, h_m=330.9)) is None
    said = header_site_problem(SITE, dataclasses.replace(SITE, lon_deg=SITE.lon_deg + 2e-5))
    assert said is not None and "longitude" in said, said
    assert header_site_problem(SITE, None) is None
    said = header_site_problem(dataclasses.replace(SITE, azimuth_deg=33.0), SITE)
    assert "azimuth 33 against 30 deg (+3 deg)" in said and "latitude" not in said, said
    said = header_site_problem(dataclasses.replace(SITE, azimuth_deg=359.0, h_m=300.0),
                               dataclasses.replace(SITE, azimuth_deg=1.0))
    assert "azimuth 359 against 1 deg (-2 deg)" in said and "height 300 against 330 m (-30 m)" in said, said


@pytest.mark.parametrize("stated, named", [(SITE, None), (dataclasses.replace(SITE, azimuth_deg=33.0), "azimuth")])
def test_a_navigated_telemetry_read_with_another_site_fails_the_set_up_check(tmp_path, stated, named):
    """A MEMS telemetry with ``casep navigate``'s header (frame, site, ``r_tel_*``) and its tracking in ECEF: read with
    the header's site, no set-up problem; with the azimuth 3 deg off, the set-up problem names the azimuth and both
    values (the fit's judge_setup fails the result with it)."""
    tel, trk, _, _ = ins_telemetry(growth=0.0, dur=20.0, trk_rate=2.0, noise=0.0, imu_noise=False)
    _, pad = launch_to_ecef(SITE, [0.0], np.zeros((1, 3)), np.zeros((1, 3)))
    c = -SITE.C.T @ pad[0]  # the pad's launch-inertial velocity at t0: the pad at rest on the Earth
    v = np.column_stack([trk[f"v_trk_{a}"] for a in "xyz"]) + c
    t = np.asarray(trk["t"])
    r = np.vstack([np.zeros((1, 3)), np.cumsum((v[1:] + v[:-1]) / 2 * np.diff(t)[:, None], axis=0)])
    r_e, v_e = launch_to_ecef(SITE, t, r, v)
    v_tel = np.column_stack([tel[f"v_tel_{a}"] for a in "xyz"]) + c
    t_tel = np.asarray(tel["t"])
    r_tel = np.vstack([np.zeros((1, 3)), np.cumsum((v_tel[1:] + v_tel[:-1]) / 2 * np.diff(t_tel)[:, None], axis=0)])
    s = SITE
    header = ["casep navigate imu.csv: strapdown telemetry, launch-inertial frame",
              f"launch site {s.lat_deg:.12g} {s.lon_deg:.12g} {s.h_m:.12g} azimuth {s.azimuth_deg:.12g} deg, "
              f"launch time {s.t0:.12g} s"]
    write_table(tmp_path / "tel.csv", {**tel, **{f"v_tel_{a}": v_tel[:, i] for i, a in enumerate("xyz")},
                                       **{f"r_tel_{a}": r_tel[:, i] for i, a in enumerate("xyz")}}, comments=header)
    write_table(tmp_path / "trk.csv", {"t": t, **{f"r_ecef_{a}": r_e[:, i] for i, a in enumerate("xyz")},
                                      **{f"v_ecef_{a}": v_e[:, i] for i, a in enumerate("xyz")}})
    flight = casep.read_flight_pair(tmp_path / "tel.csv", tmp_path / "trk.csv", tracking_frame="ecef", site=stated)
    assert flight.meta["telemetry_site"] == SITE.to_dict()  # the header was read
    problems = [p for p in flight.meta["setup"]["problems"] if "navigated in" in p]
    if named is None:
        assert not problems, problems
    else:
        assert len(problems) == 1 and "azimuth 33 against 30 deg (+3 deg)" in problems[0], problems
