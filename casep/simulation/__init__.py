"""Simulated flights: boost trajectories, scenarios, noise models, the paper's Table 1 truth.

Depends on :mod:`casep.model` (S_V of the truth) and :mod:`casep.io` (writing flights); never on
an estimator.

- :mod:`casep.simulation.trajectory`: point-mass boost in the launch-inertial frame (its assumptions)
- :mod:`casep.simulation.vehicle`: stages, pitch programme, yaw manoeuvre, attitude offsets
- :mod:`casep.simulation.environment`: gravity constants, standard atmosphere, drag, rotating Earth
- :mod:`casep.simulation.scenarios`: named scenarios (``paper``, ``paper-ar1``, ...)
- :mod:`casep.simulation.simulate`: ``casep simulate`` (flight + truth + tracking files)
- :mod:`casep.simulation.synthetic`, :mod:`casep.simulation.noise`, :mod:`casep.simulation.paper`
"""


from casep._lazy import attach

# Imported on first use (PEP 562), see casep._lazy.
__getattr__, __dir__ = attach(__name__, {
    "casep.simulation.scenarios": ("SCENARIOS", "Scenario", "get_scenario"),
    "casep.simulation.simulate": ("SimulatedFlight", "simulate_flight")}, globals())

__all__ = ["SCENARIOS", "Scenario", "get_scenario", "SimulatedFlight", "simulate_flight"]
