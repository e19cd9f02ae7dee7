"""Predicted brightness of a shape, rigid or articulated, at the geometry of observations.

:func:`model_magnitude` renders a library shape (:class:`~shapes.FacetModel`, or
:class:`~shapes.articulation.ArticulatedModel` with its joints posed by the Sun and the
observation file's columns) at given attitudes, lit by the Sun and, as ``earthshine`` says
(:func:`~lightcurve.photometry.earthshine.earthshine_applies`), by the Earth. It is the
uncalibrated prediction that :mod:`lightcurve.photometry.calibration` starts from;
:class:`PredictionGeometry` holds the arrays a prediction reads from the table, so that a
fit reads them once.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from lightcurve.io.observations import Observations
from lightcurve.photometry.articulated import ArticulatedRenderer, scheduled_columns
from lightcurve.photometry.earthshine import (
    earthshine_applies,
    known_positions,
    sun_and_earth_flux,
)
from lightcurve.photometry.render import Renderer, flux_to_magnitude
from shapes import FacetModel
from shapes.articulation import ArticulatedModel

__all__ = ["PredictionGeometry", "Shape", "model_magnitude", "shape_flux"]

#: A shape a prediction renders: rigid, or with articulated parts.
Shape = FacetModel | ArticulatedModel


@dataclass(frozen=True)
class PredictionGeometry:
    """The arrays a prediction needs, read once from an observation table: object → Sun and
    object → observer vectors (m), the object's positions (m) when the Earth's light is
    modelled, and the columns of scheduled joints."""

    sun: np.ndarray
    observer: np.ndarray
    position: np.ndarray | None
    columns: dict[str, np.ndarray]

    @classmethod
    def of(cls, model: Shape, observations: Observations, earthshine: bool) -> PredictionGeometry:
        """The arrays of ``observations`` that ``model`` needs (positions only with
        ``earthshine``; ``obj_*`` columns then required)."""
        articulated = isinstance(model, ArticulatedModel)
        return cls(
            observations.sun_vectors,
            observations.observer_vectors,
            observations.object_positions if earthshine else None,
            scheduled_columns(model, observations.table) if articulated else {},
        )


def model_magnitude(
    model: Shape,
    q: Any,
    observations: Observations,
    *,
    shadows: str = "auto",
    earthshine: str = "auto",
) -> np.ndarray:
    """Magnitudes of ``model`` (rigid or articulated) at attitudes ``q`` (inertial → body)
    and the geometry of ``observations``, lit by the Sun and, as ``earthshine`` says
    (:func:`~lightcurve.photometry.earthshine.earthshine_applies`), by the Earth: the
    uncalibrated prediction a calibration starts from."""
    with_earth = earthshine_applies(earthshine, known_positions(observations))
    geometry = PredictionGeometry.of(model, observations, with_earth)
    return flux_to_magnitude(shape_flux(model, np.asarray(q, dtype=float), geometry, shadows))


def shape_flux(
    model: Shape, q: np.ndarray, geometry: PredictionGeometry, shadows: str
) -> np.ndarray:
    """Flux ratio of ``model`` lit by the Sun (and the Earth) at ``geometry``."""
    if isinstance(model, ArticulatedModel):
        renderer: Any = ArticulatedRenderer(model, shadows=shadows)
        columns: dict[str, np.ndarray] | None = geometry.columns
    else:
        renderer, columns = Renderer(model, shadows=shadows), None
    sunlit, earthlit = sun_and_earth_flux(
        renderer, q, geometry.sun, geometry.observer, geometry.position, columns=columns
    )
    return sunlit + earthlit
