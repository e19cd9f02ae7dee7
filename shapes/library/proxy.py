"""Level-of-detail proxies: a decimated copy of a big mesh for estimation.

An inversion renders thousands of hypotheses per epoch, and a light curve does not resolve
10⁴–10⁵ facets. A shape of more than :data:`PROXY_MIN_FACETS` facets gets, when it is added
to a library, a *proxy*: the same body decimated by quadric error metrics (Garland &
Heckbert 1997, "Surface simplification using quadric error metrics", SIGGRAPH '97), through
trimesh's interface to the ``fast-simplification`` package (never a decimator of our own).

:func:`choose_proxy` starts at :data:`PROXY_START_FACETS` facets and doubles the count until
the proxy's light-curve error against the full mesh — measured by a caller-supplied function
(the renderer lives in :mod:`lightcurve`, which this package does not import) — is at most
:data:`PROXY_TOLERANCE_MAG` rms; a mesh whose proxy needs more than half its facets gets none.
A proxy of a non-convex shape carries its own visibility table, built with the full shape's
table options, so that the error is measured, and the inversion renders, with the same
shadowing as the full shape (table lookups).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from shapes.errors import ShapeError
from shapes.files import file_sha256, temp_path
from shapes.io import write_obj
from shapes.model import FacetModel
from shapes.validation import degenerate_facets, validate
from shapes.visibility.build import build_visibility_table

__all__ = [
    "PROXY_MIN_FACETS",
    "PROXY_START_FACETS",
    "PROXY_TOLERANCE_MAG",
    "ProxyError",
    "ProxyMeter",
    "choose_proxy",
    "decimate",
    "stage_proxy",
]

logger = logging.getLogger(__name__)

#: A shape with more facets than this gets a proxy when added.
PROXY_MIN_FACETS = 4096
#: Facet count of the first proxy tried (doubled until the error passes).
PROXY_START_FACETS = 768
#: The largest rms light-curve error a proxy may have against its full mesh, mag.
PROXY_TOLERANCE_MAG = 0.01
#: Decimation passes before giving up on reaching a facet count (one pass of
#: fast-simplification stops short of large reductions: Eros 49 152 → 768 takes three).
_MAX_PASSES = 8

#: The error record of a proxy (JSON-ready): ``rms_mag``, ``max_mag``, ``geometries``,
#: ``seed``, ``shadows`` (the shadowing mode of the measurement).
ProxyError = dict[str, Any]
#: ``measure(model, proxy)`` → the proxy's error record.
ProxyMeter = Callable[[FacetModel, FacetModel], ProxyError]


def decimate(model: FacetModel, n_facets: int) -> FacetModel:
    """The model decimated to about ``n_facets`` facets by quadric error metrics.

    Each facet group is decimated on its own, to its share of ``n_facets`` (at least 4
    facets; a group already that small is kept), so groups and materials stay as they
    were. Quadric decimation moves vertices off the surface, so the proxy of a convex
    one-group body is replaced by the convex hull of its vertices (trimesh's), which keeps
    it convex (rendered without shadows, like the full body). Mass properties are those
    of the full model (given inertia, centre of mass and mass): the proxy stands for the
    same body.

    Parameters
    ----------
    model : FacetModel
    n_facets : int
        Target facet count (≥ 4).

    Raises
    ------
    ShapeError
        A target below 4 facets, or a decimated mesh that fails validation.
    """
    import trimesh  # about a second to import: only where a proxy is built

    if n_facets < 4:
        raise ShapeError(f"{model.name}: a proxy needs at least 4 facets, got {n_facets}")
    total = len(model.faces)
    convex = model.is_convex and len(model.group_names) == 1
    vertices: list[np.ndarray] = []
    faces: list[np.ndarray] = []
    groups: list[np.ndarray] = []
    offset = 0
    for k in range(len(model.group_names)):
        members = model.faces[model.group_index == k]
        if len(members) == 0:
            continue
        target = max(4, round(n_facets * len(members) / total))
        mesh = trimesh.Trimesh(np.array(model.vertices), np.array(members), process=False)
        mesh.remove_unreferenced_vertices()
        for _ in range(_MAX_PASSES):
            if len(mesh.faces) <= target:
                break
            mesh = mesh.simplify_quadric_decimation(face_count=target)
        if convex:  # the optimal vertex positions leave a convex body slightly dented
            mesh = mesh.convex_hull
        # collapsed edges of thin parts (a CAD model's plates) leave zero-area facets
        mesh.update_faces(~degenerate_facets(mesh.area_faces, model.scale))
        mesh.remove_unreferenced_vertices()
        vertices.append(np.asarray(mesh.vertices, dtype=float))
        faces.append(np.asarray(mesh.faces, dtype=np.int64) + offset)
        groups.append(np.full(len(mesh.faces), k, dtype=np.int64))
        offset += len(mesh.vertices)
    proxy = FacetModel(
        np.concatenate(vertices),
        np.concatenate(faces),
        group_index=np.concatenate(groups),
        group_names=model.group_names,
        materials=model.materials,
        unit=model.unit,
        name=model.name,
        provenance={**model.provenance, "proxy_of_facets": total},
        inertia=model.inertia,
        mass=None if np.isnan(model.mass) else model.mass,
        center_of_mass=model.center_of_mass,
    )
    try:
        validate(proxy)
    except ShapeError as exc:
        raise ShapeError(
            f"{model.name}: the proxy of {n_facets} facets is not a valid mesh: {exc}"
        ) from None
    return proxy


def choose_proxy(
    model: FacetModel,
    measure: ProxyMeter,
    *,
    table_options: Mapping[str, Any] | None = None,
    start: int = PROXY_START_FACETS,
    tolerance_mag: float = PROXY_TOLERANCE_MAG,
) -> tuple[FacetModel, ProxyError] | None:
    """The smallest proxy (``start`` facets, doubled) within ``tolerance_mag`` rms.

    Parameters
    ----------
    model : FacetModel
        The full shape, with its visibility table when it has one.
    measure : callable
        ``measure(model, proxy)`` → the proxy's error record (:data:`ProxyError`).
    table_options : mapping, optional
        Options of :func:`~shapes.visibility.build_visibility_table` for the proxy's own
        table (None: no table; only a non-convex proxy of a shape with a table gets one).
    start : int
        First facet count tried.
    tolerance_mag : float
        Largest rms error accepted, mag.

    Returns
    -------
    (FacetModel, dict) or None
        The proxy (with its table) and its error record; None when no proxy of at most
        half the facets passes (or the shape is too small to need one).
    """
    if not tolerance_mag > 0:
        raise ShapeError(f"proxy tolerance must be positive, got {tolerance_mag} mag")
    n_facets = int(start)
    while 2 * n_facets <= len(model.faces):
        started = time.perf_counter()
        proxy = decimate(model, n_facets)
        if table_options is not None and model.visibility is not None and not proxy.is_convex:
            proxy = proxy.with_visibility(build_visibility_table(proxy, **table_options))
        error = measure(model, proxy)
        logger.info(
            "proxy of %s: %d facets, %.4f mag rms (max %.4f) in %.1f s",
            model.name,
            len(proxy.faces),
            error["rms_mag"],
            error["max_mag"],
            time.perf_counter() - started,
        )
        if error["rms_mag"] <= tolerance_mag:
            return proxy, error
        n_facets *= 2
    return None


def stage_proxy(
    folder: Path,
    model: FacetModel,
    meter: ProxyMeter,
    *,
    table_options: Mapping[str, Any] | None,
    final: dict[str, Path],
    staged: dict[str, Path],
    announce: Callable[[str], None] | None = None,
) -> dict[str, Any] | None:
    """Choose the proxy of ``model`` (:func:`choose_proxy`) and write it (and its table)
    under temporary names in ``folder`` for a library transaction, adding their final and
    staged paths to ``final`` and ``staged``.

    ``announce``, when given, is called with one line saying what is built.

    Returns
    -------
    dict or None
        The manifest's ``proxy`` record: ``mesh``, ``sha256``, ``facets``, ``visibility``
        (or None), ``visibility_sha256``, and the error record's fields; None when no proxy
        of at most half the facets is accurate enough.
    """
    if announce is not None:
        announce(
            f"level-of-detail proxy of the {len(model.faces)}-facet mesh (quadric "
            f"decimation from {PROXY_START_FACETS} facets, doubled until its light curves "
            f"are within {PROXY_TOLERANCE_MAG} mag rms of the full mesh's)"
        )
    chosen = choose_proxy(model, meter, table_options=table_options)
    if chosen is None:
        logger.info("%s: no proxy of at most half the facets is accurate enough", model.name)
        return None
    proxy, error = chosen
    name = model.name
    final["proxy"] = folder / f"{name}.proxy.obj"
    staged["proxy"] = temp_path(folder, f".{name}.proxy.", ".obj")
    write_obj(proxy, staged["proxy"])
    record: dict[str, Any] = {
        "mesh": final["proxy"].name,
        "sha256": file_sha256(staged["proxy"]),
        "facets": len(proxy.faces),
        "visibility": None,
    }
    if proxy.visibility is not None:
        final["proxy_visibility"] = folder / f"{name}.proxy.visibility.npz"
        staged["proxy_visibility"] = temp_path(folder, f".{name}.proxy.", ".npz")
        proxy.visibility.save(staged["proxy_visibility"])
        record["visibility"] = final["proxy_visibility"].name
        record["visibility_sha256"] = file_sha256(staged["proxy_visibility"])
    return {**record, **error}
