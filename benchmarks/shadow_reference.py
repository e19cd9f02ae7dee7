"""Self-shadowing of the renderer against an independent fine-mesh reference.

The reference is plain numpy + trimesh and uses none of the project's visibility code: for
every triangle of a fine mesh facing both the Sun and the observer it casts, from each of
``n × n`` sample points per triangle (sub-triangle centroids), the ray toward the Sun and the
ray toward the observer with trimesh's ray casting (Embree when available), and sums
``ρ A (n·L)(n·V) · (share of the triangle's points whose two rays both escape)``. The
renderer (``shadows="exact"`` and ``"table"``, both the joint lit-and-seen fraction) is
compared with it in magnitudes over random geometries with phase angles from 0° to 120°, half
of them below 20°. Same run, for context: the shadowing effect itself (``"none"`` against
the reference), the former product of two per-facet fractions (``lit · seen``, ray cast by
:func:`shapes.visible_fraction`), and the reference's own discretisation error (``n = 2``
against ``n = 4``).

Shapes: a finely tessellated box-wing with the standard materials (``subdivisions=7``, 2156
triangles), a box-wing of one material with tilted arrays (``subdivisions=8``, 2816
triangles; its compiled facets merge faces of different planes), and Itokawa (the
768-facet library shape with its table; the reference casts from its mesh subdivided once,
3072 triangles, the same surface). The box-wings' tables are built here with the library's
default sampling.

    python -m benchmarks.shadow_reference [--geometries 2000] [--seed 20261201]

Prints JSON. Seeded: geometry draws use ``numpy.random.default_rng(seed)``.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np
import trimesh

import brdf
import shapes
from benchmarks._machine import machine_info
from lightcurve.photometry.render import Renderer
from shapes import Material, primitives

SEED = 20261201
AU_M = 1.495978707e11
RANGE_M = 4.0e7
LIFT = 1e-5  # ray origins lifted off the surface, fraction of the bounding-box diagonal


def random_geometries(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body-frame unit ``L`` (uniform) and ``V`` at phase angles: the first half uniform in
    [0°, 20°), the second half uniform in [20°, 120°]; returns ``L, V, phase_deg``."""
    rng = np.random.default_rng(seed)
    light = rng.normal(size=(n, 3))
    light /= np.linalg.norm(light, axis=1, keepdims=True)
    low = n // 2
    phase = np.concatenate([rng.uniform(0.0, 20.0, low), rng.uniform(20.0, 120.0, n - low)])
    axis = np.cross(light, rng.normal(size=(n, 3)))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    a = np.radians(phase)[:, None]
    view = light * np.cos(a) + np.cross(axis, light) * np.sin(a)  # Rodrigues, axis ⟂ L
    return light, view, phase


class FineMeshReference:
    """The lit-and-seen flux of a triangle mesh by direct ray casting (trimesh only).

    Parameters
    ----------
    vertices, faces : arrays
        The fine mesh, m.
    materials : list of Material
        Distinct materials.
    material_index : (T,) int
        Material of every triangle.
    n : int
        Sample points per triangle: ``n²`` sub-triangle centroids.
    """

    def __init__(
        self,
        vertices: np.ndarray,
        faces: np.ndarray,
        materials: list[Material],
        material_index: np.ndarray,
        n: int,
    ) -> None:
        self.mesh = trimesh.Trimesh(vertices, faces, process=False)
        if trimesh.ray.has_embree:
            self.rays = trimesh.ray.ray_pyembree.RayMeshIntersector(self.mesh)
        else:
            self.rays = trimesh.ray.ray_triangle.RayMeshIntersector(self.mesh)
        self.models = [brdf.get(m.brdf, **m.params) for m in materials]
        self.material_index = np.asarray(material_index)
        tri = self.mesh.triangles
        self.normals = self.mesh.face_normals
        self.areas = self.mesh.area_faces
        # centroids of the n² congruent sub-triangles (barycentric grid, up and down ones)
        bary = []
        for i in range(n):
            for j in range(n - i):
                bary.append(((3 * i + 1) / (3 * n), (3 * j + 1) / (3 * n)))
                if i + j <= n - 2:
                    bary.append(((3 * i + 2) / (3 * n), (3 * j + 2) / (3 * n)))
        bary = np.array(bary)
        points = (
            tri[:, None, 0]
            + bary[None, :, 0, None] * (tri[:, None, 1] - tri[:, None, 0])
            + bary[None, :, 1, None] * (tri[:, None, 2] - tri[:, None, 0])
        )
        lift = LIFT * float(np.linalg.norm(np.ptp(vertices, axis=0)))
        self.origins = (points + lift * self.normals[:, None, :]).reshape(-1, 3)
        self.owner = np.repeat(np.arange(len(tri)), len(bary))
        self.per_triangle = len(bary)

    def rho(self, rows: np.ndarray, light: np.ndarray, view: np.ndarray) -> np.ndarray:
        """BRDF of triangles ``rows`` (vector forms of :mod:`brdf`), sr⁻¹."""
        out = np.empty(len(rows))
        which = self.material_index[rows]
        for k, model in enumerate(self.models):
            sel = which == k
            if sel.any():
                out[sel] = model(self.normals[rows[sel]], light, view)
        return out

    def flux(self, light: np.ndarray, view: np.ndarray) -> np.ndarray:
        """``Σ ρ A (n·L)(n·V) J / d²`` for each row of unit ``light``/``view``."""
        out = np.empty(len(light))
        for g, (l_dir, v_dir) in enumerate(zip(light, view, strict=True)):
            cos_l, cos_v = self.normals @ l_dir, self.normals @ v_dir
            front = np.flatnonzero((cos_l > 0) & (cos_v > 0))
            points = np.flatnonzero(np.isin(self.owner, front))
            lit = ~self.rays.intersects_any(self.origins[points], np.tile(l_dir, (len(points), 1)))
            both = np.zeros(len(points), bool)
            seen_points = points[lit]
            both[lit] = ~self.rays.intersects_any(
                self.origins[seen_points], np.tile(v_dir, (len(seen_points), 1))
            )
            hits = np.bincount(self.owner[points], weights=both, minlength=len(self.areas))
            joint = hits / self.per_triangle
            terms = self.rho(front, l_dir, v_dir) * self.areas[front]
            out[g] = np.sum(terms * cos_l[front] * cos_v[front] * joint[front]) / RANGE_M**2
        return out


def test_shapes() -> list[tuple[str, shapes.FacetModel, np.ndarray, np.ndarray, list, np.ndarray]]:
    """(name, renderer model with table, reference vertices, faces, materials, index)."""
    out = []
    standard = primitives.box_wing(subdivisions=7, name="box_wing_fine")
    one = Material("lambert", {"rd": 0.5})
    tilted = primitives.box_wing(
        subdivisions=8,
        array_normal=(1.0, 0.0, 0.6),
        materials={g: one for g in ("bus", "solar_array", "array_back", "yoke")},
        name="box_wing_one_material",
    )
    for model in (standard, tilted):
        distinct, group_material = model.distinct_materials
        model = model.with_visibility(shapes.build_visibility_table(model))
        out.append(
            (
                model.name,
                model,
                model.vertices,
                model.faces,
                distinct,
                group_material[model.group_index],
            )
        )
    itokawa = shapes.get_library().load("itokawa")
    vertices, faces = trimesh.remesh.subdivide(itokawa.vertices, itokawa.faces)
    distinct, group_material = itokawa.distinct_materials
    index = np.repeat(group_material[itokawa.group_index], 4)  # subdivide keeps face order ×4
    out.append(("itokawa", itokawa, vertices, faces, distinct, index))
    return out


def magnitude_difference(flux: np.ndarray, reference: np.ndarray) -> dict:
    """RMS and max of ``−2.5 log10(flux / reference)`` where both are positive."""
    both = (flux > 0) & (reference > 0)
    diff = -2.5 * np.log10(flux[both] / reference[both])
    return {
        "rms_mag": round(float(np.sqrt(np.mean(diff**2))), 5),
        "max_abs_mag": round(float(np.max(np.abs(diff))), 4),
        "compared": int(both.sum()),
        "dark_mismatch": int(np.sum((flux > 0) != (reference > 0))),
    }


def compare(flux: np.ndarray, reference: np.ndarray, phase: np.ndarray) -> dict:
    return {
        "all": magnitude_difference(flux, reference),
        "phase_below_20deg": magnitude_difference(flux[phase < 20], reference[phase < 20]),
        "phase_20_to_120deg": magnitude_difference(flux[phase >= 20], reference[phase >= 20]),
    }


def product_flux(model: shapes.FacetModel, light: np.ndarray, view: np.ndarray) -> np.ndarray:
    """The former model: per-facet flux times ``lit_k · seen_k`` (two ray-cast fractions)."""
    compiled = model.compiled()
    sun, observer = light * AU_M, view * RANGE_M
    q = np.array([0.0, 0.0, 0.0, 1.0])
    facets = Renderer(model, shadows="none").facet_flux(q, sun, observer)
    lit = shapes.visible_fraction(compiled, light)
    seen = shapes.visible_fraction(compiled, view)
    return np.sum(facets * lit * seen, axis=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--geometries", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=SEED)
    args = parser.parse_args()
    light, view, phase = random_geometries(args.geometries, args.seed)
    q = np.array([0.0, 0.0, 0.0, 1.0])
    sun, observer = light * AU_M, view * RANGE_M
    results = []
    for name, model, vertices, faces, materials, index in test_shapes():
        start = time.perf_counter()
        reference = FineMeshReference(vertices, faces, materials, index, n=2)
        ref = reference.flux(light, view)
        ref_seconds = time.perf_counter() - start
        ref_fine = FineMeshReference(vertices, faces, materials, index, n=4).flux(light, view)
        row = {
            "shape": name,
            "reference_triangles": len(faces),
            "reference_points_per_triangle": reference.per_triangle,
            "renderer_effective_facets": len(model.compiled()),
            "renderer_sample_points": model.compiled().visibility.n_points,
            "reference_seconds": round(ref_seconds, 1),
            "reference_discretisation_n2_vs_n4": compare(ref, ref_fine, phase),
            "shadowing_effect_none_vs_reference": compare(
                Renderer(model, shadows="none").flux(q, sun, observer), ref, phase
            ),
            "product_lit_times_seen_vs_reference": compare(
                product_flux(model, light, view), ref, phase
            ),
        }
        for mode in ("exact", "table"):
            start = time.perf_counter()
            flux = Renderer(model, shadows=mode).flux(q, sun, observer)
            row[f"{mode}_seconds"] = round(time.perf_counter() - start, 2)
            row[f"{mode}_vs_reference"] = compare(flux, ref, phase)
            row[f"{mode}_vs_finer_reference"] = compare(flux, ref_fine, phase)
        results.append(row)
    print(
        json.dumps(
            {
                "benchmark": "shadow_reference",
                "geometries": args.geometries,
                "seed": args.seed,
                "phase_deg": "half uniform in [0, 20), half uniform in [20, 120]",
                "ray_caster": "trimesh + embree" if trimesh.ray.has_embree else "trimesh",
                "results": results,
                "load_average": os.getloadavg(),
                "machine": machine_info(),
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
