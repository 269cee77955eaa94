"""Add a new error term by writing a model file, and separate it from a flight.

The new model extends platform36 with a gyro x drift proportional to W_x * W_y (``Kg3x``,
deg/h/g^2). S_V, the solvers and the diagnostics follow from the equation: nothing else
changes.

Run:  python examples/add_error_term.py [--out DIR] [--quick]
"""

#%% Imports and options
import argparse
import tempfile
import textwrap
from pathlib import Path

import numpy as np

import casep
from casep.simulation.simulate import simulate_flight
from casep.simulation.synthetic import inject_errors

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--out", default=None, help="folder for the model file")
ap.add_argument("--quick", action="store_true", help="10 Hz instead of 100 Hz (for CI)")
args = ap.parse_args()
out = Path(args.out or tempfile.mkdtemp(prefix="casep-model-"))

#%% The model file: one short build() that extends platform36
model_file = out / "platform37_gsens.py"
model_file.write_text(textwrap.dedent('''
    """platform37_gsens: platform36 + a gyro x drift in W_x * W_y."""

    import casadi as ca

    import casep


    def build() -> casep.ErrorModel:
        m = casep.build_model("platform36")
        m.name = "platform37_gsens"
        c = m.declare(Kg3x="deg/h/g^2")  # gyro x drift per g^2 of W_x * W_y
        Wx, Wy = m.W[0], m.W[1]  # specific force, g
        m.set_gyro_drift(m.output("gyro_drift") + ca.vertcat(c.Kg3x * Wx * Wy, 0, 0))  # rad/s
        return m
'''))
model = casep.load_model(model_file)
print(model, "->", model.names[-1], model.units[-1])

#%% A flight with the new term switched on (0.05 deg/h/g^2) and 0.1 m/s noise
sim = simulate_flight("paper", seed=4, rate=10.0 if args.quick else 100.0)
truth = np.concatenate([sim.truth, [0.05]])
dv = inject_errors(model, sim.flight.t, sim.flight.f, truth, sigma=0.1, rng=np.random.default_rng(4))
flight = casep.FlightData(sim.flight.t, sim.flight.f, dv)

#%% Separate with the new model, and see what the flight can say about Kg3x
res = casep.separate(flight, model_file, "ols")
j = model.index("Kg3x")
print(f"Kg3x: true 0.05, estimate {res.estimate[j]:.4g} +- {res.std[j]:.2g} deg/h/g^2")
print("groups involving Kg3x:", [g for g in res.diagnostics["groups"] if "Kg3x" in g])
