"""The time-offset check reads the samples the fit kept: glitches a robust fit removed are no offset."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from casep.cli import main


@pytest.fixture(scope="module")
def glitchy(tmp_path_factory):
    """The paper flight at 100 Hz (seed 1) with 30 glitches of +1 m/s on dv_x and dv_y, every 20th of the
    600 samples of largest |a| (end of the burns): glitches where a(t) is large, as tracking loses
    lock at staging. Returns (folder, clean flight, glitchy flight)."""
    d = tmp_path_factory.mktemp("glitchy")
    clean, g = d / "paper.csv", d / "glitchy.csv"
    assert main(["simulate", "--scenario", "paper", "--seed", "1", "--rate", "100", "-o", str(clean)]) == 0
    fl = pd.read_csv(clean, comment="#")
    a = np.linalg.norm(fl[["f_x", "f_y", "f_z"]].to_numpy() + [0.0, -9.80665, 0.0], axis=1)
    rows = np.argsort(a)[-600::20]
    fl.loc[rows, ["dv_x", "dv_y"]] += 1.0
    fl.to_csv(g, index=False)
    return d, clean, g


def test_glitches_removed_by_the_robust_fit_give_no_time_offset_warning(glitchy, capsys):
    """Before: exit 0 with 'a tracking time offset of 0.73 +- 0.14 ms would explain them (t = 5.12)'."""
    _, _, g = glitchy
    assert main(["separate", str(g)]) == 0
    out, err = capsys.readouterr()
    assert "sample(s) rejected as glitches" in out
    assert "time offset" not in err and "jerk" not in err, err


def test_the_test_on_every_sample_is_the_test_without_a_keep_mask(paper_problem):
    """keep all True is the plain test, to rounding; a kept subset is the test on those samples' rows."""
    from casep.checks.time_offset import time_offset_test
    from casep.simulation.simulate import simulate_flight

    S, dv, _ = paper_problem
    fl = simulate_flight("paper", seed=1, rate=20.0).flight
    t, f = np.asarray(fl.t), np.asarray(fl.f)
    r = dv - S @ np.linalg.lstsq(S.reshape(-1, S.shape[-1]), dv.reshape(-1), rcond=None)[0]
    a = time_offset_test(S, r, t, f)
    b = time_offset_test(S, r, t, f, keep=np.ones(t.size, dtype=bool))
    assert a is not None and b is not None
    np.testing.assert_allclose([b.offset, b.offset_std, b.jerk], [a.offset, a.offset_std, a.jerk], rtol=1e-12)
    keep = np.ones(t.size, dtype=bool)
    keep[::7] = False
    c = time_offset_test(S, r, t, f, keep=keep)
    assert c is not None and c.offset_std > a.offset_std  # fewer samples: a wider std
