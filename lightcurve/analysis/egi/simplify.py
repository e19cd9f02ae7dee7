"""The fewest faces the data need: a greedy simplification of a fitted EGI by an
information criterion.

A light curve over a narrow band of phase angles sees some combinations of areas alike: a
flat face and two facets tilted either side of it can fit one arc equally well, and predict
another night differently. Convex objects of the kinds observed (boxes, prisms, stages) have
few flat faces, so among EGIs that fit, the one with the fewest facets is preferred
(Occam's razor, in the form of Schwarz's Bayesian information criterion: Schwarz 1978,
"Estimating the dimension of a model", Ann. Stat. 6, 461).

The start is the set of lowest BIC among the non-zero facets of a fit
(:func:`~lightcurve.analysis.egi.fit.fit_egi`) and those facets clustered by single linkage
within each of :data:`CLUSTER_ANGLES_DEG` (each cluster one facet at its area-weighted mean
normal). Each step then tries, cheapest first,

* **removals** of each of the :data:`CANDIDATES_PER_KIND` smallest facets, its flux left to
  the others, and of the smallest quarter and half of the facets at once, and
* **merges** of each of as many nearest pairs within :data:`MERGE_ANGLE_DEG` — one facet at
  their area-weighted mean normal,

each followed by the non-negative refit of the areas over the remaining normals under the
closure rows (:func:`~lightcurve.analysis.egi.fit.solve_areas`; areas the refit sets to 0
are removed too). The BIC is ``χ² + 3 K ln E`` for ``K`` facets of three parameters (two
angles of the normal, one area) and ``E`` epochs: a change that removes ``k`` facets passes
when its χ² rises by less than ``3 k ln E``. The candidate of lowest BIC is kept when it
lowers the BIC. When none does, the facets are polished
(:func:`~lightcurve.analysis.egi.fit.polish`: every facet's normal and area) and the
candidates tried again; when still none does, the best :data:`POLISHED_CANDIDATES` are
polished and scored, and the search stops when none of them lowers the BIC either. The
polish fits magnitudes without the closure rows, so a polished set is kept only when its
closed refit fits better than the set as it stood.
"""

from __future__ import annotations

import math

import numpy as np

import brdf
from lightcurve.analysis.egi.epochs import FitEpochs
from lightcurve.analysis.egi.fit import (
    EGIFit,
    cluster_normals,
    default_smoothing,
    design_matrix,
    fit_result,
    polish,
    solve_areas,
)

__all__ = ["FACES", "MERGE_ANGLE_DEG", "choose_faces", "fewest_faces"]

#: Largest angle between two facets tried as one (deg): one-arc fits of a box split a face
#: into two facets up to 61° apart (measured), which must still be a candidate.
MERGE_ANGLE_DEG = 75.0
#: Candidates of each kind (removals, merges) scored per step, cheapest first.
CANDIDATES_PER_KIND = 24
#: Candidates polished, best first, when none passes on its normals as they stand.
POLISHED_CANDIDATES = 4
#: Neighbour angles (deg) of the single-linkage clusterings tried as starting sets.
CLUSTER_ANGLES_DEG = (15.0, 30.0, 45.0)
#: Fewest facets of a closed convex body (a tetrahedron).
MIN_FACETS = 4
#: Parameters of one facet: two angles of its normal and its area.
FACET_PARAMETERS = 3


Facets = tuple[np.ndarray, np.ndarray, float]
"""Normals (K, 3), areas (K,) and χ² of a facet set."""


def _refit(
    normals: np.ndarray,
    epochs: FitEpochs,
    material: brdf.BRDF,
    design: np.ndarray | None = None,
) -> Facets:
    """Non-negative areas over ``normals`` (``design``: their columns, when known) under
    closure: the facets kept (non-zero areas) and the χ²."""
    if design is None:
        design = design_matrix(normals, epochs, material)
    areas = solve_areas(design, normals, epochs, 0.0)
    chi2 = float(np.sum(((design @ areas - epochs.flux) / epochs.flux_sigma) ** 2))
    kept = areas > 0
    return normals[kept], areas[kept], chi2


def _candidates(
    normals: np.ndarray, areas: np.ndarray, epochs: FitEpochs, material: brdf.BRDF
) -> list[Facets]:
    """The facet sets one step away, refitted: the removals of each of the
    :data:`CANDIDATES_PER_KIND` smallest facets and of the smallest quarter and half at
    once, and the merges of as many nearest pairs within :data:`MERGE_ANGLE_DEG`."""
    design = design_matrix(normals, epochs, material)
    rank = np.argsort(np.argsort(areas))
    out = []
    for count in sorted({len(areas) // 4, len(areas) // 2} - {0, 1}):
        out.append(_refit(normals[rank >= count], epochs, material, design[:, rank >= count]))
    for k in np.argsort(areas)[:CANDIDATES_PER_KIND]:
        keep = np.arange(len(areas)) != k
        out.append(_refit(normals[keep], epochs, material, design[:, keep]))
    cosine = np.triu(normals @ normals.T, 1)
    i, j = np.nonzero(cosine >= math.cos(math.radians(MERGE_ANGLE_DEG)))
    nearest = np.argsort(-cosine[i, j], kind="stable")[:CANDIDATES_PER_KIND]
    for a, b in zip(i[nearest], j[nearest], strict=True):
        mean = areas[a] * normals[a] + areas[b] * normals[b]
        mean /= np.linalg.norm(mean)
        keep = (np.arange(len(areas)) != a) & (np.arange(len(areas)) != b)
        merged = np.vstack([normals[keep], mean])
        columns = np.hstack([design[:, keep], design_matrix(mean[None], epochs, material)])
        out.append(_refit(merged, epochs, material, columns))
    return out


def _polished(found: Facets, epochs: FitEpochs, material: brdf.BRDF) -> Facets:
    """Every facet's normal and area polished, then the areas refitted under closure; the
    facets as found when that fits worse (the polish does not hold the closure)."""
    moved, _ = polish(found[0], found[1], epochs, material, share=0.0)
    return min(_refit(moved, epochs, material), found, key=lambda facets: facets[2])


def _starts(
    normals: np.ndarray, areas: np.ndarray, epochs: FitEpochs, material: brdf.BRDF
) -> list[Facets]:
    """The facets' clusters within each of :data:`CLUSTER_ANGLES_DEG`, refitted."""
    out = []
    for angle in CLUSTER_ANGLES_DEG:
        means, _ = cluster_normals(normals, areas, 2.0 * math.sin(math.radians(angle) / 2.0))
        if len(means) < MIN_FACETS:  # no closed body (and scipy's nnls fails on one column)
            break
        out.append(_polished(_refit(means, epochs, material), epochs, material))
    return out


def fewest_faces(fit: EGIFit, epochs: FitEpochs) -> EGIFit:
    """The EGI of ``fit`` with the fewest facets the data need (module docstring).

    Parameters
    ----------
    fit : EGIFit
        A fit (its material used throughout; no smoothing term in the refits).
    epochs : FitEpochs
        The epochs it was fitted to.

    Returns
    -------
    EGIFit
        Over the facets kept (its normals only those), with χ², model flux and the areas'
        1σ of the simplified EGI; ``fit`` itself when no change passes.
    """
    material = fit.material
    penalty = FACET_PARAMETERS * math.log(len(epochs))

    def bic(found: Facets) -> float:
        return found[2] + penalty * len(found[1])

    active = fit.areas > 0
    start = (fit.normals[active], fit.areas[active], fit.chi2)
    current = min([start, *_starts(*start[:2], epochs, material)], key=bic)
    polished = False
    while len(current[1]) > MIN_FACETS:
        scored = sorted(_candidates(*current[:2], epochs, material), key=bic)
        if bic(scored[0]) < bic(current):
            current, polished = scored[0], False
            continue
        if not polished:  # stuck on the normals as they stand: polish them, then look again
            current, polished = _polished(current, epochs, material), True
            continue
        best = min(
            (_polished(found, epochs, material) for found in scored[:POLISHED_CANDIDATES]),
            key=bic,
        )
        if bic(best) >= bic(current):
            break
        current = best
    if current is start:
        return fit
    normals, areas, _ = current
    design = design_matrix(normals, epochs, material)
    return fit_result(normals, areas, design, epochs, material, fit.smoothing)


#: ``--faces`` choices: the fewest faces when the data see the normals from all sides
#: (``auto``), always (``fewest``) or never (``all``).
FACES = ("auto", "fewest", "all")


def choose_faces(fit: EGIFit, epochs: FitEpochs, faces: str = "auto") -> EGIFit:
    """``fit`` with the fewest faces (:func:`fewest_faces`) as ``faces`` says (:data:`FACES`).

    ``auto`` simplifies a fit whose data see the normals from all sides (a tumbling
    object: :func:`~lightcurve.analysis.egi.fit.default_smoothing` gives no weight) and
    keeps the fit of a stabilised object as it is: the simplification refits without the
    smoothing term, and on one band of normals that lets areas grow unseen (measured:
    stabilised nights' fits reached 387–1 903 m² for 18–22 m² bodies).
    """
    if faces not in FACES:
        raise ValueError(f"faces must be one of {', '.join(FACES)}, got {faces!r}")
    if faces == "all" or (faces == "auto" and default_smoothing(epochs) > 0.0):
        return fit
    return fewest_faces(fit, epochs)
