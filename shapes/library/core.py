"""The shape library: a folder of mesh files with a JSON manifest.

Layout::

    <library>/manifest.json              the manifest
    <library>/<name>.obj                 one mesh per shape (any format trimesh reads)
    <library>/<name>.visibility.npz      visibility table of non-convex shapes
    <library>/<name>.proxy.obj           level-of-detail proxy of a big shape (and its
    <library>/<name>.proxy.visibility.npz  table), :mod:`shapes.library.proxy`
    <library>/.manifest.lock             file lock of writers

The fields of ``manifest.json`` are described in :mod:`shapes.library.manifest`.

For ``"given"`` inertia the tensor and centre of mass are used as stored; for ``"solid"`` and
``"shell"`` they are recomputed from the mesh (uniform density, scaled to ``mass`` when
present) and stored for reference. Writers hold a :mod:`filelock` lock, write files to
temporary names and rename them into place, and roll back on failure, so a failed ``add``
or ``remove`` leaves the library as it was.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from filelock import FileLock

from shapes.articulation import ArticulatedModel, Articulation
from shapes.errors import ShapeError
from shapes.files import file_sha256, temp_path
from shapes.io import load as load_mesh
from shapes.io import write_obj
from shapes.library.manifest import (
    LOCK,
    MANIFEST,
    check_name,
    entry_files,
    manifest_entry,
    manifest_field,
    read_entry_mesh,
    read_manifest,
    swap_in,
    write_manifest,
)
from shapes.library.proxy import PROXY_MIN_FACETS, ProxyMeter, stage_proxy
from shapes.material import Material
from shapes.model import FacetModel
from shapes.validation import validate
from shapes.visibility.build import (
    build_visibility_table,
    describe_build,
    stored_build_options,
)
from shapes.visibility.sampling import DEFAULT_SAMPLES, DEFAULT_SPACING
from shapes.visibility.table import DEFAULT_RESOLUTION, TableFormatError, VisibilityTable

__all__ = [
    "MANIFEST",
    "LibraryReadOnlyError",
    "ShapeLibrary",
    "builtin_library_path",
    "check_name",
    "get_library",
]

logger = logging.getLogger(__name__)
_TABLE_OPTIONS = ("resolution", "samples", "spacing")  # a table's build options


class LibraryReadOnlyError(ShapeError, PermissionError):
    """A write (add/remove) was attempted on a read-only library."""


def builtin_library_path() -> Path:
    """The built-in library: package data of :mod:`shapes` (``shapes/data/``), read-only."""
    return Path(str(resources.files("shapes").joinpath("data")))


def get_library(path: str | os.PathLike[str] | None = None) -> ShapeLibrary:
    """The library at ``path``, else ``$LIGHTCURVE_LIBRARY``, else the built-in one.

    The built-in library is opened read-only.
    """
    if path is None:
        path = os.environ.get("LIGHTCURVE_LIBRARY") or None
    if path is None:
        return ShapeLibrary(builtin_library_path(), read_only=True)
    path = Path(path)
    builtin = path.exists() and path.resolve() == builtin_library_path().resolve()
    return ShapeLibrary(path, read_only=builtin)


class ShapeLibrary:
    """A folder of named shapes with a JSON manifest (see the module docstring).

    Parameters
    ----------
    path : path-like
        The folder (created by the first :meth:`add`).
    read_only : bool
        Refuse :meth:`add` and :meth:`remove` (the built-in library).
    """

    def __init__(self, path: str | os.PathLike[str], read_only: bool = False) -> None:
        self.path = Path(path)
        self.read_only = read_only

    def __repr__(self) -> str:
        mode = ", read-only" if self.read_only else ""
        return f"ShapeLibrary({str(self.path)!r}{mode})"

    # ------------------------------------------------------------------ reading
    @property
    def manifest_path(self) -> Path:
        return self.path / MANIFEST

    def _read_manifest(self) -> dict[str, Any]:
        return read_manifest(self.path)

    def names(self) -> list[str]:
        """Sorted shape names."""
        return sorted(self._read_manifest()["shapes"])

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name in self._read_manifest()["shapes"]

    def info(self, name: str) -> dict[str, Any]:
        """The manifest entry of a shape (a copy)."""
        shapes = self._read_manifest()["shapes"]
        if name not in shapes:
            known = ", ".join(sorted(shapes)) or "none"
            raise ShapeError(f"no shape {name!r} in library {self.path} (shapes: {known})")
        return json.loads(json.dumps(shapes[name]))

    def articulation(self, name: str) -> Articulation | None:
        """The validated parts of an articulated shape, or None for a rigid one."""
        entry = self.info(check_name(name))
        if "parts" not in entry:
            return None
        return Articulation.from_list(
            entry["parts"], entry.get("groups", []), f"{self.manifest_path}: shape {name!r}"
        )

    def load(
        self,
        name: str,
        *,
        build_visibility: bool = True,
        visibility: bool = True,
        articulated: bool = False,
    ) -> FacetModel | ArticulatedModel:
        """Load a shape with its materials, inertia and visibility table.

        Parameters
        ----------
        name : str
        build_visibility : bool
            For a non-convex shape without a stored table, build one (and store it when the
            library is writable).
        visibility : bool
            Attach the visibility table (stored or built). False skips reading, checking and
            building it: for renderers without self-shadowing (``shadows="none"``).
        articulated : bool
            For a shape with ``parts``, return an
            :class:`~shapes.articulation.ArticulatedModel` (its rigid model at joint angle 0
            otherwise, the form every rigid consumer reads).

        Raises
        ------
        ShapeError
            Unknown name, mesh file missing or changed since it was added (checksum), bad
            manifest fields, a stored table that does not fit the mesh.
        """
        entry = self.info(check_name(name))
        where = f"{self.manifest_path}: shape {name!r}"
        if articulated:
            parts = self.articulation(name)
            model = self.load(name, build_visibility=build_visibility, visibility=visibility)
            return model if parts is None else ArticulatedModel(model, parts)
        model = read_entry_mesh(self.path, name, entry, entry, where)
        if not visibility:
            return model
        if entry.get("visibility"):
            try:
                return model.with_visibility(self._read_table(entry))
            except TableFormatError as exc:
                if self.read_only or not build_visibility:
                    raise ShapeError(f"{where}: {exc}: {self._rebuild_hint(name)}") from None
                logger.warning("%s: %s; rebuilding it", where, exc)
                return self._rebuild(name, model, entry, self.path / entry["visibility"])
            except ShapeError as exc:
                raise ShapeError(f"{where}: {exc}") from None
        if not build_visibility or model.is_convex or entry.get("shadows") == "none":
            return model
        model = model.with_visibility(build_visibility_table(model))
        if not self.read_only:
            self._store_table(name, entry["sha256"], model)
        return model

    def _read_table(self, files: Mapping[str, Any]) -> VisibilityTable | None:
        """The table named by ``files["visibility"]`` (checked against its checksum)."""
        table_name = files.get("visibility")
        if not table_name:
            return None
        table_path = self.path / table_name
        if not table_path.is_file() or file_sha256(table_path) != files.get("visibility_sha256"):
            raise ShapeError(f"visibility table {table_name} missing or changed")
        return VisibilityTable.load(table_path)

    def proxy_info(self, name: str) -> dict[str, Any] | None:
        """The ``proxy`` record of a shape, its fields checked (None without a proxy)."""
        record = self.info(check_name(name)).get("proxy")
        where = f"{self.manifest_path}: proxy of shape {name!r}"
        if record is not None and not isinstance(record, dict):
            raise ShapeError(f"{where}: field 'proxy' must be an object, got {record!r}")
        fields = (("facets", int), ("rms_mag", float), ("max_mag", float), ("shadows", str))
        for key, kind in fields if record is not None else ():
            manifest_field(record, key, kind, where)
        return record

    def load_proxy(self, name: str) -> FacetModel | None:
        """The level-of-detail proxy of a shape (:mod:`shapes.library.proxy`) with its own
        visibility table, or None for a shape without one.

        Its materials, unit and mass properties are the full shape's; its error against the
        full shape is the :meth:`proxy_info` record.
        """
        record = self.proxy_info(name)
        if record is None:
            return None
        where = f"{self.manifest_path}: proxy of shape {name!r}"
        model = read_entry_mesh(self.path, name, self.info(name), record, where)
        try:
            table = self._read_table(record)
        except (ShapeError, TableFormatError) as exc:
            raise ShapeError(f"{where}: {exc}: {self._rebuild_hint(name)}") from None
        return model if table is None else model.with_visibility(table)

    def missing_table(self, name: str) -> str:
        """One line on a non-convex shape without a visibility table and how to build it."""
        skipped = " (added with --shadows none)" if self.info(name).get("shadows") else ""
        return (
            f"shape {name!r} has no visibility table{skipped}: {self._rebuild_hint(name)} to "
            "build it, or use --shadows exact (ray casting) or none"
        )

    def _rebuild_hint(self, name: str) -> str:
        """How to rebuild the table of ``name`` (a command line)."""
        if self.path.resolve() == builtin_library_path().resolve():
            return f"run `python -m shapes.library.builtin {name}`"
        return f"run `lightcurve shapes rebuild {name} --library {self.path}`"

    def _rebuild(
        self,
        name: str,
        model: FacetModel,
        entry: Mapping[str, Any],
        old_table: Path | None,
        progress: bool = False,
        proxy_meter: ProxyMeter | None = None,
    ) -> FacetModel:
        """Build and store the table of ``model`` with the sampling of ``old_table`` (when
        readable); ``progress``: tqdm bars; ``proxy_meter``: see :meth:`_store_table`."""
        table = build_visibility_table(model, **stored_build_options(old_table), progress=progress)
        model = model.with_visibility(table)
        self._store_table(name, entry["sha256"], model, proxy_meter, progress)
        return model

    def rebuild_visibility(
        self, name: str, *, progress: bool = False, proxy_meter: ProxyMeter | None = None
    ) -> FacetModel:
        """Rebuild and store the visibility table of a non-convex shape (e.g. one stored in an
        older table format, or added without one), keeping its grid resolution and sampling.
        ``progress``: tqdm bars. ``proxy_meter`` (as in :meth:`add`): a shape's proxy is
        chosen and measured again with the new table.

        Returns
        -------
        FacetModel
            The shape with its new table (a convex shape is returned without one).
        """
        self._check_writable()
        entry = self.info(check_name(name))
        model = self.load(name, visibility=False)
        if model.is_convex:
            return model
        old = entry.get("visibility")
        meter = proxy_meter if entry.get("proxy") is not None else None
        return self._rebuild(name, model, entry, self.path / old if old else None, progress, meter)

    def validate(self, name: str) -> FacetModel:
        """Check one shape: checksum, mesh validity, materials, table of non-convex shapes,
        and its level-of-detail proxy's files when it has one."""
        model = self.load(name, build_visibility=False)
        self.articulation(name)  # parts, when present, must fit the mesh groups
        self.load_proxy(name)
        try:
            validate(model)
        except ShapeError as exc:
            raise ShapeError(f"{self.path}: shape {name!r}: {exc}") from None
        if not model.is_convex and model.visibility is None and not self.info(name).get("shadows"):
            raise ShapeError(
                f"{self.path}: shape {name!r} is not convex but has no visibility table"
            )
        return model

    # ------------------------------------------------------------------ writing
    def _check_writable(self) -> None:
        if self.read_only:
            raise LibraryReadOnlyError(f"shape library {self.path} is read-only")

    @contextmanager
    def _locked(self) -> Iterator[dict[str, Any]]:
        """Hold the writer lock and yield the current manifest."""
        self.path.mkdir(parents=True, exist_ok=True)
        with FileLock(str(self.path / LOCK), timeout=60):
            yield self._read_manifest()

    def _write_manifest(self, manifest: dict[str, Any]) -> None:
        write_manifest(self.path, manifest)

    def add(
        self,
        name: str,
        mesh: str | os.PathLike[str],
        *,
        unit: str = "m",
        materials: Material | Mapping[str, Material] | None = None,
        inertia: Any = "auto",
        mass: float | None = None,
        provenance: Mapping[str, Any] | None = None,
        force: bool = False,
        keep_file: bool = False,
        parts: Any = None,
        resolution: int = DEFAULT_RESOLUTION,
        samples: int = DEFAULT_SAMPLES,
        spacing: float = DEFAULT_SPACING,
        progress: bool = False,
        visibility_table: bool = True,
        announce: Callable[[str], None] | None = None,
        proxy_meter: ProxyMeter | None = None,
    ) -> FacetModel:
        """Add a shape from a mesh file.

        Parameters
        ----------
        name : str
            ``[A-Za-z0-9_.-]+``.
        mesh : path-like
            Any file :func:`shapes.load` reads.
        unit, materials, inertia, mass :
            As :func:`shapes.load`.
        provenance : mapping, optional
            ``source``, ``license`` and any other fields; ``added`` defaults to today.
        force : bool
            Replace an existing shape of that name.
        keep_file : bool
            Copy the mesh file verbatim instead of writing it as a grouped OBJ (only for
            self-contained files: no MTL or texture side files).
        parts : list of dict or Articulation, optional
            Articulated parts (:mod:`shapes.articulation`), checked against the mesh groups
            before anything is written.
        resolution, samples, spacing, progress :
            Visibility-table parameters for non-convex shapes (:func:`build_visibility_table`;
            ``progress``: a tqdm bar).
        visibility_table : bool
            Build the visibility table of a non-convex shape. False records the shape
            without one (``"shadows": "none"``; not built on first use either): renderers
            then ray-cast its shadows or skip them, and :meth:`rebuild_visibility` builds it.
        announce : callable, optional
            Called with one line saying what table is built and how long it should take,
            before the build starts (and one line before the proxy is built).
        proxy_meter : callable, optional
            ``proxy_meter(model, proxy)`` → a proxy's light-curve error record (e.g.
            :class:`lightcurve.photometry.proxy_error.ProxyErrorMeter`): a shape of more than
            :data:`~shapes.library.proxy.PROXY_MIN_FACETS` facets then gets a
            level-of-detail proxy (:mod:`shapes.library.proxy`), stored with it under the
            entry's ``proxy`` record. None: no proxy.

        Returns
        -------
        FacetModel
            The shape as :meth:`load` will return it.
        """
        self._check_writable()
        check_name(name)
        mesh = Path(mesh)
        self._check_free(name, force)
        started = time.perf_counter()
        model = load_mesh(mesh, unit=unit, materials=materials, inertia=inertia, mass=mass)
        logger.info(
            "read %s: %d facets in %.1f s", mesh, len(model.faces), time.perf_counter() - started
        )
        groups, where = model.group_names, f"shape {name!r} ({mesh})"
        articulation = None if parts is None else Articulation.from_list(parts, groups, where)
        record = {"source": mesh.name, "source_sha256": file_sha256(mesh), **dict(provenance or {})}
        table_options = (
            {"resolution": resolution, "samples": samples, "spacing": spacing, "progress": progress}
            if visibility_table
            else None
        )
        verbatim = mesh if keep_file else None
        return self._commit(
            name,
            model,
            record,
            force=force,
            verbatim=verbatim,
            table_options=table_options,
            articulation=articulation,
            announce=announce,
            proxy_meter=proxy_meter,
        )

    def add_model(
        self,
        name: str,
        model: FacetModel,
        *,
        provenance: Mapping[str, Any] | None = None,
        force: bool = False,
        resolution: int = DEFAULT_RESOLUTION,
        samples: int = DEFAULT_SAMPLES,
        spacing: float = DEFAULT_SPACING,
        parts: Any = None,
        proxy_meter: ProxyMeter | None = None,
    ) -> FacetModel:
        """Add an in-memory model (e.g. a primitive); it is written as a grouped OBJ.

        ``parts`` and ``proxy_meter`` as in :meth:`add`.
        """
        self._check_writable()
        check_name(name)
        self._check_free(name, force)
        validate(model)
        groups, where = model.group_names, f"shape {name!r}"
        articulation = None if parts is None else Articulation.from_list(parts, groups, where)
        record = {**model.provenance, **dict(provenance or {})}
        table_options = {"resolution": resolution, "samples": samples, "spacing": spacing}
        return self._commit(
            name,
            model,
            record,
            force=force,
            verbatim=None,
            table_options=table_options,
            articulation=articulation,
            proxy_meter=proxy_meter,
        )

    def _check_free(self, name: str, force: bool) -> None:
        if not force and name in self._read_manifest()["shapes"]:
            raise ShapeError(
                f"shape {name!r} already exists in library {self.path}; use force to replace it"
            )

    def _commit(
        self,
        name: str,
        model: FacetModel,
        provenance: dict[str, Any],
        *,
        force: bool,
        verbatim: Path | None,
        table_options: dict[str, Any] | None,
        articulation: Articulation | None = None,
        announce: Callable[[str], None] | None = None,
        proxy_meter: ProxyMeter | None = None,
    ) -> FacetModel:
        """Write mesh (+ table, + proxy) under temporary names, then swap them in under the
        lock (``table_options`` None: no table for a non-convex shape)."""
        self.path.mkdir(parents=True, exist_ok=True)
        suffix = verbatim.suffix.lower() if verbatim is not None else ".obj"
        final = {"mesh": self.path / f"{name}{suffix}"}
        staged: dict[str, Path] = {}
        try:
            staged["mesh"] = temp_path(self.path, f".{name}.", suffix)
            if verbatim is not None:
                shutil.copyfile(verbatim, staged["mesh"])
            else:
                write_obj(model, staged["mesh"])
            inertia_source = model.inertia_source
            stored = load_mesh(
                staged["mesh"],
                unit=model.unit,
                name=name,
                materials=model.materials,
                inertia=model.inertia if inertia_source == "given" else inertia_source,
                mass=None if np.isnan(model.mass) else model.mass,
                center_of_mass=model.center_of_mass if inertia_source == "given" else None,
                provenance=provenance,
            )
            logger.info(
                "wrote and re-read the mesh of %s (%s, convex: %s)",
                name,
                model.inertia_source,
                stored.is_convex,
            )
            if not stored.is_convex and table_options is not None:
                if announce is not None:
                    sizes = {k: table_options[k] for k in _TABLE_OPTIONS}
                    announce(describe_build(stored, **sizes))
                table = build_visibility_table(stored, **table_options)
                final["visibility"] = self.path / f"{name}.visibility.npz"
                staged["visibility"] = temp_path(self.path, f".{name}.", ".npz")
                table.save(staged["visibility"])
                stored = stored.with_visibility(table)
            proxy = None
            if proxy_meter is not None and len(stored.faces) > PROXY_MIN_FACETS:
                options = None
                if table_options is not None:  # the proxy's table: the shape's sampling
                    options = {k: table_options[k] for k in _TABLE_OPTIONS}
                    options["progress"] = table_options.get("progress", False)
                proxy = stage_proxy(
                    self.path,
                    stored,
                    proxy_meter,
                    table_options=options,
                    announce=announce,
                    final=final,
                    staged=staged,
                )
            entry = manifest_entry(name, stored, final, staged, provenance)
            if proxy is not None:
                entry["proxy"] = proxy
            if table_options is None and not stored.is_convex:
                entry["shadows"] = "none"
            if articulation is not None:
                entry["parts"] = articulation.to_list()
            with self._locked() as manifest:
                if name in manifest["shapes"] and not force:
                    raise ShapeError(f"shape {name!r} already exists in library {self.path}")
                old = manifest["shapes"].get(name, {})
                old_files = [self.path / file_name for file_name in entry_files(old)]
                manifest["shapes"][name] = entry
                swap_in(staged, final, old_files, lambda: self._write_manifest(manifest))
            return stored
        finally:
            for path in staged.values():
                path.unlink(missing_ok=True)

    def _store_table(
        self,
        name: str,
        mesh_sha256: str,
        model: FacetModel,
        meter: ProxyMeter | None = None,
        progress: bool = False,
    ) -> None:
        """Store the table of ``model`` beside its mesh, and with ``meter`` its proxy chosen
        again for the new table (``progress``: its table's bar), in one swap if the entry is
        unchanged (a shape whose proxies now all fail loses its proxy)."""
        final = {"visibility": self.path / f"{name}.visibility.npz"}
        staged = {"visibility": temp_path(self.path, f".{name}.", ".npz")}
        try:
            model.visibility.save(staged["visibility"])
            if meter is not None:
                options = {key: getattr(model.visibility, key) for key in _TABLE_OPTIONS}
                options["progress"] = progress
                record = stage_proxy(
                    self.path, model, meter, table_options=options, final=final, staged=staged
                )
            with self._locked() as manifest:
                entry = manifest["shapes"].get(name)
                if entry is None or entry.get("sha256") != mesh_sha256:
                    return
                entry["visibility"] = final["visibility"].name
                entry["visibility_sha256"] = file_sha256(staged["visibility"])
                entry.pop("shadows", None)
                old = {"proxy": entry.pop("proxy", None)} if meter is not None else {}
                if meter is not None and record is not None:
                    entry["proxy"] = record
                old_files = [self.path / file_name for file_name in entry_files(old)]
                swap_in(staged, final, old_files, lambda: self._write_manifest(manifest))
        finally:
            for path in staged.values():
                path.unlink(missing_ok=True)

    def remove(self, name: str) -> None:
        """Remove a shape and its files."""
        self._check_writable()
        check_name(name)
        with self._locked() as manifest:
            if name not in manifest["shapes"]:
                known = ", ".join(sorted(manifest["shapes"])) or "none"
                raise ShapeError(f"no shape {name!r} in library {self.path} (shapes: {known})")
            entry = manifest["shapes"].pop(name)
            self._write_manifest(manifest)
            for file_name in entry_files(entry):
                (self.path / file_name).unlink(missing_ok=True)
