"""Ground sites: the built-in table of observatories and ``--site`` specifications.

A site is given either as ``LAT,LON,ALT_M`` (geodetic latitude and east longitude in
degrees, WGS84; height above the ellipsoid in metres) or by the name of an observatory in
``lightcurve/data/sites/observatories.csv`` (package data: ``Mount Lemmon``,
``Haleakala``/``Maui``, ``Kislovodsk``, ``Modra``, ``Zimmerwald``, ``Graz``,
``Siding Spring``, ``La Palma``, …; sources in ``lightcurve/data/sites/README.md``). Names
match ignoring case, spaces and punctuation, and aliases are accepted.
"""

from __future__ import annotations

import csv
import difflib
import re
from dataclasses import dataclass
from functools import cache
from importlib import resources
from pathlib import Path

import numpy as np

__all__ = ["SITES_PATH", "Site", "get_site", "load_sites", "site_from_label", "site_itrs"]

SITES_PATH = Path(str(resources.files("lightcurve").joinpath("data", "sites", "observatories.csv")))
_COLUMNS = ("name", "latitude_deg", "longitude_deg", "altitude_m", "aliases", "source")


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

    @property
    def label(self) -> str:
        """``name (lat, lon, alt m)`` for file headers."""
        return (
            f"{self.name} ({self.latitude_deg:.4f}, {self.longitude_deg:.4f}, "
            f"{self.altitude_m:.0f} m)"
        )


def _key(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", name.lower())


def _number(row: dict[str, str], column: str, path: Path, line: int) -> float:
    try:
        value = float(row[column])
    except (TypeError, ValueError):
        raise ValueError(
            f"{path}, line {line}, column '{column}': {row[column]!r} is not a number"
        ) from None
    if not np.isfinite(value):
        raise ValueError(f"{path}, line {line}, column '{column}': value is not finite")
    return value


@cache
def load_sites(path: Path = SITES_PATH) -> dict[str, Site]:
    """The observatory table: lookup key (name or alias, normalised) → :class:`Site`.

    Raises
    ------
    ValueError
        Naming the file, line and column of a bad entry.
    """
    path = Path(path)
    with open(path, encoding="utf-8", newline="") as handle:
        reader = csv.DictReader(handle)
        missing = [c for c in _COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"{path}: missing column(s) {', '.join(missing)}")
        sites: dict[str, Site] = {}
        for line, row in enumerate(reader, start=2):
            lat = _number(row, "latitude_deg", path, line)
            lon = _number(row, "longitude_deg", path, line)
            alt = _number(row, "altitude_m", path, line)
            if not (-90 <= lat <= 90 and -180 <= lon <= 360 and -500 <= alt <= 9000):
                raise ValueError(f"{path}, line {line}: coordinates out of range")
            site = Site(lat, lon, alt, row["name"].strip())
            for name in [row["name"], *(row["aliases"] or "").split(";")]:
                if name.strip():
                    key = _key(name)
                    if key in sites:
                        raise ValueError(f"{path}, line {line}: name {name.strip()!r} repeated")
                    sites[key] = site
    return sites


def get_site(spec: str | Site) -> Site:
    """A :class:`Site` from ``LAT,LON,ALT_M`` or an observatory name.

    Parameters
    ----------
    spec : str or Site
        ``"32.4434,-110.7881,2790"`` (deg, deg, m) or ``"Mount Lemmon"``.

    Raises
    ------
    ValueError
        For malformed coordinates or an unknown name (the message lists the known sites
        and the closest match).
    """
    if isinstance(spec, Site):
        return spec
    text = spec.strip()
    parts = text.split(",")
    if len(parts) == 3 and all(re.fullmatch(r"\s*[-+]?[\d.eE+-]+\s*", p) for p in parts):
        try:
            lat, lon, alt = (float(p) for p in parts)
        except ValueError:
            raise ValueError(f"--site expects LAT,LON,ALT_M or a site name, got {spec!r}") from None
        if not (-90 <= lat <= 90 and -180 <= lon <= 360):
            raise ValueError(
                f"--site {spec!r}: latitude must be in [-90, 90], longitude in [-180, 360]"
            )
        if not -500 <= alt <= 9000:
            raise ValueError(f"--site {spec!r}: altitude {alt} m is not on the ground (metres?)")
        return Site(lat, lon, alt)
    sites = load_sites()
    key = _key(text)
    if key in sites:
        return sites[key]
    names = sorted({site.name for site in sites.values()})
    close = difflib.get_close_matches(key, list(sites), n=1, cutoff=0.6)
    hint = f" (did you mean {sites[close[0]].name!r}?)" if close else ""
    raise ValueError(
        f"unknown site {spec!r}{hint}; known sites: {', '.join(names)}; or give LAT,LON,ALT_M"
    )


def site_itrs(site: Site) -> np.ndarray:
    """Geocentric ITRS position of a site (km), shape (3,) (WGS84 geodetic → cartesian)."""
    import erfa

    xyz = erfa.gd2gc(
        1, np.deg2rad(site.longitude_deg), np.deg2rad(site.latitude_deg), site.altitude_m
    )
    return np.asarray(xyz) / 1000.0


_LABEL = re.compile(
    r"^(?P<name>.*?)\s*\((?P<lat>[-+\d.]+),\s*(?P<lon>[-+\d.]+),\s*(?P<alt>[-+\d.]+) m\)$"
)


def site_from_label(label: str) -> Site:
    """The :class:`Site` of a file header's ``site`` entry.

    Headers written by the toolkit record ``name (lat, lon, alt m)``
    (:attr:`Site.label`, coordinates to 10⁻⁴ deg and 1 m); a bare observatory name or
    ``LAT,LON,ALT_M`` is looked up as by :func:`get_site`.

    Raises
    ------
    ValueError
        When the entry is neither.
    """
    match = _LABEL.match(label.strip())
    if match:
        lat, lon, alt = (float(match[k]) for k in ("lat", "lon", "alt"))
        return Site(lat, lon, alt, match["name"] or "site")
    return get_site(label)
