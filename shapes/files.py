"""File helpers of every package: atomic writes, output folders, temporary names, checksums.

The one atomic writer of the project (:func:`atomic_path`, and :func:`atomic_write` on top of
it): the data go to a temporary file in the target folder, are flushed to disk (``fsync``) and
the file is renamed onto the target (``os.replace``). An interrupted run therefore leaves the
old file or the complete new one, never a partial file. It lives here, in the lowest package
that writes files, so that :mod:`shapes` (meshes, visibility tables, the library manifest,
previews) and :mod:`lightcurve` (every result file, through :mod:`lightcurve.io.atomic`) share it.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

__all__ = [
    "atomic_path",
    "atomic_write",
    "file_sha256",
    "output_folder",
    "temp_path",
    "write_npz",
]


def temp_path(folder: str | os.PathLike[str], prefix: str, suffix: str) -> Path:
    """A new empty temporary file in ``folder`` (same file system as the final name).

    The file gets the permissions of a normally created file (``0666`` less the umask), not
    ``mkstemp``'s private ``0600``, so that the renamed result is readable like any other.
    """
    fd, name = tempfile.mkstemp(dir=folder, prefix=prefix, suffix=suffix)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(name, 0o666 & ~umask)
    return Path(name)


@contextmanager
def atomic_path(target: str | os.PathLike[str], suffix: str = "") -> Iterator[Path]:
    """Yield a temporary path beside ``target``; on success rename it onto ``target``.

    Parameters
    ----------
    target : path-like
        Final file path; its parent folder is created if needed.
    suffix : str
        Suffix of the temporary file (some writers infer the format from it).

    Yields
    ------
    pathlib.Path
        Where to write. Flushed to disk and renamed onto ``target`` when the block succeeds;
        removed (and ``target`` untouched) if it raises.

    Raises
    ------
    OSError
        One line naming ``target`` (or its folder) when it cannot be written.
    """
    target = Path(target)
    output_folder(target.parent)
    if target.is_dir():
        raise IsADirectoryError(f"cannot write {target}: it is a folder")
    try:
        tmp = temp_path(target.parent, f".{target.name}.", suffix + ".tmp")
    except OSError as exc:  # unwritable folder, read-only or special file system
        raise OSError(f"cannot write {target}: {exc.strerror or exc}") from None
    try:
        yield tmp
        with open(tmp, "rb") as handle:
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def atomic_write(path: str | os.PathLike[str], mode: str = "w") -> Iterator[IO[Any]]:
    """Open a file handle that replaces ``path`` atomically when the block succeeds.

    :func:`atomic_path` with the temporary file opened in ``mode`` (``"w"`` or ``"wb"``).
    """
    with atomic_path(path) as tmp, open(tmp, mode) as handle:
        yield handle


def write_npz(
    path: str | os.PathLike[str], arrays: dict[str, Any], *, compresslevel: int = 1
) -> None:
    """Write ``arrays`` as a deflate-compressed ``.npz`` atomically (``numpy.load`` reads it).

    ``numpy.savez_compressed`` always deflates at zlib's level 6; level 1 (the default here)
    wrote a 94 MB visibility table in 0.85 s instead of 1.9 s, into a file 29 % larger.
    """
    import numpy as np

    with (
        atomic_write(path, "wb") as handle,
        zipfile.ZipFile(
            handle, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=compresslevel
        ) as archive,
    ):
        for name, value in arrays.items():
            with archive.open(f"{name}.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)


def output_folder(folder: str | os.PathLike[str]) -> Path:
    """Create the output folder ``folder`` (and its parents), with a one-line error naming
    it when a file stands in the way or the location is not writable."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise OSError(
            f"cannot create the output folder {folder}: {_blocking_file(folder)} is a file"
        ) from None
    except OSError as exc:
        raise OSError(f"cannot create the output folder {folder}: {exc.strerror or exc}") from None
    return folder


def _blocking_file(folder: Path) -> Path:
    """The first existing non-folder on the way to ``folder`` (what stops ``mkdir``)."""
    for candidate in (*reversed(folder.parents), folder):
        if candidate.exists() and not candidate.is_dir():
            return candidate
    return folder


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 hex digest of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
