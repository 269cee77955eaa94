"""A telemetry casep navigate levelled on the pad, separated with a strapdown model without an initial attitude
error: the result fails naming the tilt and the model to use (casep.checks.plausibility.levelling_problem)."""

import numpy as np
import pytest

from casep.checks.plausibility import levelling_problem
from casep.io.flight import FlightData
from casep.model.loader import load_model
from casep.units import G0


def _flight(levelled):
    t = np.arange(0.0, 60.0, 0.5)
    sig = {"fb_x": np.zeros_like(t), "fb_y": np.zeros_like(t), "fb_z": np.full_like(t, -G0)}  # FRD body, at rest
    f = np.tile([0.0, 0.0, G0], (t.size, 1))
    fl = FlightData(t=t, f=f, dv=np.zeros((t.size, 3)), source="tel.csv", signals=sig)
    fl.meta["levelled"] = levelled
    return fl


@pytest.mark.parametrize("name, fails", [("strapdown12", True), ("strapdown15_phi0", False), ("platform36", False)])
def test_levelled_telemetry_needs_phi0(name, fails):
    """strapdown12 has accelerometer errors and no phi0: the levelling's tilt is named (a 1 mg bias across the
    vertical: 1e-3 rad = 206 arcsec) with the model to use; strapdown15_phi0 takes it; a platform model is not
    strapdown; a telemetry not levelled by casep is not judged."""
    model = load_model(name)
    est = {"ba_x": 1.0, "ba_y": 0.0, "ba_z": 5.0}  # mg: ba_z is along the pad's vertical, no tilt
    why = levelling_problem(_flight({"window": [0.0, 38.0], "heading": "given"}), model, est)
    assert (why is not None) == fails
    if fails:
        assert "[0, 38] s" in why and "use strapdown15_phi0" in why and "strapdown12" in why
        arcsec = float(why.split("start tilt of ")[1].split(" arcsec")[0])
        assert arcsec == pytest.approx(206.26, rel=3e-3)  # printed to 3 digits
    assert levelling_problem(_flight(None), model, est) is None


def test_the_tilt_is_sized_only_from_biases_the_flight_determines():
    """The estimates judge_setup passes are those the flight determines (std below the declared magnitude,
    casep.workflows.judging._determined_estimates): a bias without one is left out, and the message then names the
    undetermined biases and gives no tilt (a levelled telemetry under strapdown33 said "ba_y, ba_z 5.96e+06,
    1.29e+07 mg: a start tilt of 2.93e+09 arcsec" from the solver's values of undetermined biases)."""
    from types import SimpleNamespace

    from casep.workflows.judging import _determined_estimates

    model = load_model("strapdown12")
    names = list(model.names)
    est = np.zeros(len(names))
    std = np.full(len(names), 0.01)  # well below every declared magnitude
    for n, x, sd in (("ba_x", 1.0, 0.1), ("ba_y", 5.96e6, 3e6), ("ba_z", 1.29e7, 1e7)):
        est[names.index(n)], std[names.index(n)] = x, sd
    kept = _determined_estimates(SimpleNamespace(names=names, estimate=est, std=std), model)
    assert kept["ba_x"] == 1.0 and "ba_y" not in kept and "ba_z" not in kept
    why = levelling_problem(_flight({"window": [0.0, 38.0], "heading": "given"}), model, kept)
    assert "start tilt" not in why and "e+06" not in why and "e+07" not in why, why
    assert "its size is not given: the flight does not determine ba_y, ba_z" in why, why
    assert "use strapdown15_phi0" in why
