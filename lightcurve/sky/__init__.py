"""Where things are in the sky: epochs, Earth frames, sites, the Sun, orbits and the Earth's shadow.

Everything the measurement model needs to know about the *geometry* of an observation — the
object → Sun and object → observer vectors of every epoch — is computed here, from
ephemerides (astropy), two-line elements (SGP4) or simple orbits, and written into
observation tables (:mod:`lightcurve.io`). Nothing here knows shapes or reflectance.

Modules
-------
- :mod:`~lightcurve.sky.epochs` — time columns to exact UTC microseconds; astropy offline.
- :mod:`~lightcurve.sky.frames` — Earth orientation: TEME, ITRS and GCRS rotations at many
  epochs.
- :mod:`~lightcurve.sky.sites` — ground sites (:class:`~lightcurve.sky.sites.Site`), the
  built-in observatory table and ``--site`` specifications.
- :mod:`~lightcurve.sky.topocentric` — horizon coordinates at a site: elevation, azimuth,
  range, airmass.
- :mod:`~lightcurve.sky.ephemeris` — the Sun, sites in the GCRS, circular orbits and their
  observation geometry (re-exports :mod:`~lightcurve.sky.asteroids`).
- :mod:`~lightcurve.sky.asteroids` — heliocentric two-body orbits, H–G magnitudes, Itokawa.
- :mod:`~lightcurve.sky.tle` — two-line element sets: reading, checking, choosing, SGP4.
- :mod:`~lightcurve.sky.tle_reference` — skyfield's independent SGP4 → topocentric chain.
- :mod:`~lightcurve.sky.satellite_geometry` — an Earth satellite seen from a ground site.
- :mod:`~lightcurve.sky.shadow_earth` — the Earth's umbra and penumbra.
- :mod:`~lightcurve.sky.geometry` — directions, ranges, phase angle, the phase-angle bisector,
  the reciprocity twin of an attitude.
"""
