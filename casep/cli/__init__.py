"""Command line: ``casep separate``, ``casep diagnose``, ``casep simulate``, ``casep models``, ...

One module per command (``casep.cli.<command>``: ``add_parser(subparsers)`` and ``run(args) -> int``),
thin wrappers over the public API; the shared argument groups in :mod:`casep.cli.options` and
:mod:`casep.cli.flight_options`, the argument types in :mod:`casep.cli.types`, what a command reads in
:mod:`casep.cli.inputs`, its outputs in :mod:`casep.cli.outputs`, its warnings in :mod:`casep.cli.capture`,
the parser and :func:`main` in :mod:`casep.cli.app`.

The method options of ``casep separate`` (and ``--prior``/``--bounds`` of ``casep montecarlo``)
are generated from the estimator registry (:data:`casep.estimators.registry.OPTIONS`). Module level
imports only the standard library, the version and the registry; each command imports what it
needs when it runs, so building the parser and ``casep --help`` stay cheap.

Every command runs with one BLAS thread unless OPENBLAS_NUM_THREADS, OMP_NUM_THREADS or
MKL_NUM_THREADS is set (:mod:`casep.cli.blas`): casep's matrices are small and BLAS threads on a
shared machine cost more than they give.

Exit status: 0 success, 2 bad usage or bad input (one line on stderr), 1 anything else, including
a `separate` result that is not successful (``success`` false: table and JSON still written);
141 (quietly, like any Unix tool ended by SIGPIPE) when the reader of stdout closes early
(``casep models | head -1``). ``casep models`` exits 0 when at least one model loads and
reports each model file that does not as a ``warning:`` line.
"""

from casep.cli.app import EXIT_BROKEN_PIPE, build_parser, main

__all__ = ["main", "build_parser", "EXIT_BROKEN_PIPE"]
