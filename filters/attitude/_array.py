"""Array-namespace helpers so one implementation serves numpy arrays and torch tensors.

Every function of the attitude core accepts numpy arrays, torch tensors or array-likes
(lists, scalars). When any argument is a torch tensor, the others are converted to tensors of
its dtype and device and the result is a tensor; otherwise everything is a numpy array
(float64 unless a float32 array was given).
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

import numpy as np
from array_api_compat import array_namespace, is_torch_array

__all__ = ["as_arrays", "is_torch_array", "matvec"]


def as_arrays(*values: Any) -> tuple[ModuleType, tuple[Any, ...]]:
    """Return the array namespace and the inputs converted to one array kind.

    Parameters
    ----------
    *values : array_like or torch.Tensor
        Inputs to convert.

    Returns
    -------
    xp : module
        The array-API namespace (``array_api_compat.numpy`` or ``array_api_compat.torch``).
    arrays : tuple
        The inputs as arrays of that namespace, floating point.
    """
    tensors = [v for v in values if is_torch_array(v)]
    if tensors:
        import torch

        ref = tensors[0]
        dtype = ref.dtype if ref.is_floating_point() else torch.float64
        arrays = tuple(
            (v if v.is_floating_point() else v.to(dtype))
            if is_torch_array(v)
            else torch.as_tensor(np.asarray(v), dtype=dtype, device=ref.device)
            for v in values
        )
    else:
        arrays = tuple(_as_float_array(v) for v in values)
    return array_namespace(*arrays), arrays


def _as_float_array(value: Any) -> np.ndarray:
    array = np.asarray(value)
    if array.dtype not in (np.float32, np.float64):
        array = array.astype(np.float64)
    return array


def matvec(matrix: Any, vector: Any) -> Any:
    """Batched matrix-vector product ``matrix @ vector`` over leading dimensions.

    Parameters
    ----------
    matrix : (..., m, n) array
    vector : (..., n) array

    Returns
    -------
    (..., m) array
    """
    return (matrix @ vector[..., None])[..., 0]
