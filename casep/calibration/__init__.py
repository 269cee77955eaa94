"""Ground calibration: multi-position static and rotation tests with the flight models' machinery.

- :mod:`casep.calibration.model`: :class:`CalibrationModel` (declare -> ``setup()`` -> locked)
- :mod:`casep.calibration.session`: session files, segments (JSON list or label column), checks
- :mod:`casep.calibration.calibrate`: the regression of a test, :func:`casep.calibrate`
- :mod:`casep.calibration.rows`: its rows (segment means, turn integrals) and their weighting
- :mod:`casep.calibration.checks`: the checks of a session against its pattern, the warnings
- :mod:`casep.calibration.result`: :class:`Calibration`, the result
- :mod:`casep.calibration.imucal`: imucal's calibration JSON, export and import (as a prior)
- :mod:`casep.calibration.consistency`: ground versus flight, per coefficient and overall
- :mod:`casep.calibration.segment`, :mod:`casep.calibration.multiposition`,
  :mod:`casep.calibration.handturned`: a hand-turned session without labels (``--segments auto``):
  the static poses, the ``multiposition`` model (imu_tk's convention), the chain
- :mod:`casep.calibration.ferrarisauto`: the six poses and three turns of a Ferraris session without
  labels (``--segments auto`` with model ``ferraris``)
- :mod:`casep.calibration.gravity` (WGS84 normal gravity), :mod:`casep.calibration.imutk` (imu_tk's
  files), :mod:`casep.calibration.mikov` (Mikov et al.'s parameters), :mod:`casep.calibration.handsim`

``calibrate`` and ``consistency`` are both a submodule and its function, so they are not re-exported
here (as in :mod:`casep.workflows`): use ``casep.calibrate`` and
``casep.calibration.consistency.consistency``, or import them from their submodules.

Layer 8 (as :mod:`casep.workflows`): uses the model, io, regression, checks and estimators layers.
"""

from casep._lazy import attach

__getattr__, __dir__ = attach(__name__, {
    "casep.calibration.model": ("CalibrationModel", "load_calibration_model", "calibration_models"),
    "casep.calibration.session": ("Session", "Segment", "SegmentError", "read_session", "read_segments",
                                  "segments_from_labels", "FERRARIS_SEGMENTS"),
    "casep.calibration.result": ("Calibration",),
    "casep.calibration.calibrate": ("calibrate_files",),
    "casep.calibration.checks": ("RotationSignWarning", "PositionMisfitWarning", "TimeGapWarning"),
    "casep.calibration.imucal": ("to_imucal", "from_imucal", "read_imucal", "write_imucal", "imucal_prior"),
    "casep.calibration.consistency": ("Consistency", "ground_prior", "ground_versus_flight",
                                      "ground_flight_checks"),
    "casep.calibration.segment": ("detect_static", "Segmentation"),
    "casep.calibration.handturned": ("calibrate_multiposition", "calibrate_multiposition_file",
                                     "MultipositionCalibration"),
    "casep.calibration.gravity": ("normal_gravity",),
    "casep.calibration.ferrarisauto": ("find_ferraris_segments", "FerrarisSegmentation"),
}, globals())

__all__ = ["CalibrationModel", "Session", "Segment", "SegmentError", "read_session", "read_segments",
           "segments_from_labels", "FERRARIS_SEGMENTS", "Calibration", "calibrate_files",
           "load_calibration_model", "calibration_models", "RotationSignWarning", "PositionMisfitWarning",
           "TimeGapWarning", "to_imucal", "from_imucal",
           "read_imucal", "write_imucal", "imucal_prior", "Consistency", "ground_prior",
           "ground_versus_flight", "ground_flight_checks", "detect_static",
           "Segmentation", "calibrate_multiposition", "calibrate_multiposition_file", "MultipositionCalibration",
           "normal_gravity", "find_ferraris_segments", "FerrarisSegmentation"]
