"""Photometric characterization of space objects.

The ``lightcurve`` package is the application layer: observation geometry, rendering of
facet models into magnitudes, simulation, observation files, period and glint analysis,
the inversion pipeline and the ``lightcurve`` command line. It wires together the leaf
packages :mod:`brdf` (reflectance models), :mod:`shapes` (facet models and the shape
library) and :mod:`filters` (the attitude core and the estimators).
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("space-lightcurves")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0+unknown"

__all__ = ["__version__"]
