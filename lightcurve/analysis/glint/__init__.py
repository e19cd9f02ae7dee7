"""Glints: specular flashes of flat panels, and what their epochs measure.

A flat panel flashes when its normal points along the phase-angle bisector (Gou et al.
2016), so detected flashes measure panel normals and spin periods.

Modules
-------
- :mod:`~lightcurve.analysis.glint.detection` — detection against a local-polynomial
  baseline at a calibrated false-alarm level, flash fits (:func:`detect_glints`).
- :mod:`~lightcurve.analysis.glint.estimates` — panel normals (:func:`panel_normal`) and spin
  periods (:func:`glint_period`) from detected glints.
- :mod:`~lightcurve.analysis.glint.profile` — panel normals in the body frame of a stabilised
  satellite.

This ``__init__`` only hands the public names of the first two on.
"""

from lightcurve.analysis.glint.detection import (
    Glint,
    GlintDetection,
    detect_glints,
    detection_threshold,
)
from lightcurve.analysis.glint.estimates import PanelNormal, glint_period, panel_normal

__all__ = [
    "Glint",
    "GlintDetection",
    "PanelNormal",
    "detect_glints",
    "detection_threshold",
    "glint_period",
    "panel_normal",
]
