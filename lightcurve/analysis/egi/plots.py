"""The figure of an EGI fit: measured and fitted magnitudes of every file, and residuals."""

from __future__ import annotations

import os

import numpy as np

from lightcurve.analysis.convex.plots import _figure, _save
from lightcurve.analysis.egi.epochs import FitEpochs
from lightcurve.analysis.egi.fit import EGIFit

__all__ = ["plot_egi_fit"]


def plot_egi_fit(
    epochs: FitEpochs,
    fit: EGIFit,
    path: str | os.PathLike[str],
    labels: list[str],
    dpi: int = 90,
) -> None:
    """Magnitudes (measured with 1σ, fitted) and residuals against minutes since each file's
    first epoch, one column per file; written atomically as PNG.

    Parameters
    ----------
    epochs : FitEpochs
    fit : EGIFit
    path : path-like
    labels : list of str
        One title per file (``epochs.source`` indexes them).
    dpi : int
    """
    files = np.unique(epochs.source)
    figure = _figure(4.5 * len(files), 5.0)
    axes = figure.subplots(2, len(files), squeeze=False, sharex="col")
    model = fit.model_mag
    for column, k in enumerate(files):
        mask = epochs.source == k
        minutes = (epochs.mjd[mask] - epochs.mjd[mask].min()) * 1440.0
        top, bottom = axes[0, column], axes[1, column]
        top.errorbar(minutes, epochs.mag[mask], epochs.mag_err[mask], fmt=".", ms=2, lw=0.4)
        top.plot(minutes, model[mask], "-", color="C3", lw=0.8)
        top.invert_yaxis()
        top.set_title(labels[k], fontsize=9)
        bottom.plot(minutes, epochs.mag[mask] - model[mask], ".", ms=2)
        bottom.axhline(0.0, color="k", lw=0.5)
        bottom.set_xlabel("minutes")
    axes[0, 0].set_ylabel("magnitude")
    axes[1, 0].set_ylabel("measured − fitted (mag)")
    figure.subplots_adjust(left=0.1, right=0.98, bottom=0.1, top=0.93, hspace=0.1, wspace=0.3)
    _save(figure, path, dpi)
