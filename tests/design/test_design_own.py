"""casep design on one's own trajectory (a flight file): the nominal flight's specific force is the file's."""

from __future__ import annotations

import numpy as np
import pytest

from casep.cli import main


@pytest.fixture(scope="module")
def pitch_file(tmp_path_factory):
    """The paper-pitch flight (pitch plane: f_z = 0) at 5 Hz as a flight file, and its truth sidecar."""
    from casep.simulation.simulate import simulate_flight, write_simulation

    return write_simulation(simulate_flight("paper-pitch", seed=0, rate=5.0), tmp_path_factory.mktemp("d") / "p.csv")


def test_design_on_own_flight_equals_the_scenario_design(pitch_file):
    """Closed form as for the scenario: the z scale factor sees f_z = a sin(psi), so the optimum holds every free
    knot at the angle bound; and the nominal objective of the file equals the scenario's (the simulator's body
    axis is along f, which is how a file's attitude is taken)."""
    from test_design import _one_coefficient_model

    from casep.design.optimize import design

    model = _one_coefficient_model()
    kw = dict(model=model, maneuver="yaw", objective="A", max_angle=3.0, max_rate=10.0, max_lateral=10.0, knots=4,
              design_rate=1.0, starts=2, seed=1, start=20.0, sigma=0.1)
    own = design("paper-pitch", flight=pitch_file[0], **kw)
    ref = design("paper-pitch", rate=5.0, verify=False, **kw)
    assert own.solver["success"], own.solver
    np.testing.assert_allclose(np.abs(own.x), 3.0, atol=1e-5)
    assert own.before == pytest.approx(ref.before, rel=1e-3) and own.after == pytest.approx(ref.after, rel=1e-2)
    assert np.isnan(own.crlb_before[0]) and np.isfinite(own.crlb_after[0])  # f_z = 0: not identifiable before
    assert own.verification == {} and own.scenario.name == "flight p.csv-designed"
    with pytest.raises(ValueError, match="objective `miss` on one's own trajectory"):
        design("paper-pitch", flight=pitch_file[0], **{**kw, "objective": "miss"})


def test_cli_design_own_flight(pitch_file, tmp_path, capsys):
    flight, side = pitch_file
    out = tmp_path / "d.json"
    status = main(["design", "--flight", str(flight), "--truth", str(side), "--knots", "3", "--starts", "1",
                   "--max-angle", "3", "--coefficients", "Ka1z", "--json", str(out)])
    text = capsys.readouterr().out
    assert status in (0, 1) and "the designed flight is not re-flown" in text
    assert main(["design", "--flight", str(flight), "--truth", str(side), "-o", str(tmp_path / "x.csv")]) == 2
    assert "with --flight there is none" in capsys.readouterr().err
