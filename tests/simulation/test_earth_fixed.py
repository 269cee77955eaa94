"""casep.simulation.earth_fixed: a rotating-Earth flight written with ECEF/geodetic tracking and its truth."""

import json

import numpy as np
import pandas as pd
import pytest

from casep.frames import ECEF_COLUMNS, LaunchSite, ecef_to_launch
from casep.model.loader import load_model
from casep.simulation.earth_fixed import read_truth, tracking_path, write_earth_fixed_flight
from casep.simulation.scenarios import get_scenario

SITE = LaunchSite(28.5, -80.6, 3.0, 90.0, 0.0)


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    d = tmp_path_factory.mktemp("ef")
    return write_earth_fixed_flight(d / "tel.csv", SITE, frame="ecef", seed=5, telemetry_rate=10.0,
                                    tracking_rate=5.0, time_offset_ms=20.0)


def test_tracking_file_is_the_launch_frame_tracking_in_ecef(written):
    """ECEF columns converted back to launch-inertial (casep.frames) give the simulated tracking velocity."""
    assert written.tracking == tracking_path(written.telemetry) == written.telemetry.with_name("tel.tracking.csv")
    trk = pd.read_csv(written.tracking, comment="#")
    assert list(trk.columns) == list(ECEF_COLUMNS)
    r = trk[["r_ecef_x", "r_ecef_y", "r_ecef_z"]].to_numpy()
    v = trk[["v_ecef_x", "v_ecef_y", "v_ecef_z"]].to_numpy()
    _, v_launch = ecef_to_launch(SITE, trk["t"].to_numpy(), r, v)
    np.testing.assert_allclose(v_launch, written.data.v_trk, atol=1e-6)
    assert trk["t"].size == written.data.t_trk.size


def test_truth_sidecar_records_the_set_up(written):
    truth = json.loads(written.truth.read_text())
    assert truth == json.loads(json.dumps(written.truth_record))
    model = load_model(get_scenario("paper").model)
    assert truth["model"] == model.name and list(truth["coefficients"]) == list(model.names)
    np.testing.assert_allclose(list(truth["coefficients"].values()), written.data.truth, rtol=0, atol=0)
    assert truth["tracking"]["time_offset_ms"] == 20.0 and truth["tracking"]["frame"] == "ecef"
    assert truth["tracking"]["launch_site"] == SITE.to_dict() and truth["tracking"]["rate_hz"] == 5.0
    assert truth["trajectory"]["rate_hz"] == 10.0 and truth["seed"] == 5
    # the sidecar is a --truth file: read back, checked against the model
    assert read_truth(written.truth, model) == truth["coefficients"]


def test_bad_truth_and_frame(tmp_path):
    model = load_model("platform36")
    bad = tmp_path / "t.json"
    bad.write_text(json.dumps({"Kg0x": "large"}))
    with pytest.raises(ValueError, match=f"--truth {bad}: `Kg0x` must be a finite number"):
        read_truth(bad, model)
    with pytest.raises(ValueError, match="`frame`"):
        write_earth_fixed_flight(tmp_path / "x.csv", SITE, frame="launch")
    assert not (tmp_path / "x.csv").exists()
