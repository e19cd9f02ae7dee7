"""Monocular scenario files (Deng et al. 2024) and external measurement files.

:func:`load_monocular_scenario` reads a TOML scenario into a
:class:`lightcurve.studies.monocular.MonocularScenario` with errors that name the file and the
field; :func:`read_measurements` reads a CSV of measured quaternions.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from filters.attitude import (
    validate_inertia,
)
from filters.navigation.camera import PinholeCamera
from filters.navigation.monocular import (
    inertia_form,
)
from lightcurve.scenarios import ScenarioError, TomlTable, load_toml
from lightcurve.studies.monocular import (
    Criteria,
    MonocularScenario,
    PixelSetup,
    Truth,
    form_truth,
)


def _diagonal(table: TomlTable, key: str, size: int) -> np.ndarray:
    """A covariance given as one number (times the identity) or ``size`` diagonal entries."""
    value = table.data.get(key)
    if isinstance(value, int | float) and not isinstance(value, bool):
        diag = np.full(size, table.number(key, minimum=0.0))
    else:
        diag = table.array(key, (size,))
    if np.any(diag < 0):
        raise table.error(key, "variances must be >= 0")
    return np.diag(diag)


def _read_truth(table: TomlTable) -> Truth:
    try:
        inertia = validate_inertia(table.array("inertia", (3, 3)))
    except ValueError as exc:
        raise table.error("inertia", str(exc)) from None
    q0 = table.array("q0", (4,), [0.0, 0.0, 0.0, 1.0])
    if not np.linalg.norm(q0) > 0:
        raise table.error("q0", "quaternion must be non-zero")
    truth = Truth(
        inertia,
        q0 / np.linalg.norm(q0),
        np.radians(table.array("omega0_deg_s", (3,))),
        table.number("duration_s", positive=True),
        table.number("step_s", positive=True),
    )
    table.check_unknown()
    return truth


def _read_pixels(table: TomlTable) -> PixelSetup:
    cam = table.table("camera")
    width, height = cam.integer("width", minimum=1), cam.integer("height", minimum=1)
    if cam.has("fov_deg"):
        camera = PinholeCamera.from_fov(cam.number("fov_deg", positive=True), width, height)
    else:
        camera = PinholeCamera(
            cam.number("fx", positive=True),
            cam.number("fy", positive=True),
            cam.number("u0", 0.5 * width),
            cam.number("v0", 0.5 * height),
            width,
            height,
        )
    cam.check_unknown()
    target = table.table("target")
    import shapes

    library = shapes.get_library()
    shape = target.string("shape")
    if shape not in library:
        raise target.error("shape", f"no library shape {shape!r}; known: {library.names()}")
    radius = target.number("radius_m", 1.0, positive=True)
    setup = PixelSetup(
        camera,
        shape,
        radius,
        target.number("range_m", positive=True),
        table.number("pixel_sigma", minimum=0.0),
        table.number("outlier_fraction", 0.0, minimum=0.0, maximum=0.9),
        table.number("threshold_px", 1.0, positive=True),
        table.integer("refine_iterations", 10, minimum=0),
        table.string("linking", "best", choices=("best", "previous")),
        table.integer("min_matches", 30, minimum=8),
    )
    if setup.range_m <= 1.5 * radius:
        raise target.error("range_m", f"must exceed 1.5 radius_m ({1.5 * radius}) to see the body")
    target.check_unknown()
    return setup


def load_monocular_scenario(path: str | Path) -> MonocularScenario:
    """Read a monocular scenario TOML file (format in ``docs/monocular.md``).

    Raises
    ------
    ScenarioError
        Naming the file, table and field of the first problem.
    OSError
        When the file cannot be read.
    """
    root = load_toml(path)
    name = root.string("name", Path(path).stem)
    root.string("description", "")
    truth = _read_truth(root.table("truth")) if root.has("truth") else root.optional_table("truth")

    meas = root.table("measurement")
    mode = meas.string("mode", choices=("quaternion", "pixels"))
    sigma = pixels = None
    if mode == "quaternion":
        sigma = math.radians(meas.number("sigma_deg", minimum=0.0))
    else:
        pixels = _read_pixels(meas)
    meas.check_unknown()

    filt = root.table("filter")
    form = inertia_form(filt.string("form", "L", choices=("L", "k")))
    n = 6 + form.size
    q_v = filt.array("q_v0", (3,), [0.0, 0.0, 0.0])
    if q_v @ q_v >= 1:
        raise filt.error("q_v0", "vector part of a unit quaternion must have norm < 1")
    x0 = np.concatenate(
        [
            q_v,
            [math.sqrt(1 - q_v @ q_v)],
            np.radians(filt.array("omega0_deg_s", (3,))),
            filt.array("inertia0", (form.size,)),
        ]
    )
    p0 = _diagonal(filt, "initial_variance", n)
    q = _diagonal(filt, "process_noise", n)
    r = _diagonal(filt, "measurement_noise", 3)
    if not np.all(np.diag(r) > 0):
        raise filt.error("measurement_noise", "variances must be > 0")
    filt.check_unknown()

    crit = root.optional_table("criteria")
    criteria = Criteria()
    if crit is not None:
        criteria = Criteria(
            crit.number("attitude_deg", criteria.attitude_deg, positive=True),
            crit.number("rate_fraction", criteria.rate_fraction, positive=True),
            crit.number("inertia", criteria.inertia, positive=True),
            crit.number("settle_fraction", criteria.settle_fraction, positive=True, maximum=1.0),
        )
        crit.check_unknown()
    obs = root.optional_table("observability")
    max_order, rtol = 6, 1e-9
    if obs is not None:
        max_order = obs.integer("max_order", max_order, minimum=1)
        rtol = obs.number("rtol", rtol, positive=True)
        obs.check_unknown()
    root.check_unknown()
    if form.name == "k" and truth is not None:
        try:
            form_truth(form, truth.inertia, truth.q0)
        except ScenarioError as exc:
            raise root.error("truth", str(exc)) from None
    return MonocularScenario(
        Path(path), name, truth, mode, sigma, pixels, form, x0, p0, q, r, criteria, max_order, rtol
    )


def read_measurements(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read external quaternion measurements: columns ``t`` (s) and ``q1 q2 q3 q4``.

    Rows with all four quaternion entries empty are gaps (no update at that time).

    Returns
    -------
    times : (K,) numpy.ndarray
    quaternions : (K, 4) numpy.ndarray
        Normalised; NaN rows for gaps.

    Raises
    ------
    ScenarioError
        Naming the file, the line and the column of the first problem.
    """
    path = Path(path)
    try:
        table = pd.read_csv(path, comment="#", skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{path}: not a readable CSV table: {exc}") from None
    columns = ["t", "q1", "q2", "q3", "q4"]
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise ScenarioError(f"{path}: missing column(s) {', '.join(missing)}")
    if len(table) < 2:
        raise ScenarioError(f"{path}: needs at least two measurement rows, got {len(table)}")
    values = {}
    for col in columns:
        numeric = pd.to_numeric(table[col], errors="coerce")
        bad = numeric.isna() & table[col].notna() | np.isinf(numeric)
        if col == "t":
            bad |= numeric.isna()
        if bad.any():
            row = int(np.flatnonzero(bad.to_numpy())[0])
            value = table[col].iloc[row]
            raise ScenarioError(
                f"{path}: line {row + 2}, column {col}: not a finite number: {value!r}"
            )
        values[col] = numeric.to_numpy(dtype=float)
    t = values["t"]
    bad_t = np.flatnonzero(np.diff(t) <= 0)
    if bad_t.size:
        raise ScenarioError(f"{path}: line {bad_t[0] + 3}, column t: times must increase")
    q = np.stack([values[c] for c in columns[1:]], axis=1)
    partial = np.isnan(q).any(axis=1) & ~np.isnan(q).all(axis=1)
    norm = np.linalg.norm(q, axis=1)
    zero = np.isfinite(norm) & (norm < 1e-12)
    bad_q = np.flatnonzero(partial | zero)
    if bad_q.size:
        raise ScenarioError(
            f"{path}: line {bad_q[0] + 2}, columns q1-q4: quaternion must have four numbers "
            "with non-zero norm (or be left empty for a gap)"
        )
    return t, q / norm[:, None]
