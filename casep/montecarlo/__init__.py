"""Seeded Monte Carlo of the estimators against the Cramer-Rao bound, in this process or on Dask.

:func:`run_montecarlo` flies a scenario (or one's own trajectory) `runs` times with seeded
noise, optionally with dispersed vehicles and truths drawn from a prior, runs every method on
each draw and returns a :class:`MonteCarloResult` (bias, RMS, CRLB std, efficiency and 95 %
coverage per method and coefficient). Run k's numbers depend on the seed and k only, never on
the workers. Methods whose estimate is a fixed linear function of the data (``ols``, ``rls``
with no forgetting, ``ridge:<lambda>``, ``pcr``, ``map`` with the scenario's sigma) apply the
estimator's own linear map ``D = K y + b`` to all runs of a task that share a trajectory at
once; the others call the public solver per run. Both paths report the same numbers as the
solvers (tested).

Modules:

- :mod:`~casep.montecarlo.campaign`: :func:`run_montecarlo` (stages, tasks, resume, the result);
- :mod:`~casep.montecarlo.methods`: everything method-specific (the ``--methods`` spec
  language, the batched linear maps, the per-run solve);
- :mod:`~casep.montecarlo.tasks`: seeding, the campaign's context and one task;
- :mod:`~casep.montecarlo.engines`: in process or on Dask, and signal handling;
- :mod:`~casep.montecarlo.store`: the ``out`` folder (Parquet parts, resume);
- :mod:`~casep.montecarlo.result`: :class:`MonteCarloResult` and its figure;
- :mod:`~casep.montecarlo.progress`: progress on stderr (tqdm);
- :mod:`~casep.montecarlo.inputs`: one's own trajectory, truth-prior checks;
- :mod:`~casep.montecarlo.dask_worker`: the Dask worker preload.
"""

from casep.montecarlo.campaign import run_montecarlo
from casep.montecarlo.engines import Terminated, sigterm_raises
from casep.montecarlo.inputs import TRUTH_PRIOR_LIMIT
from casep.montecarlo.methods import BATCHED, METHOD_HELP
from casep.montecarlo.result import MonteCarloResult, write_figure

__all__ = ["BATCHED", "METHOD_HELP", "TRUTH_PRIOR_LIMIT", "MonteCarloResult", "Terminated", "run_montecarlo",
           "sigterm_raises", "write_figure"]
