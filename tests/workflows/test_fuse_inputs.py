"""casep.workflows.fuse_inputs.check_distinct_inputs: no input data file counted twice in a fusion."""

import hashlib
import json

import pytest

from casep.workflows.fuse_inputs import check_distinct_inputs


def _result(path, inputs):
    path.write_text(json.dumps({"coefficients": {}, "provenance": {"inputs": inputs}}))
    return path


def test_distinct_flights_pass_a_shared_prior_does_not_count(tmp_path):
    prior = {"file": "ground.json", "sha256": "p" * 64, "role": "prior"}
    a = _result(tmp_path / "a.json", [{"file": "A.csv", "sha256": "a" * 64, "role": "flight"}, prior])
    b = _result(tmp_path / "b.json", [{"file": "B.csv", "sha256": "b" * 64, "role": "flight"}, prior])
    check_distinct_inputs([a, b])


def test_the_same_flight_twice_is_refused(tmp_path):
    a = _result(tmp_path / "a.json", [{"file": "A.csv", "sha256": "a" * 64, "role": "flight"}])
    b = _result(tmp_path / "b.json", [{"file": "copy_of_A.csv", "sha256": "a" * 64, "role": "flight"}])
    with pytest.raises(ValueError, match=r"estimated from the same input file copy_of_A.csv \(sha256 aaaaaaaaaaaa"):
        check_distinct_inputs([a, b])


def test_a_result_fused_with_one_made_from_it_is_refused(tmp_path):
    a = _result(tmp_path / "a.json", [{"file": "A.csv", "sha256": "a" * 64, "role": "flight"}])
    own = hashlib.sha256(a.read_bytes()).hexdigest()
    b = _result(tmp_path / "b.json", [{"file": str(a), "sha256": own, "role": "result 1"}])
    with pytest.raises(ValueError, match="counts its data twice"):
        check_distinct_inputs([a, b])


def test_the_same_file_named_twice_is_refused_without_provenance(tmp_path):
    a = tmp_path / "a.json"
    a.write_text("{}")
    b = tmp_path / "b.json"
    b.write_text("{}")  # same bytes: the same data
    with pytest.raises(ValueError, match="same input file"):
        check_distinct_inputs([a, b])
