"""The epochs of an EGI fit: body-frame Sun and observer directions, flux and its 1σ.

The attitudes come from the observation file's truth columns (``q1..q4``, simulated data) or
from the per-epoch estimates of an inversion result folder (``lightcurve invert`` output,
``estimates.parquet``), matched to the file's rows by epoch.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from filters.attitude import attitude_matrix
from lightcurve.io.observations import Observations
from lightcurve.photometry.render import magnitude_to_flux
from lightcurve.sky.geometry import AU_M

__all__ = ["FitEpochs", "result_attitudes", "truth_attitudes"]

#: Epochs of a result folder and of a file are the same when they agree to 1 ms.
_SAME_EPOCH_DAYS = 1e-3 / 86400.0
#: ``d(flux)/flux = (0.4 ln 10) d(mag)``.
_FLUX_PER_MAG = 0.4 * math.log(10.0)


@dataclass(frozen=True)
class FitEpochs:
    """Measurements with their geometry in the body frame.

    Attributes
    ----------
    light, view : (E, 3) float
        Unit vectors to the Sun and to the observer, body frame.
    scale : (E,) float
        ``(1 AU / r_sun)² / d²`` (m⁻²), ``d`` the observer range and ``r_sun`` the Sun's:
        flux ratio per unit ``ρ A (n·L)(n·V)``, as the renderer scales it.
    mag, mag_err : (E,) float
        Measured magnitude and its 1σ.
    source : (E,) int
        Index of the file of each epoch.
    mjd : (E,) float
        Epochs (UTC MJD).
    """

    light: np.ndarray
    view: np.ndarray
    scale: np.ndarray
    mag: np.ndarray
    mag_err: np.ndarray
    source: np.ndarray
    mjd: np.ndarray

    def __len__(self) -> int:
        return len(self.mag)

    @property
    def flux(self) -> np.ndarray:
        """(E,) measured flux ratio ``F_obs / F_sun``."""
        return magnitude_to_flux(self.mag)

    @property
    def flux_sigma(self) -> np.ndarray:
        """(E,) 1σ of the flux ratio, ``F · 0.4 ln 10 · σ_mag`` (magnitude-space weights)."""
        return self.flux * _FLUX_PER_MAG * self.mag_err

    def subset(self, mask: np.ndarray) -> FitEpochs:
        """The epochs where ``mask`` is true."""
        return FitEpochs(
            self.light[mask],
            self.view[mask],
            self.scale[mask],
            self.mag[mask],
            self.mag_err[mask],
            self.source[mask],
            self.mjd[mask],
        )

    @classmethod
    def from_observations(
        cls, observations: list[Observations], attitudes: list[np.ndarray]
    ) -> FitEpochs:
        """Epochs of several files, each with its attitudes.

        Parameters
        ----------
        observations : list of Observations
            Files with magnitudes.
        attitudes : list of (E_k, 4) float
            Inertial → body quaternions (scalar last) at each file's rows.

        Returns
        -------
        FitEpochs
        """
        parts = []
        for k, (obs, q) in enumerate(zip(observations, attitudes, strict=True)):
            matrices = attitude_matrix(np.asarray(q, float))
            sun, observer = obs.sun_vectors, obs.observer_vectors
            distance = np.linalg.norm(observer, axis=1)
            sun_range = np.linalg.norm(sun, axis=1)
            light = np.einsum("eij,ej->ei", matrices, sun / sun_range[:, None])
            view = np.einsum("eij,ej->ei", matrices, observer / distance[:, None])
            parts.append(
                (
                    light,
                    view,
                    (AU_M / sun_range) ** 2 / distance**2,
                    obs.magnitudes,
                    obs.magnitude_errors,
                    np.full(len(obs), k),
                    obs.mjd,
                )
            )
        return cls(*(np.concatenate(column) for column in zip(*parts, strict=True)))


def truth_attitudes(observations: Observations) -> np.ndarray:
    """The truth quaternions ``q1..q4`` of a (simulated) file, (E, 4).

    Raises
    ------
    ValueError
        The file has no truth columns.
    """
    columns = ["q1", "q2", "q3", "q4"]
    if not all(c in observations.table for c in columns):
        raise ValueError(
            f"{observations.source}: --attitude truth needs the truth columns q1..q4, "
            "which the file does not have; give an inversion result folder instead"
        )
    return observations.table[columns].to_numpy(dtype=float)


def result_attitudes(observations: Observations, folder: Path) -> np.ndarray:
    """The attitude estimates of an inversion result folder at a file's rows, (E, 4).

    Parameters
    ----------
    observations : Observations
        The file the result folder must belong to.
    folder : pathlib.Path
        ``lightcurve invert`` output: one input's folder (``summary.json``,
        ``estimates.parquet``) or the batch folder holding ``<file stem>/``.

    Raises
    ------
    ValueError, OSError
        No result there, a failed inversion, or estimates of another file (its input names
        another file, or its epochs are not the file's).
    """
    import pandas as pd

    source = Path(str(observations.source))
    if not (folder / "summary.json").is_file() and (folder / source.stem).is_dir():
        folder = folder / source.stem
    summary_file, table_file = folder / "summary.json", folder / "estimates.parquet"
    if not summary_file.is_file() or not table_file.is_file():
        raise FileNotFoundError(
            f"{folder}: not an inversion result folder of {source.name} "
            "(no summary.json and estimates.parquet)"
        )
    summary = json.loads(summary_file.read_text())
    if summary.get("status", "ok") != "ok":
        raise ValueError(f"{folder}: the inversion failed ({summary.get('error')}): no attitudes")
    given = Path(str(summary.get("input", "")))
    if given.name != source.name:
        raise ValueError(
            f"{folder}: the result of another file ({given.name or 'unnamed'}), not of "
            f"{source.name}"
        )
    estimates = pd.read_parquet(table_file)
    mjd = estimates["mjd"].to_numpy(dtype=float)
    position = np.clip(np.searchsorted(mjd, observations.mjd), 0, len(mjd) - 1)
    before = np.clip(position - 1, 0, len(mjd) - 1)
    nearest = np.where(
        np.abs(mjd[before] - observations.mjd) < np.abs(mjd[position] - observations.mjd),
        before,
        position,
    )
    missing = np.abs(mjd[nearest] - observations.mjd) > _SAME_EPOCH_DAYS
    if np.any(missing):
        row = int(np.argmax(missing)) + 1
        raise ValueError(
            f"{folder}: no estimate at {int(missing.sum())} of the {len(missing)} epochs of "
            f"{source.name} (first: data row {row}): the result of another file"
        )
    return estimates[["q1", "q2", "q3", "q4"]].to_numpy(dtype=float)[nearest]
