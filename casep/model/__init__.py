"""The error model layer: declare -> ``setup()`` -> locked CasADi functions, model files, S_V.

Depends only on :mod:`casep.units`, :mod:`casep.exceptions` and the compiled kernels.

- :mod:`casep.model.error_model`: :class:`ErrorModel` (declarations, equations, exact Jacobians)
- :mod:`casep.model.loader`: model files (``build()``), search path, ``load_model``
- :mod:`casep.model.sv`: S_V integrated chunk by chunk from the model's Jacobians
"""


from casep._lazy import attach

# Imported on first use (PEP 562), see casep._lazy.
__getattr__, __dir__ = attach(__name__, {
    "casep.model.error_model": ("ErrorModel", "ModelDefinitionError"),
    "casep.model.loader": ("ModelFileError", "available_models", "build_model", "load_model", "model_dirs"),
    "casep.model.sv": ("SVBuilder", "build_sv")}, globals())

__all__ = ["ErrorModel", "ModelDefinitionError", "ModelFileError", "available_models", "build_model",
           "load_model", "model_dirs", "SVBuilder", "build_sv"]
