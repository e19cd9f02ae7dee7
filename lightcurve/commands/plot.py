"""Plot an inversion result folder (DIR/<stem> written by `lightcurve invert`).

Writes PNGs into the folder (or --out): light_curve.png (measured vs fitted with
residuals), states.png (attitude and rate estimates with 3-sigma bands; errors against truth
when the input has truth columns, modulo the rotational symmetry group of the result's shape:
each epoch's estimate is mapped to its symmetry-equivalent state nearest the truth),
probabilities.png (shape probabilities over time, for several candidate shapes) and
modes.png (the particle filter's final attitude modes).
"""

from __future__ import annotations

import argparse

NAME = "plot"
HELP = "plot an inversion result folder as PNG figures"
ORDER = 35


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("result", metavar="DIR/STEM", help="one input's result folder")
    parser.add_argument(
        "--out",
        "--out-dir",
        dest="out",
        metavar="DIR",
        help="where to write the PNGs (default: the result folder; --out-dir is a deprecated "
        "spelling)",
    )
    parser.add_argument(
        "--library",
        metavar="DIR",
        help="shape library of the inversion, for the shape's symmetry group (default: "
        "$LIGHTCURVE_LIBRARY or built-in)",
    )


def run(args: argparse.Namespace) -> int:
    from lightcurve.plots import plot_result

    for path in plot_result(args.result, args.out, args.library):
        print(path)
    return 0
