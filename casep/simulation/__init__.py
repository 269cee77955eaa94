"""Simulated flights: boost trajectories, scenarios, noise models, the paper's Table 1 truth.

Depends on :mod:`casep.model` (S_V of the truth) and :mod:`casep.io` (writing flights); never on
an estimator.

- :mod:`casep.simulation.trajectory`: point-mass boost over a flat non-rotating Earth
- :mod:`casep.simulation.scenarios`: named scenarios (``paper``, ``paper-ar1``, ...)
- :mod:`casep.simulation.simulate`: ``casep simulate`` (flight + truth + tracking files)
- :mod:`casep.simulation.synthetic`, :mod:`casep.simulation.noise`, :mod:`casep.simulation.paper`
"""

from casep.simulation.scenarios import SCENARIOS, Scenario, get_scenario
from casep.simulation.simulate import SimulatedFlight, simulate_flight

__all__ = ["SCENARIOS", "Scenario", "get_scenario", "SimulatedFlight", "simulate_flight"]
