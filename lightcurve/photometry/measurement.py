"""The photometric measurement model handed to the estimators in :mod:`filters`.

:class:`PhotometricModel` binds an observation set (epochs, Sun and observer vectors,
measured magnitudes and their 1σ errors) to one or several candidate shapes, each with a
:class:`~lightcurve.photometry.render.Renderer`. Estimators call :meth:`PhotometricModel.magnitude`
with batches of attitudes (sigma points, particles or candidate states × epochs) and get the
predicted magnitudes in one torch call per shape.

Dark epochs and the faint floor
-------------------------------
A facet model can be dark (no lit facet visible), where the magnitude is infinite. Filters
need finite predictions, so the model adds a floor flux ``F_floor`` before taking the
logarithm (Gou et al. 2016, sec. 2.3, ``M = −26.74 − 2.5 log10 I``):

``m = −26.74 − 2.5 log10(F_obs/F_sun + F_floor)``,

with ``F_floor`` the flux of the *faint limit*, by default 7.5 mag fainter than the
faintest measurement (0.1 % of its flux). Predictions of dark attitudes are then finite,
and the floor biases the prediction at the faintest measurement by 0.001 mag (a margin of
3 mag would bias it by 0.07 mag, more than a typical measurement error, and makes filters
over-confident).

An optional magnitude offset (the "albedo–area scale" of an estimator's state: a common
factor ``s`` on every BRDF × area is ``Δm = −2.5 log10 s``) is added by the estimators.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import torch

from lightcurve.io.observations import Observations
from lightcurve.photometry.bands import header_offset
from lightcurve.photometry.render import SUN_MAGNITUDE, Renderer, magnitude_to_flux
from shapes import FacetModel

__all__ = ["DEFAULT_FAINT_MARGIN", "PhotometricModel"]

#: The faint limit lies this many magnitudes below the faintest measurement.
DEFAULT_FAINT_MARGIN = 7.5


class PhotometricModel:
    """Predicted magnitudes of candidate shapes at the epochs of an observation set.

    Parameters
    ----------
    observations : Observations
        Measured ``mag``, ``mag_err`` and geometry (validated: finite, ``mag_err > 0``).
    shapes : FacetModel or mapping name → FacetModel
        Candidate shape(s); index ``s`` of :meth:`magnitude` follows the mapping's order.
    shadows : str
        Renderer shadow mode (``"auto"`` picks none/table/exact per shape).
    dtype : torch.dtype
        Rendering precision.
    compile : bool
        Compile the renderers' kernels (pays off for particle filters and global searches).
    faint_margin : float
        Magnitudes between the faintest measurement and the faint limit (see module
        docstring).

    Raises
    ------
    ValueError
        No magnitudes, no measurement, non-finite values, or no shape.
    """

    def __init__(
        self,
        observations: Observations,
        shapes: FacetModel | Mapping[str, FacetModel],
        *,
        shadows: str = "auto",
        dtype: torch.dtype = torch.float64,
        compile: bool = False,
        faint_margin: float = DEFAULT_FAINT_MARGIN,
    ) -> None:
        where = observations.source or observations.name
        if not observations.has_magnitudes:
            raise ValueError(f"{where}: no 'mag'/'mag_err' columns: nothing to invert")
        if len(observations) == 0:
            raise ValueError(f"{where}: no measurements")
        if isinstance(shapes, FacetModel):
            shapes = {shapes.name: shapes}
        if not shapes:
            raise ValueError("at least one candidate shape is needed")
        self.observations = observations
        self.names = list(shapes)
        self.shapes = dict(shapes)
        self.renderers = [
            Renderer(shape, shadows=shadows, dtype=dtype, compile=compile)
            for shape in shapes.values()
        ]
        self.inertias = [np.asarray(shape.inertia, dtype=float) for shape in shapes.values()]
        self.dtype = dtype
        self.device = self.renderers[0].device
        self.times = observations.times
        self.mjd = observations.mjd
        # magnitudes in a declared band are taken back to the model's V (a grey object)
        self.magnitudes = observations.magnitudes - header_offset(observations.meta)
        self.errors = observations.magnitude_errors
        for label, values in (("mag", self.magnitudes), ("mag_err", self.errors)):
            if not np.all(np.isfinite(values)):
                raise ValueError(f"{where}: column '{label}' has non-finite values")
        self.sun = torch.as_tensor(observations.sun_vectors, dtype=dtype, device=self.device)
        self.observer = torch.as_tensor(
            observations.observer_vectors, dtype=dtype, device=self.device
        )
        self.faint_limit = float(np.max(self.magnitudes) + faint_margin)
        self._floor = float(magnitude_to_flux(self.faint_limit))

    def __len__(self) -> int:
        return len(self.times)

    @property
    def n_shapes(self) -> int:
        """Number of candidate shapes."""
        return len(self.renderers)

    def magnitude(self, q: Any, epochs: Any, shape: int = 0) -> Any:
        """Predicted magnitudes with the faint floor.

        Parameters
        ----------
        q : (..., 4) array or tensor
            Attitudes (inertial → body), broadcast against the selected epochs: e.g.
            ``(P, 4)`` with one epoch index, or ``(P, E, 4)`` with ``E`` indices.
        epochs : int, slice or (E,) int array
            Epoch indices into the observation set.
        shape : int
            Index of the candidate shape.

        Returns
        -------
        (...) array
            numpy for numpy input, torch (same device as ``q``) for torch input.
        """
        flux = self.renderers[shape].flux(q, self.sun[epochs], self.observer[epochs])
        if isinstance(flux, torch.Tensor):
            return SUN_MAGNITUDE - 2.5 * torch.log10(flux + self._floor)
        return SUN_MAGNITUDE - 2.5 * np.log10(flux + self._floor)

    def magnitude_by_shape(self, q: torch.Tensor, epochs: Any, shape_index: Any) -> torch.Tensor:
        """Predicted magnitudes for particles that each carry a shape index.

        Each shape renders its own particles in one call.

        Parameters
        ----------
        q : (P, ..., 4) tensor
            Attitudes.
        epochs : int, slice or (E,) int array
            Epoch indices (broadcast as in :meth:`magnitude`).
        shape_index : (P,) int tensor
            Candidate shape of each particle.

        Returns
        -------
        (P, ...) tensor
        """
        out = None
        for s in range(self.n_shapes):
            rows = torch.nonzero(shape_index == s).flatten()
            if rows.numel() == 0:
                continue
            m = self.magnitude(q[rows], epochs, s)
            if out is None:
                out = torch.empty((q.shape[0], *m.shape[1:]), dtype=m.dtype, device=m.device)
            out[rows] = m
        if out is None:
            raise ValueError("no particle carries a valid shape index")
        return out

    def chi_squared_weights(self, epochs: Any) -> torch.Tensor:
        """``1/σ²`` of the selected measurements as a tensor (mag⁻²)."""
        err = torch.as_tensor(self.errors, dtype=self.dtype, device=self.device)[epochs]
        return 1.0 / err**2

    def measured(self, epochs: Any) -> torch.Tensor:
        """Measured magnitudes of the selected epochs as a tensor."""
        return torch.as_tensor(self.magnitudes, dtype=self.dtype, device=self.device)[epochs]
