"""PNG previews of facet models, coloured by material, seen from a chosen direction."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from shapes.files import atomic_write
from shapes.model import FacetModel

__all__ = ["render_preview"]


def render_preview(
    model: FacetModel,
    path: str | os.PathLike[str],
    view: Sequence[float] = (1.0, -1.0, 0.6),
    *,
    size: float = 6.0,
    dpi: int = 100,
) -> None:
    """Write a PNG of the model seen from direction ``view`` (body frame, toward the viewer).

    Facets facing away from the viewer are culled; the others are drawn in their material's
    colour shaded by ``0.35 + 0.65 (n · v̂)`` (a headlight), with a legend of the materials.

    Parameters
    ----------
    model : FacetModel
    path : path-like
        Output PNG, written atomically.
    view : (3,) float
        Direction from the model to the viewer.
    size : float
        Figure size, inches.
    dpi : int
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    v = np.asarray(view, float)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or not np.linalg.norm(v) > 0:
        raise ValueError(f"view must be a non-zero 3-vector, got {list(view)}")
    v = v / np.linalg.norm(v)
    distinct, group_material = model.distinct_materials
    palette = plt.get_cmap("tab10")
    base = np.array([palette(i % 10)[:3] for i in range(len(distinct))])
    facing = model.normals @ v > 0.0
    shade = 0.35 + 0.65 * (model.normals[facing] @ v)
    colours = base[group_material[model.group_index[facing]]] * shade[:, None]

    fig = plt.figure(figsize=(size, size))
    ax = fig.add_subplot(projection="3d")
    ax.add_collection3d(
        Poly3DCollection(
            model.triangles[facing], facecolors=colours, edgecolors=colours, linewidths=0.3
        )
    )
    lo, hi = model.vertices.min(axis=0), model.vertices.max(axis=0)
    centre, half = 0.5 * (lo + hi), 0.5 * float((hi - lo).max())
    for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre, strict=True):
        setter(c - half, c + half)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(
        elev=float(np.degrees(np.arcsin(np.clip(v[2], -1, 1)))),
        azim=float(np.degrees(np.arctan2(v[1], v[0]))),
    )
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    groups_of = [
        [g for g, k in zip(model.group_names, group_material, strict=True) if k == i]
        for i in range(len(distinct))
    ]
    ax.legend(
        handles=[
            Patch(color=base[i], label=f"{m.name or m.brdf} ({', '.join(groups_of[i])})")
            for i, m in enumerate(distinct)
        ],
        loc="upper left",
        fontsize="small",
    )
    ax.set_title(f"{model.name}: {len(model.faces)} facets, view {np.round(v, 3).tolist()}")
    try:
        with atomic_write(path, "wb") as handle:
            fig.savefig(handle, format="png", dpi=dpi)
    finally:
        plt.close(fig)
