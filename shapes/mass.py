"""Mass properties of triangle soups: uniform solids, thin shells, assemblies, principal axes.

Functions take ``triangles : (n, 3, 3) float`` in metres and return :class:`MassProperties`
with the inertia tensor ``J = ∫ (|r|² I − r rᵀ) dm`` about the centre of mass, in the frame of
the input coordinates (kg m²).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

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

    The solid is cut into signed tetrahedra, one per triangle ``(a, b, c)`` with a common apex
    (the mean vertex, see :func:`_reference_point`); with the corners taken relative to it,
    each has the signed volume ``V = a · (b × c) / 6``, the first moment ``V (a + b + c) / 4``
    and the second moment ``∫ r rᵀ dV = V / 20 (a aᵀ + b bᵀ + c cᵀ + s sᵀ)``,
    ``s = a + b + c``, exact for any tetrahedron (Tonon 2004, "Explicit exact formulas for
    the 3-D tetrahedron inertia tensor in terms of its vertex coordinates", Journal of
    Mathematics and Statistics 1(1), 8–11). The parts outside the solid cancel. numpy only:
    the convex command computes its shape's properties with this without importing trimesh.

    Parameters
    ----------
    triangles : (n, 3, 3) float
        Vertices of each facet, m. The surface must be closed and wound outward.
    density : float
        kg/m³.

    Raises
    ------
    ValueError
        If the mesh encloses no volume (empty, flat or wound inward).
    """
    tri = np.asarray(triangles, float)
    origin = _reference_point(tri)
    corners = tri - origin
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    signed = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0
    volume = float(signed.sum())
    if not volume > 0:
        raise ValueError(f"the mesh encloses no volume (signed volume {volume:.3g})")
    s = a + b + c
    offset = signed @ s / (4.0 * volume)
    second = (
        np.einsum("t,tki,tkj->ij", signed, corners, corners)
        + np.einsum("t,ti,tj->ij", signed, s, s)
    ) / 20.0
    central = density * (second - volume * np.outer(offset, offset))
    central = 0.5 * (central + central.T)
    return MassProperties(
        mass=density * volume,
        center_of_mass=origin + offset,
        inertia=np.trace(central) * np.eye(3) - central,
        measure=volume,
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
    origin = _reference_point(tri)
    tri = tri - origin
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
        center_of_mass=com + origin,
        inertia=np.trace(central) * np.eye(3) - central,
        measure=total_area,
    )


def _reference_point(triangles: np.ndarray) -> np.ndarray:
    """Mean vertex of a triangle soup: the point the moments are integrated about.

    About a distant origin the second moments are ``≈ m |d|²`` and the central inertia is
    their small difference: the principal moments of a 2 m box 80 m from the origin came
    out to 1e-9 only. About a point of the body the integrals keep full precision, and the
    result no longer depends on where the model happens to sit.
    """
    points = triangles.reshape(-1, 3)
    return points.mean(axis=0) if len(points) else np.zeros(3)


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


def principal_axes(inertia: np.ndarray, rtol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments (ascending) and axes of a symmetric inertia tensor.

    The axes are canonical: they depend on the tensor only, not on the eigenvectors the
    eigensolver happens to return (which, where moments are equal, change with the BLAS
    kernels of the processor). Moments within ``rtol`` of the largest count as equal; any
    basis of their common eigenspace is principal, and the one returned is the model axes
    projected on that eigenspace and orthonormalised in order, so that model axes lying in it
    are kept (a cube's or a sphere's principal axes are x, y, z; a cylinder's about z keeps x and
    y). Each of the first two axes has its largest-magnitude component positive (the first
    such component where several are equal within ``rtol``); the third completes a
    right-handed frame.

    Parameters
    ----------
    inertia : (3, 3) float
        Symmetric inertia tensor, kg m².
    rtol : float
        Relative tolerance on moments (and component magnitudes) counted as equal.

    Returns
    -------
    moments : (3,) float
        kg m², ascending.
    axes : (3, 3) float
        Columns are the principal axes in the model frame, right-handed (det = +1), so that
        ``axes.T @ inertia @ axes = diag(moments)``.
    """
    moments, vectors = np.linalg.eigh(0.5 * (inertia + np.transpose(inertia)))
    axes = np.array(vectors)
    scale = max(float(np.max(np.abs(moments))), np.finfo(float).tiny)
    start = 0
    for k in range(1, 4):
        if k == 3 or moments[k] - moments[k - 1] > rtol * scale:
            if k - start > 1:
                axes[:, start:k] = _canonical_eigenbasis(vectors[:, start:k])
            start = k
    for k in range(2):
        magnitude = np.abs(axes[:, k])
        lead = int(np.flatnonzero(magnitude >= (1.0 - rtol) * magnitude.max())[0])
        if axes[lead, k] < 0:
            axes[:, k] = -axes[:, k]
    axes[:, 2] = np.cross(axes[:, 0], axes[:, 1])
    return moments, axes


def _canonical_eigenbasis(basis: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Orthonormal basis of the column space of ``basis`` that depends on the space only.

    The space's projector ``P = B Bᵀ`` (``B`` orthonormal) is unique; the model axes
    ``P e_x, P e_y, P e_z`` are orthonormalised in that order (Gram–Schmidt), skipping any
    that lie (within ``tol``) in the span of those before, until the space is spanned. Model
    axes that lie in the space are therefore returned as they are.
    """
    projector = basis @ basis.T
    out: list[np.ndarray] = []
    for axis in projector.T:
        v = axis - sum((u @ axis) * u for u in out) if out else axis
        norm = np.linalg.norm(v)
        if norm > tol:
            out.append(v / norm)
        if len(out) == basis.shape[1]:
            break
    return np.stack(out, axis=1)
