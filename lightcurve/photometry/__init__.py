"""From a facet model in an attitude to a measured magnitude: rendering, noise and simulation.

The measurement model of the toolkit: a shape's facets, their BRDFs and shadows, seen along
the geometry of :mod:`lightcurve.sky`, give a flux and an apparent magnitude
(:mod:`~lightcurve.photometry.render`, fused numba kernels in
:mod:`~lightcurve.photometry.kernels`); the telescope, detector and sky give its noise; the
attitude comes from torque-free motion or the profile a control system holds.

Modules
-------
- :mod:`~lightcurve.photometry.render` — flux ratio and apparent magnitude of a facet model
  (:class:`~lightcurve.photometry.render.Renderer`).
- :mod:`~lightcurve.photometry.kernels` — the renderer's compiled fast path (package).
- :mod:`~lightcurve.photometry.reference` — the same measurement model written plainly in
  numpy, the reference the kernels are tested against.
- :mod:`~lightcurve.photometry.adjusted` — a library shape under continuous adjustments
  (stretch, materials, albedo–area scale, inertia and its axes): the measurement model of
  an imperfect candidate.
- :mod:`~lightcurve.photometry.articulated` — articulated shapes, each rigid group in its
  own frame.
- :mod:`~lightcurve.photometry.profiles` — attitude profiles of stabilised satellites
  (nadir, Sun-pointing, inertial).
- :mod:`~lightcurve.photometry.measurement` — the photometric measurement model handed to the
  estimators of :mod:`filters`.
- :mod:`~lightcurve.photometry.conditions` — telescope, detector, site and sky: the signal
  budget.
- :mod:`~lightcurve.photometry.psf` — seeing-limited point-spread functions, saturation.
- :mod:`~lightcurve.photometry.noise` — true magnitudes → measured magnitudes with 1σ and
  flags.
- :mod:`~lightcurve.photometry.simulate` — light-curve simulation: attitude truth, rendering,
  noise.
- :mod:`~lightcurve.photometry.bands` — the Sun's magnitude per photometric band and system.
- :mod:`~lightcurve.photometry.earthshine` — the light of the sunlit Earth on an
  Earth-orbiting object.
- :mod:`~lightcurve.photometry.proxy_error` — the light-curve error of a shape's
  level-of-detail proxy against its full mesh over random geometries.
- :mod:`~lightcurve.photometry.calibration` — the predicted magnitudes of a rigid or
  articulated shape at the geometry of observations, and its photometric parameters fitted to
  observations with known attitudes, cross-validated by night.
"""
