"""Light-curve data in the form the convex inversion fits: unit vectors, brightness, weights.

Magnitudes become intensities ``I = 10^(−0.4 m)`` reduced to unit distances,
``I · (r_obs/1 AU)² (r_sun/1 AU)²`` — except for DAMIT files, whose brightness is already
reduced (calibrated curves) or relative. Relative light curves are divided by their mean, so
that data and model are compared as ``I/⟨I⟩`` (Kaasalainen, Torppa & Muinonen 2001, eq. 3);
calibrated curves keep their absolute scale (one common scale factor is fitted). The 1σ
errors propagate from ``mag_err``: ``σ_I = 0.4 ln 10 · σ_m · I``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from lightcurve.io.damit import DamitLightcurves
    from lightcurve.io.observations import Observations

__all__ = ["Photometry"]

_FLUX_PER_MAG = 0.4 * math.log(10.0)
#: The astronomical unit (m), IAU 2012 resolution B2 (``lightcurve.sky.geometry.AU_M``, not
#: imported: that module loads the attitude core, which the fits do not need).
AU_M = 149_597_870_700.0


def _unit_and_range(vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    length = np.linalg.norm(vectors, axis=-1)
    return vectors / length[..., None], length


@dataclass(frozen=True)
class Photometry:
    """Light curves prepared for convex inversion.

    Attributes
    ----------
    mjd : (N,) float
        Epochs (MJD; light-time corrected for DAMIT files).
    sun, earth : (N, 3) float
        Unit object → Sun and object → observer vectors, inertial (ecliptic J2000 for
        asteroids).
    brightness : (N,) float
        Relative curves: ``I/⟨I⟩`` per curve; calibrated curves: reduced intensity divided by
        the mean of all calibrated points.
    sigma : (N,) float
        1σ errors of ``brightness``.
    curve : (N,) int
        Light-curve index, 0 … n_curves − 1.
    relative : (n_curves,) bool
        Whether each curve is relative.
    sources : list of str
        Input files.
    """

    mjd: np.ndarray
    sun: np.ndarray
    earth: np.ndarray
    brightness: np.ndarray
    sigma: np.ndarray
    curve: np.ndarray
    relative: np.ndarray
    sources: tuple[str, ...] = ()

    def __len__(self) -> int:
        return len(self.mjd)

    @property
    def n_curves(self) -> int:
        return len(self.relative)

    @property
    def span_days(self) -> float:
        """Time between the first and the last epoch (days)."""
        return float(self.mjd.max() - self.mjd.min())

    def thinned(self, per_curve: int) -> Photometry:
        """A copy keeping at most ``per_curve`` evenly spaced points of each light curve.

        Period scans run on thinned data: the period resolution comes from the time span,
        not from the sampling within a night.
        """
        keep = np.zeros(len(self), dtype=bool)
        for label in range(self.n_curves):
            rows = np.flatnonzero(self.curve == label)
            pick = np.unique(np.round(np.linspace(0, len(rows) - 1, min(per_curve, len(rows)))))
            keep[rows[pick.astype(int)]] = True
        fields = ("mjd", "sun", "earth", "brightness", "sigma", "curve")
        values = {name: getattr(self, name)[keep] for name in fields}
        # Relative curves are renormalised to unit mean over the points kept.
        means = np.bincount(values["curve"], values["brightness"], self.n_curves) / np.maximum(
            np.bincount(values["curve"], minlength=self.n_curves), 1
        )
        scale = np.where(self.relative, means, 1.0)[values["curve"]]
        values["brightness"] = values["brightness"] / scale
        values["sigma"] = values["sigma"] / scale
        return Photometry(**values, relative=self.relative, sources=self.sources)

    @property
    def mean_epoch(self) -> float:
        """Weighted mean epoch ``Σ t_j/σ_j² / Σ 1/σ_j²`` (MJD).

        The reference epoch of the fits: there the rotation phase and the period are least
        correlated (a change of period turns the body by ``∝ (t − t̄)``, both ways).
        """
        return float(np.average(self.mjd, weights=self.sigma**-2.0))

    @property
    def phase_angle(self) -> np.ndarray:
        """Solar phase angle (rad), shape (N,)."""
        return np.arccos(np.clip(np.sum(self.sun * self.earth, axis=1), -1.0, 1.0))

    @classmethod
    def read(cls, paths: Sequence[str | os.PathLike[str]]) -> Photometry:
        """Read observation files (any format of :func:`lightcurve.io.read`) into one data set.

        DAMIT files are parsed straight into arrays (:mod:`lightcurve.io.damit`, no pandas) when
        their values pass the checks of the observation tables; any other file, or one that
        does not, goes through :func:`lightcurve.io.read`, which gives the same data or the
        error naming the file, row and column.

        Raises
        ------
        FileNotFoundError, ObservationError
            As :func:`lightcurve.io.read`.
        """
        from lightcurve import io
        from lightcurve.io.damit import read_lightcurves

        tables: list[Observations | DamitLightcurves] = []
        for path in map(Path, paths):
            points = None
            if path.is_file() and io.sniff_format(path) == "damit":
                points = read_lightcurves(path)
            clean = points is not None and points.passes_table_checks()
            tables.append(points if clean else io.read(path))
        return cls.from_observations(tables)

    @classmethod
    def from_observations(
        cls, observations: Sequence[Observations | DamitLightcurves]
    ) -> Photometry:
        """Combine observation tables (one or more files) into one data set.

        Each file's light curves (``lightcurve_id``; one curve when absent) keep their
        ``relative`` flag; curves with fewer than two points are dropped (a relative curve of
        one point carries no information).

        Raises
        ------
        ValueError
            If nothing is left to fit.
        """
        parts, relative, sources, offset = [], [], [], 0
        for obs in observations:
            ids = obs.lightcurve_ids
            flags = obs.relative
            sun, sun_range = _unit_and_range(np.asarray(obs.sun_vectors, float))
            earth, earth_range = _unit_and_range(np.asarray(obs.observer_vectors, float))
            intensity = 10.0 ** (-0.4 * obs.magnitudes)
            if obs.meta.get("source_format") != "damit":
                intensity = intensity * (earth_range / AU_M) ** 2 * (sun_range / AU_M) ** 2
            sigma = _FLUX_PER_MAG * obs.magnitude_errors * intensity
            for label in np.unique(ids):
                rows = np.flatnonzero(ids == label)
                if len(rows) < 2:
                    continue
                is_relative = bool(flags[rows[0]])
                scale = intensity[rows].mean() if is_relative else 1.0
                parts.append(
                    (
                        obs.mjd[rows],
                        sun[rows],
                        earth[rows],
                        intensity[rows] / scale,
                        sigma[rows] / scale,
                        np.full(len(rows), offset),
                    )
                )
                relative.append(is_relative)
                offset += 1
            sources.append(str(obs.source))
        if not parts:
            raise ValueError("no light curve with at least two points to fit")
        mjd, sun, earth, brightness, sigma, curve = (
            np.concatenate(p) for p in zip(*parts, strict=True)
        )
        relative = np.array(relative, dtype=bool)
        calibrated = ~relative[curve]
        if calibrated.any():
            scale = brightness[calibrated].mean()
            brightness = np.where(calibrated, brightness / scale, brightness)
            sigma = np.where(calibrated, sigma / scale, sigma)
        return cls(mjd, sun, earth, brightness, sigma, curve, relative, tuple(sources))
