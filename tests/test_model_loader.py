"""Loading models by name and by path (casep.model_loader)."""

from __future__ import annotations

import textwrap

import pytest

import casep
from casep.model import ModelDefinitionError


def test_builtin_models_are_listed():
    names = casep.available_models()
    assert "platform36" in names and "platform39_misalignment" in names


def test_load_by_path_and_env(tmp_path, monkeypatch):
    src = textwrap.dedent(
        """
        import casep

        def build():
            m = casep.build_model("platform36")
            m.name = "platform39_dv0"
            c = m.declare(dv0x="m/s", dv0y="m/s", dv0z="m/s")  # initial velocity error, m/s
            m.set_initial_velocity_error([c.dv0x, c.dv0y, c.dv0z])
            return m
        """
    )
    path = tmp_path / "platform39_dv0.py"
    path.write_text(src)
    m = casep.load_model(str(path))
    assert m.name == "platform39_dv0" and m.n_coefficients == 39
    monkeypatch.setenv("CASEP_MODEL_PATH", str(tmp_path))
    assert casep.load_model("platform39_dv0").names[-1] == "dv0z"
    assert "platform39_dv0" in casep.available_models()


def test_unknown_model_lists_available():
    with pytest.raises(ValueError, match="unknown model `nope`. Use one of: .*platform36"):
        casep.load_model("nope")


def test_file_without_build(tmp_path):
    p = tmp_path / "nobuild.py"
    p.write_text("x = 1\n")
    with pytest.raises(ModelDefinitionError, match="Missing: build\\(\\)"):
        casep.load_model(p)
    p.write_text("def build():\n    return 3\n")
    with pytest.raises(ModelDefinitionError, match="returned int"):
        casep.load_model(p)


def test_extension_adds_a_term_and_is_recovered(tmp_path, truth36, flight_tf):
    import numpy as np

    (tmp_path / "platform37_gsens.py").write_text(textwrap.dedent(
        """
        import casadi as ca
        import casep

        def build():
            m = casep.build_model("platform36")
            m.name = "platform37_gsens"
            c = m.declare(Kg3x="deg/h/g^2")  # gyro x drift in Wx*Wy
            m.set_gyro_drift(m.output("gyro_drift") + ca.vertcat(c.Kg3x * m.W[0] * m.W[1], 0, 0))
            return m
        """
    ))
    m = casep.load_model(tmp_path / "platform37_gsens.py")
    assert m.names[-1] == "Kg3x" and 36 in m.numeric("gyro_columns")
    t, f = flight_tf
    D = np.concatenate([truth36, [0.05]])
    S = casep.build_sv(m, t, f)
    res = casep.solve_ols(S, S @ D)
    np.testing.assert_allclose(res.estimate, D, rtol=1e-6)
