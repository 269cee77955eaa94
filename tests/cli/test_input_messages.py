"""Messages of inputs that name the right thing: a tracking file with t in ms, a scenario's default truth for
another model, a result file as --truth-from-prior."""

from __future__ import annotations

import argparse
import dataclasses
import json

import numpy as np
import pytest

import casep


def test_tracking_time_in_ms_names_the_tracking_file(tmp_path):
    t = np.arange(0.0, 100.0, 0.1)
    tel = tmp_path / "tel.csv"
    trk = tmp_path / "trk.csv"
    cols = {"t": t, "f_x": 30.0 + 0 * t, "f_y": 9.8 + 0 * t, "f_z": 0 * t,
            "v_tel_x": 30.0 * t, "v_tel_y": 0 * t, "v_tel_z": 0 * t}
    tel.write_text("\n".join([",".join(cols)] + [",".join(f"{cols[c][k]:.10g}" for c in cols)
                                                 for k in range(t.size)]))
    tt = t[::5]
    trk.write_text("\n".join(["t,v_trk_x,v_trk_y,v_trk_z"] + [f"{1e3 * s:.10g},{30.0 * s:.10g},0,0" for s in tt]))
    with pytest.raises(casep.FlightDataError, match=r"trk\.csv.*column `t`.*in ms"):
        casep.read_flight_pair(tel, trk)


def test_default_truth_of_another_model_is_said():
    from casep.simulation.simulate import simulate_flight

    with pytest.raises(ValueError, match=r"no truth given: scenario `strapdown-boost`.*strapdown33.*sa_y"):
        simulate_flight("strapdown-boost", model="strapdown15_axial")


def test_truth_from_prior_reads_a_result_file(tmp_path):
    from casep.cli.montecarlo import _read_files

    m = casep.load_model("platform36")
    rng = np.random.default_rng(2)
    S = rng.standard_normal((200, 3, m.n_coefficients))
    res = casep.solve_ols(S, S @ np.ones(m.n_coefficients) + 0.1 * rng.standard_normal((200, 3)), names=m.names,
                          units=m.units, si_factors=m.si_factors)
    res = dataclasses.replace(res, model=m.name)
    path = tmp_path / "res.json"
    path.write_text(json.dumps(res.to_dict()))
    args = argparse.Namespace(prior=None, bounds=None, dispersions=None, truth_from_prior=str(path), model=None)
    table = _read_files(args, m.names, 1)["truth_prior"]
    assert set(table) == set(m.names)
    assert table["Kg0x"]["mean"] == pytest.approx(res.estimate[0], rel=1e-12)
    assert table["Kg0x"]["std"] == pytest.approx(res.std[0], rel=1e-12)


def test_a_launch_site_value_the_site_refuses_is_named_by_its_option(capsys, tmp_path):
    """`--launch-site 97.89 ...`: exit 2 naming --launch-site LAT (the site's own rule gave `lat_deg`)."""
    from casep.cli import main

    imu = tmp_path / "imu.csv"
    imu.write_text("t,w_x,w_y,w_z,fb_x,fb_y,fb_z\n" + "\n".join(f"{0.01 * k:.2f},0,0,0,0,0,9.8" for k in range(300)))
    code = main(["navigate", str(imu), "--launch-site", "97.89", "21.1", "330", "30", "--launch-time", "1",
                 "--align", "0", "2", "--heading", "30", "-o", str(tmp_path / "tel.csv")])
    err = capsys.readouterr().err
    assert code == 2 and "--launch-site LAT: " in err and "97.89" in err, err
    assert not (tmp_path / "tel.csv").exists()
