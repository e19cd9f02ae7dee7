"""The inversion pipeline for one observation file, as run by ``lightcurve invert``.

:func:`invert_file` is the batch job: read the file, load the candidate shapes from the
library, run :func:`lightcurve.inversion.invert`, and write ``estimates.parquet`` and the
summary record (returned; the batch layer writes ``summary.json``). Every option is plain
data so the job can be shipped to worker processes or a Dask cluster.

Summary keys (the contract of ``docs/inversion.md``): ``input``, ``method``, ``status``,
``error``, ``shape``, ``shape_probabilities``, ``none_fits``, ``epoch`` (ISO UTC of the last
measurement), ``quaternion``, ``omega_rad_s``, ``attitude_sigma_deg``, ``omega_sigma_rad_s``,
``modes``, ``residual_rms_mag``, ``n_measurements``, ``runtime_s`` and, with ``modes``,
``attitude_mode``, ``attitude_mode_probability``, ``attitude_offsets_deg`` (None without).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from lightcurve import io
from lightcurve.io.atomic import atomic_write_table
from lightcurve.io.observations import iso_epochs

__all__ = ["SUMMARY_KEYS", "check_request", "invert_file", "resolve_shapes"]

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
    "n_measurements",
    "runtime_s",
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


def _invert_arguments(
    *,
    q0: list[float] | None,
    omega0_rad_s: list[float] | None,
    attitude_sigma_deg: float | None,
    omega_sigma_rad_s: float | None,
    omega_max_rad_s: float | None,
    particles: int | None,
    init: str,
    mode_weak_sigma_deg: float | None = None,
) -> dict[str, Any]:
    """The keyword arguments of :func:`lightcurve.inversion.invert` from the job's options
    (those left None keep the library's defaults)."""
    arguments = {
        "q0": None if q0 is None else np.asarray(q0, float),
        "omega0": None if omega0_rad_s is None else np.asarray(omega0_rad_s, float),
        "attitude_sigma_deg": attitude_sigma_deg,
        "omega_sigma": omega_sigma_rad_s,
        "omega_max": omega_max_rad_s,
        "particles": particles,
        "init": init,
        "mode_weak_sigma_deg": mode_weak_sigma_deg,
    }
    return {k: v for k, v in arguments.items() if v is not None}


def check_request(options: dict[str, Any]) -> None:
    """Check the options of a batch of :func:`invert_file` jobs before any input is read,
    with the library's own rules (:func:`lightcurve.inversion.validate_request`).

    Raises
    ------
    ValueError
        The request the library would reject for every input.
    """
    from lightcurve.inversion import validate_request

    names = options.get("shape_names")
    keys = ("q0", "omega0_rad_s", "attitude_sigma_deg", "omega_sigma_rad_s", "omega_max_rad_s")
    validate_request(
        options["method"],
        modes=bool(options.get("modes")),
        n_shapes=None if names is None else len(names),
        **_invert_arguments(
            **{key: options.get(key) for key in keys},
            particles=options.get("particles"),
            init=options.get("init", "search"),
            mode_weak_sigma_deg=options.get("mode_weak_sigma_deg"),
        ),
    )


def invert_file(
    input_path: Path,
    result_dir: Path,
    *,
    method: str,
    shape_names: list[str] | None,
    library: str | None = None,
    q0: list[float] | None = None,
    omega0_rad_s: list[float] | None = None,
    attitude_sigma_deg: float | None = None,
    omega_sigma_rad_s: float | None = None,
    omega_max_rad_s: float | None = None,
    particles: int | None = None,
    seed: int = 0,
    init: str = "search",
    drop_bad_rows: bool = False,
    modes: bool = False,
    mode_weak_sigma_deg: float | None = None,
    progress: Callable[[float, str], None] | None = None,
) -> dict[str, Any]:
    """Invert one observation file and write its estimates (see the module docstring).

    A file whose header names its object's shape (``# shape: NAME``, as ``lightcurve
    simulate`` writes) must name a shape of the library; with ``shape_names`` None that
    shape is the file's only candidate. ``progress(fraction, message)``, when given, is
    handed to :func:`~lightcurve.inversion.invert`.

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

    observations = io.read(input_path, drop_bad_rows=drop_bad_rows)
    lib = get_library(library)
    declared = observations.meta.get("shape")
    if declared is not None:
        try:
            lib.load(declared)
        except ValueError as exc:
            raise ValueError(f"{input_path}: header 'shape: {declared}': {exc}") from None
    if shape_names is None:
        if declared is None:
            raise ValueError(
                f"{input_path}: no candidate shape: the file has no '# shape:' header and "
                "none of --shape, --shapes, --all-shapes was given"
            )
        shape_names = [declared]
    candidates = {name: lib.load(name) for name in shape_names}
    options = _invert_arguments(
        q0=q0,
        omega0_rad_s=omega0_rad_s,
        attitude_sigma_deg=attitude_sigma_deg,
        omega_sigma_rad_s=omega_sigma_rad_s,
        omega_max_rad_s=omega_max_rad_s,
        particles=particles,
        init=init,
        mode_weak_sigma_deg=mode_weak_sigma_deg,
    )
    result = invert(
        observations,
        candidates,
        method=method,
        modes=modes,
        seed=seed,
        progress=progress,
        **options,
    )
    atomic_write_table(result.estimates, result_dir / "estimates.parquet")
    return {
        "method": method,
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
        "n_measurements": int(result.n_measurements),
        "dropped_rows": len(observations.dropped),
        "notes": list(getattr(result, "notes", [])),
        **(result.attitude_mode or dict.fromkeys(SUMMARY_KEYS[-3:])),
    }
