"""The Monte Carlo moved to :mod:`casep.montecarlo`; these names stay here for its importers."""

# re-export: remove after merge (importers: casep/cli.py, examples/monte_carlo_study.py,
# tests/estimators/test_registry.py, tests/io/test_io.py's monkeypatch path, tests/workflows/test_range_audit.py)
from casep.montecarlo import (  # noqa: F401
    BATCHED,
    METHOD_HELP,
    MonteCarloResult,
    Terminated,
    run_montecarlo,
    sigterm_raises,
    write_figure,
)
