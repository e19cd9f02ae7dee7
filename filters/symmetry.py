"""Rotational symmetry of a facet model and attitude errors modulo that symmetry.

A proper rotation ``R`` (body frame) that maps the facet set of a shape onto itself —
centroids, normals, areas, materials, and the tangent directions of anisotropic materials —
and leaves the inertia tensor unchanged (``R J Rᵀ = J``) makes two attitudes
indistinguishable for all time: with ``A(q') = R A(q)`` and ``ω' = R ω`` the body-frame Sun
and observer directions become ``R L`` and ``R V``, the rendered flux of the rotated shape is
the flux of the shape itself, and torque-free motion maps onto torque-free motion. Light
curves therefore determine the attitude only up to the group ``G`` of such rotations: a
box with three different sides and one material has ``|G| = 4``, a cube 24, and a body of
revolution a continuous group about its axis.

:func:`symmetry_group` finds ``G`` from plain arrays (this package imports no shape code):
rotation candidates come from matching a pair of rotation-invariant facet descriptors
(material, area, distance of the centroid from the centre of mass, height of the facet
plane), and each candidate is verified on every facet with a k-d tree. A cyclic subgroup
about one axis of order ≥ ``continuous_order`` (a facetted cylinder, cone or rocket body) is
reported as a continuous symmetry about that axis.

:class:`SymmetryGroup` gives the symmetry-equivalent attitudes and rates of an estimate and
the attitude error modulo ``G`` (for a continuous axis ``a``: the angle between the inertial
directions ``A(q)ᵀ a`` of the two attitudes, minimised over the discrete part).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from filters.attitude import (
    attitude_angle,
    attitude_matrix,
    quaternion_conjugate,
    quaternion_from_matrix,
    quaternion_multiply,
    quaternion_to_rotation_vector,
)

__all__ = ["SymmetryGroup", "symmetry_group"]

#: Cyclic subgroups of at least this order about one axis are treated as continuous.
CONTINUOUS_ORDER = 8


@dataclass(frozen=True)
class SymmetryGroup:
    """A finite group of body-frame rotations, possibly with a continuous axis.

    Attributes
    ----------
    rotations : (G, 3, 3) numpy.ndarray
        Proper rotations ``R`` (``v' = R v`` in the body frame), identity first.
    axis : (3,) numpy.ndarray or None
        Unit axis of a continuous rotational symmetry (body frame), if any.
    reflections : (H, 3, 3) numpy.ndarray
        Improper symmetries ``M`` (det −1, mirror planes and rotoreflections) of the facet
        set and inertia; they cause the *mirror ambiguity* (:meth:`mirror_twin`).
    """

    rotations: np.ndarray
    axis: np.ndarray | None = None
    reflections: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))

    @property
    def order(self) -> int:
        """Number of discrete elements ``|G|`` (the continuous part not counted)."""
        return len(self.rotations)

    @property
    def quaternions(self) -> np.ndarray:
        """(G, 4) quaternions ``s`` with ``A(s) = R`` (sign-canonical)."""
        return quaternion_from_matrix(self.rotations)

    @property
    def is_trivial(self) -> bool:
        """Only the identity, no continuous axis."""
        return self.order == 1 and self.axis is None

    def equivalent_attitudes(self, q: Any) -> np.ndarray:
        """Attitudes ``s_g ⊗ q`` indistinguishable from ``q`` (``A = R_g A(q)``).

        Parameters
        ----------
        q : (..., 4) array

        Returns
        -------
        (G, ..., 4) numpy.ndarray
            Identity first; for a continuous axis only the discrete representatives.
        """
        q = np.asarray(q, dtype=float)
        s = self.quaternions.reshape((self.order,) + (1,) * (q.ndim - 1) + (4,))
        return quaternion_multiply(s, q)

    def equivalent_rates(self, omega: Any) -> np.ndarray:
        """Body rates ``R_g ω`` that go with :meth:`equivalent_attitudes`.

        Parameters
        ----------
        omega : (..., 3) array
            rad/s, body frame.

        Returns
        -------
        (G, ..., 3) numpy.ndarray
        """
        omega = np.asarray(omega, dtype=float)
        return np.einsum("gij,...j->g...i", self.rotations, omega)

    def closest(self, q_reference: Any, q: Any) -> tuple[np.ndarray, np.ndarray]:
        """The symmetry-equivalent of ``q`` nearest to ``q_reference`` and its group index.

        Parameters
        ----------
        q_reference, q : (..., 4) array

        Returns
        -------
        q_equivalent : (..., 4) numpy.ndarray
        index : (...) int numpy.ndarray
            Element ``g`` of :attr:`rotations` used (``q_equivalent = s_g ⊗ q``).
        """
        q_reference, q = np.broadcast_arrays(
            np.asarray(q_reference, dtype=float), np.asarray(q, dtype=float)
        )
        return _nearest(q_reference, self.equivalent_attitudes(q))

    def nearest_equivalent(self, q_reference: Any, q: Any) -> tuple[np.ndarray, np.ndarray]:
        """The state of the group's orbit of ``q`` nearest ``q_reference``, and its rotation.

        As :meth:`closest`, and with a continuous axis ``a`` each discrete representative is
        also turned about ``a`` by the angle that brings it nearest the reference: with
        ``d = c ⊗ q_ref⁻¹`` the scalar part of ``r ⊗ d``, ``r = [a sin(φ/2), cos(φ/2)]``, is
        ``cos(φ/2) d4 − sin(φ/2) a·d_v``, largest in magnitude at ``(sin, cos) ∝ (−a·d_v,
        d4)``. The remaining angle is then :meth:`attitude_error`'s.

        Parameters
        ----------
        q_reference, q : (..., 4) array

        Returns
        -------
        q_equivalent : (..., 4) numpy.ndarray
        rotation : (..., 3, 3) numpy.ndarray
            Body-frame rotation ``R`` with ``A(q_equivalent) = R A(q)``; body rates and
            body-frame errors of ``q`` map to those of ``q_equivalent`` by ``R``.
        """
        q_reference, q = np.broadcast_arrays(
            np.asarray(q_reference, dtype=float), np.asarray(q, dtype=float)
        )
        candidates = self.equivalent_attitudes(q)
        if self.axis is not None:
            d = quaternion_multiply(candidates, quaternion_conjugate(q_reference)[None])
            along = d[..., :3] @ self.axis
            norm = np.hypot(along, d[..., 3])
            safe = np.where(norm > 0, norm, 1.0)
            sin = np.where(norm > 0, -along / safe, 0.0)
            cos = np.where(norm > 0, d[..., 3] / safe, 1.0)
            twist = np.concatenate([sin[..., None] * self.axis, cos[..., None]], axis=-1)
            candidates = quaternion_multiply(twist, candidates)
        picked, _ = _nearest(q_reference, candidates)
        return picked, attitude_matrix(picked) @ np.swapaxes(attitude_matrix(q), -1, -2)

    def attitude_error(self, q_estimate: Any, q_true: Any) -> np.ndarray:
        """Attitude error (rad) modulo the group.

        Discrete group: ``min_g angle(q̂, s_g ⊗ q)``. With a continuous axis ``a``: the
        smallest angle between ``A(q̂)ᵀ a`` and ``A(s_g ⊗ q)ᵀ a`` over ``g`` (rotations
        about the axis itself are unobservable and not counted).

        Parameters
        ----------
        q_estimate, q_true : (..., 4) array

        Returns
        -------
        (...) numpy.ndarray
            Radians in ``[0, π]``.
        """
        q_estimate, q_true = np.broadcast_arrays(
            np.asarray(q_estimate, dtype=float), np.asarray(q_true, dtype=float)
        )
        candidates = self.equivalent_attitudes(q_true)
        if self.axis is None:
            return np.min(attitude_angle(q_estimate[None], candidates), axis=0)
        axis_estimate = np.swapaxes(attitude_matrix(q_estimate), -1, -2) @ self.axis
        axis_true = np.swapaxes(attitude_matrix(candidates), -1, -2) @ self.axis
        cosine = np.clip(np.sum(axis_estimate[None] * axis_true, axis=-1), -1.0, 1.0)
        return np.min(np.arccos(cosine), axis=0)

    def rate_error(
        self, q_estimate: Any, omega_estimate: Any, q_true: Any, omega_true: Any
    ) -> np.ndarray:
        """Norm of ``ω̂ − R_g ω`` (rad/s) for the element ``g`` closest in attitude.

        Parameters
        ----------
        q_estimate, omega_estimate, q_true, omega_true : arrays
            ``(..., 4)`` and ``(..., 3)``.

        Returns
        -------
        (...) numpy.ndarray
        """
        _, index = self.closest(q_estimate, q_true)
        rates = self.equivalent_rates(np.broadcast_to(omega_true, (*index.shape, 3)))
        picked = np.take_along_axis(rates, np.asarray(index)[None, ..., None], axis=0)[0]
        return np.linalg.norm(np.asarray(omega_estimate, dtype=float) - picked, axis=-1)

    def mirror_twin(
        self, q: Any, omega: Any, sun: Any, observer: Any
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """The state that mirrors ``(q, ω)`` in a mirror-symmetric shape.

        With an improper symmetry ``M`` of the shape and ``P = I − 2 n nᵀ`` the reflection
        across the plane of the Sun and observer directions (``n ∝ ŝ × ô``), the attitude
        ``A' = M A(q) P`` sees the Sun and the observer at ``M L`` and ``M V`` in the body
        frame, so it renders the same brightness, and ``ω' = −M ω`` keeps it torque-free
        (``M J Mᵀ = J``). The twin's light curve matches exactly while the geometry stands
        still and drifts away as the Sun–observer plane turns: the photometric mirror
        ambiguity, resolved only by long arcs.

        Parameters
        ----------
        q : (..., 4) array
        omega : (..., 3) array
            rad/s.
        sun, observer : (3,) array
            Object → Sun and object → observer directions (inertial) at the epoch of
            ``q``.

        Returns
        -------
        (q', ω') : numpy arrays, or None when the shape has no improper symmetry.
        """
        if len(self.reflections) == 0:
            return None
        normal = np.cross(np.asarray(sun, float), np.asarray(observer, float))
        normal /= np.linalg.norm(normal)
        plane = np.eye(3) - 2.0 * np.outer(normal, normal)
        mirror = self.reflections[0]
        twin = mirror @ attitude_matrix(np.asarray(q, dtype=float)) @ plane
        return quaternion_from_matrix(twin), -np.asarray(omega, dtype=float) @ mirror.T

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description: order, axis, quaternions, number of reflections."""
        return {
            "order": self.order,
            "continuous_axis": None if self.axis is None else self.axis.tolist(),
            "quaternions": self.quaternions.tolist(),
            "reflections": len(self.reflections),
        }


def symmetry_group(
    centroids: Any,
    normals: Any,
    areas: Any,
    *,
    labels: Any = None,
    tangents: Any = None,
    anisotropic: Any = None,
    inertia: Any = None,
    vertices: Any = None,
    tolerance: float = 1e-5,
    continuous_order: int = CONTINUOUS_ORDER,
) -> SymmetryGroup:
    """Proper rotations mapping a facet set (and its materials and inertia) onto itself.

    Parameters
    ----------
    centroids : (K, 3) array
        Facet centroids relative to the centre of mass (body frame, any length unit).
    normals : (K, 3) array
        Outward unit normals.
    areas : (K,) array
        Facet areas.
    labels : (K,) int array, optional
        Material of each facet (all equal when omitted).
    tangents : (K, 3) array, optional
        Material reference tangents; checked (up to sign) where ``anisotropic`` is true.
    anisotropic : (K,) bool array, optional
        Facets whose BRDF depends on the tangent direction.
    inertia : (3, 3) array, optional
        Body-frame inertia; rotations must satisfy ``R J Rᵀ = J`` (relative tolerance 1e-3).
    vertices : (V, 3) array, optional
        Mesh vertices relative to the centre of mass. They must map onto themselves too,
        which keeps the outline of flat parts (merged coplanar facets forget it): a 2 × 1 m
        plate then has a 180° symmetry about its normal, not a continuous one.
    tolerance : float
        Matching tolerance, relative to the model size (positions), to the largest area
        (areas) and absolute on unit vectors.
    continuous_order : int
        Order from which a cyclic subgroup about one axis is reported as continuous.

    Returns
    -------
    SymmetryGroup
    """
    c = np.asarray(centroids, dtype=float)
    n = np.asarray(normals, dtype=float)
    a = np.asarray(areas, dtype=float)
    k = len(a)
    labels = np.zeros(k, dtype=int) if labels is None else np.asarray(labels, dtype=int)
    if tangents is not None:
        tangents = np.asarray(tangents, dtype=float)
    if vertices is not None:
        # Vertices join as pseudo-facets: no normal, no area, their own label.
        v = np.unique(np.asarray(vertices, dtype=float), axis=0)
        c = np.concatenate([c, v])
        n = np.concatenate([n, np.zeros_like(v)])
        a = np.concatenate([a, np.zeros(len(v))])
        labels = np.concatenate([labels, np.full(len(v), -1)])
        if tangents is not None:
            tangents = np.concatenate([tangents, np.zeros_like(v)])
        if anisotropic is not None:
            anisotropic = np.concatenate([np.asarray(anisotropic, bool), np.zeros(len(v), bool)])
    scale = max(float(np.max(np.linalg.norm(c, axis=1))), 1e-300)
    cs = c / scale
    area_scale = float(np.max(a))
    # Rotation-invariant descriptors of each facet.
    descriptors = np.stack(
        [a / area_scale, np.linalg.norm(cs, axis=1), np.sum(cs * n, axis=1)], axis=1
    )
    descriptors = np.concatenate([descriptors, labels[:, None] * 10.0], axis=1)
    tree = cKDTree(descriptors)
    classes = tree.query_ball_point(descriptors, r=tolerance, p=np.inf)
    vectors, owners = _candidate_vectors(cs, n, tolerance)
    first, second = _reference_pair(vectors, owners, classes, tolerance)
    if first is None:
        # Every facet vector is parallel to one line (a degenerate model): only identity.
        return SymmetryGroup(np.eye(3)[None])
    verify = _Verifier(
        cs,
        n,
        a / area_scale,
        labels=labels,
        tangents=tangents,
        anisotropic=anisotropic,
        inertia=inertia,
        tolerance=tolerance,
    )
    pair = (first, second)
    rotations = _matches(
        np.eye(3), pair, vectors, owners, classes, verify=verify, tolerance=tolerance
    )
    reflections = _matches(
        np.diag([1.0, 1.0, -1.0]),
        pair,
        vectors,
        owners,
        classes,
        verify=verify,
        tolerance=tolerance,
    )
    rotations = np.stack(rotations)
    return SymmetryGroup(
        rotations,
        _continuous_axis(rotations, continuous_order),
        np.stack(reflections) if reflections else np.zeros((0, 3, 3)),
    )


def _matches(base, pair, vectors, owners, classes, *, verify, tolerance) -> list[np.ndarray]:
    """Symmetries ``R B`` (``R`` proper) of the facet set, ``B`` the identity (rotations)
    or a reflection (improper symmetries): ``R`` maps the reflected reference pair onto
    every matching pair and is kept when it passes ``verify``."""
    first, second = pair
    v1, v2 = base @ vectors[first], base @ vectors[second]
    found = [np.eye(3)] if np.allclose(base, np.eye(3)) else []
    for j in _matching_vectors(first, vectors, owners, classes):
        for m in _matching_vectors(second, vectors, owners, classes):
            if abs(vectors[j] @ vectors[m] - v1 @ v2) > 10 * tolerance:
                continue
            r = _triad(v1, v2, vectors[j], vectors[m])
            if r is None:
                continue
            element = r @ base
            if any(np.allclose(element, known, atol=1e-6) for known in found):
                continue
            if verify(element):
                found.append(element)
    return found


def _candidate_vectors(cs: np.ndarray, n: np.ndarray, tolerance: float):
    """Unit normals and non-zero unit centroid directions, with the facet owning each.

    Vectors of kind 0 are normals and of kind 1 centroid directions; a rotation must map a
    vector onto a vector of the same kind, so the kind is folded into ``owners``.
    """
    norms = np.linalg.norm(cs, axis=1)
    keep = norms > tolerance
    has_normal = np.linalg.norm(n, axis=1) > 0.5
    vectors = np.concatenate([n[has_normal], cs[keep] / norms[keep, None]])
    owners = np.concatenate(
        [
            np.stack([np.flatnonzero(has_normal), np.zeros(int(has_normal.sum()), int)], 1),
            np.stack([np.flatnonzero(keep), np.ones(int(keep.sum()), int)], 1),
        ]
    )
    return vectors, owners


def _reference_pair(vectors, owners, classes, tolerance):
    """Two non-parallel vectors from the facets with the smallest descriptor classes."""
    size = np.array([len(classes[f]) for f in owners[:, 0]])
    order = np.argsort(size, kind="stable")
    first = int(order[0])
    for second in order[1:]:
        if np.linalg.norm(np.cross(vectors[first], vectors[second])) > 1e3 * tolerance:
            return first, int(second)
    return None, None


def _matching_vectors(index, vectors, owners, classes):
    """Vectors of the same kind owned by facets in the descriptor class of ``index``'s facet."""
    facet, kind = owners[index]
    members = set(classes[facet])
    return [i for i in range(len(vectors)) if owners[i, 1] == kind and owners[i, 0] in members]


def _triad(u1, u2, w1, w2):
    """Rotation ``R`` with ``R u1 = w1`` and ``R u2`` in the half-plane of ``w2`` (TRIAD)."""

    def frame(x, y):
        z = np.cross(x, y)
        norm = np.linalg.norm(z)
        if norm < 1e-9:
            return None
        z /= norm
        return np.stack([x, np.cross(z, x), z], axis=1)

    f, g = frame(u1, u2), frame(w1, w2)
    if f is None or g is None:
        return None
    return g @ f.T


class _Verifier:
    """Checks a candidate rotation against every facet (and the inertia)."""

    def __init__(self, cs, n, a, *, labels, tangents, anisotropic, inertia, tolerance):
        self.cs, self.n, self.a, self.labels = cs, n, a, labels
        self.tree = cKDTree(np.concatenate([cs, n], axis=1))
        self.tangents = None if tangents is None else np.asarray(tangents, dtype=float)
        self.anisotropic = (
            np.zeros(len(a), bool) if anisotropic is None else np.asarray(anisotropic, bool)
        )
        self.inertia = None if inertia is None else np.asarray(inertia, dtype=float)
        self.tolerance = tolerance

    def __call__(self, r: np.ndarray) -> bool:
        if self.inertia is not None:
            rotated = r @ self.inertia @ r.T
            if np.max(np.abs(rotated - self.inertia)) > 1e-3 * np.max(np.abs(self.inertia)):
                return False
        moved = np.concatenate([self.cs @ r.T, self.n @ r.T], axis=1)
        distance, match = self.tree.query(moved)
        if np.any(distance > 10 * self.tolerance):
            return False
        if np.any(self.labels[match] != self.labels) or np.any(
            np.abs(self.a[match] - self.a) > 10 * self.tolerance
        ):
            return False
        if self.tangents is not None and self.anisotropic.any():
            rows = np.flatnonzero(self.anisotropic)
            dots = np.abs(np.sum((self.tangents[rows] @ r.T) * self.tangents[match[rows]], 1))
            if np.any(dots < 1 - 10 * self.tolerance):
                return False
        return True


def _continuous_axis(rotations: np.ndarray, continuous_order: int) -> np.ndarray | None:
    """Axis shared by at least ``continuous_order − 1`` non-identity elements, if any."""
    rotvec = quaternion_to_rotation_vector(quaternion_from_matrix(rotations[1:]))
    angles = np.linalg.norm(rotvec, axis=1)
    if len(angles) + 1 < continuous_order:
        return None
    axes = rotvec / np.maximum(angles, 1e-300)[:, None]
    for axis in axes:
        same = np.abs(axes @ axis) > 1 - 1e-6
        if same.sum() + 1 >= continuous_order:
            return axis * np.sign(axis[np.argmax(np.abs(axis))])
    return None


def _nearest(q_reference: np.ndarray, candidates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The candidate ``(G, ..., 4)`` nearest ``q_reference`` at every index, and which."""
    angles = attitude_angle(q_reference[None], candidates)
    index = np.argmin(angles, axis=0)
    return np.take_along_axis(candidates, index[None, ..., None], axis=0)[0], index
