"""casep.workflows.coefficients: prior and bounds files of every accepted form, and a scales file."""

import json
import warnings

import numpy as np
import pytest

from casep.io.result_files import write_json_atomic
from casep.model.loader import load_model
from casep.simulation.simulate import simulate_flight
from casep.workflows.coefficients import read_coefficient_file, read_scales
from casep.workflows.separate import separate


@pytest.fixture(scope="module")
def model():
    return load_model("platform36")


@pytest.fixture(scope="module")
def result(model):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ill-conditioned boost flight
        return separate(simulate_flight("paper", seed=2, rate=10.0).flight, model, "ols", noise="white",
                        robust="none")


def test_a_result_file_becomes_its_posterior(result, model, tmp_path):
    """Mean = estimate, std = sqrt(diag C), and the correlation with the std rebuild the result's covariance."""
    path = tmp_path / "r.json"
    write_json_atomic(result.to_dict(), path)
    prior = read_coefficient_file(path, "prior", model.names)
    names = prior["correlation"]["names"]
    idx = [result.names.index(n) for n in names]
    assert len(idx) > 10
    mean = np.array([prior[n]["mean"] for n in names])
    sd = np.array([prior[n]["std"] for n in names])
    np.testing.assert_allclose(mean, result.estimate[idx], rtol=1e-12)
    C = np.asarray(prior["correlation"]["matrix"]) * np.outer(sd, sd)
    np.testing.assert_allclose(C, result.covariance[np.ix_(idx, idx)], rtol=1e-9, atol=0)


def test_a_failed_result_is_refused(result, model, tmp_path):
    path = tmp_path / "failed.json"
    write_json_atomic({**result.to_dict(), "success": False, "status": 2, "message": "did not converge"}, path)
    with pytest.raises(ValueError, match="a failed result .*did not converge"):
        read_coefficient_file(path, "prior", model.names)


def test_plain_prior_and_bounds_are_checked_against_the_model(model, tmp_path):
    good, bad = tmp_path / "b.json", tmp_path / "bad.json"
    good.write_text(json.dumps({"Kg0x": [-1.0, 1.0], "Ka0x": 0.0}))
    assert read_coefficient_file(good, "bounds", model.names) == {"Kg0x": [-1.0, 1.0], "Ka0x": 0.0}
    bad.write_text(json.dumps({"Kg0q": {"mean": 0.0, "std": 1.0}}))
    with pytest.raises(ValueError, match=f"--prior {bad}.*Kg0q"):
        read_coefficient_file(bad, "prior", model.names)
    with pytest.raises(ValueError, match="`kind`"):
        read_coefficient_file(good, "scales", model.names)


def test_scales(model, tmp_path):
    path = tmp_path / "s.json"
    path.write_text(json.dumps({"Kg0x": 0.5}))
    assert read_scales(path, model.names) == {"Kg0x": 0.5}
    for entry, message in (({"Kg0x": -1}, "finite number > 0"), ({"Kg0x": True}, "finite number > 0"),
                           ({"nope": 1.0}, "nope")):
        path.write_text(json.dumps(entry))
        with pytest.raises(ValueError, match=message):
            read_scales(path, model.names)
