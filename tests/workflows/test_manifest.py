"""The flight manifest: several flights from different ranges, each with its own frame, site, launch time
and time scale, read by the CLI and the API; validated with errors naming file, flight and key.

The reference converts each Earth-fixed tracking file by hand (casep.frames, with each flight's own
site) into a launch-frame tracking file and estimates the two flights jointly from those: main could
not estimate an ECEF flight and a geodetic flight together at all (one --tracking-frame for all).
"""

from __future__ import annotations

import json
import textwrap
import warnings

import numpy as np
import pandas as pd
import pytest

import casep
from casep.cli import main
from casep.frames import LaunchSite, ecef_to_launch, geodetic_to_launch

SITE_A = LaunchSite(28.5, -80.6, 3.0, 90.0, 0.0)  # Florida, due east; ECEF tracking from lift-off
SITE_B = LaunchSite(34.7, -120.6, 100.0, 190.0, 0.0)  # California, south; geodetic tracking in seconds of day
DAY = 43200.0  # lift-off of flight B at 12:00:00


@pytest.fixture(scope="module")
def ranges(tmp_path_factory):
    from casep.simulation.simulate import simulate_two_rate

    folder = tmp_path_factory.mktemp("manifest")
    a = simulate_two_rate("paper", seed=0, telemetry_rate=20.0, tracking_rate=20.0, rotating_earth=True, site=SITE_A)
    b = simulate_two_rate("paper", seed=1, telemetry_rate=20.0, tracking_rate=10.0, rotating_earth=True, site=SITE_B)
    a.write(folder / "a_tel.csv", folder / "a_trk.csv", tracking_frame="ecef")
    b.write(folder / "b_tel.csv", folder / "b_trk0.csv", tracking_frame="geodetic")
    trk = pd.read_csv(folder / "b_trk0.csv", comment="#")
    trk["t"] = trk["t"] + DAY  # the range's clock: seconds of day
    trk.to_csv(folder / "b_trk.csv", index=False, float_format="%.17g")
    # by hand: each tracking file into the launch-inertial frame of its own site, on the telemetry's time scale
    ta = pd.read_csv(folder / "a_trk.csv", comment="#")
    _, va = ecef_to_launch(SITE_A, ta["t"], ta[["r_ecef_x", "r_ecef_y", "r_ecef_z"]].to_numpy(),
                           ta[["v_ecef_x", "v_ecef_y", "v_ecef_z"]].to_numpy())
    site_b_day = LaunchSite(SITE_B.lat_deg, SITE_B.lon_deg, SITE_B.h_m, SITE_B.azimuth_deg, DAY)
    _, vb = geodetic_to_launch(site_b_day, trk["t"], *(trk[c].to_numpy() for c in
                                                       ("lat", "lon", "h", "v_east", "v_north", "v_up")))
    for name, t, v in (("a_trk_launch.csv", ta["t"], va), ("b_trk_launch.csv", trk["t"] - DAY, vb)):
        pd.DataFrame({"t": t, "v_trk_x": v[:, 0], "v_trk_y": v[:, 1], "v_trk_z": v[:, 2]}).to_csv(
            folder / name, index=False, float_format="%.17g")
    (folder / "flights.toml").write_text(textwrap.dedent(f"""\
        # two ranges, two frames, two time scales
        [[flight]]
        label = "A"
        telemetry = "a_tel.csv"
        tracking = "a_trk.csv"
        frame = "ecef"
        site = {{ lat_deg = 28.5, lon_deg = -80.6, h_m = 3.0, azimuth_deg = 90.0 }}
        launch_time_s = 0.0

        [[flight]]
        label = "B"
        telemetry = "b_tel.csv"
        tracking = "b_trk.csv"
        frame = "geodetic"
        site = {{ lat_deg = 34.7, lon_deg = -120.6, h_m = 100.0, azimuth_deg = 190.0 }}
        launch_time_s = {DAY}
        time_shift_s = {DAY}
        """))
    return folder


def test_manifest_ecef_and_geodetic_jointly_equal_the_hand_conversion(ranges, capsys):
    f = ranges
    ref, man = f / "ref.json", f / "man.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", casep.IllConditionedWarning)
        # Earth-fixed tracking fits each flight's clock offset dt_trk by default (casep.io.pair.fits_time_offset):
        # the hand-converted launch-frame pairs are fitted with it too
        assert main(["separate", str(f / "a_tel.csv"), str(f / "b_tel.csv"), "--tracking", str(f / "a_trk_launch.csv"),
                     "--tracking", str(f / "b_trk_launch.csv"), "--model", "platform36_timeoffset",
                     "--json", str(ref)]) == 0
        capsys.readouterr()  # launch-frame tracking from the pad: 409 m/s at the first sample reads as a late start
        assert main(["separate", "--manifest", str(f / "flights.toml"), "--json", str(man)]) == 0
    out = "".join(capsys.readouterr())  # the report and the warnings (stderr)
    assert "set-up check" not in out and "after lift-off" not in out and "look" not in out
    r, m = json.loads(ref.read_text()), json.loads(man.read_text())
    est_r, est_m, std = (np.array(d, dtype=float) for d in (r["estimates"], m["estimates"], r["std"]))
    assert np.max(np.abs(est_m - est_r) / std) < 1e-6
    assert np.allclose(m["std"], r["std"], rtol=1e-9)
    own = [n for n in m["per_flight"]["names"] if n.startswith("dt_trk[")]  # the rule: one clock offset per flight
    assert own == ["dt_trk[A]", "dt_trk[B]"] and np.all(np.isfinite(m["per_flight"]["std"]))  # the manifest's labels


def test_manifest_api_and_diagnose(ranges, capsys):
    man = casep.read_manifest(ranges / "flights.toml")
    assert man.labels == ["A", "B"] and man.flights[1].time_shift_s == DAY
    assert man.flights[0].telemetry == ranges / "a_tel.csv"  # relative to the manifest's folder
    flights = man.read()
    assert flights[1].meta["time_shift_s"] == DAY and flights[1].meta["setup"]["problems"] == []
    out = ranges / "diag.json"
    assert main(["diagnose", "--manifest", str(ranges / "flights.toml"), "--json", str(out)]) == 0
    assert "identifiable jointly" in capsys.readouterr().out
    prov = json.loads(out.read_text())["provenance"]
    assert [f["role"] for f in prov["inputs"]] == ["manifest", "telemetry", "tracking", "telemetry", "tracking"]
    assert prov["manifest"]["flights"][1]["time_shift_s"] == DAY
    assert prov["flights"][1]["tracking_frame"]["frame"] == "geodetic"


def _write(folder, name, text):
    p = folder / name
    p.write_text(textwrap.dedent(text))
    return p


@pytest.mark.parametrize("body, message", [
    ('[[flight]]\ntelemetry = "a_tel.csv"\ntrackign = "a_trk.csv"\n', r"flight 1, key `trackign`: Extra inputs"),
    ('[[flight]]\ntracking = "a_trk.csv"\n', r"flight 1, key `telemetry`: Field required"),
    ('[[flight]]\ntelemetry = "a_tel.csv"\ntracking = "a_trk.csv"\nframe = "ecef"\n',
     r"flight 1: Value error, frame 'ecef' needs `site` and `launch_time_s`"),
    ('[[flight]]\ntelemetry = "a_tel.csv"\ntracking = "a_trk.csv"\nframe = "ecef"\nlaunch_time_s = 0\n'
     'site = { lat_deg = 95.0, lon_deg = 0, h_m = 0, azimuth_deg = 90 }\n',
     r"flight 1, key `site.lat_deg`: Input should be less than or equal to 89.999 \(got 95.0\)"),
    ('[[flight]]\ntelemetry = "a_tel.csv"\ntracking = "a_trk.csv"\nframe = "mars"\n', r"key `frame`: Input should be"),
    ('[[flight]]\ntelemetry = "a_tel.csv"\ntime_shift_s = 5\n', r"`time_shift_s` describes a tracking file"),
    ('[[flight]]\ntelemetry = "a_tel.csv"\nclock_drift_std_ppm = 5\n', r"`clock_drift_std_ppm` describes a tracking"),
    ('[[flight]]\ntelemetry = "a_tel.csv"\ntracking = "a_trk.csv"\nclock_drift_std_ppm = -1\n',
     r"flight 1, key `clock_drift_std_ppm`: Value error, the std must be a finite number >= 0 \(ppm\), got -1.0"),
    ('[[flight]]\ntelemetry = "a_tel.csv"\ntracking = "a_trk.csv"\nclock_drift_std_ppm = nan\n',
     r"key `clock_drift_std_ppm`: Value error, the std must be a finite number >= 0 \(ppm\), got nan"),
    ('[[flight]]\ntelemetry = "missing.csv"\n', r"flight 1, key `telemetry`: file .*missing.csv does not exist"),
    ('[[flight]]\ntelemetry = "a_tel.csv"\n[[flight]]\ntelemetry = "./a_tel.csv"\n',
     r"flights 1 and 2 have the same telemetry file"),
    ('[flight\n', r"not valid TOML"),
    ('telemetry = "a_tel.csv"\n', r"no \[\[flight\]\] table"),
    ('[[flight]]\ntelemetry = "a_tel.csv"\ntracking = "a_trk.csv"\nlaunch_time_s = 1e400\n', r"launch_time_s"),
])
def test_manifest_errors_name_file_flight_and_key(ranges, body, message):
    p = _write(ranges, "bad.toml", body)
    with pytest.raises(ValueError, match=message) as exc:
        casep.read_manifest(p)
    assert "bad.toml" in str(exc.value)


def test_manifest_clock_drift_std_reaches_the_flight(ranges):
    """``clock_drift_std_ppm`` is read into the flight as ``read_flight_pair(clock_drift_std=...)`` puts it (0: the
    rate exact, accepted), and left out without it (the default then the separation's, as without the option)."""
    text = '[[flight]]\ntelemetry = "b_tel.csv"\ntracking = "b_trk_launch.csv"\n'
    for extra, want in (("clock_drift_std_ppm = 7.5\n", 7.5), ("clock_drift_std_ppm = 0\n", 0.0), ("", None)):
        man = casep.read_manifest(_write(ranges, "std.toml", text + extra))
        assert man.flights[0].clock_drift_std_ppm == want
        flight = man.flights[0].read()
        assert flight.meta.get("clock_drift_std_ppm") == want
        direct = casep.read_flight_pair(ranges / "b_tel.csv", ranges / "b_trk_launch.csv", clock_drift_std=want)
        assert direct.meta.get("clock_drift_std_ppm") == want


def test_cli_manifest_rules_and_repeated_options(ranges, capsys):
    f = ranges
    toml = str(f / "flights.toml")
    assert main(["separate", "--manifest", toml, "--tracking", str(f / "a_trk.csv")]) == 2
    assert "leave out --tracking" in capsys.readouterr().err
    assert main(["separate", "--manifest", toml, "--launch-site", "1", "2", "3", "4"]) == 2
    assert "leave out --launch-site" in capsys.readouterr().err
    assert main(["separate"]) == 2
    assert "give a flight file, or --manifest" in capsys.readouterr().err
    assert main(["noise", "--manifest", toml]) == 2  # noise reads one flight
    assert "lists 2 flights" in capsys.readouterr().err
    for argv in (["separate", "x.csv", "--launch-site", "1", "2", "3", "4", "--launch-site", "1", "2", "3", "5"],
                 ["separate", "x.csv", "--model", "platform36", "--model=platform39_misalignment"],
                 ["diagnose", "x.csv", "--launch-time", "0", "--launch-time", "1"]):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert "given twice: it takes one value" in err


def test_fuse_and_impact_read_the_manifest(tmp_path, capsys):
    """`fuse --manifest` fuses the flights' `result` files, `impact --manifest` reads its flight and result:
    the same numbers as the files given by hand."""
    from casep.simulation.simulate import simulate_flight, write_simulation

    paths = []
    for seed in (5, 6):
        fl, _ = write_simulation(simulate_flight("paper", seed=seed, rate=5.0), tmp_path / f"f{seed}.csv")
        r = tmp_path / f"r{seed}.json"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", casep.IllConditionedWarning)
            assert main(["separate", str(fl), "--json", str(r)]) == 0
        paths.append((fl, r))
    body = "".join(f'[[flight]]\ntelemetry = "{fl.name}"\nresult = "{r.name}"\n\n' for fl, r in paths)
    man = _write(tmp_path, "m.toml", body)
    one = _write(tmp_path, "one.toml", f'[[flight]]\ntelemetry = "{paths[0][0].name}"\nresult = "{paths[0][1].name}"\n')
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    assert main(["fuse", str(paths[0][1]), str(paths[1][1]), "--json", str(a)]) == 0
    assert main(["fuse", "--manifest", str(man), "--json", str(b)]) == 0
    assert json.loads(a.read_text())["estimates"] == json.loads(b.read_text())["estimates"]
    assert main(["fuse", "--manifest", str(man), str(paths[0][1])]) == 2
    assert "leave out the RESULT.json files" in capsys.readouterr().err
    ia, ib = tmp_path / "ia.json", tmp_path / "ib.json"
    assert main(["impact", str(paths[0][0]), "--result", str(paths[0][1]), "--json", str(ia)]) == 0
    assert main(["impact", "--manifest", str(one), "--json", str(ib)]) == 0
    assert json.loads(ia.read_text())["miss"] == json.loads(ib.read_text())["miss"]
