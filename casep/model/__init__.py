"""The error model layer: declare -> ``setup()`` -> locked CasADi functions, model files, S_V.

Depends only on :mod:`casep.units`, :mod:`casep.exceptions` and the compiled kernels.

- :mod:`casep.model._model`: :class:`ErrorModel` (declarations, equations, exact Jacobians)
- :mod:`casep.model.loader`: model files (``build()``), search path, ``load_model``
- :mod:`casep.model.sv`: S_V integrated chunk by chunk from the model's Jacobians
"""

from casep.model._model import ErrorModel, ModelDefinitionError
from casep.model.loader import ModelFileError, available_models, build_model, load_model, model_dirs
from casep.model.sv import SVBuilder, build_sv

__all__ = ["ErrorModel", "ModelDefinitionError", "ModelFileError", "available_models", "build_model",
           "load_model", "model_dirs", "SVBuilder", "build_sv"]
