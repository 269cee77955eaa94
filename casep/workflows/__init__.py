"""End-to-end jobs built from the layers below, each the body of a CLI subcommand:
:mod:`casep.workflows.separate` (flight -> model -> estimate), several flights, radar, the
demo, and what the commands report. Monte Carlo campaigns are :mod:`casep.montecarlo`.
Nothing below imports them.

The submodules are not re-exported here (``separate`` is both a module and its function);
use ``casep.separate`` or import from the submodule.
"""

__all__: list[str] = []
