"""Mass properties of triangle soups: uniform solids, thin shells, assemblies, principal axes.

Functions take ``triangles : (n, 3, 3) float`` in metres and return :class:`MassProperties`
with the inertia tensor ``J = ∫ (|r|² I − r rᵀ) dm`` about the centre of mass, in the frame of
the input coordinates (kg m²).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import trimesh

__all__ = [
    "MassProperties",
    "combine",
    "principal_axes",
    "shell_properties",
    "solid_properties",
    "translate_inertia",
]


@dataclass(frozen=True)
class MassProperties:
    """Mass, centre of mass (m) and inertia tensor about it (kg m²).

    ``measure`` is the volume (m³) for a solid, the area (m²) for a shell.
    """

    mass: float
    center_of_mass: np.ndarray
    inertia: np.ndarray
    measure: float


def solid_properties(triangles: np.ndarray, density: float = 1.0) -> MassProperties:
    """Mass properties of the uniform solid bounded by a closed, outward-wound triangle mesh.

    Uses trimesh's divergence-theorem integrals (Eberly, "Polyhedral Mass Properties"), which
    are exact for polyhedra.

    Parameters
    ----------
    triangles : (n, 3, 3) float
        Vertices of each facet, m. The surface must be closed and wound outward.
    density : float
        kg/m³.
    """
    props = trimesh.triangles.mass_properties(np.asarray(triangles, float), density=density)
    return MassProperties(
        mass=float(props.mass),
        center_of_mass=np.asarray(props.center_mass, float),
        inertia=np.asarray(props.inertia, float),
        measure=float(props.volume),
    )


def shell_properties(triangles: np.ndarray, areal_density: float = 1.0) -> MassProperties:
    """Mass properties of a thin uniform shell on the triangles (open meshes allowed).

    Each triangle with vertices ``a, b, c`` and area ``A`` contributes the exact second moment
    ``∫ r rᵀ dA = A/12 (a aᵀ + b bᵀ + c cᵀ + s sᵀ)``, ``s = a + b + c``.

    Parameters
    ----------
    triangles : (n, 3, 3) float
        Facet vertices, m.
    areal_density : float
        kg/m².
    """
    tri = np.asarray(triangles, float)
    areas = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    total_area = float(areas.sum())
    s = tri.sum(axis=1)
    second = (
        np.einsum("n,nvi,nvj->ij", areas, tri, tri) + np.einsum("n,ni,nj->ij", areas, s, s)
    ) / 12.0
    com = (areas @ s) / (3.0 * total_area)
    mass = areal_density * total_area
    central = areal_density * second - mass * np.outer(com, com)
    central = 0.5 * (central + central.T)
    return MassProperties(
        mass=mass,
        center_of_mass=com,
        inertia=np.trace(central) * np.eye(3) - central,
        measure=total_area,
    )


def translate_inertia(inertia: np.ndarray, mass: float, offset: np.ndarray) -> np.ndarray:
    """Parallel-axis theorem: inertia about a point displaced by ``offset`` from the COM.

    ``J_P = J_C + m (|d|² I − d dᵀ)``.
    """
    d = np.asarray(offset, float)
    return np.asarray(inertia, float) + mass * (d @ d * np.eye(3) - np.outer(d, d))


def combine(parts: Sequence[MassProperties]) -> MassProperties:
    """Mass properties of an assembly of rigid parts (parallel-axis theorem)."""
    mass = sum(p.mass for p in parts)
    com = sum(p.mass * p.center_of_mass for p in parts) / mass
    inertia = sum(translate_inertia(p.inertia, p.mass, p.center_of_mass - com) for p in parts)
    return MassProperties(
        mass=mass,
        center_of_mass=np.asarray(com, float),
        inertia=np.asarray(inertia, float),
        measure=sum(p.measure for p in parts),
    )


def principal_axes(inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments (ascending) and axes of a symmetric inertia tensor.

    Returns
    -------
    moments : (3,) float
        kg m², ascending.
    axes : (3, 3) float
        Columns are the principal axes in the model frame, right-handed (det = +1), each of
        the first two with its largest-magnitude component positive, so that
        ``axes.T @ inertia @ axes = diag(moments)``.
    """
    moments, axes = np.linalg.eigh(0.5 * (inertia + np.transpose(inertia)))
    for k in range(2):
        if axes[np.argmax(np.abs(axes[:, k])), k] < 0:
            axes[:, k] = -axes[:, k]
    axes[:, 2] = np.cross(axes[:, 0], axes[:, 1])
    return moments, axes
