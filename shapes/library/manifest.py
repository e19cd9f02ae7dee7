"""The manifest of a shape library: names, format, reading, entries and atomic updates.

The folder's layout is described in :mod:`shapes.library.core`, whose
:class:`~shapes.library.ShapeLibrary` is the one user of this module.

``manifest.json``::

    {"format": "space-lightcurves shape library", "version": 1,
     "shapes": {"<name>": {
        "mesh": "<name>.obj", "unit": "m" | "km", "sha256": "<hex of the mesh file>",
        "facets": int, "groups": [str, ...],
        "materials": {"<group>": {"brdf": str, "params": {str: float},
                                  "name"?: str, "reference_direction"?: [x, y, z]}},
        "inertia": {"source": "solid" | "shell" | "given", "mass"?: kg,
                    "tensor": 3×3 kg m² about the centre of mass, "center_of_mass": [m]},
        "visibility": "<name>.visibility.npz" | null, "visibility_sha256"?: str,
        "shadows"?: "none",
        "proxy"?: {"mesh": "<name>.proxy.obj", "sha256": str, "facets": int,
                   "visibility": "<name>.proxy.visibility.npz" | null,
                   "visibility_sha256"?: str, "rms_mag": float, "max_mag": float,
                   "geometries": int, "seed": int, "max_phase_deg": float,
                   "shadows": "table" | "none"},
        "provenance": {"source": str, "license": str, "added": "YYYY-MM-DD", ...},
        "parts"?: [{"name": str, "groups": [str, ...],
                    "joint": {"kind": "fixed" | "sun_tracking" | "scheduled", ...}}, ...]}}}

``"shadows": "none"`` marks a non-convex shape added without its table (``add`` with
``visibility_table=False``): it is not built on first use either, until
:meth:`ShapeLibrary.rebuild_visibility` builds it (which drops the mark).

``parts`` (optional) makes the shape articulated: named rigid parts made of mesh groups,
each on a one-axis joint (:mod:`shapes.articulation`). They are validated when added and
when loaded; :meth:`ShapeLibrary.load` with ``articulated=True`` returns an
:class:`~shapes.articulation.ArticulatedModel`.
 Updates are
transactions: files are staged under temporary names, renamed into place with the old
files kept as backups, and the manifest written last; a failure restores everything.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from shapes.errors import ShapeError
from shapes.files import atomic_write, file_sha256
from shapes.io import load as load_mesh
from shapes.material import Material
from shapes.model import FacetModel

__all__ = [
    "FORMAT",
    "LOCK",
    "MANIFEST",
    "VERSION",
    "check_name",
    "entry_files",
    "manifest_entry",
    "manifest_field",
    "read_entry_mesh",
    "read_manifest",
    "swap_in",
    "write_manifest",
]

MANIFEST = "manifest.json"
#: Lock file of writers, beside the manifest.
LOCK = ".manifest.lock"
FORMAT = "space-lightcurves shape library"
VERSION = 1
_NAME = re.compile(r"[A-Za-z0-9_.-]+")


def check_name(name: str) -> str:
    """Return ``name`` if it is a valid shape name (``[A-Za-z0-9_.-]+``, not ``.``/``..``)."""
    if not isinstance(name, str) or not _NAME.fullmatch(name) or name in (".", ".."):
        raise ShapeError(
            f"invalid shape name {name!r}: use letters, digits, '_', '.', '-' "
            "(no path separators, not '.' or '..')"
        )
    return name


def read_manifest(folder: Path) -> dict[str, Any]:
    """The manifest of the library in ``folder`` (an empty one when it has none yet).

    Raises
    ------
    ShapeError
        ``folder`` is a file, or the manifest is unreadable, of another format or version,
        or without a ``shapes`` object (the message names the file).
    """
    path = folder / MANIFEST
    if not path.is_file():
        if folder.exists() and not folder.is_dir():
            raise ShapeError(f"{folder}: not a folder")
        return {"format": FORMAT, "version": VERSION, "shapes": {}}
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ShapeError(f"{path}: unreadable manifest ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ShapeError(f"{path}: not a shape-library manifest")
    if data.get("version") != VERSION:
        raise ShapeError(
            f"{path}: manifest version {data.get('version')!r} is not "
            f"supported (expected {VERSION})"
        )
    if not isinstance(data.get("shapes"), dict):
        raise ShapeError(f"{path}: field 'shapes' must be an object")
    return data


def write_manifest(folder: Path, manifest: dict[str, Any]) -> None:
    """Write ``manifest`` into ``folder`` atomically, shapes sorted by name."""
    manifest["shapes"] = dict(sorted(manifest["shapes"].items()))
    with atomic_write(folder / MANIFEST) as handle:
        handle.write(json.dumps(manifest, indent=2) + "\n")


def entry_files(entry: Mapping[str, Any]) -> list[str]:
    """The file names of a manifest entry: mesh, table, and its proxy's mesh and table."""
    proxy = entry.get("proxy") or {}
    names = [entry.get("mesh"), entry.get("visibility"), proxy.get("mesh"), proxy.get("visibility")]
    return [name for name in names if name]


def manifest_field(entry: Mapping[str, Any], key: str, kind: type, where: str) -> Any:
    """``entry[key]``, checked to be a ``kind`` (the error names ``where`` and the field)."""
    value = entry.get(key)
    if not isinstance(value, kind):
        raise ShapeError(f"{where}: field {key!r} must be a {kind.__name__}, got {value!r}")
    return value


def read_entry_mesh(
    folder: Path, name: str, entry: Mapping[str, Any], files: Mapping[str, Any], where: str
) -> FacetModel:
    """The mesh ``folder / files["mesh"]`` (checked against ``files["sha256"]``) with the
    materials, unit, inertia and provenance of the shape's ``entry`` (``files`` is the entry
    itself, or its ``proxy`` record: a proxy takes the full mesh's stored inertia).

    Raises
    ------
    ShapeError
        A missing or changed file, bad fields (the message starts with ``where``).
    """
    mesh_path = folder / manifest_field(files, "mesh", str, where)
    if not mesh_path.is_file():
        raise ShapeError(f"{where}: mesh file {mesh_path} is missing")
    if file_sha256(mesh_path) != files.get("sha256"):
        raise ShapeError(f"{where}: {mesh_path.name} changed since it was added (sha256 mismatch)")
    materials = {
        group: Material.from_dict(spec, f"{where}, material of group {group!r}")
        for group, spec in manifest_field(entry, "materials", dict, where).items()
    }
    inertia_spec = manifest_field(entry, "inertia", dict, where)
    source = inertia_spec.get("source")
    if source not in ("solid", "shell", "given"):
        raise ShapeError(f"{where}: inertia source must be solid, shell or given")
    given = source == "given" or files is not entry
    return load_mesh(
        mesh_path,
        unit=manifest_field(entry, "unit", str, where),
        name=name,
        materials=materials,
        inertia=np.asarray(inertia_spec.get("tensor"), float) if given else source,
        mass=inertia_spec.get("mass"),
        center_of_mass=inertia_spec.get("center_of_mass") if given else None,
        provenance=entry.get("provenance", {}),
    )


def manifest_entry(
    name: str,
    model: FacetModel,
    final: dict[str, Path],
    staged: dict[str, Path],
    provenance: dict[str, Any],
) -> dict[str, Any]:
    """The manifest entry of ``model`` stored as ``final`` files (checksums of ``staged``).

    Parameters
    ----------
    name : str
    model : FacetModel
        The shape as it will be loaded (materials, inertia, unit).
    final, staged : dict of str to Path
        ``"mesh"`` (and ``"visibility"``) paths: in place, and the staged copies whose
        checksums are recorded.
    provenance : dict
        Source, license, ... (``file`` and ``unit`` are dropped); ``added`` is today.
    """
    inertia: dict[str, Any] = {
        "source": model.inertia_source,
        "tensor": model.inertia.tolist(),
        "center_of_mass": model.center_of_mass.tolist(),
    }
    if not np.isnan(model.mass):
        inertia["mass"] = model.mass
    entry: dict[str, Any] = {
        "mesh": final["mesh"].name,
        "unit": model.unit,
        "sha256": file_sha256(staged["mesh"]),
        "facets": len(model.faces),
        "groups": list(model.group_names),
        "materials": {g: model.materials[g].to_dict() for g in model.group_names},
        "inertia": inertia,
        "visibility": final["visibility"].name if "visibility" in final else None,
        "provenance": {
            "license": "unknown",
            "added": _dt.date.today().isoformat(),
            **{k: v for k, v in provenance.items() if k not in ("file", "unit")},
        },
    }
    if "visibility" in staged:
        entry["visibility_sha256"] = file_sha256(staged["visibility"])
    return entry


def swap_in(
    staged: dict[str, Path],
    final: dict[str, Path],
    old_files: list[Path],
    write_manifest: Callable[[], None],
) -> None:
    """Rename staged files into place and write the manifest; undo everything on failure."""
    backups: list[tuple[Path, Path]] = []
    moved: list[Path] = []
    try:
        for path in {*old_files, *final.values()}:
            if path.exists():
                backup = path.with_name(f".{path.name}.backup")
                os.replace(path, backup)
                backups.append((backup, path))
        for key, path in staged.items():
            os.replace(path, final[key])
            moved.append(final[key])
        write_manifest()
    except BaseException:
        for path in moved:
            path.unlink(missing_ok=True)
        for backup, path in backups:
            os.replace(backup, path)
        raise
    for backup, _ in backups:
        backup.unlink(missing_ok=True)
