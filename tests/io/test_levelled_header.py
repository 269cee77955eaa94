"""casep navigate's header line saying it levelled the telemetry (casep.io.files.levelled_comment, levelling_record)
and the model casep separate takes by default from it (casep.model.loader.default_model)."""

from types import SimpleNamespace

import numpy as np

from casep.io.files import header_facts, levelled_comment, levelling_record, read_flight, simulated_comment, write_table
from casep.io.tables import Table
from casep.model.loader import PHI0_MODELS, default_model
from casep.units import G0


def _cols(strapdown: bool) -> dict:
    t = np.arange(4.0)
    cols = {"t": t, "f_x": t * 0, "f_y": t * 0, "f_z": t * 0 + G0, "v_tel_x": t * 0, "v_tel_y": t * 0,
            "v_tel_z": t * 0, "v_trk_x": t * 0, "v_trk_y": t * 0, "v_trk_z": t * 0}
    if strapdown:
        cols.update({"q_w": t * 0 + 1, "q_x": t * 0, "q_y": t * 0, "q_z": t * 0, "fb_x": t * 0, "fb_y": t * 0,
                     "fb_z": t * 0 - G0, "w_x": t * 0, "w_y": t * 0, "w_z": t * 0})
    return cols


def test_levelled_header_round_trip(tmp_path):
    """The header line casep navigate writes is read back as the window, the heading's origin, its body axis and
    value."""
    al = SimpleNamespace(method="heading", heading_axis="x", heading_deg=200.0)
    cols = _cols(False)
    path = tmp_path / "tel.csv"
    write_table(path, cols, comments=["casep navigate imu.csv", levelled_comment((0.0, 38.5), al)])
    back = {"window": [0.0, 38.5], "heading": "given", "heading_axis": "x", "heading_deg": 200.0}
    assert levelling_record(Table(path)) == back
    assert read_flight(path).meta["levelled"] == back
    write_table(path, cols, comments=["another INS"])
    assert read_flight(path).meta["levelled"] is None


def test_strapdown_telemetry_defaults_to_a_model_that_covers_its_errors(tmp_path):
    """Without --model: on a strapdown telemetry strapdown42_extended (every strapdown33 term plus phi0, which
    the levelling needs: casep.checks.plausibility.levelling_problem), platform36 on a platform one, strapdown33
    on a raw IMU record; the model casep simulate names in the header when it is a shipped one, with its phi0
    twin (PHI0_MODELS) when casep navigate levelled the telemetry."""
    al = SimpleNamespace(method="heading", heading_axis="x", heading_deg=200.0)
    write_table(tmp_path / "sd.csv", _cols(True))
    write_table(tmp_path / "pl.csv", _cols(False))
    assert default_model(tmp_path / "sd.csv") == "strapdown42_extended"
    assert default_model(tmp_path / "pl.csv") == "platform36"
    assert default_model(None, imu=True) == "strapdown33" and default_model(None) == "platform36"
    sim = ["casep simulated flight: scenario strapdown-boost", simulated_comment("strapdown33", 0, 10.0)]
    write_table(tmp_path / "sim.csv", _cols(True), comments=sim)
    assert header_facts(tmp_path / "sim.csv")["simulated_model"] == "strapdown33"
    assert default_model(tmp_path / "sim.csv") == "strapdown33"
    write_table(tmp_path / "lev.csv", _cols(True), comments=[*sim, levelled_comment((0.0, 9.0), al)])
    assert default_model(tmp_path / "lev.csv") == PHI0_MODELS["strapdown33"] == "strapdown42_extended"
    write_table(tmp_path / "own.csv", _cols(True), comments=[simulated_comment("my_model", 3, 10.0)])
    assert default_model(tmp_path / "own.csv") == "strapdown42_extended"  # not a shipped model: the rule
    from casep.model.loader import load_model

    assert {"phi0_x", "phi0_y", "phi0_z"} <= set(load_model(default_model(tmp_path / "sd.csv")).names)
