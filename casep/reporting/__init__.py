"""Showing a result: matplotlib figures (:mod:`casep.reporting.plots`) and the self-contained
HTML report (:mod:`casep.reporting.report`). Depends on the result and the diagnostics."""

__all__: list[str] = []
