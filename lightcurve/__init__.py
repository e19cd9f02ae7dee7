"""Photometric characterization of space objects.

The ``lightcurve`` package is the application layer: observation geometry, rendering of
facet models into magnitudes, simulation, observation files, period and glint analysis,
the inversion pipeline and the ``lightcurve`` command line. It wires together the leaf
packages :mod:`brdf` (reflectance models), :mod:`shapes` (facet models and the shape
library) and :mod:`filters` (the attitude core and the estimators).

Modules
-------
- :mod:`~lightcurve.batch` — Resumable batch execution over input files: locally, in parallel,
  or on a Dask cluster.
- :mod:`~lightcurve.cli` — The ``lightcurve`` command line.
- :mod:`~lightcurve.cli_reference` — Generate the CLI reference (``docs/cli.md``) from the
  parser's own help texts.
- :mod:`~lightcurve.importing` — Importing photometry: a table, a site and the target's geometry
  into observations.
- :mod:`~lightcurve.joint_shape` — The joint shape-and-attitude fit of ``lightcurve shape``
  with the attitude inversion as its attitude step.
- :mod:`~lightcurve.pipeline` — The inversion pipeline for one observation file, as run by
  ``lightcurve invert``.
- :mod:`~lightcurve.plots` — Figures of an inversion result folder (``lightcurve plot
  DIR/<stem>``).
- :mod:`~lightcurve.analysis` — What a light curve says without an attitude filter: periods,
  spin, glints, convex shapes (package).
- :mod:`~lightcurve.attitude_modes` — Attitude-mode identification: is the object held by a
  control system, or tumbling? (package).
- :mod:`~lightcurve.commands` — Subcommands of the ``lightcurve`` CLI, one module each (see
  :mod:`lightcurve.cli`) (package).
- :mod:`~lightcurve.datasets` — Adapters for real data sets shipped in ``data/`` (each module
  documents its source) (package).
- :mod:`~lightcurve.inversion` — Photometric attitude inversion: the programmatic API behind
  ``lightcurve invert`` (package).
- :mod:`~lightcurve.io` — Observation files and tables: their format, validation, reading and
  atomic writing (package).
- :mod:`~lightcurve.photometry` — From a facet model in an attitude to a measured magnitude:
  rendering, noise and simulation (package).
- :mod:`~lightcurve.scenarios` — Scenario files of the close-range navigation studies (package).
- :mod:`~lightcurve.sky` — Where things are in the sky: epochs, Earth frames, sites, the Sun,
  orbits and the Earth's shadow (package).
- :mod:`~lightcurve.studies` — Monte Carlo studies that the command line offers to users, one
  module per study (package).
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("space-lightcurves")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0+unknown"

__all__ = ["__version__"]
