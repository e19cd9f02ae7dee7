"""Input handling shared by the BRDF kernels: one code path for numpy arrays and torch tensors.

The kernels are written against the array-API namespace returned here, so the same lines run
on numpy arrays and on torch tensors (CPU or GPU, with autograd). Real scalar parameters are
kept as Python floats: they then fold into the arithmetic without allocating full-size arrays
and without promoting float32 inputs to float64.
"""

from __future__ import annotations

import sys
from numbers import Real
from types import ModuleType
from typing import Any

import array_api_compat.numpy as xp_numpy
import numpy as np

__all__ = ["prepare"]


def prepare(
    arrays: tuple[Any, ...], params: tuple[Any, ...] = ()
) -> tuple[ModuleType, tuple[Any, ...], tuple[Any, ...]]:
    """Resolve the array namespace of a kernel call and convert its inputs.

    If any input is a torch tensor, everything becomes tensors of the dtype and device of the
    first floating-point tensor (float64 when none is floating); otherwise numpy arrays
    (float64 unless already float32/float64).

    Parameters
    ----------
    arrays : tuple
        Geometric inputs (cosines or direction vectors); always returned as arrays, ``None``
        passes through.
    params : tuple
        Model parameters; real scalars are returned as Python floats, ``None`` passes through,
        anything else as an array.

    Returns
    -------
    xp : module
        ``array_api_compat.numpy`` or ``array_api_compat.torch``.
    arrays, params : tuple
        The converted inputs, in order.
    """
    # A plain isinstance test (no cached namespace lookup) keeps the kernels traceable by
    # torch.compile; torch is only consulted when the caller has imported it.
    torch = sys.modules.get("torch")
    tensors = [v for v in (*arrays, *params) if torch is not None and isinstance(v, torch.Tensor)]
    if tensors:
        import array_api_compat.torch as xp

        floating = [t for t in tensors if t.is_floating_point()]
        dtype = floating[0].dtype if floating else torch.float64
        device = (floating or tensors)[0].device

        def convert(value: Any) -> Any:
            if isinstance(value, torch.Tensor):
                return value if value.is_floating_point() else value.to(dtype)
            return torch.as_tensor(np.asarray(value), dtype=dtype, device=device)

    else:
        xp = xp_numpy

        def convert(value: Any) -> Any:
            array = np.asarray(value)
            if array.dtype not in (np.float32, np.float64):
                array = array.astype(np.float64)
            return array

    converted_arrays = tuple(None if v is None else convert(v) for v in arrays)
    converted_params = tuple(
        None if v is None else float(v) if _is_real_scalar(v) else convert(v) for v in params
    )
    return xp, converted_arrays, converted_params


def _is_real_scalar(value: Any) -> bool:
    return isinstance(value, Real) and not isinstance(value, bool)
