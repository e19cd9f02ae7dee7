"""Asteroid observing geometry: heliocentric two-body orbits, H–G magnitudes, Itokawa.

Keplerian orbits from osculating elements (ecliptic and mean equinox of J2000, the frame of
JPL's small-body elements and of DAMIT's light-curve files), the Earth's heliocentric
position from astropy, the H–G phase law (Bowell et al. 1989, "Application of photometric
models to asteroids") and the object → Sun and object → observer vectors of an observation
file for an asteroid seen from the geocentre. All names are importable from
:mod:`lightcurve.sky.ephemeris` too.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from lightcurve.io.observations import Observations, validate_table
from lightcurve.sky.frames import astropy_offline

__all__ = [
    "AU_KM",
    "ITOKAWA_APPARITIONS",
    "ITOKAWA_HG",
    "ITOKAWA_ORBIT",
    "SUN_MU_KM3_S2",
    "HeliocentricOrbit",
    "asteroid_geometry",
    "earth_heliocentric",
    "hg_magnitude",
    "itokawa_geometry",
    "nightly_epochs",
]

AU_KM = 149_597_870.7
#: Heliocentric gravitational constant (km³/s², IAU 2015 nominal / DE430).
SUN_MU_KM3_S2 = 132_712_440_041.939_4
_SECONDS_PER_DAY = 86_400.0


@dataclass(frozen=True)
class HeliocentricOrbit:
    """A Keplerian (two-body) heliocentric orbit from osculating elements.

    Elements refer to the ecliptic and mean equinox of J2000 (the frame of JPL's small-body
    elements and of DAMIT's light-curve files).

    Parameters
    ----------
    semi_major_axis_au : float
        a (AU).
    eccentricity : float
        e (0 ≤ e < 1).
    inclination_deg, node_deg, perihelion_deg : float
        i, longitude of the ascending node Ω and argument of perihelion ω (degrees).
    mean_anomaly_deg : float
        M at ``epoch_mjd`` (degrees).
    epoch_mjd : float
        Osculation epoch (MJD, TDB).
    """

    semi_major_axis_au: float
    eccentricity: float
    inclination_deg: float
    node_deg: float
    perihelion_deg: float
    mean_anomaly_deg: float
    epoch_mjd: float

    def __post_init__(self) -> None:
        if not self.semi_major_axis_au > 0:
            raise ValueError(f"semi-major axis must be > 0 AU, got {self.semi_major_axis_au}")
        if not 0 <= self.eccentricity < 1:
            raise ValueError(f"eccentricity must be in [0, 1), got {self.eccentricity}")

    @property
    def mean_motion(self) -> float:
        """n = √(μ/a³) (rad/s)."""
        return float(np.sqrt(SUN_MU_KM3_S2 / (self.semi_major_axis_au * AU_KM) ** 3))

    @property
    def period_days(self) -> float:
        """Orbital period 2π/n (days)."""
        return 2 * np.pi / self.mean_motion / _SECONDS_PER_DAY

    def _perifocal_axes(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit vectors towards perihelion (P) and 90° ahead of it (Q), ecliptic frame."""
        i, node, peri = np.deg2rad([self.inclination_deg, self.node_deg, self.perihelion_deg])
        cn, sn, ci, si, cw, sw = (
            np.cos(node),
            np.sin(node),
            np.cos(i),
            np.sin(i),
            np.cos(peri),
            np.sin(peri),
        )
        p = np.array([cn * cw - sn * sw * ci, sn * cw + cn * sw * ci, sw * si])
        q = np.array([-cn * sw - sn * cw * ci, -sn * sw + cn * cw * ci, cw * si])
        return p, q

    def eccentric_anomaly(self, mjd: np.ndarray) -> np.ndarray:
        """Eccentric anomaly E (rad) at epochs ``mjd`` (TDB): Kepler's ``E − e sin E = M``.

        Newton's method from ``E = M + e sin M``; 8 steps reach machine precision for
        e < 0.9 (the error squares each step).
        """
        e = self.eccentricity
        mean = (
            np.deg2rad(self.mean_anomaly_deg)
            + self.mean_motion * (np.asarray(mjd, float) - self.epoch_mjd) * _SECONDS_PER_DAY
        )
        mean = np.remainder(mean, 2 * np.pi)
        anomaly = mean + e * np.sin(mean)
        for _ in range(8):
            anomaly = anomaly - (anomaly - e * np.sin(anomaly) - mean) / (1 - e * np.cos(anomaly))
        return anomaly

    def position(self, mjd: np.ndarray) -> np.ndarray:
        """Heliocentric position (km, ecliptic J2000) at epochs ``mjd`` (TDB), shape (n, 3)."""
        anomaly = np.atleast_1d(self.eccentric_anomaly(mjd))
        a, e = self.semi_major_axis_au * AU_KM, self.eccentricity
        x = a * (np.cos(anomaly) - e)
        y = a * np.sqrt(1 - e * e) * np.sin(anomaly)
        p, q = self._perifocal_axes()
        return x[:, None] * p + y[:, None] * q

    def velocity(self, mjd: np.ndarray) -> np.ndarray:
        """Heliocentric velocity (km/s, ecliptic J2000), shape (n, 3)."""
        anomaly = np.atleast_1d(self.eccentric_anomaly(mjd))
        a, e = self.semi_major_axis_au * AU_KM, self.eccentricity
        rate = self.mean_motion / (1 - e * np.cos(anomaly))
        vx = -a * np.sin(anomaly) * rate
        vy = a * np.sqrt(1 - e * e) * np.cos(anomaly) * rate
        p, q = self._perifocal_axes()
        return vx[:, None] * p + vy[:, None] * q

    @classmethod
    def from_state(
        cls, position_km: np.ndarray, velocity_km_s: np.ndarray, epoch_mjd: float
    ) -> HeliocentricOrbit:
        """Osculating elements of a heliocentric state (km, km/s, ecliptic J2000).

        Raises
        ------
        ValueError
            If the state is not a bound, non-rectilinear orbit.
        """
        r = np.asarray(position_km, float)
        v = np.asarray(velocity_km_s, float)
        mu = SUN_MU_KM3_S2
        h = np.cross(r, v)
        radius = np.linalg.norm(r)
        energy = v @ v / 2 - mu / radius
        if not (energy < 0 and np.linalg.norm(h) > 0):
            raise ValueError("state is not on a bound, non-rectilinear heliocentric orbit")
        a = -mu / (2 * energy)
        e_vec = np.cross(v, h) / mu - r / radius
        e = float(np.linalg.norm(e_vec))
        inclination = np.arccos(np.clip(h[2] / np.linalg.norm(h), -1, 1))
        node_vec = np.array([-h[1], h[0], 0.0])
        node = np.arctan2(node_vec[1], node_vec[0]) if np.linalg.norm(node_vec) > 0 else 0.0
        # ω from the eccentricity vector in the orbital plane (node line as reference).
        n_hat = np.array([np.cos(node), np.sin(node), 0.0])
        w_hat = np.cross(h / np.linalg.norm(h), n_hat)
        perihelion = np.arctan2(e_vec @ w_hat, e_vec @ n_hat)
        # True anomaly ν = u − ω from the argument of latitude u, so that ω + ν stays the
        # direction of r when e → 0 (ω then ill-defined); E from ν.
        latitude = np.arctan2(r @ w_hat, r @ n_hat)
        true_anomaly = latitude - perihelion
        anomaly = np.arctan2(np.sqrt(1 - e * e) * np.sin(true_anomaly), e + np.cos(true_anomaly))
        mean = anomaly - e * np.sin(anomaly)
        return cls(
            float(a / AU_KM),
            e,
            float(np.rad2deg(inclination)),
            float(np.rad2deg(node) % 360),
            float(np.rad2deg(perihelion) % 360),
            float(np.rad2deg(mean) % 360),
            float(epoch_mjd),
        )


def earth_heliocentric(mjd: np.ndarray) -> np.ndarray:
    """Heliocentric position of the Earth (km, ecliptic and mean equinox J2000).

    astropy's built-in ephemeris (``get_body("earth")``) transformed to
    ``HeliocentricMeanEcliptic(equinox="J2000")``.

    Parameters
    ----------
    mjd : (n,) array
        UTC Modified Julian Dates.

    Returns
    -------
    (n, 3) numpy.ndarray
    """
    u = astropy_offline()
    from astropy.coordinates import HeliocentricMeanEcliptic, get_body
    from astropy.time import Time

    t = Time(np.atleast_1d(mjd), format="mjd", scale="utc")
    ecliptic = get_body("earth", t).transform_to(
        HeliocentricMeanEcliptic(equinox="J2000", obstime=t)
    )
    return ecliptic.cartesian.xyz.to_value(u.km).T


def hg_magnitude(
    absolute_magnitude: float,
    slope: float,
    sun_range_au: np.ndarray,
    observer_range_au: np.ndarray,
    phase_angle_rad: np.ndarray,
) -> np.ndarray:
    """Apparent V magnitude in the IAU H, G system (Bowell et al. 1989).

    ``V = H + 5 log10(r Δ) − 2.5 log10((1 − G) Φ1 + G Φ2)``,
    ``Φ_k = exp(−A_k tan(α/2)^B_k)``, A = (3.33, 1.87), B = (0.63, 1.22).
    """
    tangent = np.tan(np.asarray(phase_angle_rad) / 2)
    phi1 = np.exp(-3.33 * tangent**0.63)
    phi2 = np.exp(-1.87 * tangent**1.22)
    return (
        absolute_magnitude
        + 5 * np.log10(np.asarray(sun_range_au) * np.asarray(observer_range_au))
        - 2.5 * np.log10((1 - slope) * phi1 + slope * phi2)
    )


def asteroid_geometry(
    orbit: HeliocentricOrbit,
    mjd: np.ndarray,
    *,
    name: str = "asteroid",
    min_elongation_deg: float | None = 60.0,
    absolute_magnitude: float | None = None,
    slope: float = 0.15,
    max_magnitude: float | None = None,
    max_phase_deg: float | None = None,
    night_gap_days: float = 0.5,
) -> Observations:
    """Geometry-only observation table of an asteroid seen from the geocentre.

    Vectors in the ecliptic J2000 frame (km): object → Sun ``−r`` and object → Earth
    ``r_⊕ − r``, with ``r`` from the two-body ``orbit`` and ``r_⊕`` from astropy. The epochs
    are the asteroid's (light-time corrected, as in DAMIT files); the orbit's TDB and the
    Earth's UTC differ by about a minute, which moves the geometry by far less than the
    precision of the two-body orbit.

    Parameters
    ----------
    orbit : HeliocentricOrbit
    mjd : (n,) array
        Candidate epochs (MJD).
    name : str
    min_elongation_deg : float or None
        Keep epochs with the solar elongation (Sun–Earth–object angle) at least this.
    absolute_magnitude, slope : float
        H and G for the brightness limit.
    max_magnitude : float or None
        Keep epochs with the predicted V magnitude at most this (needs H).
    max_phase_deg : float or None
        Keep epochs with the solar phase angle (Sun–object–Earth) at most this.
    night_gap_days : float
        A gap longer than this between kept epochs starts a new light curve
        (``lightcurve_id``: one per night).

    Returns
    -------
    Observations
        Columns ``mjd``, ``sun_*``, ``obs_*`` (km), ``lightcurve_id``, and ``v_predicted``
        when H is given; ``meta["frame"]`` is "ecliptic J2000", ``meta["target"]``
        "asteroid".

    Raises
    ------
    ValueError
        If no epoch passes the limits, or a magnitude limit is given without H.
    """
    mjd = np.atleast_1d(np.asarray(mjd, dtype=float))
    if max_magnitude is not None and absolute_magnitude is None:
        raise ValueError("max_magnitude needs absolute_magnitude (H)")
    r = orbit.position(mjd)
    earth = earth_heliocentric(mjd)
    to_sun = -r
    to_earth = earth - r
    sun_range = np.linalg.norm(to_sun, axis=1)
    earth_range = np.linalg.norm(to_earth, axis=1)
    keep = np.ones(len(mjd), dtype=bool)
    if min_elongation_deg is not None:
        # Elongation: angle at the Earth between the Sun (−r⊕) and the object (−to_earth).
        cos_elongation = np.sum(earth * to_earth, axis=1) / (
            np.linalg.norm(earth, axis=1) * earth_range
        )
        keep &= cos_elongation <= np.cos(np.deg2rad(min_elongation_deg))
    table = {
        "mjd": mjd,
        **{f"sun_{a}": to_sun[:, k] for k, a in enumerate("xyz")},
        **{f"obs_{a}": to_earth[:, k] for k, a in enumerate("xyz")},
    }
    phase = np.arccos(np.clip(np.sum(to_sun * to_earth, axis=1) / (sun_range * earth_range), -1, 1))
    if max_phase_deg is not None:
        keep &= phase <= np.deg2rad(max_phase_deg)
    if absolute_magnitude is not None:
        v = hg_magnitude(absolute_magnitude, slope, sun_range / AU_KM, earth_range / AU_KM, phase)
        table["v_predicted"] = v
        if max_magnitude is not None:
            keep &= v <= max_magnitude
    if not keep.any():
        raise ValueError(f"no epoch of {name} passes the elongation, phase and brightness limits")
    frame = pd.DataFrame({key: np.asarray(value)[keep] for key, value in table.items()})
    frame = frame.sort_values("mjd", kind="stable").reset_index(drop=True)
    frame["lightcurve_id"] = np.r_[0, np.cumsum(np.diff(frame["mjd"]) > night_gap_days)]
    meta = {"object": name, "frame": "ecliptic J2000", "target": "asteroid"}
    return Observations(validate_table(frame, name, meta, require_magnitudes=False), meta)


def nightly_epochs(
    windows: Sequence[tuple[float, float]],
    every_days: float = 3.0,
    hours: float = 5.0,
    cadence_minutes: float = 10.0,
) -> np.ndarray:
    """Epochs of one observing run per night: a light curve every ``every_days`` days.

    Parameters
    ----------
    windows : sequence of (start, end)
        Observing windows (MJD); nights start at ``start``, ``start + every_days`` … < end.
    every_days : float
        Nights between light curves.
    hours : float
        Length of each night's run.
    cadence_minutes : float
        Time between exposures.

    Returns
    -------
    (n,) numpy.ndarray
        Sorted MJDs.
    """
    offsets = np.arange(0.0, hours * 60.0, cadence_minutes) / 1440.0
    nights = np.concatenate([np.arange(a, b, every_days) for a, b in windows])
    return np.sort((nights[:, None] + offsets).ravel())


#: (25143) Itokawa: a, e, i, Ω, ω of JPL's osculating elements (ecliptic J2000, rounded as
#: in docs/analysis.md). M is not JPL's: it is fixed by the 2004 close approach (minimum
#: geocentric distance on 2004 June 26.0 = MJD 53182, where M = 24.1645°); the orbit then
#: passes 0.0133 AU from the Earth, as recorded for that approach.
ITOKAWA_ORBIT = HeliocentricOrbit(1.324, 0.280, 1.62, 69.1, 162.8, 24.1645, 53182.0)
#: Itokawa's H, G (V band) for observability limits.
ITOKAWA_HG = (19.2, 0.21)
#: Itokawa's 2001 (Feb–Apr) and 2004 (Jan–Aug) apparitions, MJD windows.
ITOKAWA_APPARITIONS = ((51930.0, 52010.0), (53010.0, 53250.0))


def itokawa_geometry(mjd: np.ndarray) -> Observations:
    """Itokawa from the geocentre at the epochs ``mjd`` (MJD, UTC) where a ground telescope sees it.

    Kept: solar elongation ≥ 60°, V ≤ 18 (from :data:`ITOKAWA_HG`), phase angle ≤ 90°; one light
    curve per night (:func:`asteroid_geometry`).
    """
    return asteroid_geometry(
        ITOKAWA_ORBIT,
        mjd,
        name="itokawa",
        min_elongation_deg=60.0,
        absolute_magnitude=ITOKAWA_HG[0],
        slope=ITOKAWA_HG[1],
        max_magnitude=18.0,
        max_phase_deg=90.0,
    )
