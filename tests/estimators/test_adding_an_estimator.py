"""The worked example of docs/guide/adding-an-estimator.md: its module, taken from the page, registered
at run time and solved through casep.separate, against NumPy's lstsq on the weighted rows."""

import importlib.util
import re
import sys
from pathlib import Path

import numpy as np
import pytest

import casep
from casep.estimators import registry
from casep.regression.problem import Problem

PAGE = Path(__file__).resolve().parents[2] / "docs" / "guide" / "adding-an-estimator.md"


def _module(tmp_path):
    """The page's first Python block (under "## The module"), imported from a file of its own."""
    text = PAGE.read_text()
    section = text[text.index("## The module"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    path = tmp_path / "zweighted_example.py"
    path.write_text(code)
    spec = importlib.util.spec_from_file_location("zweighted_example", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture
def zweighted(tmp_path):
    mod = _module(tmp_path)
    registry.register(mod.ZWEIGHTED)
    yield mod
    registry.unregister("zweighted")
    sys.modules.pop("zweighted_example", None)


def _data(rng, ratio):
    N, n = 400, 5
    S = rng.normal(size=(N, 3, n))
    D = np.array([1.0, -2.0, 0.5, 3.0, -1.0])
    noise = rng.normal(size=(N, 3)) * np.array([0.1, 0.1, 0.1 * ratio])  # z axis `ratio` times noisier
    return S, S @ D + noise, np.arange(N) * 0.05, D


def test_worked_example_matches_weighted_lstsq(zweighted, rng):
    ratio = 3.0
    S, y, t, _ = _data(rng, ratio)
    problem = Problem.from_arrays(S, y, t, names=[f"D{j}" for j in range(5)])
    res = casep.separate(problem, method="zweighted", options={"z_ratio": ratio}, noise="white", robust="none")
    # independent: lstsq on the rows divided by their relative std
    w = np.array([1.0, 1.0, 1.0 / ratio])
    A = (S * w[None, :, None]).reshape(-1, 5)
    b = (y * w).reshape(-1)
    x, rss, rank, _ = np.linalg.lstsq(A, b, rcond=None)
    sigma = np.sqrt(rss[0] / (A.shape[0] - rank))
    std = sigma * np.sqrt(np.diag(np.linalg.inv(A.T @ A)))
    assert res.method == "zweighted" and res.success
    np.testing.assert_allclose(res.estimate, x, rtol=1e-10)
    np.testing.assert_allclose(res.std, std, rtol=1e-8)
    np.testing.assert_allclose(res.residuals, y - S @ x, atol=1e-12)  # raw residuals, not weighted
    assert res.extras.z_ratio == ratio and "z axis weighted by 1/3" in res.text()
    # the weighting matters: ordinary least squares differs by more than rounding
    assert np.max(np.abs(casep.solve_ols(S, y).estimate - x)) > 1e-4


def test_worked_example_is_a_registered_method(zweighted, rng):
    S, y, t, D = _data(rng, 1.0)
    assert "zweighted" in registry.METHODS and registry.OPTIONS["z_ratio"].default == 1.0
    assert any(m["name"] == "zweighted" for m in registry.describe())
    # its rule, in its public solver
    with pytest.raises(ValueError, match=r"option --z-ratio \(`z_ratio`\) must be in \(0, 100\]"):
        zweighted.solve_zweighted(S, y, z_ratio=500.0)
    with pytest.raises(ValueError, match="option --z-ratio .* is not taken by method `ols`"):
        casep.separate(Problem.from_arrays(S, y, t), method="ols", options={"z_ratio": 2.0})
    np.testing.assert_allclose(zweighted.solve_zweighted(S, y, z_ratio=1.0).estimate, casep.solve_ols(S, y).estimate,
                               rtol=1e-12)  # ratio 1: ordinary least squares


def test_unregistered_after_the_test():
    assert "zweighted" not in registry.METHODS and "z_ratio" not in registry.OPTIONS


def test_worked_example_on_a_flight_from_python_and_the_command_line(zweighted, tmp_path, capsys):
    """On a flight file: the result names its model (impact and fuse need it), and `casep separate
    --method zweighted --z-ratio 2` runs once the method is registered, with the Python API's numbers."""
    import json

    from casep.cli import main
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper", seed=4, rate=5.0)
    path = tmp_path / "f.csv"
    casep.write_flight(sim.flight, path)
    flight = casep.read_flight(path)
    res = casep.separate(flight, "platform36", method="zweighted", options={"z_ratio": 2.0})
    assert res.model == "platform36" and res.extras.z_ratio == 2.0
    by_keyword = casep.separate(flight, "platform36", method="zweighted", z_ratio=2.0)  # a registered method's option
    np.testing.assert_array_equal(by_keyword.estimate, res.estimate)
    with pytest.raises(ValueError, match="`z_ratio`.*not taken by method `ols`"):
        casep.separate(flight, "platform36", method="ols", z_ratio=2.0)
    out = tmp_path / "r.json"
    assert main(["separate", str(path), "--method", "zweighted", "--z-ratio", "2", "--json", str(out)]) in (0, 1)
    data = json.loads(out.read_text())
    assert data["method"] == "zweighted" and data["model"] == "platform36"
    np.testing.assert_allclose([c["estimate"] for c in data["coefficients"]], res.estimate, rtol=1e-9, atol=1e-12)
    capsys.readouterr()
