"""What the estimators of one inversion share: the photometric model, the options, the
random generator, the notes and the shapes' symmetry groups; and the checks of the inputs.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

import brdf
from filters.attitude import (
    quaternion_canonical,
    quaternion_normalize,
)
from filters.global_search import (
    BatchProblem,
    Prior,
    SearchResult,
)
from filters.symmetry import SymmetryGroup, symmetry_group
from lightcurve.inversion.options import InversionOptions
from lightcurve.io.observations import Observations
from lightcurve.photometry.measurement import PhotometricModel
from shapes import FacetModel, get_library

#: Fewest measurements an inversion accepts (six unknowns and a consistency check).
MIN_MEASUREMENTS = 30

Progress = Callable[[float, str], None]


def shape_symmetry(shape: FacetModel) -> SymmetryGroup:
    """Rotational symmetry group of a shape (facets, materials, tangents, inertia)."""
    compiled = shape.compiled()
    anisotropic = np.array(
        [
            brdf.get(compiled.materials[i].brdf, **compiled.materials[i].params).anisotropic
            for i in compiled.material_index
        ]
    )
    com = shape.center_of_mass
    return symmetry_group(
        compiled.centroids - com,
        compiled.normals,
        compiled.areas,
        labels=compiled.material_index,
        tangents=compiled.tangents,
        anisotropic=anisotropic,
        inertia=shape.inertia,
        vertices=shape.vertices - com,
    )


def resolve_shapes(shapes: Any) -> dict[str, FacetModel]:
    """Candidate shapes by name: a FacetModel, a library name, a sequence of names or a
    mapping name → FacetModel (names load from the built-in library)."""
    if isinstance(shapes, FacetModel):
        return {shapes.name: shapes}
    if isinstance(shapes, str):
        shapes = [shapes]
    if isinstance(shapes, Mapping):
        resolved = dict(shapes)
    else:
        library = get_library()
        resolved = {}
        for name in shapes:
            try:
                resolved[name] = library.load(name)
            except (ValueError, OSError) as exc:
                raise ValueError(f"shape {name!r} cannot be loaded: {exc}") from None
    if not resolved:
        raise ValueError("no candidate shape given")
    for name, model in resolved.items():
        if not isinstance(model, FacetModel):
            raise ValueError(f"shape {name!r} is not a FacetModel")
    return resolved


def check_observations(observations: Observations) -> None:
    """Reject observations an inversion cannot use, naming the file, row and column."""
    where = observations.source or observations.name
    if not observations.has_magnitudes:
        raise ValueError(f"{where}: no 'mag'/'mag_err' columns: nothing to invert")
    n = len(observations)
    if n < MIN_MEASUREMENTS:
        raise ValueError(
            f"{where}: {n} measurement(s); at least {MIN_MEASUREMENTS} are needed to invert"
        )
    for column in ("mag", "mag_err"):
        values = observations.table[column].to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise ValueError(f"{where}: row {bad[0] + 1}, column '{column}': value is not finite")
    if observations.relative.any():
        raise ValueError(
            f"{where}: relative (uncalibrated) light curves cannot be inverted for attitude "
            "with a fixed shape; use calibrated magnitudes"
        )


@dataclass
class Context:
    """Everything the estimators share for one run.

    Attributes
    ----------
    method : str
    observations : Observations
    model : PhotometricModel
    options : InversionOptions
        Validated for ``method``.
    prior : Prior or None
        Gaussian prior on the initial state (None without ``q0``).
    attitude_sigma : float
        Prior 1σ per axis of the attitude (rad).
    omega_sigma : float
        Prior 1σ per axis of the rates (rad/s).
    omega_max : float
        Radius of the rate ball of the global search (rad/s).
    particles : int
        Particle count of the PF.
    progress : callable or None
    rng : numpy.random.Generator
        The one generator of every random draw, in run order.
    seed : int
    notes : list of str
        Notes collected for the result.
    start : float
        ``time.perf_counter()`` at the start of the run.
    """

    method: str
    observations: Observations
    model: PhotometricModel
    options: InversionOptions
    prior: Prior | None
    attitude_sigma: float
    omega_sigma: float
    omega_max: float
    particles: int
    progress: Progress | None
    rng: np.random.Generator
    seed: int
    notes: list[str]
    start: float
    _groups: dict[int, SymmetryGroup] = field(default_factory=dict)

    def symmetry(self, s: int) -> SymmetryGroup:
        """Symmetry group of shape ``s`` (computed once)."""
        if s not in self._groups:
            self._groups[s] = shape_symmetry(self.model.shapes[self.names[s]])
        return self._groups[s]

    def report(self, fraction: float, message: str) -> None:
        """Pass progress (fraction clipped to [0, 1]) to the caller's callback."""
        if self.progress is not None:
            self.progress(min(max(fraction, 0.0), 1.0), message)

    @property
    def names(self) -> list[str]:
        """Candidate shape names, in shape-index order."""
        return self.model.names

    def problem(self) -> BatchProblem:
        """The batch problem of the measurements (:func:`batch_problem`); the UKF/MMAE
        search estimates the inertia under the filters' prior about each shape's own
        (``inertia_sigma``), the PF's searches it uniformly."""
        if self.method == "pf":
            return batch_problem(self.model, self.options.estimate_inertia)
        return batch_problem(
            self.model,
            self.options.estimate_inertia,
            self.options.inertia_sigma,
            free_offset="scale" in self.options.estimate,
        )

    def windows(self, longest: float, growth: float = 2.0) -> tuple[float, ...]:
        """Growing fit windows (s): 30 s, growing ``growth``-fold, up to ``longest``."""
        windows = [30.0] if longest > 30.0 else []
        while windows and growth * windows[-1] < longest:
            windows.append(growth * windows[-1])  # grow gently: LM stays in its basin
        return (*windows, longest)


def batch_problem(
    model: PhotometricModel,
    estimate_inertia: bool = False,
    inertia_sigma: float = math.inf,
    free_offset: bool = False,
) -> BatchProblem:
    """The torque-free batch problem (:class:`filters.global_search.BatchProblem`) of a
    photometric model's measurements and shapes (``inertia_sigma``: 1σ of the prior on the
    tanh inertia parameters about each shape's own; ``free_offset``: a common magnitude
    offset profiled out; see there)."""

    def measure(q: torch.Tensor, epochs: np.ndarray, shape: torch.Tensor) -> torch.Tensor:
        return model.magnitude_by_shape(q.to(model.dtype), epochs, shape).to(torch.float64)

    shapes = list(model.shapes.values())
    return BatchProblem(
        model.times,
        model.magnitudes,
        model.errors,
        measure,
        [s.inertia for s in shapes],
        principal_axes=[s.principal_axes for s in shapes],
        estimate_inertia=estimate_inertia,
        inertia_sigma=inertia_sigma,
        free_offset=free_offset,
    )


def initial_prior(
    q0: Any, omega0: Any, attitude_sigma: float, omega_sigma: float, omega_max: float
) -> Prior | None:
    """The prior on the initial state from ``q0`` (normalised, sign-canonical) and
    ``omega0`` (rad/s; without it the rates are centred on zero with 1σ ``omega_max``);
    None without ``q0``."""
    if q0 is None:
        return None
    q = quaternion_canonical(quaternion_normalize(np.asarray(q0, dtype=float)))
    if omega0 is None:
        return Prior(q, np.zeros(3), attitude_sigma, omega_max)
    return Prior(q, np.asarray(omega0, dtype=float), attitude_sigma, omega_sigma)


def symmetry_note(name: str, group: SymmetryGroup) -> str | None:
    """The result's note on a shape's rotational symmetry (None for none)."""
    if group.is_trivial:
        return None
    if group.axis is not None:
        return (
            f"{name} has a continuous rotational symmetry about body axis "
            f"{np.round(group.axis, 3).tolist()}: the rotation about it is unobservable"
        )
    return (
        f"{name} has {group.order} rotational symmetries: the attitude is determined only "
        "up to them (see 'symmetry')"
    )


def capped(covariance: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Covariances ``(B, n, n)`` whose 1σ along any direction is at most ``sigma`` in the
    units of each component: eigenvalues of ``S⁻¹ P S⁻¹`` (``S = diag σ``) clipped to
    ``[0, 1]``."""
    scale = np.outer(sigma, sigma)
    scaled = covariance / scale
    values, vectors = np.linalg.eigh(0.5 * (scaled + np.swapaxes(scaled, -1, -2)))
    clipped = (vectors * np.clip(values, 0.0, 1.0)[..., None, :]) @ np.swapaxes(vectors, -1, -2)
    return clipped * scale


def subset(found: SearchResult, keep: Any) -> SearchResult:
    """The candidates of ``found`` selected by an index, slice or mask."""
    return dataclasses.replace(
        found,
        q=found.q[keep],
        omega=found.omega[keep],
        k=None if found.k is None else found.k[keep],
        shape=found.shape[keep],
        chi2=found.chi2[keep],
        covariance=found.covariance[keep],
    )
