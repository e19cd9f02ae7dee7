"""The inversion pipeline for one observation file, as run by ``lightcurve invert``.

:func:`invert_file` is the batch job: read the file, load the candidate shapes from the
library, run :func:`lightcurve.inversion.invert`, and write ``estimates.parquet`` and the
summary record (returned; the batch layer writes ``summary.json``). It takes two frozen
objects, plain data that ships to worker processes or a Dask cluster: an :class:`InvertJob`
(method, candidate shapes, library, the prior and search request, seed, ``modes``, how to
read the file) and the inversion's tuning, an
:class:`~lightcurve.inversion.options.InversionOptions`.

Summary keys (the contract of ``docs/inversion.md``, "Result files"): ``input``, ``method``,
``status``, ``error``, ``shape``, ``shape_probabilities``, ``none_fits``, ``epoch`` (ISO UTC
of the last measurement), ``quaternion``, ``omega_rad_s``, ``attitude_sigma_deg``,
``omega_sigma_rad_s``, ``modes``, ``residual_rms_mag``, ``model_error_mag``,
``rejected_fraction``, ``consistent``, ``parameters`` (name → ``{"value", "sigma"}``),
``n_measurements``, ``runtime_s``, ``shape_model`` (the model each candidate was rendered
with: :func:`candidate_model`) and, with ``modes``, ``attitude_mode``,
``attitude_mode_probability``, ``attitude_offsets_deg`` (None without).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from lightcurve import io
from lightcurve.io.atomic import atomic_write_table
from lightcurve.io.observations import iso_epochs

if TYPE_CHECKING:
    from lightcurve.inversion.options import InversionOptions
    from shapes import FacetModel, ShapeLibrary

__all__ = [
    "SUMMARY_KEYS",
    "InvertJob",
    "candidate_model",
    "check_request",
    "invert_file",
    "resolve_shapes",
]

SUMMARY_KEYS = (
    "input",
    "method",
    "status",
    "error",
    "shape",
    "shape_probabilities",
    "none_fits",
    "epoch",
    "quaternion",
    "omega_rad_s",
    "attitude_sigma_deg",
    "omega_sigma_rad_s",
    "modes",
    "residual_rms_mag",
    "model_error_mag",
    "rejected_fraction",
    "consistent",
    "parameters",
    "n_measurements",
    "runtime_s",
    "shape_model",
    "attitude_mode",
    "attitude_mode_probability",
    "attitude_offsets_deg",
)


def resolve_shapes(
    library: str | os.PathLike[str] | None,
    shape: str | None = None,
    shapes: list[str] | None = None,
    all_shapes: bool = False,
) -> list[str] | None:
    """Candidate shape names from the ``--shape``/``--shapes``/``--all-shapes`` options.

    Names given by an option must be in the library: a misspelt name is an error at start,
    before any input is read. ``None`` (no option given) means every input names its own
    shape in its ``# shape:`` header; an unknown name there becomes that input's error
    record rather than stopping the batch.
    """
    from shapes import get_library

    given = sum(x is not None and x is not False for x in (shape, shapes, all_shapes or None))
    if given > 1:
        raise ValueError("give at most one of --shape, --shapes or --all-shapes")
    if given == 0:
        return None
    if all_shapes:
        return list(get_library(library).names())
    names = [shape] if shape is not None else [s.strip() for s in shapes if s.strip()]
    if not names:
        raise ValueError("--shapes needs at least one name")
    known = set(get_library(library).names())
    unknown = [name for name in names if name not in known]
    if unknown:
        option = "--shape" if shape is not None else "--shapes"
        raise ValueError(
            f"{option}: no shape named {', '.join(map(repr, unknown))} in the library "
            f"(known: {', '.join(sorted(known))}; `lightcurve shapes list`)"
        )
    return names


@dataclass(frozen=True)
class InvertJob:
    """What a ``lightcurve invert`` run asks of every input file, besides the tuning that
    :class:`~lightcurve.inversion.options.InversionOptions` holds.

    Attributes
    ----------
    method : {"ukf", "mmae", "pf"}
    shape_names : tuple of str, optional
        Candidate shapes (:func:`resolve_shapes`); None: the shape each file's
        ``# shape:`` header names.
    library : str, optional
        Shape library folder (default: ``$LIGHTCURVE_LIBRARY`` or the built-in one).
    q0 : tuple of 4 float, optional
        Prior attitude at the first epoch (scalar last, inertial → body).
    omega0_rad_s : tuple of 3 float, optional
        Prior body rates at the first epoch, rad/s.
    attitude_sigma_deg, omega_sigma_rad_s, omega_max_rad_s : float, optional
        Prior 1σ of the attitude (deg) and of the rates (rad/s), bound on ``|ω|`` (rad/s).
    particles : int, optional
        PF particles.
    seed : int
        Seed of the inversion's random draws.
    modes : bool
        Also weigh stabilised attitude profiles against tumbling.
    drop_bad_rows : bool
        Drop invalid rows of an input instead of failing it.
    full_mesh : bool
        Render every candidate with its full mesh, never its level-of-detail proxy.

    The prior, bound and particle count left None keep the defaults of
    :func:`lightcurve.inversion.invert`. Sequences are stored as tuples.
    """

    method: str
    shape_names: tuple[str, ...] | None = None
    library: str | None = None
    q0: tuple[float, ...] | None = None
    omega0_rad_s: tuple[float, ...] | None = None
    attitude_sigma_deg: float | None = None
    omega_sigma_rad_s: float | None = None
    omega_max_rad_s: float | None = None
    particles: int | None = None
    seed: int = 0
    modes: bool = False
    drop_bad_rows: bool = False
    full_mesh: bool = False

    def __post_init__(self) -> None:
        for name in ("shape_names", "q0", "omega0_rad_s"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, tuple):
                object.__setattr__(self, name, tuple(_items(value)))


def candidate_model(
    library: ShapeLibrary, name: str, noise_mag: float, *, full_mesh: bool = False
) -> tuple[FacetModel, dict[str, Any]]:
    """A candidate shape as the inversion renders it, and the record saying which model.

    The shape's level-of-detail proxy (:mod:`shapes.library.proxy`) stands in for it when
    the proxy's stored rms light-curve error is below the data's noise ``noise_mag`` and was
    measured with the shadowing the full shape renders with (its table, or none for a convex
    shape); ``full_mesh`` forces the full shape.

    Returns
    -------
    model : FacetModel
    record : dict
        ``name``, ``proxy`` (bool), ``n_facets`` (of the model used), ``full_facets``,
        ``proxy_rms_mag`` and ``proxy_max_mag`` (None without a proxy), ``noise_mag``.
    """
    entry = library.info(name)
    stored = library.proxy_info(name)
    record: dict[str, Any] = {
        "name": name,
        "proxy": False,
        "n_facets": entry.get("facets"),
        "full_facets": entry.get("facets"),
        "proxy_rms_mag": None if stored is None else stored["rms_mag"],
        "proxy_max_mag": None if stored is None else stored["max_mag"],
        "noise_mag": noise_mag,
    }
    if entry.get("visibility"):
        full_shadows = "table"
    else:  # a non-convex shape added without its table is ray-cast
        full_shadows = "exact" if entry.get("shadows") == "none" else "none"
    if (
        stored is not None
        and not full_mesh
        and stored["rms_mag"] < noise_mag
        and stored["shadows"] == full_shadows
    ):
        proxy = library.load_proxy(name)
        if proxy is not None:
            record.update(proxy=True, n_facets=len(proxy.faces))
            return proxy, record
    return library.load(name), record


def _items(value: Sequence[Any] | Any) -> list[Any]:
    """The items of a list, tuple or numpy array as plain Python values."""
    return value.tolist() if hasattr(value, "tolist") else list(value)


def _invert_arguments(job: InvertJob) -> dict[str, Any]:
    """The request keywords of :func:`lightcurve.inversion.invert` from the job (those left
    None keep the library's defaults)."""
    arguments = {
        "q0": None if job.q0 is None else np.asarray(job.q0, float),
        "omega0": None if job.omega0_rad_s is None else np.asarray(job.omega0_rad_s, float),
        "attitude_sigma_deg": job.attitude_sigma_deg,
        "omega_sigma": job.omega_sigma_rad_s,
        "omega_max": job.omega_max_rad_s,
        "particles": job.particles,
    }
    return {k: v for k, v in arguments.items() if v is not None}


def check_request(job: InvertJob, options: InversionOptions | None = None) -> None:
    """Check a batch of :func:`invert_file` jobs before any input is read, with the
    library's own rules (:func:`lightcurve.inversion.validate_request`).

    Raises
    ------
    ValueError
        The request the library would reject for every input.
    """
    from lightcurve.inversion import validate_request

    validate_request(
        job.method,
        options,
        modes=job.modes,
        n_shapes=None if job.shape_names is None else len(job.shape_names),
        **_invert_arguments(job),
    )


def invert_file(
    input_path: Path,
    result_dir: Path,
    job: InvertJob,
    options: InversionOptions | None = None,
    *,
    progress: Callable[[float, str], None] | None = None,
) -> dict[str, Any]:
    """Invert one observation file and write its estimates (see the module docstring).

    With ``job.shape_names`` None, the shape a file's header names (``# shape: NAME``, as
    ``lightcurve simulate`` writes) is its only candidate and must be a shape of the
    library; with candidates given, the header's shape is not used (an object simulated
    from a shape the library does not have is inverted with the candidates). ``options``
    (default: the defaults) tune the inversion. ``progress(fraction, message)``, when
    given, is handed to :func:`~lightcurve.inversion.invert`.

    Returns
    -------
    dict
        The summary record, without ``input``/``runtime_s`` (added by the batch layer).

    Raises
    ------
    ValueError, OSError
        Bad input file, unknown shape, or an inversion that cannot run; the batch layer
        turns them into an error record.
    """
    from lightcurve.inversion import invert
    from shapes import get_library

    observations = io.read(input_path, drop_bad_rows=job.drop_bad_rows)
    lib = get_library(job.library)
    declared = observations.meta.get("shape")
    errors = observations.magnitude_errors if observations.has_magnitudes else np.zeros(0)
    noise = float(np.median(errors)) if len(errors) else 0.0

    def load(name: str) -> tuple[FacetModel, dict[str, Any]]:
        return candidate_model(lib, name, noise, full_mesh=job.full_mesh)

    if job.shape_names is None:
        if declared is None:
            raise ValueError(
                f"{input_path}: no candidate shape: the file has no '# shape:' header and "
                "none of --shape, --shapes, --all-shapes was given"
            )
        try:
            loaded = {declared: load(declared)}
        except ValueError as exc:
            raise ValueError(f"{input_path}: header 'shape: {declared}': {exc}") from None
    else:
        loaded = {name: load(name) for name in job.shape_names}
    candidates = {name: model for name, (model, _) in loaded.items()}
    result = invert(
        observations,
        candidates,
        method=job.method,
        modes=job.modes,
        seed=job.seed,
        progress=progress,
        options=options,
        **_invert_arguments(job),
    )
    atomic_write_table(result.estimates, result_dir / "estimates.parquet")
    return {
        "method": job.method,
        "status": "ok",
        "error": None,
        "shape": result.shape,
        "shape_probabilities": {k: float(v) for k, v in result.shape_probabilities.items()},
        "none_fits": bool(result.none_fits),
        "epoch": iso_epochs(np.array([result.epoch_mjd]))[0],
        "quaternion": [float(v) for v in result.quaternion],
        "omega_rad_s": [float(v) for v in result.omega_rad_s],
        "attitude_sigma_deg": float(result.attitude_sigma_deg),
        "omega_sigma_rad_s": [float(v) for v in result.omega_sigma_rad_s],
        "modes": [
            {
                "quaternion": [float(v) for v in mode["quaternion"]],
                "omega_rad_s": [float(v) for v in mode["omega_rad_s"]],
                "weight": float(mode["weight"]),
            }
            for mode in result.modes
        ],
        "residual_rms_mag": float(result.residual_rms_mag),
        "model_error_mag": float(result.model_error_mag),
        "rejected_fraction": float(result.rejected_fraction),
        "consistent": not bool(result.none_fits),
        "parameters": {
            name: {"value": float(v["value"]), "sigma": float(v["sigma"])}
            for name, v in result.parameters.items()
        },
        "n_measurements": int(result.n_measurements),
        "dropped_rows": len(observations.dropped),
        "notes": list(getattr(result, "notes", [])),
        "shape_model": loaded[result.shape][1] if result.shape in loaded else None,
        "candidate_models": {name: record for name, (_, record) in loaded.items()},
        **(result.attitude_mode or dict.fromkeys(SUMMARY_KEYS[-3:])),
    }
