"""Observation geometry of an Earth satellite seen from a ground site.

The object's position comes from one of three sources, all ending in the same table:

* TLEs and SGP4 (:func:`from_tle`): TEME → GCRS and TEME → ITRS by
  :func:`lightcurve.sky.frames.frame_rotations`;
* topocentric elevation, azimuth and range, as some reductions record them
  (:func:`from_horizontal`): site-fixed east–north–up → ITRS → GCRS;
* topocentric right ascension, declination (GCRS axes) and range (:func:`from_radec`).

The Sun is astropy's (:func:`lightcurve.sky.ephemeris.sun_position`), the site the WGS84
position rotated with the Earth. :meth:`SatelliteGeometry.table` gives the columns of an
observation file — ``mjd``, object → Sun ``sun_*`` and object → observer ``obs_*`` (GCRS,
km) — and, alongside, the Earth-shadow state (:mod:`lightcurve.sky.shadow_earth`), the sunlit
fraction of the Sun's disc, the phase angle, the range, the elevation and azimuth at the
site and the airmass (Kasten & Young 1989). Positions are geometric (no light time: 0.1 s
for a LEO, 0.12 s for a GEO, well below a photometric exposure).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np
import pandas as pd

from lightcurve.sky.ephemeris import Site, sun_position
from lightcurve.sky.frames import FrameRotations, frame_rotations
from lightcurve.sky.geometry import phase_angle
from lightcurve.sky.shadow_earth import EarthShadow, earth_shadow
from lightcurve.sky.sites import site_itrs
from lightcurve.sky.tle import DEFAULT_MAX_AGE_DAYS, TLE, propagate_teme
from lightcurve.sky.topocentric import airmass, horizontal_from_itrs, itrs_from_horizontal

__all__ = [
    "SatelliteGeometry",
    "from_horizontal",
    "from_radec",
    "from_tle",
]


def _apply(matrices: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """``M_i v_i`` for stacks of matrices (n, 3, 3) and vectors (n, 3) or one vector (3,)."""
    return np.einsum("nij,...nj->...ni", matrices, np.broadcast_to(vectors, (len(matrices), 3)))


@dataclass(frozen=True)
class SatelliteGeometry:
    """Positions of an object, a site and the Sun at a set of epochs.

    Attributes
    ----------
    site : Site
    mjd : (n,) numpy.ndarray
        UTC MJD.
    object_gcrs, site_gcrs, sun_gcrs : (n, 3) numpy.ndarray
        Geocentric GCRS positions (km).
    topocentric_itrs : (n, 3) numpy.ndarray
        Site → object vectors, ITRS (km).
    rotations : FrameRotations
    shadow_model : str
    tle_age_days : (n,) numpy.ndarray or None
        Epoch minus the epoch of the TLE used (TLE route only).
    object_velocity_gcrs : (n, 3) numpy.ndarray or None
        Geocentric GCRS velocity of the object (km/s; TLE route only).
    """

    site: Site
    mjd: np.ndarray
    object_gcrs: np.ndarray
    site_gcrs: np.ndarray
    sun_gcrs: np.ndarray
    topocentric_itrs: np.ndarray
    rotations: FrameRotations
    shadow_model: str = "conical"
    tle_age_days: np.ndarray | None = None
    object_velocity_gcrs: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.mjd)

    @property
    def horizontal(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Elevation, azimuth (deg) and range (km) of the object at the site."""
        return horizontal_from_itrs(self.site, self.topocentric_itrs)

    @property
    def sun_elevation_deg(self) -> np.ndarray:
        """Elevation of the Sun at the site (deg)."""
        sun_itrs = _apply(self.rotations.itrs_to_gcrs.transpose(0, 2, 1), self.sun_gcrs)
        return horizontal_from_itrs(self.site, sun_itrs - site_itrs(self.site))[0]

    @property
    def shadow(self) -> EarthShadow:
        """Earth-shadow state of the object."""
        return earth_shadow(self.object_gcrs, self.sun_gcrs, self.shadow_model)

    def table(self) -> pd.DataFrame:
        """The observation-file columns and the geometry columns (see the module doc)."""
        to_sun = self.sun_gcrs - self.object_gcrs
        to_observer = self.site_gcrs - self.object_gcrs
        elevation, azimuth, distance = self.horizontal
        shadow = self.shadow
        columns = {
            "mjd": self.mjd,
            **{f"sun_{a}": to_sun[:, k] for k, a in enumerate("xyz")},
            **{f"obs_{a}": to_observer[:, k] for k, a in enumerate("xyz")},
            "shadow": shadow.state,
            "sunlit_fraction": shadow.sunlit_fraction,
            "phase_angle_deg": np.rad2deg(phase_angle(to_sun, to_observer)),
            "range_km": distance,
            "elevation_deg": elevation,
            "azimuth_deg": azimuth,
            "airmass": airmass(elevation),
            **{f"obj_{a}": self.object_gcrs[:, k] for k, a in enumerate("xyz")},
        }
        if self.object_velocity_gcrs is not None:
            columns.update(
                {f"obj_v{a}": self.object_velocity_gcrs[:, k] for k, a in enumerate("xyz")}
            )
        if self.tle_age_days is not None:
            columns["tle_age_days"] = self.tle_age_days
        return pd.DataFrame(columns)

    def subset(self, keep: np.ndarray) -> SatelliteGeometry:
        """The epochs where ``keep`` is true."""
        rotations = FrameRotations(
            *(getattr(self.rotations, f.name)[keep] for f in fields(FrameRotations))
        )
        return SatelliteGeometry(
            self.site,
            self.mjd[keep],
            self.object_gcrs[keep],
            self.site_gcrs[keep],
            self.sun_gcrs[keep],
            self.topocentric_itrs[keep],
            rotations,
            self.shadow_model,
            None if self.tle_age_days is None else self.tle_age_days[keep],
            None if self.object_velocity_gcrs is None else self.object_velocity_gcrs[keep],
        )


def _from_object_itrs(
    site: Site,
    mjd: np.ndarray,
    rotations: FrameRotations,
    object_itrs: np.ndarray,
    *,
    shadow_model: str,
    tle_age_days: np.ndarray | None = None,
    object_velocity_gcrs: np.ndarray | None = None,
) -> SatelliteGeometry:
    station = site_itrs(site)
    return SatelliteGeometry(
        site,
        mjd,
        _apply(rotations.itrs_to_gcrs, object_itrs),
        _apply(rotations.itrs_to_gcrs, station),
        sun_position(mjd),
        object_itrs - station,
        rotations,
        shadow_model,
        tle_age_days,
        object_velocity_gcrs,
    )


def from_tle(
    tles: Sequence[TLE],
    site: Site,
    mjd: np.ndarray,
    max_age_days: float | None = DEFAULT_MAX_AGE_DAYS,
    shadow_model: str = "conical",
) -> SatelliteGeometry:
    """Geometry of one object from its TLEs (the one nearest in epoch per row).

    Parameters
    ----------
    tles : sequence of TLE
        Element sets of one object, sorted by epoch (:func:`lightcurve.sky.tle.select_object`).
    site : Site
    mjd : (n,) array
        UTC epochs.
    max_age_days : float or None
        Warn for epochs farther than this from their TLE's epoch.
    shadow_model : {"conical", "cylindrical"}

    Returns
    -------
    SatelliteGeometry
    """
    mjd = np.atleast_1d(np.asarray(mjd, dtype=float))
    state = propagate_teme(tles, mjd, max_age_days)
    rotations = frame_rotations(mjd)
    object_itrs = _apply(rotations.teme_to_itrs, state.position_km)
    # TEME → GCRS turns by precession–nutation only (< 10⁻¹¹ rad/s): velocities rotate as
    # vectors, the frame's own rate adds < 10⁻⁶ m/s.
    velocity = _apply(rotations.teme_to_gcrs, state.velocity_km_s)
    return _from_object_itrs(
        site,
        mjd,
        rotations,
        object_itrs,
        shadow_model=shadow_model,
        tle_age_days=state.age_days,
        object_velocity_gcrs=velocity,
    )


def from_horizontal(
    site: Site,
    mjd: np.ndarray,
    elevation_deg: np.ndarray,
    azimuth_deg: np.ndarray,
    range_km: np.ndarray,
    shadow_model: str = "conical",
) -> SatelliteGeometry:
    """Geometry from topocentric elevation, azimuth (deg, from north through east) and range.

    Parameters
    ----------
    site : Site
    mjd : (n,) array
        UTC epochs.
    elevation_deg, azimuth_deg : (n,) array
        Geometric (unrefracted) horizon coordinates (deg).
    range_km : (n,) array
        Site → object distance (km).
    shadow_model : {"conical", "cylindrical"}
    """
    mjd = np.atleast_1d(np.asarray(mjd, dtype=float))
    rotations = frame_rotations(mjd)
    topocentric = itrs_from_horizontal(site, elevation_deg, azimuth_deg, range_km)
    return _from_object_itrs(
        site, mjd, rotations, site_itrs(site) + topocentric, shadow_model=shadow_model
    )


def from_radec(
    site: Site,
    mjd: np.ndarray,
    ra_deg: np.ndarray,
    dec_deg: np.ndarray,
    range_km: np.ndarray,
    shadow_model: str = "conical",
) -> SatelliteGeometry:
    """Geometry from topocentric right ascension, declination (deg) and range (km).

    The direction is taken in the GCRS axes (those of J2000/ICRS star catalogues to 0.02″);
    the annual aberration that astrometry against stars leaves in a satellite's direction
    (≤ 20″) is not removed — it moves the object by 0.1 % of the range at most, which the
    brightness does not see.
    """
    mjd = np.atleast_1d(np.asarray(mjd, dtype=float))
    rotations = frame_rotations(mjd)
    ra, dec = np.deg2rad(ra_deg), np.deg2rad(dec_deg)
    direction = np.stack([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)], -1)
    topocentric_gcrs = np.asarray(range_km, dtype=float)[:, None] * direction
    topocentric_itrs = _apply(rotations.itrs_to_gcrs.transpose(0, 2, 1), topocentric_gcrs)
    return _from_object_itrs(
        site, mjd, rotations, site_itrs(site) + topocentric_itrs, shadow_model=shadow_model
    )
