"""The Monte Carlo moved to :mod:`casep.montecarlo`; these names stay here for its importers."""

# re-export: remove after merge (casep/cli.py, tests/estimators/test_registry.py, tests/io/test_io.py,
# tests/workflows/test_range_audit.py import from here)
from casep.montecarlo import (  # noqa: F401
    BATCHED,
    METHOD_HELP,
    MonteCarloResult,
    Terminated,
    run_montecarlo,
    sigterm_raises,
    write_figure,
)
