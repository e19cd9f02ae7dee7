"""Subcommands of the ``lightcurve`` CLI, one module each (see :mod:`lightcurve.cli`).

Modules
-------
- :mod:`~lightcurve.commands.calibrate` — Calibrate a library shape's photometry on observations of
  an object with a known profile.
- :mod:`~lightcurve.commands.convex` — Convex shape and spin inversion of asteroid light curves
  (Kaasalainen & Torppa 2001).
- :mod:`~lightcurve.commands.geometry` — Write a geometry file for an Earth-orbiting object seen
  from a ground site.
- :mod:`~lightcurve.commands.glint` — Glint analysis of a light curve (Gou et al. 2016, sec.
  2.2).
- :mod:`~lightcurve.commands.import_` — Import a photometry table as an observation file.
- :mod:`~lightcurve.commands.invert` — Invert observation files for attitude, rates and shape,
  in batch.
- :mod:`~lightcurve.commands.monocular` — Monocular attitude, rate and inertia estimation of a
  tumbling target (Deng et al. 2024).
- :mod:`~lightcurve.commands.period` — Rotation-period search over one or more observation files
  (Gou et al. 2016, sec. 2.1).
- :mod:`~lightcurve.commands.plan` — Fisher-information observation planning for small-body
  landing navigation (Li et al. 2024).
- :mod:`~lightcurve.commands.plot` — Plot an inversion result folder (DIR/<stem> written by
  `lightcurve invert`).
- :mod:`~lightcurve.commands.propagate` — Propagate a torque-free rigid body and print its
  attitude, rates and invariants.
- :mod:`~lightcurve.commands.relnav` — Multi-mode relative navigation with IMU input and robust
  position fixes.
- :mod:`~lightcurve.commands.shapes` — Manage the shape library: list, show, add, remove,
  validate, rebuild and render shapes.
- :mod:`~lightcurve.commands.simulate` — Simulate a light curve of a library shape over the
  epochs of a geometry file.
- :mod:`~lightcurve.commands.stereo` — Monte Carlo study of stereo relative-state and inertia
  estimation (Feng et al.).
"""
