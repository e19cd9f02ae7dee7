"""Observation geometry from ephemerides: Sun, ground sites and simple orbits (astropy).

Positions are geocentric GCRS in kilometres; times are UTC MJD. astropy's built-in solar
ephemeris and the IERS tables shipped with ``astropy-iers-data`` are used; automatic
downloads are switched off so everything runs offline.

:func:`orbit_geometry` turns an orbit and a ground site into the object → Sun and
object → observer vectors of an observation file. Asteroid geometry (heliocentric orbits,
H–G magnitudes, Itokawa) is :mod:`lightcurve.sky.asteroids`, its names importable from here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from lightcurve.io.observations import Observations, validate_table
from lightcurve.sky.asteroids import (
    AU_KM,
    ITOKAWA_APPARITIONS,
    ITOKAWA_HG,
    ITOKAWA_ORBIT,
    SUN_MU_KM3_S2,
    HeliocentricOrbit,
    asteroid_geometry,
    earth_heliocentric,
    hg_magnitude,
    itokawa_geometry,
    nightly_epochs,
)
from lightcurve.sky.frames import astropy_offline, frame_rotations, interpolate_at_nodes
from lightcurve.sky.shadow_earth import earth_shadow
from lightcurve.sky.sites import Site, site_itrs
from lightcurve.sky.topocentric import airmass, horizontal_from_itrs

__all__ = [
    "AU_KM",
    "ITOKAWA_APPARITIONS",
    "ITOKAWA_HG",
    "ITOKAWA_ORBIT",
    "SUN_MU_KM3_S2",
    "CircularOrbit",
    "HeliocentricOrbit",
    "Site",
    "asteroid_geometry",
    "earth_heliocentric",
    "hg_magnitude",
    "itokawa_geometry",
    "nightly_epochs",
    "orbit_geometry",
    "site_position",
    "sun_position",
]

EARTH_MU_KM3_S2 = 398_600.4418
EARTH_RADIUS_KM = 6378.137


def _astropy():
    u = astropy_offline()
    from astropy.coordinates import EarthLocation, get_body
    from astropy.time import Time

    return u, EarthLocation, get_body, Time


def sun_position(mjd: np.ndarray) -> np.ndarray:
    """Geocentric GCRS position of the Sun (km).

    astropy's built-in ephemeris (``get_body("sun")``: astrometric, light time included).
    For many epochs it is evaluated on the six-hour node grid of :mod:`lightcurve.sky.frames`
    and interpolated (cubic Lagrange, four nodes): the error is below 10 m, 10⁻¹⁰ of the
    distance (``tests/lightcurve/sky/test_frames.py``).

    Parameters
    ----------
    mjd : (n,) array
        UTC Modified Julian Dates.

    Returns
    -------
    (n, 3) numpy.ndarray
    """
    return interpolate_at_nodes(np.atleast_1d(np.asarray(mjd, dtype=float)), _sun_astropy)


def _sun_astropy(mjd: np.ndarray) -> np.ndarray:
    u, _, get_body, time = _astropy()
    t = time(mjd, format="mjd", scale="utc")
    return get_body("sun", t).cartesian.xyz.to_value(u.km).T


def site_position(site: Site, mjd: np.ndarray) -> np.ndarray:
    """Geocentric GCRS position of a ground site (km), Earth rotation included.

    The site's WGS84 ITRS position rotated by :func:`lightcurve.sky.frames.frame_rotations`
    (astropy's ITRS → GCRS transformation, IERS Earth orientation).

    Parameters
    ----------
    site : Site
    mjd : (n,) array
        UTC Modified Julian Dates.

    Returns
    -------
    (n, 3) numpy.ndarray
    """
    rotations = frame_rotations(np.atleast_1d(np.asarray(mjd, dtype=float)))
    return rotations.itrs_to_gcrs @ site_itrs(site)


@dataclass(frozen=True)
class CircularOrbit:
    """A circular Keplerian orbit about the Earth (two-body, GCRS axes).

    Parameters
    ----------
    radius_km : float
        Orbit radius (km); GEO is 42164.
    inclination_deg, raan_deg : float
        Inclination and right ascension of the ascending node (degrees).
    argument_of_latitude_deg : float
        Position along the orbit at ``epoch_mjd`` (degrees from the node).
    epoch_mjd : float
        Reference epoch (UTC MJD).
    """

    radius_km: float
    inclination_deg: float = 0.0
    raan_deg: float = 0.0
    argument_of_latitude_deg: float = 0.0
    epoch_mjd: float = 60000.0

    def __post_init__(self) -> None:
        if not self.radius_km > EARTH_RADIUS_KM:
            raise ValueError(f"orbit radius {self.radius_km} km is inside the Earth")

    @classmethod
    def geostationary(cls, longitude_deg: float, epoch_mjd: float) -> CircularOrbit:
        """A geostationary orbit above ``longitude_deg`` (east) at ``epoch_mjd``."""
        _, _, _, time = _astropy()
        sidereal = time(epoch_mjd, format="mjd", scale="utc").sidereal_time("apparent", 0.0)
        return cls(42_164.17, 0.0, 0.0, float(sidereal.deg) + longitude_deg, epoch_mjd)

    @property
    def mean_motion(self) -> float:
        """Angular rate along the orbit (rad/s)."""
        return float(np.sqrt(EARTH_MU_KM3_S2 / self.radius_km**3))

    def _in_plane(self, mjd: np.ndarray, derivative: int) -> np.ndarray:
        """Position (``derivative`` 0, km) or velocity (1, km/s), GCRS, shape (n, 3)."""
        n = self.mean_motion
        u = (
            np.deg2rad(self.argument_of_latitude_deg)
            + n * (np.asarray(mjd) - self.epoch_mjd) * 86400
        )
        i, raan = np.deg2rad(self.inclination_deg), np.deg2rad(self.raan_deg)
        phase = u + 0.5 * np.pi * derivative
        in_plane = (
            np.stack([np.cos(phase), np.sin(phase)], axis=-1) * self.radius_km * n**derivative
        )
        node = np.array([np.cos(raan), np.sin(raan), 0.0])
        normal_in_plane = np.array([-np.sin(raan) * np.cos(i), np.cos(raan) * np.cos(i), np.sin(i)])
        return in_plane[:, :1] * node + in_plane[:, 1:] * normal_in_plane

    def position(self, mjd: np.ndarray) -> np.ndarray:
        """GCRS position (km) at UTC MJDs, shape (n, 3)."""
        return self._in_plane(mjd, 0)

    def velocity(self, mjd: np.ndarray) -> np.ndarray:
        """GCRS velocity (km/s) at UTC MJDs, shape (n, 3)."""
        return self._in_plane(mjd, 1)


def orbit_geometry(
    orbit: CircularOrbit,
    site: Site,
    mjd: np.ndarray,
    name: str = "object",
    min_elevation_deg: float | None = 10.0,
    max_sun_elevation_deg: float | None = -12.0,
) -> Observations:
    """Geometry-only observation table of an orbiting object seen from a site.

    Parameters
    ----------
    orbit : CircularOrbit
    site : Site
    mjd : (n,) array
        Candidate UTC epochs.
    name : str
        Object name for the metadata.
    min_elevation_deg : float or None
        Keep only epochs with the object at least this high above the site's horizon (a
        spherical-Earth horizon); None keeps all above the (WGS84) horizon.
    max_sun_elevation_deg : float or None
        Keep only epochs when the Sun is at most this high at the site (−12°: nautical
        twilight); None keeps all.

    Epochs with the object in the Earth's shadow (cylindrical umbra) are always dropped:
    the renderer does not model eclipses; so are epochs with the object below the site's
    WGS84 horizon (not observable, and without an airmass).

    Returns
    -------
    Observations
        Columns ``mjd``, ``epoch``, ``sun_*``, ``obs_*`` (km, GCRS), the object's horizon
        coordinates at the site, ``range_km``, ``elevation_deg``, ``azimuth_deg`` (WGS84
        vertical) and ``airmass`` (Kasten & Young 1989), and the object's geocentric
        position ``obj_x, obj_y, obj_z`` (km) and velocity ``obj_vx, obj_vy, obj_vz`` (km/s).
    """

    mjd = np.asarray(mjd, dtype=float)
    r_obj = orbit.position(mjd)
    itrs_to_gcrs = frame_rotations(mjd).itrs_to_gcrs  # as site_position, kept for the horizon
    r_site = itrs_to_gcrs @ site_itrs(site)
    r_sun = sun_position(mjd)
    to_observer = r_site - r_obj
    elevation, azimuth, distance = horizontal_from_itrs(
        site, np.einsum("nji,nj->ni", itrs_to_gcrs, -to_observer)
    )
    up = r_site / np.linalg.norm(r_site, axis=1, keepdims=True)
    sun_dir = r_sun / np.linalg.norm(r_sun, axis=1, keepdims=True)
    keep = ~earth_shadow(r_obj, r_sun, "cylindrical").in_umbra & (elevation > 0.0)
    if min_elevation_deg is not None:
        los = -to_observer / np.linalg.norm(to_observer, axis=1, keepdims=True)
        keep &= np.sum(up * los, axis=1) >= np.sin(np.deg2rad(min_elevation_deg))
    if max_sun_elevation_deg is not None:
        keep &= np.sum(up * sun_dir, axis=1) <= np.sin(np.deg2rad(max_sun_elevation_deg))
    if not keep.any():
        raise ValueError(
            "no epoch has the object sunlit, above the minimum elevation and the site dark"
        )
    mjd, r_obj, r_sun, to_observer, elevation, azimuth, distance = (
        a[keep] for a in (mjd, r_obj, r_sun, to_observer, elevation, azimuth, distance)
    )
    v_obj = orbit.velocity(mjd)
    to_sun = r_sun - r_obj
    table = pd.DataFrame(
        {
            "mjd": mjd,
            **{f"sun_{a}": to_sun[:, k] for k, a in enumerate("xyz")},
            **{f"obs_{a}": to_observer[:, k] for k, a in enumerate("xyz")},
            "range_km": distance,
            "elevation_deg": elevation,
            "azimuth_deg": azimuth,
            "airmass": airmass(elevation),
            **{f"obj_{a}": r_obj[:, k] for k, a in enumerate("xyz")},
            **{f"obj_v{a}": v_obj[:, k] for k, a in enumerate("xyz")},
        }
    )
    meta = {
        "object": name,
        "frame": "GCRS",
        "site": site.label,
        "target": "satellite",
    }
    return Observations(validate_table(table, name, meta, require_magnitudes=False), meta)
