"""casep.workflows.joint_report: the several-flight result JSON and tables."""

from types import SimpleNamespace

import numpy as np

from casep.workflows.joint_report import flights_crlb_lines, joint_result_dict, joint_summary_lines


def test_joint_json_keeps_the_shared_block():
    names = ["Kg0x", "Ka0x", "dt_trk[A]", "dt_trk[B]"]
    C = np.arange(16.0).reshape(4, 4)
    d = {"coefficients": {n: k for k, n in enumerate(names)}, "names": names, "units": ["deg/h", "mg", "ms", "ms"],
         "estimates": [1.0, 2.0, 3.0, 4.0], "std": [0.1, 0.2, 0.3, 0.4], "si_factors": None,
         "covariance": C.tolist()}
    res = SimpleNamespace(names=names, to_dict=lambda: {k: (list(v) if isinstance(v, dict) else v)
                                                         for k, v in d.items()})
    jp = SimpleNamespace(layout=SimpleNamespace(names=("Kg0x", "Ka0x", "dt_trk")))
    summary = {"flights": [{"file": "A"}, {"file": "B"}], "consistency": {"overall": None}}
    out = joint_result_dict(res, jp, summary)
    assert out["names"] == ["Kg0x", "Ka0x"] and out["estimates"] == [1.0, 2.0] and out["std"] == [0.1, 0.2]
    assert out["coefficients"] == ["Kg0x", "Ka0x"]
    assert out["si_factors"] is None
    np.testing.assert_array_equal(out["covariance"], C[:2, :2])
    assert out["flights"] == summary["flights"] and out["consistency"] == summary["consistency"]


def test_summary_lines_flag_disagreeing_flights():
    flights = [{"file": "A.csv", "n_samples": 10, "sigma": 0.1}]
    agree = {"flights": flights, "consistency": {"overall": {"chi2": 3.0, "dof": 4, "p_value": 0.5}}}
    lines = joint_summary_lines(agree)
    assert lines[0] == "A.csv: 10 samples, sigma 0.1 m/s" and "disagree" not in lines[1]
    from casep.estimators.joint import FAIL_P, WARN_P

    disagree = {"flights": flights, "consistency": {"overall": {"chi2": 90.0, "dof": 4, "p_value": FAIL_P / 2},
                                                    "note": "one flight"}}
    lines = joint_summary_lines(disagree)
    assert lines[1].endswith("<- the flights disagree")
    assert lines[2] == "note: one flight"
    doubt = {"flights": flights, "consistency": {"overall": {"chi2": 15.0, "dof": 4, "p_value": WARN_P / 2}}}
    assert joint_summary_lines(doubt)[1].endswith(f"<- below {WARN_P:g}: do the flights agree?")
    nf = {"flights": flights, "consistency": {"overall": None, "noise_free": {
        "agree": False, "residual_rms": {"A.csv": 2.5e-4}, "rounding_level": {"A.csv": 1e-9}}}}
    assert joint_summary_lines(nf)[1] == ("consistency of the noise-free flights: joint least-squares residual RMS "
                                          "A.csv 0.00025 m/s  <- above their rounding level: the flights disagree")


def test_crlb_table():
    d = {"flights": ["A.csv", "B.csv"], "sigmas": [0.1, 0.2], "identifiable_alone": [1, 0], "identifiable_joint": 1,
         "coefficients": [{"name": "Kg0x", "unit": "deg/h", "crlb_alone": [0.5, float("nan")],
                           "verdict_alone": ["identifiable", "unidentifiable"], "crlb_joint": 0.4,
                           "verdict_joint": "identifiable"}]}
    lines = flights_crlb_lines(d, "platform36", with_prior=True)
    assert lines[0].startswith("model platform36, 2 flights") and lines[0].endswith("joint bound with the prior")
    assert lines[2].split()[:2] == ["Kg0x", "deg/h"] and lines[2].split()[3] == "+" and lines[2].endswith("+")
    assert lines[-1] == "identifiable jointly: 1 of 1"
