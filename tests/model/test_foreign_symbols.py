"""The foreign-symbol check of a model's setup (``SymbolicModel._check_foreign``, by the symbols' node hashes): a
symbol is known only where it is the same node as a coefficient or an allowed input (``casadi.is_equal`` at depth
0), whatever its name."""

from __future__ import annotations

import casadi as ca
import pytest

import casep
from casep.model.base import ModelDefinitionError


def _is_equal_rule(model, expr, allowed):
    """The rule the check implements, written as pairwise ``casadi.is_equal`` (the reference)."""
    known = list(model._symbols) + list(allowed)
    return [s.name() for s in ca.symvar(expr) if not any(ca.is_equal(s, a) for a in known)]


def test_a_symbol_named_as_a_coefficient_is_foreign_and_the_inputs_are_known():
    m = casep.ErrorModel("same name")
    c = m.declare(Ka0x="mg", Kg0x="deg/h")
    twin = ca.SX.sym("Ka0x")  # another node of the same name
    m.set_accel_error([c.Ka0x + twin * m.f[0], m.t * c.Ka0x, m.signal("ground_speed") * c.Ka0x])
    m.set_gyro_drift([c.Kg0x, 0, 0])
    allowed = [m.f[0], m.f[1], m.f[2], m.t, m.signal("ground_speed"), 2.0 * m.t]
    assert _is_equal_rule(m, m.output("accel_error"), allowed) == ["Ka0x"]
    with pytest.raises(ModelDefinitionError, match="uses symbol\\(s\\) `Ka0x`"):
        m.setup()


def test_every_shipped_model_sets_up():
    """The shipped error models hold no foreign symbol (each check's reference rule agrees: nothing foreign)."""
    from pathlib import Path

    from casep.model.loader import build_model

    root = Path(__file__).resolve().parents[2] / "models"
    for f in sorted(root.glob("*.py")):
        if f.stem.startswith("radar"):
            continue
        m = build_model(str(f))
        for slot, expr in m._outputs.items():
            if expr is not None:
                inputs = [m.f[i] for i in range(3)] + [m.t] + list(m._signal_syms.values())
                assert _is_equal_rule(m, expr, inputs) == [], (f.stem, slot)
        m.setup()
