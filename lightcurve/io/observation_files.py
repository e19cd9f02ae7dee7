"""Reading and writing observation files: one registry for CSV, Parquet and DAMIT text.

Like astropy's unified I/O, :func:`read` picks the reader from the format name or sniffs it
from the file (suffix, then content), and :func:`write` picks the writer from the suffix.

* **CSV**: optional ``# key: value`` metadata lines, then a header row, then one row per
  measurement (``docs/formats.md``).
* **Parquet**: the same columns; the metadata is stored in the schema's key-value metadata
  under ``lightcurve.meta`` (JSON).
* **DAMIT** light-curve text (Kaasalainen & Ďurech): first line the number of light
  curves; each starts with ``N flag`` (flag 0 = relative, 1 = calibrated) followed by N
  lines ``JD brightness sx sy sz ex ey ez`` (brightness in intensity units; asteroid → Sun
  and asteroid → Earth vectors in AU, ecliptic J2000). It becomes one table with a
  ``lightcurve_id`` column; read only.
"""

from __future__ import annotations

import io
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from lightcurve.io.atomic import atomic_path
from lightcurve.io.damit import AU_KM, read_lightcurves
from lightcurve.io.observation_rules import ObservationError, read_text

if TYPE_CHECKING:
    import pandas as pd

    from lightcurve.io.observations import Observations

__all__ = ["AU_KM", "formats", "read", "read_damit", "write"]

PARQUET_META_KEY = b"lightcurve.meta"

Reader = Callable[..., "Observations"]
_READERS: dict[str, Reader] = {}
_SUFFIXES = {".csv": "csv", ".txt": None, ".parquet": "parquet", ".pq": "parquet"}


def _register(name: str) -> Callable[[Reader], Reader]:
    def decorator(func: Reader) -> Reader:
        _READERS[name] = func
        return func

    return decorator


def formats() -> list[str]:
    """Names of the registered input formats."""
    return sorted(_READERS)


def sniff_format(path: str | os.PathLike[str]) -> str:
    """Guess a file's format from its suffix, else from its first bytes."""
    path = Path(path)
    known = _SUFFIXES.get(path.suffix.lower())
    if known:
        return known
    with open(path, "rb") as handle:
        head = handle.read(4096)
    if head.startswith(b"PAR1"):
        return "parquet"
    first = head.decode("utf-8", "replace").strip().splitlines()[:1]
    if first and first[0].strip().isdigit():
        return "damit"
    return "csv"


def read(
    path: str | os.PathLike[str],
    format: str | None = None,
    require_magnitudes: bool = True,
    drop_bad_rows: bool = False,
    **options: object,
) -> Observations:
    """Read an observation file.

    Parameters
    ----------
    path : path-like
        CSV, Parquet or DAMIT light-curve file.
    format : {"csv", "parquet", "damit"}, optional
        Skip format detection.
    require_magnitudes : bool
        Require ``mag``/``mag_err`` (False for geometry files used by ``simulate``).
    drop_bad_rows : bool
        Keep the valid rows and list the dropped ones in ``Observations.dropped`` instead of
        raising on the first bad row.
    **options
        Reader-specific options (DAMIT: ``mag_err``).

    Returns
    -------
    Observations

    Raises
    ------
    ObservationError
        Naming the file, the row and the column.
    FileNotFoundError
        If the file does not exist.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such observation file")
    fmt = format or sniff_format(path)
    if fmt not in _READERS:
        raise ObservationError(f"unknown format {fmt!r}; known: {', '.join(formats())}", str(path))
    return _READERS[fmt](
        path, require_magnitudes=require_magnitudes, drop_bad_rows=drop_bad_rows, **options
    )


@_register("csv")
def read_csv(
    path: Path, require_magnitudes: bool = True, drop_bad_rows: bool = False
) -> Observations:
    """Read the project's CSV observation format (see :func:`read`)."""
    import pandas as pd

    text = read_text(path)
    lines = text.splitlines()
    meta, n_meta = _parse_header(lines, str(path))
    body = "\n".join(lines[n_meta:])
    if not body.strip():
        raise ObservationError("no header row and no data", str(path))
    try:
        table = pd.read_csv(
            io.StringIO(body),
            dtype=str,
            skipinitialspace=True,
            keep_default_na=False,
            na_values=[""],
        )
    except pd.errors.ParserError as exc:
        raise ObservationError(f"malformed CSV: {exc}", str(path)) from None
    except pd.errors.EmptyDataError:
        raise ObservationError("no header row and no data", str(path)) from None
    if not drop_bad_rows:
        _check_field_counts(body, str(path))
    return _finish(table, meta, path, require_magnitudes, drop_bad_rows)


@_register("parquet")
def read_parquet(
    path: Path, require_magnitudes: bool = True, drop_bad_rows: bool = False
) -> Observations:
    """Read the project's Parquet observation format (see :func:`read`)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        arrow = pq.read_table(path)
    except (pa.ArrowException, OSError) as exc:
        raise ObservationError(
            f"cannot read Parquet file (truncated or corrupt?): {exc}", str(path)
        ) from None
    raw_meta = (arrow.schema.metadata or {}).get(PARQUET_META_KEY)
    meta = json.loads(raw_meta) if raw_meta else {}
    return _finish(arrow.to_pandas(), meta, path, require_magnitudes, drop_bad_rows)


@_register("damit")
def read_damit(
    path: Path,
    require_magnitudes: bool = True,
    drop_bad_rows: bool = False,
    mag_err: float = 0.01,
) -> Observations:
    """Read a DAMIT light-curve file into one table (see the module docstring).

    Magnitudes are ``−2.5 log10(brightness)``; DAMIT files carry no uncertainties, so every
    point gets ``mag_err`` (default 0.01 mag). Rows within each light curve are sorted by
    time (a few real light curves are not); this is recorded in ``meta['notes']``.
    """
    import pandas as pd

    points = read_lightcurves(path, mag_err)
    table = pd.DataFrame(
        {
            "mjd": points.mjd,
            "mag": points.magnitudes,
            "mag_err": mag_err,
            **{c: points.sun_km[:, i] for i, c in enumerate(("sun_x", "sun_y", "sun_z"))},
            **{c: points.observer_km[:, i] for i, c in enumerate(("obs_x", "obs_y", "obs_z"))},
            "lightcurve_id": points.lightcurve_ids,
            "relative": points.relative,
        }
    )
    meta = points.meta
    return _finish(table, meta, path, require_magnitudes, drop_bad_rows, allow_duplicates=True)


def write(observations: Observations, path: str | os.PathLike[str]) -> None:
    """Write an observation table atomically as CSV or Parquet (by suffix).

    Parameters
    ----------
    observations : Observations
    path : path-like
        ``.csv`` or ``.parquet``.
    """
    path = Path(path)
    fmt = _SUFFIXES.get(path.suffix.lower())
    table = observations.table
    with atomic_path(path, suffix=path.suffix) as tmp:
        if fmt == "csv":
            header = "".join(f"# {k}: {v}\n" for k, v in observations.meta.items())
            with open(tmp, "w", encoding="utf-8", newline="") as handle:
                handle.write(header)
                table.to_csv(handle, index=False, float_format=None, lineterminator="\n")
        elif fmt == "parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq

            arrow = pa.Table.from_pandas(table, preserve_index=False)
            schema_meta = dict(arrow.schema.metadata or {})
            schema_meta[PARQUET_META_KEY] = json.dumps(observations.meta).encode()
            pq.write_table(arrow.replace_schema_metadata(schema_meta), tmp)
        else:
            raise ValueError(f"{path}: cannot write format {path.suffix!r} (use .csv or .parquet)")


def _parse_header(lines: list[str], source: str) -> tuple[dict[str, str], int]:
    meta: dict[str, str] = {}
    count = 0
    for line in lines:
        stripped = line.strip()
        if not stripped.startswith("#"):
            if stripped:
                break
            count += 1
            continue
        count += 1
        content = stripped.lstrip("#").strip()
        if not content:
            continue
        key, sep, value = content.partition(":")
        if not sep or not key.strip():
            raise ObservationError(f"line {count}: metadata lines must read '# key: value'", source)
        meta[key.strip()] = value.strip()
    return meta, count


def _check_field_counts(body: str, source: str) -> None:
    lines = body.splitlines()
    if not lines:
        return
    n_header = len(lines[0].split(","))
    for index, line in enumerate(lines[1:], start=1):
        if line.strip() and len(line.split(",")) != n_header:
            raise ObservationError(
                f"has {len(line.split(','))} fields, the header has {n_header} "
                "(truncated or malformed line)",
                source,
                row=index,
            )


def _finish(
    table: pd.DataFrame,
    meta: dict[str, str],
    path: Path,
    require_magnitudes: bool,
    drop_bad_rows: bool,
    allow_duplicates: bool = False,
) -> Observations:
    from lightcurve.io.observations import Observations, RowProblem, validate_table

    problems: list[RowProblem] = []
    canonical = validate_table(
        table,
        str(path),
        meta,
        require_magnitudes=require_magnitudes,
        drop_bad_rows=drop_bad_rows,
        problems=problems,
        allow_duplicate_epochs=allow_duplicates,
    )
    return Observations(canonical, meta, str(path), problems)
