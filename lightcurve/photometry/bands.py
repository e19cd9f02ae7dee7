"""Photometric bands: the Sun's apparent magnitude at 1 AU per band and magnitude system.

A light curve's magnitudes are ``m = m☉ − 2.5 log10(F_obs/F☉)`` with ``m☉`` the Sun's
magnitude *in the band and system of the observations*. The renderer uses
:data:`~lightcurve.photometry.render.SUN_MAGNITUDE` (−26.74, the Sun's V magnitude of the
measurement model); a file in another band differs from it by the constant
:func:`band_offset`, assuming the object reflects the Sun's spectrum unchanged (a grey
object; a coloured surface adds its own colour term).

The values are the Sun's absolute magnitudes of Willmer (2018, Table 3) moved to 1 AU by
the distance modulus ``5 log10(1 AU / 10 pc) = −31.572``: Johnson–Cousins and 2MASS bands
in both systems, and the LSST bands in AB (as tabulated for the LSST bandpasses by the
Rubin Observatory's moving-object metrics, which take them from the same table).

References
----------
Willmer, C. N. A. (2018). The absolute magnitude of the Sun in several filters.
*The Astrophysical Journal Supplement Series* 236, 47.
"""

from __future__ import annotations

from lightcurve.photometry.render import SUN_MAGNITUDE

__all__ = [
    "SUN_MAGNITUDES",
    "SYSTEMS",
    "band_header",
    "band_offset",
    "header_band",
    "header_offset",
    "sun_magnitude",
]

#: ``5 log10(1 AU / 10 pc)``: absolute (10 pc) to apparent (1 AU) magnitude.
_ONE_AU_MODULUS = -31.572

#: Magnitude systems.
SYSTEMS = ("vega", "ab")

#: Absolute magnitudes of the Sun (Willmer 2018, Table 3): band → (Vega, AB); None where
#: the table gives no value for that system.
_ABSOLUTE: dict[str, tuple[float | None, float | None]] = {
    "B": (5.44, 5.31),
    "V": (4.81, 4.80),
    "K": (3.27, 5.08),
}

#: Apparent magnitudes of the Sun at 1 AU in the LSST bands, AB (Willmer 2018 via the LSST
#: bandpasses).
_LSST_AB = {"u": -25.30, "g": -26.52, "r": -26.93, "i": -27.05, "z": -27.07, "y": -27.07}

#: ``(band, system)`` → the Sun's apparent magnitude at 1 AU.
SUN_MAGNITUDES: dict[tuple[str, str], float] = {
    **{
        (band, system): round(value + _ONE_AU_MODULUS, 3)
        for band, values in _ABSOLUTE.items()
        for system, value in zip(SYSTEMS, values, strict=True)
        if value is not None
    },
    **{(band, "ab"): value for band, value in _LSST_AB.items()},
}


def sun_magnitude(band: str, system: str) -> float:
    """The Sun's apparent magnitude at 1 AU in ``band`` (``V``, ``B``, ``K``, LSST
    ``u g r i z y``) and ``system`` (``vega`` or ``ab``).

    Raises
    ------
    ValueError
        For a band or system the table does not hold, naming the ones it does.
    """
    key = (band, system.lower())
    if system.lower() not in SYSTEMS:
        raise ValueError(f"unknown magnitude system {system!r}: use one of {', '.join(SYSTEMS)}")
    if key not in SUN_MAGNITUDES:
        known = ", ".join(f"{b} ({s})" for b, s in sorted(SUN_MAGNITUDES))
        raise ValueError(f"no Sun magnitude for band {band!r} in {system}: known are {known}")
    return SUN_MAGNITUDES[key]


def band_offset(band: str, system: str) -> float:
    """``m☉(band, system) − SUN_MAGNITUDE`` (mag): add it to the renderer's magnitudes to
    predict a grey object's magnitudes in that band and system."""
    return sun_magnitude(band, system) - SUN_MAGNITUDE


def band_header(band: str, system: str) -> dict[str, str]:
    """Header entries of an observation file in ``band`` and ``system`` (checked)."""
    return {
        "band": band,
        "magnitude_system": system.lower(),
        "sun_magnitude": f"{sun_magnitude(band, system):.3f}",
    }


def header_band(meta: dict[str, str]) -> tuple[str, str] | None:
    """The ``(band, system)`` an observation file's header declares (``band`` and
    ``magnitude_system`` entries), or None when it declares none."""
    if "band" not in meta:
        return None
    return meta["band"], meta.get("magnitude_system", "vega")


def header_offset(meta: dict[str, str]) -> float:
    """:func:`band_offset` of the band a header declares; 0 without one."""
    band = header_band(meta)
    return 0.0 if band is None else band_offset(*band)
