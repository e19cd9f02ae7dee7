"""What a light curve says without an attitude filter: periods, spin, glints, convex shapes.

Modules
-------
- :mod:`~lightcurve.analysis.period` — rotation-period search: multi-harmonic Fourier
  periodogram, aliases, sidereal correction.
- :mod:`~lightcurve.analysis.fourier_design` — the weighted least-squares design of Fourier
  series in one or more frequencies with per-curve trends (shared by the two searches).
- :mod:`~lightcurve.analysis.tumbling` — two-period analysis of tumblers (two-dimensional
  Fourier series, precession and rotation periods).
- :mod:`~lightcurve.analysis.two_period_series` — the two-period Fourier series and its
  least-squares fit at trial frequency pairs (used by the two-period search).
- :mod:`~lightcurve.analysis.tumbling_reading` — a tumbler's pair read as precession and
  rotation by a convex facet model under torque-free motion.
- :mod:`~lightcurve.analysis.rotator_rival` — the one-period rival of the two-period
  analysis: a rotator whose light curve changes with the geometry.
- :mod:`~lightcurve.analysis.drift` — per-night periods and their drift (spin-down).
- :mod:`~lightcurve.analysis.spin` — principal-axis spin states (DAMIT convention) and
  simulated rotators.
- :mod:`~lightcurve.analysis.glint` — glints (specular flashes): detection, panel normals,
  spin periods, body normals of stabilised satellites (package).
- :mod:`~lightcurve.analysis.convex` — convex shape and spin inversion (Kaasalainen & Torppa
  2001; package).
- :mod:`~lightcurve.analysis.egi` — convex shapes of objects with known attitudes: the
  extended Gaussian image and its Minkowski solid (package).
- :mod:`~lightcurve.analysis.photometric_planning` — which epochs of a light curve carry
  attitude information: Fisher-information scheduling.
"""
