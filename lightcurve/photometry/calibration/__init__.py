"""Calibration of a shape's photometric parameters on observations with known attitudes.

Modules
-------
- :mod:`~lightcurve.photometry.calibration.prediction` — the predicted magnitudes of a rigid
  or articulated shape, lit by the Sun and the Earth, at the geometry of observations
  (:func:`model_magnitude`).
- :mod:`~lightcurve.photometry.calibration.fit` — the robust fit of a magnitude offset,
  attitude and joint offsets and BRDF parameters (:func:`calibrate`, :class:`Calibration`),
  and its cross-validation by night (:func:`cross_validate`, :func:`night_index`).
"""

from lightcurve.photometry.calibration.fit import (
    ATTITUDE_OFFSETS,
    Calibration,
    calibrate,
    cross_validate,
    night_index,
)
from lightcurve.photometry.calibration.prediction import (
    PredictionGeometry,
    Shape,
    model_magnitude,
    shape_flux,
)

__all__ = [
    "ATTITUDE_OFFSETS",
    "Calibration",
    "PredictionGeometry",
    "Shape",
    "calibrate",
    "cross_validate",
    "model_magnitude",
    "night_index",
    "shape_flux",
]
