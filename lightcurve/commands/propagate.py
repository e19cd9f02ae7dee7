"""Propagate a torque-free rigid body and print its attitude, rates and invariants.

The state is integrated with scipy's DOP853 (rtol = atol = 1e-12) by the shared attitude
core. Quaternions are scalar-last and map inertial vectors into the body frame; rates are
printed in deg/s. The rotational kinetic energy and |H| columns show the conservation.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from lightcurve.commands._args import float_vector, inertia_tensor, unit_quaternion

NAME = "propagate"
HELP = "propagate a tumbling rigid body (torque-free) and print its state"
ORDER = 90

# The nutating body of Deng et al. 2024 (scenario A) as the default demonstration.
_NUTATION_INERTIA = "0.85,1.37,1.0,0.13,0.17,-0.11"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--inertia",
        type=inertia_tensor,
        default=_NUTATION_INERTIA,  # a string default goes through the type
        metavar="Jxx,Jyy,Jzz[,Jxy,Jxz,Jyz]",
        help="body-frame inertia, kg m² or any unit (only the ratios matter); the default is "
        "the nutation scenario of docs/monocular.md",
    )
    parser.add_argument(
        "--q0",
        type=unit_quaternion,
        default=np.array([0.0, 0.0, 0.0, 1.0]),
        metavar="q1,q2,q3,q4",
        help="initial attitude quaternion, scalar last, inertial→body",
    )
    parser.add_argument(
        "--omega0",
        type=float_vector(3),
        default=np.array([5.0, 2.3, 3.5]),
        metavar="wx,wy,wz",
        help="initial body rates, deg/s",
    )
    parser.add_argument("--duration", type=float, default=600.0, help="seconds")
    parser.add_argument("--step", type=float, default=60.0, help="output step, s")
    parser.add_argument(
        "--out", metavar="FILE", help="also write the table to this CSV file (default: print only)"
    )


def run(args: argparse.Namespace) -> int:
    import pandas as pd

    from filters.attitude import propagate, quaternion_canonical, validate_inertia

    inertia = validate_inertia(args.inertia)
    if not (args.duration > 0 and args.step > 0):
        raise ValueError("--duration and --step must be positive seconds")
    times = np.arange(0.0, args.duration + 0.5 * args.step, args.step)
    x0 = np.concatenate([args.q0, np.deg2rad(args.omega0)])
    states = propagate(x0, times, inertia)
    q = quaternion_canonical(states[:, :4])  # q4 ≥ 0, as every other command writes it
    w = states[:, 4:]
    table = pd.DataFrame(
        {
            "t_s": times,
            **{f"q{i + 1}": q[:, i] for i in range(4)},
            **{f"w{axis}_deg_s": np.rad2deg(w[:, k]) for k, axis in enumerate("xyz")},
            "energy": 0.5 * np.einsum("ni,ij,nj->n", w, inertia, w),
            "h_norm": np.linalg.norm(w @ inertia.T, axis=1),
        }
    )
    table.to_string(sys.stdout, index=False, float_format=lambda v: f"{v:.6f}")
    sys.stdout.write("\n")
    if args.out:
        from lightcurve.io.atomic import atomic_write_table

        atomic_write_table(table, args.out)
    return 0
