"""Does the inertial attitude search of the attitude-mode test find the global optimum?
Prints JSON.

    python -m benchmarks.inertial_search [--leo 40] [--geo 20] [--seed 0] [--out FILE]

Objects: a box-wing held fixed in inertial space at a uniformly random attitude, one
night each, 0.03 mag noise — ``--leo`` of them on the low orbits of the attitude-mode
study (:mod:`benchmarks.attitude_modes`, ``--orbit leo``, epochs every 10 s, redrawn until
two passes of ≥ 20 measurements) and ``--geo`` in its geostationary slots (epochs every
300 s). Object ``i`` of each orbit draws everything from
``numpy.random.default_rng([seed, i, orbit == "leo"])``.

Each light curve's ``inertial`` hypothesis is fitted as ``invert --modes`` fits it
(:func:`lightcurve.attitude_modes.hypotheses.stabilised`, 4096 screened attitudes seeded
by ``i``) but from the uniform attitudes alone, without the starts the tumbling inversion
adds, and compared with a local fit started at the true attitude. A *miss*: the search's
``χ²`` exceeds that local fit's by more than 1 and its attitude is more than 3° from the
truth (symmetry-folded) — a better valley was there to find. A fit within 3° of the
truth with a higher ``χ²`` (a glint-sharp minimum next to it) is counted apart
(``near_misses``). ``cpu_s``: the search's CPU per object (one thread advised:
``OMP_NUM_THREADS=1``).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
import time

import numpy as np

from benchmarks._machine import machine_info
from benchmarks.attitude_modes import NOISE_MAG, geo_geometry, leo_object
from filters.attitude import random_quaternion
from lightcurve.attitude_modes.hypotheses import stabilised
from lightcurve.attitude_modes.offsets import ProfileFit, local_fit
from lightcurve.inversion import shape_symmetry
from lightcurve.io.atomic import atomic_write_json, json_ready
from lightcurve.photometry.measurement import PhotometricModel
from lightcurve.photometry.simulate import GaussianNoise, simulate
from shapes import get_library

#: Screened uniform attitudes (``invert --modes``'s default).
SEARCH_CANDIDATES = 4096
#: A search ``χ²`` this far above the truth's local fit, at more than ``MISS_DEG`` from
#: the truth, is a miss.
MISS_CHI2 = 1.0
MISS_DEG = 3.0


def run_object(seed: int, index: int, orbit: str) -> dict:
    """Simulate inertial object ``index`` on ``orbit`` (``"leo"`` or ``"geo"``) and search
    its attitude."""
    rng = np.random.default_rng([seed, index, orbit == "leo"])
    shape = get_library().load("box_wing")
    truth = random_quaternion(1, rng)[0]
    draw = functools.partial(
        simulate,
        shape=shape,
        q0=truth,
        profile="inertial",
        noise=GaussianNoise(NOISE_MAG),
        seed=rng,
    )
    geometry = None if orbit == "leo" else geo_geometry(rng, 300.0)[0]
    obs = leo_object(rng, 10.0, draw)[1] if geometry is None else draw(geometry)
    record = {"orbit": orbit, "index": index}
    return record | search_against_truth(
        PhotometricModel(obs, {"box_wing": shape}), shape, truth, index
    )


def search_against_truth(model: PhotometricModel, shape, truth: np.ndarray, seed: int) -> dict:
    """Fit the ``inertial`` hypothesis of ``model``'s first shape from uniform attitudes
    alone (screen seeded by ``seed``) and compare it with a local fit started at the true
    attitude ``truth`` (module doc): measurements, both ``χ²``, the symmetry-folded error
    (deg), consistency, miss and near miss, and the search's CPU (s)."""
    symmetry = shape_symmetry(shape)
    cpu0 = time.process_time()
    found = stabilised(
        model,
        0,
        "inertial",
        position=None,
        velocity=None,
        symmetry_order=symmetry.order,
        offset_sigma=math.radians(10.0),
        consistency_level=0.999,
        search_candidates=SEARCH_CANDIDATES,
        rng=np.random.default_rng(seed),
        extra_starts=[],
        weak_sigma=math.radians(1.0),
    )
    cpu = time.process_time() - cpu0
    q_ref = np.broadcast_to(np.array([0.0, 0.0, 0.0, 1.0]), (len(model), 4))
    at_truth = local_fit(ProfileFit(model, 0, q_ref, truth), np.zeros(3), None)
    error = math.degrees(float(symmetry.attitude_error(found.quaternion, truth)))
    worse = found.chi2 > at_truth.chi2 + MISS_CHI2
    return {
        "n_measurements": len(model),
        "chi2": found.chi2,
        "truth_local_chi2": at_truth.chi2,
        "error_deg": error,
        "consistent": found.consistent,
        "miss": bool(worse and error > MISS_DEG),
        "near_miss": bool(worse and error <= MISS_DEG),
        "cpu_s": cpu,
    }


def study(n_leo: int, n_geo: int, seed: int) -> dict:
    """Run the objects and summarise them (module doc)."""
    start = time.perf_counter()
    records = [run_object(seed, i, "leo") for i in range(n_leo)]
    records += [run_object(seed, i, "geo") for i in range(n_geo)]
    summary = {}
    for orbit in ("leo", "geo"):
        rows = [r for r in records if r["orbit"] == orbit]
        cpu = [r["cpu_s"] for r in rows]
        summary[orbit] = {
            "objects": len(rows),
            "misses": int(sum(r["miss"] for r in rows)),
            "missed": [r["index"] for r in rows if r["miss"]],
            "near_misses": int(sum(r["near_miss"] for r in rows)),
            "inconsistent": int(sum(not r["consistent"] for r in rows)),
            "cpu_s_median": float(np.median(cpu)) if cpu else None,
            "cpu_s_total": float(np.sum(cpu)),
        }
    return {
        "study": "inertial attitude search, box-wing, one night, 0.03 mag",
        "seed": seed,
        "search_candidates": SEARCH_CANDIDATES,
        **summary,
        "records": records,
        "wall_s": time.perf_counter() - start,
        "machine": machine_info(),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--leo", type=int, default=40, help="low-orbit objects (default 40)")
    parser.add_argument("--geo", type=int, default=20, help="geostationary objects (default 20)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", help="also write the JSON here")
    args = parser.parse_args(argv)
    report = study(args.leo, args.geo, args.seed)
    print(json.dumps(json_ready(report), indent=1))
    if args.out:
        atomic_write_json(args.out, json_ready(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
