"""Model declaration, set-up checks and the exact Jacobians (casep.model)."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import casep
from casep.model.error_model import ModelDefinitionError
from casep.units import ARCSEC, DEG_PER_HOUR, G0


def _toy() -> casep.ErrorModel:
    m = casep.ErrorModel("toy")
    c = m.declare(Kg0x="deg/h", Ka1y="mg/g")
    m.set_gyro_drift(ca.vertcat(c.Kg0x, 0, 0))
    m.set_accel_error([0, c.Ka1y * m.W[1], 0])
    return m


def test_platform36_order_and_units(platform36):
    assert platform36.n_coefficients == 36
    assert platform36.names[:5] == ("Kg0x", "Kg1x", "Kg1xy", "Kg1xz", "Kg2x")
    assert platform36.names[15:22] == ("Ka0x", "Ka1x", "Ka1xy", "Ka1xz", "Ka2x", "Ka2xy", "Ka2xz")
    assert platform36.names[-1] == "Ka2zy"
    assert platform36.units[4] == "deg/h/g^2" and platform36.units[17] == "ug/g"
    np.testing.assert_allclose(platform36.si_factors[0], np.pi / 180 / 3600)
    np.testing.assert_allclose(platform36.si_factors[15], 1e-3 * G0)
    np.testing.assert_allclose(platform36.si_factors[35], 1e-6 * G0)


def test_gyro_jacobian_rows_match_eq1(platform36):
    # Eq. (1) by hand at W = (1.5, 2.0, -0.5) g, per axis: [1, W_i, W_j, W_k, W_i^2].
    W = np.array([1.5, 2.0, -0.5])
    G = np.array(platform36.functions["dphidot_dD"](W * G0))
    k = DEG_PER_HOUR
    expect = np.zeros((3, 36))
    expect[0, 0:5] = k * np.array([1, W[0], W[1], W[2], W[0] ** 2])
    expect[1, 5:10] = k * np.array([1, W[1], W[2], W[0], W[1] ** 2])
    expect[2, 10:15] = k * np.array([1, W[2], W[0], W[1], W[2] ** 2])
    np.testing.assert_allclose(G, expect, rtol=1e-14, atol=0)


def test_accel_jacobian_rows_match_eq3(platform36):
    W = np.array([1.5, 2.0, -0.5])
    A = np.array(platform36.functions["dDelta_dD"](W * G0))
    mg, ug = 1e-3 * G0, 1e-6 * G0
    wx, wy, wz = W
    expect = np.zeros((3, 36))
    expect[0, 15:22] = [mg, mg * wx, ug * wy, ug * wz, ug * wx**2, ug * wx * wy, ug * wx * wz]
    expect[1, 22:29] = [mg, mg * wy, ug * wz, ug * wx, ug * wy**2, ug * wy * wz, ug * wy * wx]
    expect[2, 29:36] = [mg, mg * wz, ug * wx, ug * wy, ug * wz**2, ug * wz * wx, ug * wz * wy]
    np.testing.assert_allclose(A, expect, rtol=1e-14, atol=0)


def test_platform39_adds_misalignment_only(platform36, platform39):
    assert platform39.names[:36] == platform36.names
    assert platform39.names[36:] == ("phi0x", "phi0y", "phi0z")
    assert platform39.units[36:] == ("arcsec",) * 3
    phi0 = np.array(platform39.functions["dphi0_dD"]()["dphi0_dD"])
    np.testing.assert_allclose(phi0[:, 36:], ARCSEC * np.eye(3))
    assert not phi0[:, :36].any()


def test_lifecycle_locked_and_not_setup():
    m = _toy()
    with pytest.raises(RuntimeError, match="not set up. Use: model.setup"):
        _ = m.functions
    m.setup()
    with pytest.raises(RuntimeError, match="locked after setup"):
        m.coefficient("Ka0x", "mg")
    with pytest.raises(RuntimeError, match="locked"):
        m.set_accel_error([0, 0, 0])


def test_missing_coefficients_and_outputs():
    with pytest.raises(ModelDefinitionError, match="Missing: error coefficients"):
        casep.ErrorModel("empty").setup()
    m = casep.ErrorModel("no_out")
    m.coefficient("Ka0x", "mg")
    with pytest.raises(ModelDefinitionError, match="Missing: error outputs. Use: model.set_gyro_drift"):
        m.setup()


def test_nonlinear_term_is_named():
    m = casep.ErrorModel("bad")
    c = m.declare(Ka0x="mg", Ka1x="mg/g")
    m.set_accel_error([0, c.Ka0x * c.Ka1x, 0])
    with pytest.raises(ModelDefinitionError, match=r"`accel_error` component y is not linear.*Ka0x, Ka1x"):
        m.setup()


def test_coefficient_free_term_is_named():
    m = casep.ErrorModel("bad")
    c = m.declare(Ka0x="mg")
    m.set_accel_error([c.Ka0x, 0, 0.01 * m.W[2]])
    with pytest.raises(ModelDefinitionError, match="`accel_error` component z has a term without a coefficient"):
        m.setup()


def test_unused_coefficient_is_named():
    m = casep.ErrorModel("bad")
    c = m.declare(Ka0x="mg", Ka0y="mg")
    m.set_accel_error([c.Ka0x, 0, 0])
    with pytest.raises(ModelDefinitionError, match="`Ka0y`.*used in no output"):
        m.setup()


def test_foreign_symbol_and_f_in_initial_terms():
    m = casep.ErrorModel("bad")
    c = m.declare(Ka0x="mg")
    m.set_accel_error([c.Ka0x * ca.SX.sym("q"), 0, 0])
    with pytest.raises(ModelDefinitionError, match="symbol\\(s\\) `q`"):
        m.setup()
    m = casep.ErrorModel("bad2")
    c = m.declare(phi0x="arcsec")
    m.set_initial_misalignment([c.phi0x * m.W[0], 0, 0])
    with pytest.raises(ModelDefinitionError, match="`initial_misalignment` uses symbol"):
        m.setup()


def test_declaration_errors():
    m = casep.ErrorModel("bad")
    m.coefficient("Ka0x", "mg")
    with pytest.raises(ValueError, match="`Ka0x` is declared twice"):
        m.coefficient("Ka0x", "mg")
    with pytest.raises(ValueError, match="unknown unit `furlong`"):
        m.coefficient("K1", "furlong")
    with pytest.raises(ValueError, match="not a valid identifier"):
        m.coefficient("1K", "mg")
    assert m.coefficient("K2", "furlong/fortnight", si_factor=1.66e-4) is not None
    with pytest.raises(ValueError, match="must be 3 x 1"):
        m.set_accel_error(ca.SX.zeros(2, 1))


# --- "did you mean" for coefficient names -----------------------------------

@pytest.mark.parametrize("typo, meant", [
    ("KaOy", "Ka0y"),   # letter O for digit 0
    ("KgOz", "Kg0z"),
    ("KalX", "Ka1x"),   # letter l for digit 1, wrong case
    ("KaIx", "Ka1x"),   # capital I for digit 1
    ("kg0x", "Kg0x"),   # case only
    ("Ka1Xy", "Ka1xy"),
    ("Ka2zz", "Ka2z"),  # no look-alike: difflib's closest
])
def test_suggest_names_ranks_the_meant_name_first(platform36, typo, meant):
    from casep.model.error_model import suggest_names

    assert suggest_names(typo, platform36.names)[0] == meant


def test_difflib_alone_misranks_the_o_zero_confusion(platform36):
    """Why the look-alike folding exists: plain difflib puts Ka2y before Ka0y for KaOy."""
    import difflib

    assert difflib.get_close_matches("KaOy", platform36.names, n=3)[0] != "Ka0y"


def test_unknown_coefficient_message_and_index(platform36):
    from casep.model.error_model import unknown_coefficient_message

    msg = unknown_coefficient_message("KaOy", platform36.names, "--prior p.json")
    assert msg.startswith("--prior p.json: unknown coefficient `KaOy` (did you mean `Ka0y`?); the model has Kg0x")
    assert "did you mean" not in unknown_coefficient_message("zzzz", platform36.names, "x")
    with pytest.raises(KeyError, match=r"model `platform36`: unknown coefficient `KaOy` \(did you mean `Ka0y`\?\)"):
        platform36.index("KaOy")
    assert platform36.index("Ka0y") == list(platform36.names).index("Ka0y")


def test_declared_scales_and_their_checks():
    """Typical magnitudes live in the model: declare(name=(unit, scale))."""
    m = casep.ErrorModel("s")
    c = m.declare(Ka0x=("mg", 2.0), Ka1x="mg/g")
    m.set_accel_error([c.Ka0x + c.Ka1x * m.W[0], 0, 0])
    m.setup()
    assert m.scales == {"Ka0x": 2.0}
    p36 = casep.load_model("platform36")
    from casep.simulation.paper import TABLE1_TRUTH

    assert p36.scales == {n: abs(v) for n, v in TABLE1_TRUTH.items()}  # the paper's magnitudes
    for bad in (0.0, -1.0, float("inf"), "big", True):
        with pytest.raises(ValueError, match="`scale` of `Kb`"):
            casep.ErrorModel("t").declare(Kb=("mg", bad))
    with pytest.raises(ValueError, match="unit"):
        casep.ErrorModel("t").declare(Kb=("mg", 1.0, 2.0))


@pytest.mark.parametrize("kind, declare, set_output", [
    (casep.ErrorModel, {"Ka0x": "mg"}, lambda m, c: m.set_accel_error([c.Ka0x, 0, 0])),
    (casep.TrackingModel, {"range_bias": "m"}, lambda m, c: m.set_range_error(c.range_bias)),
    (casep.calibration.CalibrationModel, {"ba_x": "mg"}, lambda m, c: m.set_accel_reading([c.ba_x, 0, 0])),
])
def test_every_model_kind_has_one_life_cycle_and_one_error_style(kind, declare, set_output):
    """ErrorModel, TrackingModel and CalibrationModel share their declaration machinery
    (casep.model.base.SymbolicModel): the same checks, the same "Missing: ... Use: ..." errors."""
    m = kind("toy")
    with pytest.raises(ModelDefinitionError, match=r"`toy`: Missing: error coefficients\. Use: model\.declare"):
        m.setup()
    c = m.declare(**declare)
    with pytest.raises(ModelDefinitionError, match=r"`toy`: Missing: .*\. Use: model\.set_"):
        m.setup()
    with pytest.raises(ValueError, match=r"coefficient `\w+` is declared twice in .*`toy`"):
        m.declare(**declare)
    unused = m.coefficient("spare", "m", si_factor=2.0, scale=3.0)
    assert float(ca.evalf(ca.substitute(unused, m.symbols[-1], 1.0))) == 2.0  # symbol * si_factor
    set_output(m, c)
    with pytest.raises(ModelDefinitionError, match=r"`spare` declared but used in no"):
        m.setup()
    m2 = kind("toy")
    c2 = m2.declare(**declare)
    with pytest.raises(RuntimeError, match=r"`toy` is not set up\. Use: model\.setup\(\)"):
        _ = m2.functions if hasattr(kind, "functions") else m2.jacobian(np.zeros((1, 11)))
    set_output(m2, c2)
    assert m2.setup() is m2 and m2.is_setup and m2.names == tuple(declare)
    with pytest.raises(RuntimeError, match=r"`toy` is locked after setup\(\)\. Use: declare every coefficient"):
        m2.declare(other="m")
    name = next(iter(declare))
    with pytest.raises(KeyError, match=rf"unknown coefficient `{name.upper()}` \(did you mean `{name}`\?\)"):
        m2.index(name.upper())
