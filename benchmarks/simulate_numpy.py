"""The straightforward numpy light-curve simulation: the baseline of ``benchmarks/simulate.py``.

What a careful user writes without the toolkit: read the mesh (OBJ) and the geometry file,
integrate the torque-free attitude with scipy's DOP853 at rtol = atol = 1e-12 (as the
toolkit's truth), then one Python loop over epochs, each vectorised over facets, evaluating
the Ashikhmin–Shirley BRDF (Ashikhmin & Shirley 2000, isotropic, the form of
``docs/brdf.md``) and ``F/F_sun = (1 AU/r_sun)² Σ ρ A (n·L)(n·V)/d²`` with no shadowing,
``m = −26.74 − 2.5 log10 F/F_sun``. Dark epochs are dropped. Writes a CSV with ``mjd`` and
``mag``. No toolkit import, so its start-up is numpy's, scipy's and pandas'.

    python benchmarks/simulate_numpy.py GEOMETRY.csv MESH.obj --q0 … --omega0 … (deg/s)
        --inertia Jxx,Jyy,Jzz --rd … --rs … --nu … --out OUT.csv
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

AU_M = 1.495978707e11
SUN_MAGNITUDE = -26.74


def read_obj(path: str) -> tuple[np.ndarray, np.ndarray]:
    """Triangle normals (unit) and areas (m²) of an OBJ file in metres."""
    vertices, faces = [], []
    with open(path, encoding="utf-8") as handle:
        for line in handle:
            if line.startswith("v "):
                vertices.append([float(v) for v in line.split()[1:4]])
            elif line.startswith("f "):
                faces.append([int(v.split("/")[0]) - 1 for v in line.split()[1:4]])
    v, f = np.array(vertices), np.array(faces)
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    double_area = np.linalg.norm(cross, axis=1)
    return cross / double_area[:, None], 0.5 * double_area


def attitude_matrix(q: np.ndarray) -> np.ndarray:
    """``A(q)`` with ``v_B = A v_I``, scalar-last quaternion (Markley & Crassidis 2014)."""
    x, y, z, w = q
    return np.array(
        [
            [w * w + x * x - y * y - z * z, 2 * (x * y + w * z), 2 * (x * z - w * y)],
            [2 * (x * y - w * z), w * w - x * x + y * y - z * z, 2 * (y * z + w * x)],
            [2 * (x * z + w * y), 2 * (y * z - w * x), w * w - x * x - y * y + z * z],
        ]
    )


def truth(times: np.ndarray, q0: np.ndarray, omega0: np.ndarray, inertia: np.ndarray):
    """Torque-free ``[q, ω]`` at ``times`` (DOP853, rtol = atol = 1e-12), q renormalised."""
    j_inv = 1.0 / inertia

    def rhs(_t, x):
        q, w = x[:4], x[4:]
        x1, x2, x3, x4 = q
        q_dot = 0.5 * np.array(
            [
                x4 * w[0] - x3 * w[1] + x2 * w[2],
                x3 * w[0] + x4 * w[1] - x1 * w[2],
                -x2 * w[0] + x1 * w[1] + x4 * w[2],
                -x1 * w[0] - x2 * w[1] - x3 * w[2],
            ]
        )
        h = inertia * w
        w_dot = -j_inv * np.array(
            [w[1] * h[2] - w[2] * h[1], w[2] * h[0] - w[0] * h[2], w[0] * h[1] - w[1] * h[0]]
        )
        return np.concatenate([q_dot, w_dot])

    x0 = np.concatenate([q0 / np.linalg.norm(q0), omega0])
    sol = solve_ivp(
        rhs, (times[0], times[-1]), x0, method="DOP853", t_eval=times, rtol=1e-12, atol=1e-12
    )
    states = sol.y.T
    states[:, :4] /= np.linalg.norm(states[:, :4], axis=1, keepdims=True)
    return states


def ashikhmin_shirley(nl, nv, lv, rd, rs, nu):
    """Isotropic Ashikhmin–Shirley ρ (sr⁻¹) of one epoch's facets."""
    visible = (nl > 0) & (nv > 0)
    length = math.sqrt(max(2.0 + 2.0 * lv, 1e-12))
    vh = 0.5 * length
    nh = np.clip((nl + nv) / length, 1e-6, 1.0)
    fresnel = rs + (1.0 - rs) * (1.0 - vh) ** 5
    specular = (
        (nu + 1.0) / (8.0 * math.pi) * fresnel / vh * nh**nu / np.maximum(np.maximum(nl, nv), 1e-6)
    )
    diffuse = (
        28.0
        * rd
        / (23.0 * math.pi)
        * (1.0 - rs)
        * (1.0 - (1.0 - nl / 2) ** 5)
        * (1.0 - (1.0 - nv / 2) ** 5)
    )
    return np.where(visible, diffuse + specular, 0.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("geometry")
    parser.add_argument("mesh")
    for name in ("q0", "omega0", "inertia"):
        parser.add_argument(f"--{name}", required=True)
    for name in ("rd", "rs", "nu"):
        parser.add_argument(f"--{name}", type=float, required=True)
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    table = pd.read_csv(args.geometry, comment="#")
    times = (table["mjd"].to_numpy() - table["mjd"].iloc[0]) * 86400.0
    sun = table[["sun_x", "sun_y", "sun_z"]].to_numpy() * 1e3
    observer = table[["obs_x", "obs_y", "obs_z"]].to_numpy() * 1e3
    normals, areas = read_obj(args.mesh)
    states = truth(
        times,
        np.array([float(v) for v in args.q0.split(",")]),
        np.deg2rad([float(v) for v in args.omega0.split(",")]),
        np.array([float(v) for v in args.inertia.split(",")]),
    )
    flux = np.empty(len(times))
    for e in range(len(times)):
        a = attitude_matrix(states[e, :4])
        r_sun, d = np.linalg.norm(sun[e]), np.linalg.norm(observer[e])
        light, view = a @ (sun[e] / r_sun), a @ (observer[e] / d)
        nl, nv = normals @ light, normals @ view
        rho = ashikhmin_shirley(nl, nv, float(light @ view), args.rd, args.rs, args.nu)
        total = np.sum(rho * areas * np.maximum(nl, 0.0) * np.maximum(nv, 0.0))
        flux[e] = total * (AU_M / r_sun) ** 2 / d**2
    lit = flux > 0
    magnitude = SUN_MAGNITUDE - 2.5 * np.log10(flux[lit])
    pd.DataFrame({"mjd": table["mjd"].to_numpy()[lit], "mag": magnitude}).to_csv(
        args.out, index=False, float_format="%.10f"
    )


if __name__ == "__main__":
    main()
