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
    with pytest.raises(ValueError, match=r"RESULT \S*a.json read the flight file A.csv and \S*b.json the flight "
                                         r"file copy_of_A.csv, and the two files have the same content \(sha256 a{12}"):
        check_distinct_inputs([a, b])


def test_a_result_fused_with_one_made_from_it_is_refused(tmp_path):
    a = _result(tmp_path / "a.json", [{"file": "A.csv", "sha256": "a" * 64, "role": "flight"}])
    own = hashlib.sha256(a.read_bytes()).hexdigest()
    b = _result(tmp_path / "b.json", [{"file": str(a), "sha256": own, "role": "result 1"}])
    with pytest.raises(ValueError, match=r"b.json was made from RESULT \S*a.json .*counts its data twice"):
        check_distinct_inputs([a, b])


def test_the_same_file_named_twice_is_refused_without_provenance(tmp_path):
    a = tmp_path / "a.json"
    a.write_text("{}")
    b = tmp_path / "b.json"
    b.write_text("{}")  # same bytes: the same data
    with pytest.raises(ValueError, match="are the same file content"):
        check_distinct_inputs([a, b])


def test_a_shared_telemetry_with_other_tracking_is_one_flight_each_result_naming_its_own_files(tmp_path):
    """Two results whose telemetry files have the same content but whose tracking files differ are two estimates of
    one record (not independent): refused, each result named with its own files, the shared one's role said."""
    a = _result(tmp_path / "p1.json", [{"file": "p1.csv", "sha256": "a" * 64, "role": "telemetry"},
                                      {"file": "p1.tracking.csv", "sha256": "b" * 64, "role": "tracking"}])
    b = _result(tmp_path / "p2.json", [{"file": "p2.csv", "sha256": "a" * 64, "role": "telemetry"},
                                      {"file": "p2.tracking.csv", "sha256": "c" * 64, "role": "tracking"}])
    with pytest.raises(ValueError) as info:
        check_distinct_inputs([a, b])
    msg = str(info.value)
    assert f"RESULT {a} read the telemetry file p1.csv and {b} the telemetry file p2.csv" in msg
    assert "same content" in msg and "not independent" in msg
    assert f"{a}: tracking p1.tracking.csv; {b}: tracking p2.tracking.csv" in msg
    # both reading one tracking file under one name
    c = _result(tmp_path / "p3.json", [{"file": "p3.csv", "sha256": "d" * 64, "role": "telemetry"},
                                      {"file": "p2.tracking.csv", "sha256": "c" * 64, "role": "tracking"}])
    with pytest.raises(ValueError, match=r"both read the tracking file p2.tracking.csv"):
        check_distinct_inputs([b, c])
