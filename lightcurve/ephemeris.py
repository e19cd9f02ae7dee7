"""Observation geometry from ephemerides: Sun, ground sites and simple orbits (astropy).

Positions are geocentric GCRS in kilometres; times are UTC MJD. astropy's built-in solar
ephemeris and the IERS tables shipped with ``astropy-iers-data`` are used; automatic
downloads are switched off so everything runs offline.

:func:`orbit_geometry` turns an orbit and a ground site into the object → Sun and
object → observer vectors of an observation file.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from lightcurve.observations import Observations, validate_table

__all__ = ["CircularOrbit", "Site", "orbit_geometry", "site_position", "sun_position"]

EARTH_MU_KM3_S2 = 398_600.4418
EARTH_RADIUS_KM = 6378.137


def _astropy():
    from astropy.utils import iers

    iers.conf.auto_download = False
    iers.conf.auto_max_age = None
    import astropy.units as u
    from astropy.coordinates import EarthLocation, get_body
    from astropy.time import Time

    return u, EarthLocation, get_body, Time


def sun_position(mjd: np.ndarray) -> np.ndarray:
    """Geocentric GCRS position of the Sun (km).

    Parameters
    ----------
    mjd : (n,) array
        UTC Modified Julian Dates.

    Returns
    -------
    (n, 3) numpy.ndarray
    """
    u, _, get_body, time = _astropy()
    t = time(np.atleast_1d(mjd), format="mjd", scale="utc")
    return get_body("sun", t).cartesian.xyz.to_value(u.km).T


@dataclass(frozen=True)
class Site:
    """A ground observatory.

    Parameters
    ----------
    latitude_deg, longitude_deg : float
        Geodetic latitude and east longitude (degrees, WGS84).
    altitude_m : float
        Height above the ellipsoid (m).
    name : str
    """

    latitude_deg: float
    longitude_deg: float
    altitude_m: float = 0.0
    name: str = "site"


def site_position(site: Site, mjd: np.ndarray) -> np.ndarray:
    """Geocentric GCRS position of a ground site (km), Earth rotation included.

    Parameters
    ----------
    site : Site
    mjd : (n,) array
        UTC Modified Julian Dates.

    Returns
    -------
    (n, 3) numpy.ndarray
    """
    u, earth_location, _, time = _astropy()
    location = earth_location.from_geodetic(
        site.longitude_deg * u.deg, site.latitude_deg * u.deg, site.altitude_m * u.m
    )
    t = time(np.atleast_1d(mjd), format="mjd", scale="utc")
    return location.get_gcrs(t).cartesian.xyz.to_value(u.km).T


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

    def position(self, mjd: np.ndarray) -> np.ndarray:
        """GCRS position (km) at UTC MJDs, shape (n, 3)."""
        n = np.sqrt(EARTH_MU_KM3_S2 / self.radius_km**3)
        u = (
            np.deg2rad(self.argument_of_latitude_deg)
            + n * (np.asarray(mjd) - self.epoch_mjd) * 86400
        )
        i, raan = np.deg2rad(self.inclination_deg), np.deg2rad(self.raan_deg)
        in_plane = np.stack([np.cos(u), np.sin(u)], axis=-1) * self.radius_km
        node = np.array([np.cos(raan), np.sin(raan), 0.0])
        normal_in_plane = np.array([-np.sin(raan) * np.cos(i), np.cos(raan) * np.cos(i), np.sin(i)])
        return in_plane[:, :1] * node + in_plane[:, 1:] * normal_in_plane


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
        spherical-Earth horizon); None keeps all.
    max_sun_elevation_deg : float or None
        Keep only epochs when the Sun is at most this high at the site (−12°: nautical
        twilight); None keeps all.

    Epochs with the object in the Earth's shadow (cylindrical umbra) are always dropped:
    the renderer does not model eclipses.

    Returns
    -------
    Observations
        Columns ``mjd``, ``epoch``, ``sun_*``, ``obs_*`` (km, GCRS).
    """
    mjd = np.asarray(mjd, dtype=float)
    r_obj = orbit.position(mjd)
    r_site = site_position(site, mjd)
    r_sun = sun_position(mjd)
    to_observer = r_site - r_obj
    up = r_site / np.linalg.norm(r_site, axis=1, keepdims=True)
    sun_dir = r_sun / np.linalg.norm(r_sun, axis=1, keepdims=True)
    keep = ~_in_earth_shadow(r_obj, sun_dir)
    if min_elevation_deg is not None:
        los = -to_observer / np.linalg.norm(to_observer, axis=1, keepdims=True)
        keep &= np.sum(up * los, axis=1) >= np.sin(np.deg2rad(min_elevation_deg))
    if max_sun_elevation_deg is not None:
        keep &= np.sum(up * sun_dir, axis=1) <= np.sin(np.deg2rad(max_sun_elevation_deg))
    if not keep.any():
        raise ValueError(
            "no epoch has the object sunlit, above the minimum elevation and the site dark"
        )
    mjd, r_obj, r_site, r_sun, to_observer = (
        a[keep] for a in (mjd, r_obj, r_site, r_sun, to_observer)
    )
    to_sun = r_sun - r_obj
    table = pd.DataFrame(
        {
            "mjd": mjd,
            **{f"sun_{a}": to_sun[:, k] for k, a in enumerate("xyz")},
            **{f"obs_{a}": to_observer[:, k] for k, a in enumerate("xyz")},
        }
    )
    meta = {
        "object": name,
        "frame": "GCRS",
        "site": f"{site.name} ({site.latitude_deg:.4f}, {site.longitude_deg:.4f}, "
        f"{site.altitude_m:.0f} m)",
        "target": "satellite",
    }
    return Observations(validate_table(table, name, meta, require_magnitudes=False), meta)


def _in_earth_shadow(position: np.ndarray, sun_direction: np.ndarray) -> np.ndarray:
    """Cylindrical umbra test: behind the Earth and within one Earth radius of the axis."""
    along = np.sum(position * sun_direction, axis=1)
    perpendicular = np.linalg.norm(position - along[:, None] * sun_direction, axis=1)
    return (along < 0) & (perpendicular < EARTH_RADIUS_KM)
