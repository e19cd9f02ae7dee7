"""Manage the shape library: list, show, add, remove, validate, rebuild and render shapes.

The library is the folder given by --library, else $LIGHTCURVE_LIBRARY, else the built-in
library shipped with the project (read-only). See docs/shapes.md for the manifest format.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

import brdf
import shapes
from lightcurve.commands._args import brdf_parameters, show_progress
from lightcurve.commands._source import literal

if TYPE_CHECKING:
    from shapes.articulation import ArticulatedModel

NAME = "shapes"
HELP = "manage the shape library (list, show, add, remove, validate, rebuild, render)"
ORDER = 30


def _floats(text: str, what: str, counts: Sequence[int]) -> list[float]:
    """Comma-separated finite numbers, ``len`` in ``counts``; ShapeError naming the option."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in counts or not all(math.isfinite(v) for v in values):
        raise shapes.ShapeError(
            f"{what}: expected {' or '.join(map(str, counts))} comma-separated finite numbers, "
            f"got {text!r}"
        )
    return values


def add_arguments(parser: argparse.ArgumentParser) -> None:
    library_help = "library folder (default: $LIGHTCURVE_LIBRARY, else the built-in library)"
    parser.add_argument("--library", metavar="DIR", default=None, help=library_help)
    sub = parser.add_subparsers(dest="shapes_command", metavar="ACTION", required=True)

    def action(name: str, help_text: str) -> argparse.ArgumentParser:
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.add_argument("--library", metavar="DIR", default=argparse.SUPPRESS, help=library_help)
        return p

    action("list", "list the shapes of the library")
    p = action("show", "print facets, groups, materials, area, volume and inertia of a shape")
    p.add_argument("name", help="shape name")
    p = action("add", "add a mesh file (OBJ/PLY/STL/GLB/GLTF/DAMIT) as a new shape")
    p.add_argument("name", help="shape name: letters, digits, '_', '.', '-'")
    p.add_argument("mesh", help="mesh file")
    p.add_argument("--brdf", metavar="KIND", help="one material for every group: BRDF name")
    p.add_argument(
        "--param",
        metavar="KEY=VALUE",
        action="append",
        default=[],
        help="BRDF parameter (repeatable), e.g. --param rd=0.4 --param rs=0.3",
    )
    p.add_argument(
        "--units", choices=("m", "km"), default="m", help="length unit of the mesh coordinates"
    )
    p.add_argument(
        "--inertia",
        metavar="Jxx,Jyy,Jzz[,Jxy,Jxz,Jyz]",
        help="given inertia about the centre of mass, kg m² (default: computed)",
    )
    p.add_argument("--mass", type=float, help="mass, kg (scales a computed inertia)")
    p.add_argument("--source", help="provenance: where the mesh comes from")
    p.add_argument("--license", help="provenance: licence of the mesh")
    p.add_argument(
        "--parts",
        metavar="PARTS.json",
        help="articulated parts: a JSON list of {name, groups, joint} (docs/shapes.md)",
    )
    p.add_argument(
        "--shadows",
        choices=("table", "none"),
        default="table",
        help="table: build the visibility table of a non-convex shape now (minutes for 10⁵ "
        "facets); none: skip it (shadows then ray-cast, or off; `shapes rebuild NAME` builds "
        "it later)",
    )
    threshold = literal("shapes.library.proxy", "PROXY_MIN_FACETS")
    p.add_argument(
        "--proxy",
        choices=("auto", "none"),
        default="auto",
        help=f"auto: a mesh of more than {threshold} facets also gets a level-of-detail "
        "proxy for the inversions (quadric decimation, its light-curve error measured over "
        "10⁴ random geometries; tens of seconds); none: skip it",
    )
    p.add_argument("--force", action="store_true", help="replace an existing shape")
    p = action("remove", "remove a shape")
    p.add_argument("name", help="shape name")
    p = action("validate", "check every shape (or one): checksum, mesh, materials, tables")
    p.add_argument("name", nargs="?", help="shape name (default: every shape)")
    p = action(
        "rebuild",
        "rebuild the visibility tables of every non-convex shape (or one), e.g. tables written "
        "in an older format or skipped at add; keeps each table's resolution and sampling; a "
        "shape's level-of-detail proxy is chosen and measured again with the new table",
    )
    p.add_argument("name", nargs="?", help="shape name (default: every non-convex shape)")
    p = action("render", "write a PNG preview coloured by material")
    p.add_argument("name", help="shape name")
    p.add_argument("--out", required=True, metavar="FILE.png", help="output PNG")
    p.add_argument(
        "--view",
        default="1,-1,0.6",
        metavar="x,y,z",
        help="direction toward the viewer, body frame",
    )
    p.add_argument(
        "--sun",
        metavar="x,y,z",
        help="articulated shapes: body-frame Sun direction that poses the Sun-tracking parts "
        "(default: every joint at angle 0)",
    )
    p.add_argument(
        "--angle",
        metavar="PART=DEG",
        action="append",
        default=[],
        help="articulated shapes: joint angle of a part, degrees (repeatable)",
    )


def run(args: argparse.Namespace) -> int:
    from shapes.library import LibraryReadOnlyError

    library = shapes.get_library(args.library)
    command = args.shapes_command
    try:
        return _ACTIONS[command](library, args)
    except LibraryReadOnlyError:
        raise shapes.ShapeError(
            f"the built-in shape library ({library.path}) is read-only; pass --library DIR "
            f"(or set $LIGHTCURVE_LIBRARY) to {command} shapes in a library of your own"
        ) from None


def _list(library: shapes.ShapeLibrary, args: argparse.Namespace) -> int:
    names = library.names()
    print(f"# {library.path}{' (read-only)' if library.read_only else ''}: {len(names)} shapes")
    if not library.path.exists():
        print(
            f"# (no library there yet: `lightcurve shapes add NAME MESH --library {library.path}`)"
        )
    rows = [("name", "facets", "unit", "groups", "self-shadowing", "proxy", "source")]
    for name in names:
        entry = library.info(name)
        provenance = entry.get("provenance", {})
        rows.append(
            (
                name,
                str(entry.get("facets", "?")),
                str(entry.get("unit", "?")),
                ",".join(entry.get("groups", [])),
                _self_shadowing(entry),
                _proxy_column(entry.get("proxy")),
                str(provenance.get("source", "")),
            )
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for row in rows:
        print("  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip())
    return 0


def _self_shadowing(entry: dict[str, Any]) -> str:
    """The ``list`` column: a table, skipped at add (``--shadows none``), or convex."""
    if entry.get("visibility"):
        return "table"
    return "none (skipped: shapes rebuild)" if entry.get("shadows") else "none (convex)"


def _proxy_column(proxy: dict[str, Any] | None) -> str:
    """The ``list`` column: the proxy's facets and rms error, or ``-``."""
    if proxy is None:
        return "-"
    return f"{proxy['facets']} ({proxy['rms_mag']:.4f} mag rms)"


def _proxy_text(proxy: dict[str, Any]) -> str:
    """One line on a proxy: facets, error and how it was measured."""
    return (
        f"{proxy['facets']} facets, light-curve error {proxy['rms_mag']:.4f} mag rms "
        f"(max {proxy['max_mag']:.3f}) over {proxy['geometries']} random geometries "
        f"(seed {proxy['seed']}, phase ≤ {proxy['max_phase_deg']:g}°, shadows "
        f"{proxy['shadows']})"
    )


#: Entries smaller than this fraction of the largest printed as 0 (round-off, not data).
_ROUND_OFF = 1e-12


def _matrix(matrix: np.ndarray) -> str:
    """Rows of ``%14.6g`` numbers; round-off (``-2.89e-17`` beside 5902.7) printed as 0."""
    matrix = np.asarray(matrix, dtype=float)
    scale = float(np.max(np.abs(matrix), initial=0.0))
    shown = np.where(np.abs(matrix) <= _ROUND_OFF * scale, 0.0, matrix)
    return "\n".join("    " + "  ".join(f"{v:14.6g}" for v in row) for row in shown)


def _show(library: shapes.ShapeLibrary, args: argparse.Namespace) -> int:
    entry = library.info(args.name)
    model = library.load(args.name, build_visibility=False)
    compiled = model.compiled()
    print(f"shape {args.name}  ({library.path / entry['mesh']}, source unit {model.unit})")
    print(f"  facets: {len(model.faces)}  vertices: {len(model.vertices)}  ", end="")
    print(f"effective facets (merged): {len(compiled)}")
    print(f"  watertight: {model.is_watertight}  convex: {model.is_convex}  ", end="")
    table = model.visibility
    print(f"visibility table: {f'{len(table.grid)} directions' if table else 'none'}")
    print(f"  area: {model.area:.6g} m²  ", end="")
    print(f"volume: {f'{model.volume:.6g} m³' if model.volume is not None else 'n/a (open mesh)'}")
    print("  groups:")
    for k, group in enumerate(model.group_names):
        members = model.group_index == k
        material = model.materials[group]
        params = ", ".join(f"{p}={v:g}" for p, v in material.params.items())
        label = f" '{material.name}'" if material.name else ""
        print(
            f"    {group}: {int(members.sum())} facets, {model.areas[members].sum():.6g} m², "
            f"{material.brdf}({params}){label}"
        )
    mass = f"{model.mass:.6g} kg" if not math.isnan(model.mass) else "not given"
    print(f"  inertia ({model.inertia_source}, mass {mass}), kg m², about the centre of mass")
    centre = np.array2string(model.center_of_mass, precision=6, suppress_small=True)
    print(f"  centre of mass: {centre} m")
    print(_matrix(model.inertia))
    print(f"  principal moments: {np.array2string(model.principal_moments, precision=6)} kg m²")
    print("  principal axes (columns):")
    print(_matrix(model.principal_axes))
    if entry.get("proxy") is not None:
        print(f"  level-of-detail proxy: {_proxy_text(entry['proxy'])}")
    articulation = library.articulation(args.name)
    if articulation is not None:
        print(
            f"  parts: {len(articulation.parts)} (articulated; unnamed groups move with the body)"
        )
        for part in articulation.parts:
            print(f"    {part.name}: groups {', '.join(part.groups)}; {_joint_text(part.joint)}")
    for key, value in entry.get("provenance", {}).items():
        print(f"  {key}: {value}")
    return 0


def _joint_text(joint: Any) -> str:
    """One line describing a joint."""
    if joint.kind == "fixed":
        return "fixed joint"

    def vec(v: np.ndarray) -> str:
        return "[" + ", ".join(f"{x:g}" for x in v) + "]"

    low, high = joint.limits_deg
    text = (
        f"{joint.kind} joint about {vec(joint.axis)} through {vec(joint.pivot)} m, "
        f"limits [{low:g}, {high:g}] deg, offset {joint.offset_deg:g} deg"
    )
    if joint.normal is not None:
        text += f", normal {vec(joint.normal)}"
    if joint.column is not None:
        text += f", angle from column {joint.column!r}"
    return text


def _read_parts(path: str) -> Any:
    """The JSON list of parts of ``shapes add --parts``."""
    try:
        with open(path, encoding="utf-8") as handle:
            return json.load(handle)
    except (OSError, json.JSONDecodeError) as exc:
        raise shapes.ShapeError(f"--parts {path}: unreadable JSON ({exc})") from None


def _material(kind: str, items: Sequence[str]) -> shapes.Material:
    """The material of ``--brdf KIND --param KEY=VALUE …``; a missing parameter is named with
    the model's typical value as the option to pass."""
    from shapes.material import BRDF_PARAMETERS

    params = brdf_parameters(items)
    try:
        return shapes.Material(kind, params)
    except shapes.ShapeError as exc:
        missing = [name for name in BRDF_PARAMETERS.get(kind, ((), ()))[0] if name not in params]
        if not missing:
            raise
        typical = {spec.name: spec.default for spec in brdf.describe(kind).parameters}
        example = " ".join(f"--param {name}={typical[name]:g}" for name in missing)
        raise shapes.ShapeError(f"{exc}: give them, e.g. {example}") from None


def _add(library: shapes.ShapeLibrary, args: argparse.Namespace) -> int:
    from lightcurve.photometry.proxy_error import ProxyErrorMeter

    if args.param and not args.brdf:
        raise shapes.ShapeError("--param needs --brdf KIND")
    material = _material(args.brdf, args.param) if args.brdf else None
    if material is not None:
        brdf.get(material.brdf, **material.params)  # parameter ranges (BRDFParameterError)
    inertia = "auto" if args.inertia is None else _floats(args.inertia, "--inertia", (3, 6))
    provenance = {k: v for k, v in (("source", args.source), ("license", args.license)) if v}

    def announce(line: str) -> None:
        skip = "--proxy none" if line.startswith("level-of-detail") else "--shadows none"
        if not args.quiet:
            print(f"building the {line} ({skip} skips it)", file=sys.stderr, flush=True)

    model = library.add(
        args.name,
        args.mesh,
        unit=args.units,
        materials=material,
        inertia=inertia,
        mass=args.mass,
        provenance=provenance,
        force=args.force,
        progress=show_progress(args),
        parts=_read_parts(args.parts) if args.parts else None,
        visibility_table=args.shadows == "table",
        announce=announce,
        proxy_meter=ProxyErrorMeter(progress=show_progress(args)) if args.proxy == "auto" else None,
    )
    if not args.quiet:
        print(
            f"added {args.name}: {len(model.faces)} facets, {len(model.compiled())} effective, "
            f"groups {', '.join(model.group_names)}, inertia {model.inertia_source}"
            + (", visibility table built" if model.visibility is not None else "")
            + (
                f", no visibility table (`lightcurve shapes rebuild {args.name}` builds it)"
                if model.visibility is None and not model.is_convex
                else ""
            )
            + (", parts " + ", ".join(library.articulation(args.name).names) if args.parts else "")
        )
        proxy = library.info(args.name).get("proxy")
        if proxy is not None:
            print(f"proxy of {args.name}: {_proxy_text(proxy)}")
    return 0


def _remove(library: shapes.ShapeLibrary, args: argparse.Namespace) -> int:
    library.remove(args.name)
    if not args.quiet:
        print(f"removed {args.name}")
    return 0


def _validate(library: shapes.ShapeLibrary, args: argparse.Namespace) -> int:
    names = [args.name] if args.name else library.names()
    failed = 0
    for name in names:
        try:
            model = library.validate(name)
        except (ValueError, OSError) as exc:
            failed += 1
            print(f"FAILED {name}: {exc}", file=sys.stderr)
            continue
        detail = "convex" if model.is_convex else "visibility table ok"
        print(f"ok {name}: {len(model.faces)} facets, {len(model.compiled())} effective, {detail}")
    print(f"{len(names) - failed} of {len(names)} shapes valid")
    return 1 if failed else 0


def _rebuild(library: shapes.ShapeLibrary, args: argparse.Namespace) -> int:
    from lightcurve.photometry.proxy_error import ProxyErrorMeter

    names = [args.name] if args.name else library.names()
    for name in names:
        progress = show_progress(args)
        meter = ProxyErrorMeter(progress=progress)
        model = library.rebuild_visibility(name, progress=progress, proxy_meter=meter)
        table = model.visibility
        if args.quiet:
            continue
        if table is None:
            print(f"{name}: convex, no visibility table")
            continue
        print(
            f"rebuilt {name}: {len(table.grid)} directions, {table.n_points} sample points, "
            f"{table.bits.nbytes / 2**20:.1f} MiB of bits"
        )
        proxy = library.info(name).get("proxy")
        if proxy is not None:
            print(f"proxy of {name}: {_proxy_text(proxy)}")
    return 0


def _render(library: shapes.ShapeLibrary, args: argparse.Namespace) -> int:
    from shapes.articulation import ArticulatedModel
    from shapes.preview import render_preview

    view = _floats(args.view, "--view", (3,))
    model = library.load(args.name, build_visibility=False, articulated=True)
    if isinstance(model, ArticulatedModel):
        model = _pose(model, args)
    elif args.sun or args.angle:
        raise shapes.ShapeError(f"--sun/--angle: shape {args.name!r} has no articulated parts")
    render_preview(model, args.out, view)
    print(f"wrote {args.out}")
    return 0


def _pose(model: ArticulatedModel, args: argparse.Namespace) -> shapes.FacetModel:
    """The shape with its moving parts turned per --sun and --angle."""
    from shapes.articulation import axis_rotation

    moving = model.articulation.moving
    angles = np.zeros(len(moving))
    if args.sun:
        sun = np.asarray(_floats(args.sun, "--sun", (3,)))
        for k, part in enumerate(moving):
            if part.joint.kind == "sun_tracking":
                angles[k] = part.joint.angles(sun, None, f"part {part.name!r}")
    names = [p.name for p in moving]
    for item in args.angle:
        name, _, value = item.partition("=")
        if name not in names:
            raise shapes.ShapeError(
                f"--angle {item!r}: no moving part {name!r} (moving parts: {', '.join(names)})"
            )
        joint = moving[names.index(name)].joint
        angle = _floats(value, f"--angle {name}", (1,))[0]
        low, high = joint.limits_deg
        if not low <= angle <= high:
            raise shapes.ShapeError(
                f"--angle {name}: {angle:g} deg is outside the joint limits [{low:g}, {high:g}]"
            )
        angles[names.index(name)] = angle
    rotations = (
        np.stack(
            [
                axis_rotation(p.joint.axis, np.radians(a))
                for p, a in zip(moving, angles, strict=True)
            ]
        )
        if moving
        else np.zeros((0, 3, 3))
    )
    return model.posed(rotations)


_ACTIONS: dict[str, Any] = {
    "list": _list,
    "show": _show,
    "add": _add,
    "remove": _remove,
    "validate": _validate,
    "rebuild": _rebuild,
    "render": _render,
}
