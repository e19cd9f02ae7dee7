"""Simulate a light curve of a library shape over the epochs of a geometry file.

GEOMETRY is an observation file (CSV, Parquet) whose mag columns may be absent. By default
(--profile torque-free) the attitude --q0/--omega0 holds at its first epoch and the body
tumbles torque-free with the shape's inertia (or --inertia). A stabilised --profile holds
the attitude a control system would: inertial (fixed at --q0, default the identity), nadir
(LVLH: body z to nadir, x along the velocity, y along the negative orbit normal; with
--yaw-steering turned about z to keep the Sun in the body x-z plane; needs the obj_*
columns that `lightcurve geometry` writes) or sun-pointing (body z to the Sun, x towards
the celestial north pole), composed with a fixed --offset-deg ROLL,PITCH,YAW. The parts of
an articulated shape follow their joints (Sun-tracking, or angles from the file's columns)
and their angles are written as joint_<part>_deg. The output is an observation file with
mag and mag_err filled and the truth columns q1 q2 q3 q4 (inertial→body) and wx wy wz
(rad/s) added. --band (with --magnitude-system) gives the magnitudes in another band than
V, from the Sun's magnitude in it, and records it in the header. Epochs when the object is
dark, or undetected under --ccd or --conditions, are dropped and counted in the file's
header. Below 27 970 km (a file with the obj_* columns) the Earth's reflected light is
added (--earthshine auto; off drops it) with its share in an earthshine_fraction column.

Noise: --noise-mag (Gaussian magnitudes), --ccd (photon noise with a sky and read noise), or
the observing conditions of a telescope and site (--conditions FILE.toml or a name in
a built-in telescope, e.g. half_metre; --condition TABLE.KEY=VALUE overrides one value and may be
given alone to start from the 0.5 m defaults): extinction with airmass, seeing losses,
sky, dark current, read noise, gain, scintillation and saturation, with the columns
extinction_mag and saturated added (see docs/rendering.md).
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

import numpy as np

from lightcurve.commands._args import (
    add_band_options,
    add_earthshine_option,
    band_of,
    float_vector,
    inertia_tensor,
    unit_quaternion,
)
from lightcurve.commands._source import dataclass_fields, literal

if TYPE_CHECKING:
    from lightcurve.photometry.simulate import CCDNoise

NAME = "simulate"
HELP = "simulate a light curve of a library shape over a geometry file"
ORDER = 20


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("geometry", metavar="GEOMETRY", help="observation/geometry file")
    parser.add_argument("--shape", required=True, help="shape name in the library")
    parser.add_argument(
        "--library",
        metavar="DIR",
        help="shape library folder (default: $LIGHTCURVE_LIBRARY or built-in)",
    )
    parser.add_argument(
        "--q0",
        type=unit_quaternion,
        metavar="q1,q2,q3,q4",
        help="attitude at the first epoch, scalar last, inertial→body (torque-free, required);"
        " the fixed attitude of --profile inertial (default the identity)",
    )
    parser.add_argument(
        "--omega0",
        type=float_vector(3),
        metavar="wx,wy,wz",
        help="body rates at the first epoch, deg/s (torque-free, required)",
    )
    parser.add_argument(
        "--profile",
        choices=literal("lightcurve.photometry.profiles", "PROFILES"),
        default="torque-free",
        help="attitude profile (torque-free: tumbling from --q0/--omega0)",
    )
    parser.add_argument(
        "--offset-deg",
        type=float_vector(3),
        metavar="ROLL,PITCH,YAW",
        help="fixed 3-2-1 offset of a stabilised profile from its frame, deg (default: 0,0,0)",
    )
    parser.add_argument(
        "--yaw-steering",
        action="store_true",
        help="nadir profile: yaw about the nadir axis to keep the Sun in the body x-z plane",
    )
    add_earthshine_option(parser)
    parser.add_argument(
        "--calibration",
        metavar="FILE",
        help="calibration.json of `lightcurve calibrate`: its materials, magnitude offset, "
        "attitude and joint offsets replace the library's (and its earthshine choice, under "
        "--earthshine auto)",
    )
    add_band_options(
        parser,
        "the Sun's magnitude in it (Willmer 2018) replaces V's, recorded in the header",
    )
    parser.add_argument(
        "--inertia",
        type=inertia_tensor,
        metavar="Jxx,Jyy,Jzz[,Jxy,Jxz,Jyz]",
        help="body-frame inertia, kg m² (only the ratios matter) (default: the shape's)",
    )
    noise = parser.add_mutually_exclusive_group()
    noise.add_argument(
        "--noise-mag", type=float, metavar="SIGMA", help="Gaussian noise, mag (default: none)"
    )
    noise.add_argument(
        "--ccd",
        nargs="*",
        metavar="KEY=VALUE",
        help="CCD photon-noise model; keys: "
        + ", ".join(dataclass_fields("lightcurve.photometry.noise", "CCDNoise"))
        + " (defaults: a 0.5 m telescope, 1 s exposures)",
    )
    noise.add_argument(
        "--conditions",
        metavar="FILE.toml|NAME",
        help="observing conditions: a TOML file with [telescope] [detector] [site] [sky] "
        "[photometry] tables, or a built-in telescope name (half_metre)",
    )
    parser.add_argument(
        "--condition",
        action="append",
        default=[],
        metavar="TABLE.KEY=VALUE",
        help="override one observing condition (repeatable), e.g. site.seeing_fwhm_arcsec=1.5 "
        "or photometry.saturated=drop; alone, starts from the 0.5 m defaults",
    )
    parser.add_argument(
        "--shadows",
        choices=literal("lightcurve.photometry.render", "SHADOW_MODES"),
        default="auto",
        help="self-shadowing: none, the shape's visibility table, ray casting, or auto "
        "(the table when the shape has one, else none)",
    )
    parser.add_argument("--seed", type=int, default=0, help="noise seed")
    parser.add_argument(
        "--out", required=True, metavar="FILE", help="output file (.csv or .parquet)"
    )


def _ccd(pairs: list[str]) -> CCDNoise:
    from lightcurve.photometry.simulate import CCDNoise

    values = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or key not in CCDNoise.__dataclass_fields__:
            raise ValueError(
                f"--ccd expects KEY=VALUE with KEY in {', '.join(CCDNoise.__dataclass_fields__)}"
                f", got {pair!r}"
            )
        try:
            values[key] = float(value)
        except ValueError:
            raise ValueError(f"--ccd {key}: not a number: {value!r}") from None
    return CCDNoise(**values)


def run(args: argparse.Namespace) -> int:
    from lightcurve import io
    from lightcurve.photometry.conditions import load_conditions
    from lightcurve.photometry.simulate import GaussianNoise, ObservingNoise, simulate
    from shapes import FacetModel, get_library

    if args.profile == "torque-free" and (args.q0 is None or args.omega0 is None):
        raise ValueError(
            "--profile torque-free (the default) needs --q0 and --omega0, the attitude and "
            "body rates at the first epoch"
        )
    if args.profile != "torque-free" and args.omega0 is not None:
        raise ValueError(f"--omega0 does not apply to --profile {args.profile}")
    if args.profile not in ("torque-free", "inertial") and args.q0 is not None:
        raise ValueError(f"--q0 does not apply to --profile {args.profile}")
    if args.yaw_steering and args.profile != "nadir":
        raise ValueError("--yaw-steering applies to --profile nadir only")
    if args.offset_deg is not None and args.profile == "torque-free":
        raise ValueError("--offset-deg applies to stabilised profiles only")
    band = band_of(args)
    geometry = io.read(args.geometry, require_magnitudes=False)
    library = get_library(args.library)
    shape = library.load(args.shape, visibility=args.shadows != "none", articulated=True)
    rigid = isinstance(shape, FacetModel)
    if args.shadows == "table" and rigid and shape.visibility is None and not shape.is_convex:
        raise ValueError(library.missing_table(args.shape))
    magnitude_offset, offset_deg, earthshine = 0.0, args.offset_deg, args.earthshine
    if args.calibration is not None:
        shape, magnitude_offset, offset_deg, earthshine = _calibrated(args, shape)
    if args.condition and (args.noise_mag is not None or args.ccd is not None):
        raise ValueError("--condition goes with --conditions (or alone), not --noise-mag/--ccd")
    if args.noise_mag is not None:
        noise = GaussianNoise(args.noise_mag)
    elif args.ccd is not None:
        noise = _ccd(args.ccd)
    elif args.conditions is not None or args.condition:
        noise = ObservingNoise(load_conditions(args.conditions, args.condition))
    else:
        noise = None
    result = simulate(
        geometry,
        shape,
        q0=args.q0,
        omega0=None if args.omega0 is None else np.deg2rad(args.omega0),
        inertia=args.inertia,
        noise=noise,
        shadows=args.shadows,
        seed=args.seed,
        profile=args.profile,
        offset_deg=offset_deg,
        yaw_steering=args.yaw_steering,
        band=band,
        magnitude_offset=magnitude_offset,
        earthshine=earthshine,
    )
    io.write(result, args.out)
    notes = [
        f"{result.meta[key]} {what} dropped"
        for key, what in (
            ("dropped_dark", "dark epochs"),
            ("dropped_nondetections", "non-detections"),
            ("dropped_saturated", "saturated points"),
        )
        if key in result.meta
    ]
    if "saturated" in result.table and result.table["saturated"].any():
        notes.append(f"{int(result.table['saturated'].sum())} saturated points flagged")
    print(
        f"{args.out}: {len(result)} measurements of {shape.name}, "
        f"mag {result.magnitudes.min():.2f}..{result.magnitudes.max():.2f}"
        + "".join(f", {note}" for note in notes)
    )
    return 0


def _calibrated(args: argparse.Namespace, shape):
    """The shape with the materials and joint offsets of ``--calibration``, its magnitude
    offset, the profile's offsets (the calibration's, or ``--offset-deg``, not both) and the
    earthshine mode (``--earthshine auto`` follows the calibration's model)."""
    import json
    from pathlib import Path

    from shapes import Material
    from shapes.articulation import ArticulatedModel

    try:
        calibration = json.loads(Path(args.calibration).read_text(encoding="utf-8"))
        materials = calibration["materials"]
        magnitude_offset = float(calibration["magnitude_offset"])
        offset_deg = np.asarray(calibration["offset_deg"], dtype=float)
        joint_offsets = {k: float(v) for k, v in calibration.get("joint_offsets_deg", {}).items()}
        earthshine = bool(calibration.get("earthshine", False))
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as error:
        raise ValueError(
            f"--calibration {args.calibration}: not a calibration file ({error})"
        ) from None
    if calibration.get("shape") != shape.name:
        raise ValueError(
            f"--calibration {args.calibration} is of shape {calibration.get('shape')!r}, "
            f"not {shape.name!r}"
        )
    unknown = sorted(set(materials) - set(shape.materials))
    if unknown:
        raise ValueError(f"--calibration: {shape.name} has no material group {', '.join(unknown)}")
    if np.any(offset_deg) and args.offset_deg is not None:
        raise ValueError("--offset-deg and a calibration with attitude offsets: give one")
    calibrated = {
        group: Material(entry["brdf"], entry["params"], name=entry.get("name", group))
        for group, entry in materials.items()
    }
    shape = shape.replace(materials={**shape.materials, **calibrated})
    if joint_offsets:
        if not isinstance(shape, ArticulatedModel):
            raise ValueError(f"--calibration: joint offsets, but {shape.name} has no parts")
        shape = shape.with_joint_offsets(joint_offsets)
    offsets = args.offset_deg if args.offset_deg is not None else offset_deg
    mode = args.earthshine if args.earthshine != "auto" else ("on" if earthshine else "off")
    return shape, magnitude_offset, offsets if np.any(offsets) else args.offset_deg, mode
