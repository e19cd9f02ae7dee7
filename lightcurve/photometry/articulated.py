"""Rendering of articulated shapes: every rigid group rendered in its own frame, fluxes summed.

An articulated shape (:class:`shapes.articulation.ArticulatedModel`) splits into rigid
groups: the body (groups no part names, and ``fixed`` parts) and each moving part. At every
epoch the joints give the part → body rotation ``R_g`` from the body-frame Sun direction
(and observation-file columns for ``scheduled`` joints). The flux is a sum over facets, so
it is the sum over groups of each group's flux with the body-frame Sun and observer vectors
carried into the group's frame, ``R_gᵀ A(q) s`` and ``R_gᵀ A(q) o``: each group is rendered
by an ordinary :class:`~lightcurve.photometry.render.Renderer` (fused kernels, its own materials)
with per-row directions, and the rigid path is untouched.

Shadow modes
------------
``"none"``
    No self-shadowing (each group's facets only need to face the Sun and the observer).
``"exact"``
    A facet point counts when it is both lit and seen, ray cast every epoch against all
    groups in their current pose (:class:`shapes.visibility.posed.PosedShadows`): shadows
    cast by one part on another follow the joints. The reference; costs ray casts per epoch.
``"table"``
    Each group's own visibility table (built once, in the group's frame, where it stays
    valid whatever the joint angles): shadowing *within* a rigid group is kept,
    shadowing *between* groups is neglected. Exact when parts never shadow one another
    (e.g. arrays on long yokes away from the Sun-facing side of the bus); otherwise it
    over-estimates the flux by the area one group hides of another.
``"auto"``
    ``"exact"`` when the shape has more than one rigid group or a self-shadowing group,
    else ``"none"``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numba import njit

from filters.attitude import rotate
from lightcurve.photometry.render import Renderer, flux_to_magnitude
from shapes.articulation import ArticulatedModel, axis_rotation
from shapes.visibility import DEFAULT_SAMPLES, build_visibility_table
from shapes.visibility.posed import PosedShadows

__all__ = ["ARTICULATED_SHADOW_MODES", "ArticulatedRenderer", "scheduled_columns"]

ARTICULATED_SHADOW_MODES = ("auto", "none", "table", "exact")


class ArticulatedRenderer:
    """Renders an articulated shape for batches of attitudes and geometries.

    Parameters
    ----------
    shape : ArticulatedModel
    shadows : {"auto", "none", "table", "exact"}
        See the module docstring.
    samples : int
        Ray origins per effective facet for ``"exact"`` (and the tables of ``"table"``).
    **options
        Passed to every group's :class:`~lightcurve.photometry.render.Renderer` (``dtype``,
        ``backend``, ...).
    """

    def __init__(
        self,
        shape: ArticulatedModel,
        shadows: str = "auto",
        samples: int = DEFAULT_SAMPLES,
        **options: Any,
    ) -> None:
        if shadows not in ARTICULATED_SHADOW_MODES:
            raise ValueError(
                f"shadows must be one of {', '.join(ARTICULATED_SHADOW_MODES)}, got {shadows!r}"
            )
        self.shape = shape
        groups = shape.rigid_groups()
        self._has_body = bool(np.any(shape.facet_part() == -1))
        if shadows == "auto":
            alone = len(groups) == 1 and groups[0].is_convex
            shadows = "none" if alone else "exact"
        self.shadows = shadows
        self.groups = groups
        pivots = [np.zeros(3)] * self._has_body + [p.joint.pivot for p in self._moving]
        if shadows == "table":
            groups = [
                g if g.is_convex else g.with_visibility(build_visibility_table(g, samples=samples))
                for g in groups
            ]
        mode = "auto" if shadows == "table" else "none"
        self.renderers = [Renderer(g, shadows=mode, **options) for g in groups]
        self._shadows = PosedShadows(groups, pivots, samples) if shadows == "exact" else None

    @property
    def _moving(self) -> list[Any]:
        return self.shape.articulation.moving

    def joint_angles(
        self, q: Any, sun: Any, columns: Mapping[str, Any] | None = None
    ) -> np.ndarray:
        """Angle of every part's joint, degrees, ``(n_parts, ...)``.

        Parameters
        ----------
        q : (..., 4) array
            Attitudes (inertial → body).
        sun : (..., 3) array
            Object → Sun vectors, inertial frame.
        columns : mapping, optional
            Observation-file columns (``scheduled`` joints), each broadcast against ``q``.
        """
        sun_body = rotate(np.asarray(q, float), np.asarray(sun, float))
        return self.shape.articulation.joint_angles(sun_body, columns)

    def flux(
        self,
        q: Any,
        sun: Any,
        observer: Any,
        columns: Mapping[str, Any] | None = None,
        *,
        joint_sun: Any | None = None,
    ) -> np.ndarray:
        """Flux ratio ``F_obs / F_sun``, shape of the broadcast leading axes.

        Parameters are those of :meth:`Renderer.flux <lightcurve.photometry.render.Renderer.flux>`
        (numpy), plus ``columns`` for ``scheduled`` joints and ``joint_sun``, the object → Sun
        vectors that drive ``sun_tracking`` joints when the light is another source's (the
        Earth's, :mod:`lightcurve.photometry.earthshine`; default ``sun``).
        """
        q, sun, observer = (np.asarray(v, float) for v in (q, sun, observer))
        pose_sun = sun if joint_sun is None else np.asarray(joint_sun, float)
        shape = np.broadcast_shapes(
            q.shape[:-1], sun.shape[:-1], observer.shape[:-1], pose_sun.shape[:-1]
        )
        q, sun, observer, pose_sun = (_rows(v, shape) for v in (q, sun, observer, pose_sun))
        if columns is not None:
            columns = {
                k: np.broadcast_to(np.asarray(v, float), shape).ravel() for k, v in columns.items()
            }
        moving = self._moving
        sun_body = _to_body(q, sun)
        pose_body = sun_body if joint_sun is None else _to_body(q, pose_sun)
        angles = [p.joint.angles(pose_body, columns, f"part {p.name!r}") for p in moving]  # deg
        attitudes = [q] * self._has_body + [
            _joint_attitude(p.joint.axis, a, q) for p, a in zip(moving, angles, strict=True)
        ]
        if self._shadows is None:
            total = sum(
                r.flux(a, sun, observer) for r, a in zip(self.renderers, attitudes, strict=True)
            )
            return np.asarray(total).reshape(shape)
        sun, observer = np.array(sun), np.array(observer)  # writable for torch
        attitudes = [np.array(a) for a in attitudes]
        rotations = np.stack(
            [np.broadcast_to(np.eye(3), (len(q), 3, 3))] * self._has_body
            + [
                axis_rotation(p.joint.axis, np.radians(a))
                for p, a in zip(moving, angles, strict=True)
            ]
        )
        obs_body = _to_body(q, observer)
        fractions = self._shadows.fractions(
            rotations,
            sun_body / np.linalg.norm(sun_body, axis=1, keepdims=True),
            obs_body / np.linalg.norm(obs_body, axis=1, keepdims=True),
        )
        total = sum(
            np.sum(r.facet_flux(a, sun, observer) * f, axis=-1)
            for r, a, f in zip(self.renderers, attitudes, fractions, strict=True)
        )
        return np.asarray(total).reshape(shape)

    def magnitude(
        self, q: Any, sun: Any, observer: Any, columns: Mapping[str, Any] | None = None
    ) -> np.ndarray:
        """Apparent magnitude (``inf`` when dark); parameters of :meth:`flux`."""
        return flux_to_magnitude(self.flux(q, sun, observer, columns))


def scheduled_columns(shape: ArticulatedModel, table: Any) -> dict[str, np.ndarray]:
    """The observation-table columns that ``shape``'s ``scheduled`` joints read (degrees),
    those present in ``table`` (a missing one is named by the joint when it is rendered)."""
    return {
        p.joint.column: table[p.joint.column].to_numpy(float)
        for p in shape.articulation.parts
        if p.joint.column is not None and p.joint.column in table
    }


_JIT = {"error_model": "numpy", "nogil": True, "cache": True}


def _to_body(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``A(q) v`` for rows of quaternions and vectors (the attitude core's
    :func:`~filters.attitude.rotate`: ``v − 2 q₄ (q_v × v) + 2 q_v × (q_v × v)``), one
    compiled pass."""
    out = np.empty(v.shape)
    _to_body_rows(np.ascontiguousarray(q), np.ascontiguousarray(v), out)
    return out


@njit(**_JIT)
def _to_body_rows(q, v, out):  # pragma: no cover - compiled
    for r in range(q.shape[0]):
        x, y, z, w = q[r, 0], q[r, 1], q[r, 2], q[r, 3]
        vx, vy, vz = v[r, 0], v[r, 1], v[r, 2]
        tx, ty, tz = 2.0 * (y * vz - z * vy), 2.0 * (z * vx - x * vz), 2.0 * (x * vy - y * vx)
        out[r, 0] = vx - w * tx + (y * tz - z * ty)
        out[r, 1] = vy - w * ty + (z * tx - x * tz)
        out[r, 2] = vz - w * tz + (x * ty - y * tx)


def _joint_attitude(axis: np.ndarray, angle: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Attitude of a part's frame, ``A(q_g) = R(θ)ᵀ A(q)``: ``q_g = [a sin(θ/2), cos(θ/2)] ⊗ q``,
    i.e. ``[c q_v + s (q₄ a − a × q_v), c q₄ − s a·q_v]`` with ``c, s = cos, sin(θ/2)``.

    Parameters
    ----------
    axis : (3,) float
        Unit joint axis, body frame.
    angle : (N,) float
        Joint angles, degrees.
    q : (N, 4) float
        Body attitudes (inertial → body).
    """
    out = np.empty(q.shape)
    ax, ay, az = (float(v) for v in axis)
    _joint_attitude_rows(ax, ay, az, np.ascontiguousarray(angle), np.ascontiguousarray(q), out)
    return out


@njit(**_JIT)
def _joint_attitude_rows(ax, ay, az, angle, q, out):  # pragma: no cover - compiled
    for r in range(q.shape[0]):
        half = 0.5 * math.radians(angle[r])
        s, c = math.sin(half), math.cos(half)
        x, y, z, w = q[r, 0], q[r, 1], q[r, 2], q[r, 3]
        out[r, 0] = c * x + s * (w * ax - (ay * z - az * y))
        out[r, 1] = c * y + s * (w * ay - (az * x - ax * z))
        out[r, 2] = c * z + s * (w * az - (ax * y - ay * x))
        out[r, 3] = c * w - s * (ax * x + ay * y + az * z)


def _rows(value: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as C-ordered ``(rows, n)`` rows of ``shape``, copied only when broadcast."""
    if value.shape[:-1] != shape:
        value = np.broadcast_to(value, (*shape, value.shape[-1])).copy()
    return np.ascontiguousarray(value.reshape(-1, value.shape[-1]))
