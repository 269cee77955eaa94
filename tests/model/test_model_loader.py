"""Loading models by name and by path (casep.model.loader)."""

from __future__ import annotations

import textwrap

import pytest

import casep
from casep.model.error_model import ModelDefinitionError


def test_builtin_models_are_listed():
    names = casep.available_models()
    assert "platform36" in names and "platform39_misalignment" in names


def test_richer_models_extend_the_model_and_list_every_window_model():
    """Each model RICHER_MODELS names for a model (outside parentheses, which describe) is shipped and declares every
    coefficient of it; every shipped window model that extends strapdown6_window is named for it (a window's misfit
    advice names them all)."""
    import re

    from casep.model.loader import RICHER_MODELS, shipped_model

    shipped = set(casep.available_models())
    for base, advice in RICHER_MODELS.items():
        named = [n for n in re.findall(r"[a-z][a-z0-9_]+", re.sub(r"\([^)]*\)", "", advice)) if n in shipped]
        assert named, (base, advice)
        have = set(shipped_model(base).names)
        for n in named:
            assert have < set(shipped_model(n).names), (base, n)
    windows = {n for n in shipped if n.endswith("_window") and n != "strapdown6_window"
               and set(shipped_model("strapdown6_window").names) < set(shipped_model(n).names)}
    assert windows == {"strapdown12_window", "strapdown9_vehicle_window", "strapdown7_speed_window"}
    assert all(n in RICHER_MODELS["strapdown6_window"] for n in windows)


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


# --- a broken model file is one line naming the file and the line ----------

_BROKEN = {
    # name: (source, line reported, text expected after "line N...: ")
    "syntax": ("import casep\n\ndef build(:\n    pass\n", 3, "SyntaxError: "),
    "import": ("import casep\nimport casep_no_such_module_xyz\n", 2, "ModuleNotFoundError: No module named"),
    "name": ("import casep\n\ndef build():\n    m = casep.build_model('platform36')\n    return ca.vertcat(1)\n",
             5, "NameError: name 'ca' is not defined"),
    # The deepest frame inside the file: the helper's line, not build()'s call of it.
    "deep": ("def helper(x):\n    return 1 / x\n\n\ndef build():\n    return helper(0)\n",
             2, "ZeroDivisionError: division by zero"),
    "exit0": ("import sys\n\ndef build():\n    sys.exit(0)\n", 4, "SystemExit(0): a model file must not exit"),
    "exit_at_import": ("import sys\nsys.exit('bye')\n", 2, "SystemExit('bye')"),
    "raise_at_import": ("x = 1\nraise RuntimeError('no\\nway')\n", 2, "RuntimeError: no way"),
}


@pytest.mark.parametrize("kind", list(_BROKEN))
def test_broken_model_file_is_one_line_naming_file_and_line(tmp_path, kind):
    src, line, text = _BROKEN[kind]
    path = tmp_path / f"broken_{kind}.py"
    path.write_text(src)
    with pytest.raises(ModelDefinitionError) as e:
        casep.load_model(path)
    msg = str(e.value)
    assert msg.startswith(f"model file {path}, line {line}")
    assert text in msg and "\n" not in msg


def test_broken_base_model_is_named_not_the_extension(tmp_path, monkeypatch):
    (tmp_path / "base_bad.py").write_text("def build():\n    return undefined_name\n")
    ext = tmp_path / "ext.py"
    ext.write_text("import casep\n\ndef build():\n    return casep.build_model('base_bad')\n")
    monkeypatch.setenv("CASEP_MODEL_PATH", str(tmp_path))
    with pytest.raises(ModelDefinitionError, match=r"model file .*base_bad\.py, line 2, in build\(\): NameError"):
        casep.load_model(ext)


def test_setup_error_names_the_model_file(tmp_path):
    path = tmp_path / "unused.py"
    path.write_text("import casep\n\ndef build():\n    m = casep.build_model('platform36')\n"
                    "    m.declare(Kzz='mg')\n    return m\n")
    with pytest.raises(ModelDefinitionError, match=rf"^model file {path}: .*`Kzz` declared but used in no output"):
        casep.load_model(path)


def test_keyboard_interrupt_in_build_is_not_swallowed(tmp_path):
    path = tmp_path / "ctrl_c.py"
    path.write_text("def build():\n    raise KeyboardInterrupt\n")
    with pytest.raises(KeyboardInterrupt):
        casep.load_model(path)
