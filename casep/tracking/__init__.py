"""Tracking-system errors in the same estimate: radar stations, their measurements and biases.

Layer 2 (beside :mod:`casep.analysis`): imports the model layer, :mod:`casep.io`,
:mod:`casep.frames` and :mod:`casep.analysis`; the workflows run the estimators on what it builds.

- :mod:`casep.tracking.stations`: station files (JSON, pydantic) and measurement files
- :mod:`casep.tracking.geometry`: the predicted measurement h(r, v) and H = dh/d(r, v) (CasADi)
- :mod:`casep.tracking.regression`: the joint measurement-domain regression [-H S_P | T]
- :mod:`casep.tracking.diagnostics`: CRLB with tracking terms fixed and free, mixed
  near-dependencies, the gain of each station
"""
