"""The shape library: a folder of named mesh files with a JSON manifest, and the built-in one.

Modules
-------
- :mod:`~shapes.library.core` — :class:`ShapeLibrary`: loading, validating, adding and
  removing shapes; :func:`get_library`, :func:`builtin_library_path`.
- :mod:`~shapes.library.proxy` — level-of-detail proxies: quadric decimation of a big mesh
  until its light-curve error (measured by the caller) is within tolerance; staging.
- :mod:`~shapes.library.manifest` — the manifest: names, format, reading and writing,
  entries, the staged-rename transaction.
- :mod:`~shapes.library.builtin` — builds the built-in library (``shapes/data``) from the
  primitives and the SBGAT meshes (``python -m shapes.library.builtin``).

This ``__init__`` only hands the public names on.
"""

from shapes.library.core import (
    MANIFEST,
    LibraryReadOnlyError,
    ShapeLibrary,
    builtin_library_path,
    check_name,
    get_library,
)

__all__ = [
    "MANIFEST",
    "LibraryReadOnlyError",
    "ShapeLibrary",
    "builtin_library_path",
    "check_name",
    "get_library",
]
