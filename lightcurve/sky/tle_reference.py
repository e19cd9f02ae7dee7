"""Independent reference for the TLE geometry: skyfield's SGP4 → ITRS → topocentric chain.

skyfield (Rhodes, a development dependency) has its own time scales, its own TEME → ITRS
rotation (IAU 1982 GMST) and its own WGS84 sites; only the ``sgp4`` propagator and the IERS
Earth-orientation data are shared with :mod:`lightcurve.sky.satellite_geometry`. It runs offline
on its built-in time scale; that one knows UT1 but not the pole's position, so the IERS pole
coordinates bundled with astropy are handed to it — polar motion moves a geostationary
satellite by up to 60 m in the ITRS (0.3″ seen from the ground).

Used by ``tests/lightcurve/sky/test_tle.py`` and ``benchmarks/tle_geometry.py``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from lightcurve.sky.frames import astropy_offline
from lightcurve.sky.satellite_geometry import from_tle
from lightcurve.sky.sites import Site, site_itrs
from lightcurve.sky.tle import TLE

__all__ = ["compare_topocentric", "skyfield_timescale"]


def skyfield_timescale():
    """skyfield's built-in time scale with astropy's bundled IERS pole coordinates."""
    astropy_offline()
    from astropy.time import Time
    from astropy.utils import iers
    from skyfield.api import load

    ts = load.timescale(builtin=True)
    table = iers.earth_orientation_table.get()
    mjd = np.asarray(table["MJD"].value, dtype=float)
    x = np.asarray(table["PM_x"].value, dtype=float)
    y = np.asarray(table["PM_y"].value, dtype=float)
    known = np.isfinite(x) & np.isfinite(y)
    tt = Time(mjd[known], format="mjd", scale="utc").tt.jd
    ts.polar_motion_table = (tt, x[known], y[known])
    return ts


def compare_topocentric(
    tle: TLE, sites: Sequence[Site], mjd: np.ndarray, ts=None
) -> tuple[np.ndarray, np.ndarray]:
    """Direction and range differences, ours against skyfield's, per site and epoch.

    Parameters
    ----------
    tle : TLE
    sites : sequence of Site
    mjd : (n,) array
        UTC epochs.
    ts : skyfield Timescale, optional
        Default :func:`skyfield_timescale`.

    Returns
    -------
    angle_arcsec, range_m : (len(sites), n) numpy.ndarray
        Angle between the two site → object vectors (″) and the difference of their lengths
        (m).
    """
    from skyfield.api import EarthSatellite, wgs84
    from skyfield.framelib import itrs

    ts = ts or skyfield_timescale()
    whole = np.floor(mjd)
    t = ts.utc(1858, 11, 17 + whole, 0, 0, (mjd - whole) * 86400.0)
    satellite = EarthSatellite(tle.line1, tle.line2, ts=ts)
    # The object's ITRS position does not depend on the site: compute it once.
    first = from_tle([tle], sites[0], mjd, max_age_days=None)
    object_itrs = first.topocentric_itrs + site_itrs(sites[0])
    angles, ranges = [], []
    for site in sites:
        ours = object_itrs - site_itrs(site)
        topos = wgs84.latlon(site.latitude_deg, site.longitude_deg, site.altitude_m)
        theirs = (satellite - topos).at(t).frame_xyz(itrs).km.T
        cross = np.linalg.norm(np.cross(ours, theirs), axis=1)
        angles.append(np.degrees(np.arctan2(cross, np.sum(ours * theirs, axis=1))) * 3600.0)
        ranges.append(
            np.abs(np.linalg.norm(ours, axis=1) - np.linalg.norm(theirs, axis=1)) * 1000.0
        )
    return np.array(angles), np.array(ranges)
