"""Which part of a perturbed object's difference from its library model the photometry sees.
Prints JSON.

For the objects of the model-mismatch benchmark (:mod:`benchmarks.mismatch_study`: seed, run
``i`` drawn around ``box``, ``box_wing`` or ``rocket_body`` in turn, geostationary scenario),
the noiseless light curve of the perturbed object at its true attitudes is compared with
those of candidates that carry back one part of the truth at a time:

``library``
    the parent as the library has it;
``stretch``
    the parent's mesh stretched by the truth's factors along its principal axes;
``materials``
    the library mesh with the truth's materials;
``stretch+materials``
    both: what is left is the appendage (mass does not change the light at given
    attitudes).

Each is rendered with ray-cast shadows at the same attitudes and geometry; the figure is the
rms and the 90th percentile of the magnitude difference after the best common offset (the
albedo–area scale any inversion estimates). Attitudes are the truth's: the figures say how
far each candidate is from the object where the answer is right, the floor of the misfit an
inversion with that candidate can reach.

    python -m benchmarks.mismatch_parts [--runs 16] [--seed 0] [--out FILE]
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from benchmarks._machine import machine_info
from benchmarks._report import emit_report
from benchmarks.mismatch import DEFAULT_SHAPES
from benchmarks.mismatch_study import GEO_DURATION_S, draw_case, simulate_case
from lightcurve.photometry.render import Renderer, flux_to_magnitude
from shapes import FacetModel, get_library

#: Candidates of the comparison, in order (module docstring).
PARTS = ("library", "stretch", "materials", "stretch+materials")


def candidate_parts(case: Any) -> dict[str, FacetModel]:
    """The library parent of ``case`` with each part of its perturbation put back."""
    parent = get_library().load(case.parent)
    p = case.perturbation
    stretched = p.stretched(parent.vertices)
    materials = {g: p.model.materials[g] for g in parent.group_names}
    return {
        "library": parent,
        "stretch": parent.replace(vertices=stretched, visibility=None),
        "materials": parent.replace(materials=materials),
        "stretch+materials": parent.replace(
            vertices=stretched, visibility=None, materials=materials
        ),
    }


def part_errors(seed: int, index: int, geo_duration_s: float = GEO_DURATION_S) -> dict[str, Any]:
    """rms and 90th percentile (mag) of each candidate's difference from run ``index``'s
    object at its true attitudes, after the best common offset: ``{part: {"rms_mag",
    "p90_mag"}}`` for every part of :data:`PARTS`, with the ``parent`` name and the kind of
    ``appendage`` (None without one)."""
    parent = DEFAULT_SHAPES[index % len(DEFAULT_SHAPES)]
    case = draw_case(seed, index, "geo", parent, geo_duration_s=geo_duration_s)
    observed = simulate_case(case, "perturbed")
    q = observed.truth[:, :4]
    sun, observer = observed.sun_vectors, observed.observer_vectors

    def magnitudes(model: FacetModel) -> np.ndarray:
        flux = Renderer(model, shadows="exact").flux(q, sun, observer)
        return flux_to_magnitude(np.maximum(flux, 1e-30))

    truth = magnitudes(case.perturbation.model)
    out = {}
    for name, model in candidate_parts(case).items():
        d = magnitudes(model) - truth
        d = d - np.mean(d)
        out[name] = {
            "rms_mag": float(np.sqrt(np.mean(d**2))),
            "p90_mag": float(np.percentile(np.abs(d), 90)),
        }
    return {"parent": parent, "appendage": _appendage(case), **out}


def _appendage(case: Any) -> str | None:
    """Kind of the case's appendage, or None."""
    added = case.perturbation.appendage
    return None if added is None else added.kind


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.mismatch_parts", description=__doc__
    )
    parser.add_argument("--runs", type=int, default=16)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default=None)
    args = parser.parse_args(argv)
    runs = [part_errors(args.seed, i) for i in range(args.runs)]
    summary = {
        part: {
            "median_rms_mag": float(np.median([r[part]["rms_mag"] for r in runs])),
            "max_rms_mag": float(np.max([r[part]["rms_mag"] for r in runs])),
        }
        for part in PARTS
    }
    report = {
        "benchmark": "mismatch_parts",
        "seed": args.seed,
        "runs": args.runs,
        "machine": machine_info(),
        "summary": summary,
        "cases": runs,
    }
    emit_report(report, args.out)


if __name__ == "__main__":
    main()
