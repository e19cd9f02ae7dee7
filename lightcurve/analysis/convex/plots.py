"""Figures of a convex inversion: model against observed light curves, and the shape.

Both are drawn with matplotlib's Agg canvas directly (no pyplot, no 3-D toolkit): a convex
body seen from far away shows only the facets that face the viewer, and those never overlap,
so its picture is one :class:`~matplotlib.collections.PolyCollection` of their orthographic
projections, with no depth sorting.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

import numpy as np

from lightcurve.analysis.convex.data import Photometry

__all__ = ["plot_fit", "plot_shape"]


def _figure(width: float, height: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width, height))
    FigureCanvasAgg(figure)
    return figure


def _save(figure, path: str | os.PathLike[str], dpi: int) -> None:
    from lightcurve.io.atomic import atomic_path

    with atomic_path(path, suffix=".png") as tmp:
        figure.savefig(tmp, format="png", dpi=dpi)


def plot_fit(
    data: Photometry,
    model: np.ndarray,
    path: str | os.PathLike[str],
    panels: int = 6,
    dpi: int = 90,
) -> None:
    """Observed (with σ) and model brightness of the longest light curves, against hours
    since each curve's first point; written atomically as PNG.

    Parameters
    ----------
    data : Photometry
    model : (N,) float
        Model brightness at the data's points (same normalisation as ``data.brightness``).
    path : path-like
    panels : int
        Light curves shown (the longest; ties by curve order).
    dpi : int
    """
    counts = np.bincount(data.curve, minlength=data.n_curves)
    # A stable sort: ties among equally long curves go to the lower curve number.
    chosen = np.sort(np.argsort(-counts, kind="stable")[:panels])
    columns = min(3, len(chosen))
    rows = math.ceil(len(chosen) / columns)
    figure = _figure(4 * columns, 2.8 * rows)
    axes = figure.subplots(rows, columns, squeeze=False)
    for ax, label in zip(axes.flat, chosen, strict=False):
        mask = data.curve == label
        hours = (data.mjd[mask] - data.mjd[mask].min()) * 24.0
        ax.errorbar(hours, data.brightness[mask], data.sigma[mask], fmt=".", ms=3, lw=0.5)
        ax.plot(hours, model[mask], "-", color="C3", lw=1.0)
        ax.set_title(f"curve {label}, MJD {data.mjd[mask].min():.1f}", fontsize=9)
        ax.set_xlabel("hours")
    for ax in list(axes.flat)[len(chosen) :]:
        ax.set_visible(False)
    axes[0, 0].set_ylabel("relative brightness")
    figure.subplots_adjust(left=0.07, right=0.98, bottom=0.1, top=0.93, wspace=0.25, hspace=0.5)
    _save(figure, path, dpi)


def plot_shape(
    vertices: np.ndarray,
    faces: np.ndarray,
    path: str | os.PathLike[str],
    *,
    view: Sequence[float] = (1.0, -1.0, 0.6),
    title: str = "convex model",
    size: float = 6.0,
    dpi: int = 100,
) -> None:
    """A convex polyhedron seen from direction ``view`` (body frame, toward the viewer),
    orthographic, shaded by a headlight ``0.35 + 0.65 (n · v̂)`` like
    :func:`shapes.preview.render_preview`, with the body axes drawn from the centre.

    Parameters
    ----------
    vertices : (V, 3) float
        Body frame, any length unit (labelled m).
    faces : (T, 3) int
        Outward triangles of a convex, closed mesh (hidden facets are not sorted away).
    path : path-like
        Output PNG, written atomically.
    view : (3,) float
        Direction from the body to the viewer.
    title : str
    size : float
        Figure size, inches.
    dpi : int
    """
    from matplotlib.collections import PolyCollection

    v = np.asarray(view, float)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or not np.linalg.norm(v) > 0:
        raise ValueError(f"view must be a non-zero 3-vector, got {list(view)}")
    v = v / np.linalg.norm(v)
    # Screen axes: right = up_ref × v (z up unless looking along z), up = v × right.
    reference = np.array([0.0, 0.0, 1.0]) if abs(v[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
    right = np.cross(reference, v)
    right /= np.linalg.norm(right)
    screen = np.stack([right, np.cross(v, right)])
    triangles = np.asarray(vertices, float)[np.asarray(faces)]
    cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    normals = cross / np.maximum(np.linalg.norm(cross, axis=1, keepdims=True), 1e-300)
    facing = normals @ v > 0.0
    shade = (0.35 + 0.65 * (normals[facing] @ v))[:, None] * np.array([[0.12, 0.47, 0.71]])
    figure = _figure(size, size)
    ax = figure.add_axes((0.1, 0.08, 0.85, 0.84))
    ax.add_collection(
        PolyCollection(
            triangles[facing] @ screen.T, facecolors=shade, edgecolors=shade, linewidths=0.3
        )
    )
    flat = np.asarray(vertices, float) @ screen.T
    centre = 0.5 * (flat.min(axis=0) + flat.max(axis=0))
    half = 0.55 * float(np.ptp(flat, axis=0).max())
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_aspect("equal")
    reach = 0.8 * half
    for name, axis in zip("xyz", np.eye(3), strict=True):
        tip = reach * (screen @ axis)
        ax.annotate("", xy=tip, xytext=(0, 0), arrowprops={"arrowstyle": "->", "color": "k"})
        ax.text(*(1.08 * tip), name, ha="center", va="center")
    ax.set_xlabel("m (screen right)")
    ax.set_ylabel("m (screen up)")
    ax.set_title(f"{title}: {len(faces)} facets, view {np.round(v, 3).tolist()}")
    _save(figure, path, dpi)
