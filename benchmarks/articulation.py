"""Articulated shapes: accuracy against an independent reference, and rendering cost.

Run ``python benchmarks/articulation.py [--quick] [--sections accuracy,speed]``; prints one
JSON document.

accuracy
    A nadir-pointing (LVLH) box-wing in a geostationary slot (100° W, seen from Mount Lemmon,
    night of 2024-03-10, one epoch every 120 s) whose arrays track the Sun, simulated by
    :func:`lightcurve.photometry.simulate.simulate` (shadows ``exact``) and recomputed by an
    independent numpy/trimesh reference: the attitude from the orbit position and velocity (body z
    to nadir, y to the negative orbit normal), the array angle by hand from the body-frame Sun,
    the array vertices turned by hand, the posed mesh ray cast with trimesh's pure-numpy
    intersector from seeded uniform random points of every triangle (a point counts only
    when it is both lit and seen), the BRDFs in their vector form per triangle. Two drives:
    the built-in continuous one and one limited to [−150°, −30°], which the Sun leaves at
    the start and end of the night (the reference clips to the nearer limit on the circle).
speed
    :class:`~lightcurve.photometry.articulated.ArticulatedRenderer` on ``box_wing_tracking`` against
    :class:`~lightcurve.photometry.render.Renderer` on the rigid ``box_wing`` (same mesh, same
    materials), same rows, same run; best of several repeats, per shadow mode.
Seed 20261201 for every random draw.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

_HERE = Path(__file__).resolve().parent
sys.path[:] = [str(_HERE.parent)] + [p for p in sys.path if Path(p or ".").resolve() != _HERE]

import numpy as np  # noqa: E402
import trimesh  # noqa: E402

import brdf  # noqa: E402
from benchmarks._machine import machine_info  # noqa: E402
from benchmarks._report import add_sections_argument  # noqa: E402
from filters.attitude import quaternion_from_matrix  # noqa: E402
from lightcurve.photometry.articulated import ArticulatedRenderer  # noqa: E402
from lightcurve.photometry.render import Renderer  # noqa: E402
from lightcurve.photometry.simulate import simulate  # noqa: E402
from lightcurve.sky.ephemeris import CircularOrbit, orbit_geometry  # noqa: E402
from lightcurve.sky.sites import get_site  # noqa: E402
from shapes import get_library  # noqa: E402
from shapes.articulation import ArticulatedModel, Articulation  # noqa: E402

SEED = 20261201
AU_M = 149_597_870_700.0
LIMITED = (-150.0, -30.0)
ARRAY_GROUPS = ("solar_array", "array_back", "yoke")


def night_geometry(cadence_s: float):
    """GEO slot 100° W from Mount Lemmon over the night of 2024-03-10 (orbit kept)."""
    mjd0 = 60379.0 + 1.0 / 24.0  # 2024-03-10 01:00 UTC
    mjd = mjd0 + np.arange(0.0, 12 * 3600.0, cadence_s) / 86400.0
    orbit = CircularOrbit.geostationary(-100.0, mjd0)
    geometry = orbit_geometry(orbit, get_site("Mount Lemmon"), mjd, "geo-box-wing-tracking")
    return orbit, geometry


def lvlh_matrices(orbit: CircularOrbit, mjd: np.ndarray) -> np.ndarray:
    """Inertial → body matrices of the nadir-pointing frame (rows: body axes, inertial)."""
    step = 1.0 / 86400.0
    r = orbit.position(mjd)
    v = (orbit.position(mjd + step) - orbit.position(mjd - step)) / 2.0
    z = -r / np.linalg.norm(r, axis=1, keepdims=True)
    h = np.cross(r, v)
    y = -h / np.linalg.norm(h, axis=1, keepdims=True)
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=1)


def reference_angle(sun_body: np.ndarray, limits: tuple[float, float]) -> np.ndarray:
    """Array angle about +y that turns the +x cell normal toward the Sun, within limits."""
    # rotation about y by θ maps x to (cos θ, 0, −sin θ): best θ = atan2(−s_z, s_x)
    ideal = np.degrees(np.arctan2(-sun_body[:, 2], sun_body[:, 0]))
    low, high = limits
    inside = (np.mod(ideal - low, 360.0) <= high - low) | (high - low >= 360.0)
    dist_low = np.abs((ideal - low + 180.0) % 360.0 - 180.0)
    dist_high = np.abs((ideal - high + 180.0) % 360.0 - 180.0)
    clipped = np.where(dist_low <= dist_high, low, high)
    inside_value = low + np.mod(ideal - low, 360.0)
    return np.where(inside, np.where(high - low >= 360.0, ideal, inside_value), clipped)


def reference_flux(
    model, a_matrices, sun_m, obs_m, angles_deg, points_per_triangle: int
) -> np.ndarray:
    """Flux ratio of the posed box-wing by per-epoch ray casting (trimesh, numpy)."""
    rng = np.random.default_rng(SEED)
    groups = [model.group_names[k] for k in model.group_index]
    moving = np.isin(groups, ARRAY_GROUPS)
    moving_vertices = np.unique(model.faces[moving])
    u = rng.random((len(model.faces), points_per_triangle, 2))
    flip = u.sum(axis=2) > 1.0
    u[flip] = 1.0 - u[flip]
    materials = [model.materials[g] for g in groups]
    models = [brdf.get(m.brdf, **m.params) for m in materials]
    flux = np.zeros(len(sun_m))
    for e in range(len(sun_m)):
        theta = math.radians(angles_deg[e])
        rot = np.array(
            [
                [math.cos(theta), 0.0, math.sin(theta)],
                [0.0, 1.0, 0.0],
                [-math.sin(theta), 0.0, math.cos(theta)],
            ]
        )
        vertices = model.vertices.copy()
        vertices[moving_vertices] = vertices[moving_vertices] @ rot.T
        mesh = trimesh.Trimesh(vertices, model.faces, process=False)
        tri = vertices[model.faces]
        edge1, edge2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        cross = np.cross(edge1, edge2)
        area = 0.5 * np.linalg.norm(cross, axis=1)
        normal = cross / (2.0 * area[:, None])
        light = a_matrices[e] @ sun_m[e]
        view = a_matrices[e] @ obs_m[e]
        r_sun, r_obs = np.linalg.norm(light), np.linalg.norm(view)
        light, view = light / r_sun, view / r_obs
        cos_l, cos_v = normal @ light, normal @ view
        front = np.flatnonzero((cos_l > 0) & (cos_v > 0))
        if len(front) == 0:
            continue
        pts = (
            tri[front, 0, None]
            + u[front, :, :1] * edge1[front, None]
            + u[front, :, 1:] * edge2[front, None]
            + 1e-6 * normal[front, None]
        ).reshape(-1, 3)
        intersector = trimesh.ray.ray_triangle.RayMeshIntersector(mesh)
        n_pts = len(pts)
        hits = intersector.intersects_any(
            np.concatenate([pts, pts]),
            np.concatenate([np.tile(light, (n_pts, 1)), np.tile(view, (n_pts, 1))]),
        )
        both = ~(hits[:n_pts] | hits[n_pts:])
        fraction = both.reshape(len(front), points_per_triangle).mean(axis=1)
        rho = np.array([models[f](normal[f], light, view) for f in front]).reshape(-1)
        terms = rho * area[front] * cos_l[front] * cos_v[front] * fraction
        flux[e] = terms.sum() / r_obs**2 * (AU_M / r_sun) ** 2
    return flux


def accuracy(cadence_s: float, points: int) -> dict:
    library = get_library()
    shape = library.load("box_wing_tracking", articulated=True)
    orbit, geometry = night_geometry(cadence_s)
    mjd = geometry.table["mjd"].to_numpy(float)
    a_matrices = lvlh_matrices(orbit, mjd)
    r0 = orbit.position(mjd[:1])[0]
    v0 = (orbit.position(mjd[:1] + 1.0 / 86400.0) - orbit.position(mjd[:1] - 1.0 / 86400.0))[0] / 2
    rate = float(np.linalg.norm(np.cross(r0, v0)) / (r0 @ r0))  # rad/s
    q0 = np.asarray(quaternion_from_matrix(a_matrices[0]))
    omega0 = np.array([0.0, -rate, 0.0])  # LVLH turns about the orbit normal = −y_body
    results = {"epochs": len(mjd), "cadence_s": cadence_s, "reference_points": points}
    for label, limits in (("continuous", (-180.0, 180.0)), ("limited", LIMITED)):
        parts = shape.articulation.to_list()
        parts[0]["joint"]["limits_deg"] = list(limits)
        model = ArticulatedModel(
            shape.model, Articulation.from_list(parts, shape.model.group_names, "benchmark")
        )
        start = time.perf_counter()
        sim = simulate(geometry, model, q0=q0, omega0=omega0, shadows="exact")
        seconds = time.perf_counter() - start
        kept = np.isin(mjd, sim.table["mjd"].to_numpy(float))
        sun, obs = geometry.sun_vectors[kept], geometry.observer_vectors[kept]
        sun_body = np.einsum("eij,ej->ei", a_matrices[kept], sun)
        angle = reference_angle(sun_body, limits)
        flux = reference_flux(shape.model, a_matrices[kept], sun, obs, angle, points)
        ref_mag = -26.74 - 2.5 * np.log10(flux)
        residual = sim.table["mag"].to_numpy() - ref_mag
        joint = sim.table["joint_arrays_deg"].to_numpy()
        rot_normal = np.stack(
            [np.cos(np.radians(joint)), np.zeros_like(joint), -np.sin(np.radians(joint))], 1
        )
        s_unit = sun_body / np.linalg.norm(sun_body, axis=1, keepdims=True)
        sun_angle = np.degrees(np.arccos(np.clip(np.sum(rot_normal * s_unit, 1), -1, 1)))
        out_of_plane = np.degrees(np.arcsin(np.abs(s_unit[:, 1])))
        ideal = np.degrees(np.arctan2(-s_unit[:, 2], s_unit[:, 0]))
        beyond = ~((ideal >= limits[0]) & (ideal <= limits[1]))
        q_sim = sim.table[["q1", "q2", "q3", "q4"]].to_numpy()
        q_ref = np.asarray(quaternion_from_matrix(a_matrices[kept]))
        attitude_deg = np.degrees(2 * np.arccos(np.clip(np.abs(np.sum(q_sim * q_ref, 1)), 0, 1)))
        results[label] = {
            "limits_deg": list(limits),
            "measurements": len(residual),
            "rms_mag": float(np.sqrt(np.mean(residual**2))),
            "max_abs_mag": float(np.max(np.abs(residual))),
            "joint_deg_range": [float(joint.min()), float(joint.max())],
            "joint_within_limits": bool(
                np.all((joint >= limits[0] - 1e-9) & (joint <= limits[1] + 1e-9))
            ),
            "joint_vs_reference_max_deg": float(np.max(np.abs(joint - angle))),
            "epochs_sun_beyond_limits": int(beyond.sum()),
            "array_sun_angle_deg_max_tracking": float(
                np.max(np.abs(sun_angle - out_of_plane)[~beyond], initial=0.0)
            ),
            "array_sun_angle_deg_range_beyond": (
                [float(sun_angle[beyond].min()), float(sun_angle[beyond].max())]
                if beyond.any()
                else None
            ),
            "attitude_sim_vs_lvlh_max_deg": float(attitude_deg.max()),
            "simulate_seconds": round(seconds, 3),
        }
    return results


def _best_pair(first, second, repeats: int) -> tuple[float, float]:
    """Best-of-``repeats`` seconds of two calls, timed alternately (same machine state)."""
    best = [math.inf, math.inf]
    for _ in range(repeats):
        for k, call in enumerate((first, second)):
            start = time.perf_counter()
            call()
            best[k] = min(best[k], time.perf_counter() - start)
    return best[0], best[1]


def speed(rows: int, exact_rows: int, repeats: int) -> dict:
    library = get_library()
    rigid = library.load("box_wing")
    articulated = library.load("box_wing_tracking", articulated=True)
    rng = np.random.default_rng(SEED)
    q = rng.normal(size=(rows, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    sun = rng.normal(size=(rows, 3)) * 1.496e11
    obs = rng.normal(size=(rows, 3)) * 3.6e7
    out = {"rows": rows, "exact_rows": exact_rows, "repeats": repeats, "modes": {}}
    for mode, n in (("none", rows), ("table", rows), ("exact", exact_rows)):
        base = Renderer(rigid, shadows=mode)
        art = ArticulatedRenderer(articulated, shadows=mode)
        args = (q[:n], sun[:n], obs[:n])
        base.flux(*args)  # compile / warm caches
        art.flux(*args)
        t_rigid, t_art = _best_pair(
            lambda b=base, a=args: b.flux(*a), lambda r=art, a=args: r.flux(*a), repeats
        )
        out["modes"][mode] = {
            "rigid_s": round(t_rigid, 5),
            "articulated_s": round(t_art, 5),
            "ratio": round(t_art / t_rigid, 3),
            "rigid_rows_per_s": round(n / t_rigid),
        }
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer epochs and rows")
    add_sections_argument(parser, ("accuracy", "speed"))
    args = parser.parse_args(argv)
    sections = args.sections
    report: dict = {"machine": machine_info(), "seed": SEED}
    if "accuracy" in sections:
        report["accuracy"] = accuracy(600.0 if args.quick else 120.0, 32 if args.quick else 64)
    if "speed" in sections:
        report["speed"] = speed(20000, 500, 5) if args.quick else speed(100000, 2000, 15)
    print(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
