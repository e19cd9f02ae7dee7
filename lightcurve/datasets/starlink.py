"""Starlink v1.5 brightness observations (Pomenis, Mount Lemmon) and the two-surface model.

Source: Fankhauser, Askari & Tyson, "Satellite Optical Brightness" (2023), MIT license;
the observations are package data (``lightcurve/data/starlink/``, read through
:mod:`importlib.resources`, so an installed wheel carries them). The
observations give the UTC time, the satellite height above the Earth (km), its topocentric
altitude and azimuth (degrees) and the measured AB magnitude at Mount Lemmon (32.4434° N,
110.7881° W, ~2790 m).

The brightness model of the paper (``starlink_surface_descriptions.txt``): two flat
surfaces, the chassis underside (3.64 m², normal ``(0, 0, −1)`` pointing to nadir) and the
solar array (22.68 m², normal ``(0, 1, 0)``, perpendicular to the chassis and turned toward
the Sun). In the body frame used here ``+z`` is the local vertical (away from the Earth's
centre; the geocentric vertical, within 0.2° of the geodetic one) and ``+y`` is the Sun's
direction projected on the horizontal plane. Materials are the ``starlink-chassis`` and
``starlink-solar-array`` presets of ``brdf/data/materials.toml`` (two-lobe BRDFs), fitted to the
laboratory BRDF tables of the same paper — nothing is tuned to the brightness observations;
``ONE_LOBE_MATERIALS`` names the earlier one-lobe (Cook–Torrance) fits of the same tables.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd

from brdf.materials import load_presets
from filters.attitude import quaternion_from_matrix
from lightcurve.io.observations import (
    OBJECT_POSITION_COLUMNS,
    OBSERVER_COLUMNS,
    SUN_COLUMNS,
    Observations,
    datetime_to_mjd,
    validate_table,
)
from lightcurve.photometry.earthshine import earthshine_applies, sun_and_earth_flux
from lightcurve.photometry.render import Renderer, flux_to_magnitude
from lightcurve.sky.ephemeris import Site, site_position
from shapes import FacetModel, Material, primitives

__all__ = [
    "CHASSIS_AREA_M2",
    "MATERIALS",
    "MOUNT_LEMMON",
    "ONE_LOBE_MATERIALS",
    "POMENIS_PATH",
    "SOLAR_ARRAY_AREA_M2",
    "predict_observations",
    "predict_pomenis",
    "read_pomenis",
    "starlink_attitude",
    "starlink_model",
]

#: The Pomenis observations: package data of :mod:`lightcurve`.
POMENIS_PATH = Path(
    str(resources.files("lightcurve").joinpath("data", "starlink", "pomenis_observations.csv"))
)
MOUNT_LEMMON = Site(32.4434, -110.7881, 2790.0, "Mount Lemmon (Pomenis)")
CHASSIS_AREA_M2 = 3.64
SOLAR_ARRAY_AREA_M2 = 22.68
#: Presets (``brdf/data/materials.toml``) of the chassis and the solar array: the two-lobe fits.
MATERIALS = ("starlink-chassis", "starlink-solar-array")
#: The best one-lobe fits (Cook–Torrance) of the same lab tables.
ONE_LOBE_MATERIALS = ("starlink-chassis-cook-torrance", "starlink-solar-array-cook-torrance")


def read_pomenis(path: str | Path = POMENIS_PATH) -> pd.DataFrame:
    """The Pomenis observations with parsed times.

    Returns
    -------
    pandas.DataFrame
        Columns ``mjd`` (UTC), ``height_km``, ``altitude_deg``, ``azimuth_deg``, ``mag``
        (AB), sorted by time.
    """
    raw = pd.read_csv(path, comment="#")
    expected = {
        "observation_time",
        "satellite_height",
        "satellite_altitude",
        "satellite_azimuth",
        "ab_magnitude",
    }
    missing = expected - set(raw.columns)
    if missing:
        raise ValueError(f"{path}: missing column(s) {', '.join(sorted(missing))}")
    times = pd.to_datetime(raw["observation_time"], utc=True, format="ISO8601")
    table = pd.DataFrame(
        {
            "mjd": datetime_to_mjd(times),
            "height_km": raw["satellite_height"].astype(float),
            "altitude_deg": raw["satellite_altitude"].astype(float),
            "azimuth_deg": raw["satellite_azimuth"].astype(float),
            "mag": raw["ab_magnitude"].astype(float),
        }
    )
    return table.sort_values("mjd", kind="stable").reset_index(drop=True)


def starlink_model(materials: tuple[str, str] = MATERIALS) -> FacetModel:
    """The two-surface Starlink v1.5 model with lab-fitted materials.

    Parameters
    ----------
    materials : (str, str)
        Preset names (``brdf/data/materials.toml``) of the chassis and the solar array.
    """
    presets = load_presets()
    unknown = [name for name in materials if name not in presets]
    if unknown:
        raise ValueError(f"no material preset(s) {', '.join(unknown)} in brdf/data/materials.toml")
    chassis, solar_array = (presets[name] for name in materials)
    model = primitives.panels(
        {
            "chassis": ((0.0, 0.0, -1.0), CHASSIS_AREA_M2, (0.0, 0.0, 0.0)),
            "solar_array": ((0.0, 1.0, 0.0), SOLAR_ARRAY_AREA_M2, (0.0, 2.0, 0.0)),
        },
        {
            name: Material(preset.model, dict(preset.params), name=name)
            for name, preset in (("chassis", chassis), ("solar_array", solar_array))
        },
        name="starlink_v1.5",
    )
    return model.replace(
        provenance={"source": "Fankhauser, Askari & Tyson (2023)", "license": "MIT"},
        inertia=np.eye(3),
    )


def starlink_attitude(position_km: np.ndarray, sun_km: np.ndarray) -> np.ndarray:
    """Attitude quaternions of the nadir-pointing, Sun-facing configuration.

    Parameters
    ----------
    position_km : (n, 3) array
        Satellite geocentric position (GCRS, km).
    sun_km : (n, 3) array
        Sun geocentric position (GCRS, km).

    Returns
    -------
    (n, 4) numpy.ndarray
        ``q`` with ``A(q)`` rows = body x, y, z axes in GCRS (``+z`` up, ``+y`` toward the
        Sun's horizontal projection).
    """
    z = position_km / np.linalg.norm(position_km, axis=1, keepdims=True)
    to_sun = sun_km - position_km
    y = to_sun - np.sum(to_sun * z, axis=1, keepdims=True) * z
    y /= np.linalg.norm(y, axis=1, keepdims=True)
    x = np.cross(y, z)
    return quaternion_from_matrix(np.stack([x, y, z], axis=1))


def pomenis_geometry(
    table: pd.DataFrame, site: Site = MOUNT_LEMMON
) -> tuple[Observations, np.ndarray]:
    """Observation geometry (GCRS, km) and attitudes of the Pomenis observations.

    The satellite is placed along the observed line of sight (elevation, azimuth) at the
    recorded height above the WGS84 ellipsoid (:func:`lightcurve.sky.topocentric.range_from_height`,
    :func:`lightcurve.sky.satellite_geometry.from_horizontal`) — the route of
    ``lightcurve import --alt-az-range-columns … --range-kind height``.

    Returns
    -------
    observations : Observations
        ``mjd``, ``mag`` (measured), ``mag_err`` (0.1, nominal), Sun and observer vectors
        and the satellite's geocentric position (``obj_*``, km).
    q : (n, 4) numpy.ndarray
        Model attitudes.
    """
    from lightcurve.sky.satellite_geometry import from_horizontal
    from lightcurve.sky.topocentric import range_from_height

    elevation = table["altitude_deg"].to_numpy()
    azimuth = table["azimuth_deg"].to_numpy()
    distance = range_from_height(site, elevation, azimuth, table["height_km"].to_numpy())
    geometry = from_horizontal(site, table["mjd"].to_numpy(), elevation, azimuth, distance)
    vectors = geometry.table()[["mjd", *SUN_COLUMNS, *OBSERVER_COLUMNS]]
    frame = vectors.assign(mag=table["mag"].to_numpy(), mag_err=0.1)
    for k, column in enumerate(OBJECT_POSITION_COLUMNS):  # for the Earth's light
        frame[column] = geometry.object_gcrs[:, k]
    meta = {
        "object": "Starlink v1.5 (Pomenis)",
        "frame": "GCRS",
        "site": site.name,
        "target": "satellite",
        "duplicate_epochs": "allowed",
    }
    order = np.argsort(frame["mjd"].to_numpy(), kind="stable")
    observations = Observations(validate_table(frame.iloc[order], "pomenis", meta), meta, "pomenis")
    q = starlink_attitude(geometry.object_gcrs[order], geometry.sun_gcrs[order])
    return observations, q


def predict_observations(
    observations: Observations,
    site: Site = MOUNT_LEMMON,
    materials: tuple[str, str] = MATERIALS,
    *,
    earthshine: str = "auto",
) -> np.ndarray:
    """Predicted magnitudes of a Starlink v1.5 in any observation file from ``site``.

    The satellite's and the Sun's geocentric positions are recovered from the file's
    object → observer and object → Sun vectors and the site's GCRS position; the attitude
    follows the nadir-pointing, Sun-facing law (:func:`starlink_attitude`).

    Parameters
    ----------
    observations : Observations
        GCRS vectors (e.g. from ``lightcurve import``).
    site : Site
    materials : (str, str)
        Presets of the chassis and the solar array (`starlink_model`).
    earthshine : {"auto", "on", "off"}
        Add the light of a Lambertian Earth (:mod:`lightcurve.photometry.earthshine`; by
        default below :data:`~lightcurve.photometry.earthshine.EARTHSHINE_ALTITUDE_KM`).

    Returns
    -------
    (n,) numpy.ndarray
        Magnitudes.
    """
    position = _satellite_position(observations, site)
    q = starlink_attitude(position, position + observations.sun_vectors / _KM)
    lit_by_earth = earthshine_applies(earthshine, position * _KM)
    sun, earth = _fluxes(q, observations, materials, position if lit_by_earth else None)
    return flux_to_magnitude(sun + earth)


#: Metres per kilometre.
_KM = 1000.0


def _satellite_position(observations: Observations, site: Site) -> np.ndarray:
    """Geocentric GCRS positions (km) from the site's and the object → observer vectors."""
    return site_position(site, observations.mjd) - observations.observer_vectors / _KM


def _fluxes(
    q: np.ndarray,
    observations: Observations,
    materials: tuple[str, str],
    position_km: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Flux ratios lit by the Sun and by the Earth (zeros without ``position_km``)."""
    # The paper's model is two independent surfaces: no mutual shadowing.
    renderer = Renderer(starlink_model(materials), shadows="none")
    position = None if position_km is None else position_km * _KM
    sun, observer = observations.sun_vectors, observations.observer_vectors
    return sun_and_earth_flux(renderer, q, sun, observer, position)


def predict_pomenis(
    table: pd.DataFrame | None = None,
    materials: tuple[str, str] = MATERIALS,
    *,
    earthshine: str = "auto",
) -> pd.DataFrame:
    """Predicted vs measured magnitude of the Pomenis observations.

    Parameters
    ----------
    table : pandas.DataFrame, optional
        Observations as returned by :func:`read_pomenis` (default: all of them).
    materials : (str, str)
        Presets of the chassis and the solar array (`starlink_model`).
    earthshine : {"auto", "on", "off"}
        Add the light of a Lambertian Earth (:mod:`lightcurve.photometry.earthshine`; by
        default below :data:`~lightcurve.photometry.earthshine.EARTHSHINE_ALTITUDE_KM`).

    Returns
    -------
    pandas.DataFrame
        ``mjd``, ``measured``, ``predicted``, ``residual`` (measured − predicted),
        ``phase_angle_deg``, ``altitude_deg``, ``height_km``, ``earthshine_fraction``
        (the Earth's share of the predicted flux; 0 without it).
    """
    from lightcurve.sky.geometry import phase_angle

    table = read_pomenis() if table is None else table
    observations, q = pomenis_geometry(table)
    lit_by_earth = earthshine_applies(earthshine, observations.object_positions)
    position = observations.object_positions / _KM if lit_by_earth else None
    sun, earth = _fluxes(q, observations, materials, position)
    predicted = flux_to_magnitude(sun + earth)
    measured = observations.magnitudes
    return pd.DataFrame(
        {
            "mjd": observations.mjd,
            "measured": measured,
            "predicted": predicted,
            "residual": measured - predicted,
            "phase_angle_deg": np.rad2deg(
                phase_angle(observations.sun_vectors, observations.observer_vectors)
            ),
            "altitude_deg": table["altitude_deg"].to_numpy(),
            "height_km": table["height_km"].to_numpy(),
            "earthshine_fraction": np.divide(
                earth, sun + earth, out=np.zeros_like(earth), where=sun + earth > 0
            ),
        }
    )
