"""casep.reporting.noise_text: a result's noise, robust-fit, exclusion and gap diagnostics as lines."""

from casep.reporting.noise_text import noise_lines, robust_line

ROBUST = {"function": "huber", "rejected_count": 8, "rejected": [{"where": f"t={k}.0 s"} for k in range(8)],
          "downweighted": 3, "iterations": 4}


def test_robust_line_names_six_places_then_ellipsis():
    line = robust_line(ROBUST)
    assert line.startswith("robust (huber): 8 sample(s) rejected as glitches: t=0.0 s, ")
    assert "t=5.0 s, ..." in line and "t=6.0 s" not in line
    assert line.endswith("3 row(s) down-weighted, 4 iteration(s)")
    auto = robust_line({**ROBUST, "rejected_count": 1, "rejected": [{"where": "t=1.0 s"}],
                        "automatic": {"glitches_found": 1, "expected_from_noise": 0.0123}})
    assert "automatic: the filter found 1 glitch(es) where Gaussian noise gives 0.012" in auto
    assert ", ..." not in auto


def test_noise_lines_each_record_one_line_in_order():
    diag = {"noise": {"note": "white noise assumed", "rule": "given", "axes": {"x": {"tau_s": 0.5}}},
            "robust": ROBUST,
            "excluded": {"count": 2, "alpha": 0.01, "samples": [{"where": "t=3.0 s", "axis": "x"},
                                                              {"where": "t=4.0 s", "axis": "z"}]},
            "gaps": [{"length": 1.25, "where": "t=10 s"}]}
    lines = noise_lines(diag)
    assert lines[0] == "noise: white noise assumed, tau 0.5 s (given)"
    assert lines[1].startswith("robust (huber)")
    assert lines[2] == ("excluded: 2 sample(s) flagged at alpha 0.01 removed and the fit repeated: t=3.0 s x, "
                        "t=4.0 s z")
    assert lines[3] == "tracking gaps: 1 longer than 3 sample periods: 1.25 s before t=10 s"
    assert noise_lines({}) == []


def test_joint_lines_are_labelled_per_flight():
    nd = {"note": "white", "rule": "r", "axes": {"x": {"tau_s": 1.0}}}
    lines = noise_lines({"noise": {"A.csv": {**nd, "robust": ROBUST}, "B.csv": nd}}, joint=True)
    assert lines[0] == "A.csv: noise: white, tau 1 s (r)"
    assert lines[1].startswith("A.csv: robust (huber)")
    assert lines[2] == "B.csv: noise: white, tau 1 s (r)" and len(lines) == 3
