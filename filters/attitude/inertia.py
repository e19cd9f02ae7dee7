"""Inertia tensors: validity, principal axes and the two filter parameterisations.

Without external torques only the *shape* of the inertia tensor is observable, so filters
estimate a scale-free parameterisation:

* The normalised tensor ``L = J / Jzz`` with the five free entries
  ``l = [Lxx, Lyy, Lxy, Lxz, Lyz]`` (Deng et al. 2024, state entries 7–11).
* The principal-axis *tanh* form ``k = [k1, k2] ∈ ℝ²`` (Feng et al.):
  ``J ∝ diag(1 + e^{2 k2}, 1 + e^{2 k1}, e^{2 k1} + e^{2 k2})``, for which the ratios
  ``px = (Jyy − Jzz)/Jxx = −tanh k2``, ``py = (Jzz − Jxx)/Jyy = tanh k1`` and
  ``pz = (Jxx − Jyy)/Jzz = tanh(k2 − k1)``. Every ``k`` is a physical inertia and every
  physical principal inertia (strict triangle inequalities) has exactly one ``k``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from filters.attitude.arrays import as_arrays

__all__ = [
    "InertiaError",
    "inertia_from_normalized",
    "inertia_from_tanh",
    "inertia_ratios",
    "moment_ratios",
    "normalized_from_inertia",
    "principal_axes",
    "ratios_from_tanh",
    "tanh_from_inertia",
    "validate_inertia",
]


class InertiaError(ValueError):
    """An inertia tensor that no rigid body can have."""


def validate_inertia(inertia: Any, rtol: float = 1e-9) -> np.ndarray:
    """Check that ``J`` is a physical inertia tensor and return it as a float array.

    A physical tensor is symmetric, positive definite and its principal moments satisfy the
    triangle inequalities ``J1 + J2 ≥ J3`` (and permutations); a thin plate reaches equality.

    Parameters
    ----------
    inertia : (3, 3) array_like or (3,) array_like
        Tensor, or principal moments ``[Jxx, Jyy, Jzz]``.
    rtol : float
        Relative tolerance for symmetry and the inequalities.

    Returns
    -------
    (3, 3) numpy.ndarray
        The tensor (diagonal when moments were given).

    Raises
    ------
    InertiaError
        Naming the violated condition and the offending values.
    """
    j = np.asarray(inertia, dtype=float)
    if j.shape == (3,):
        j = np.diag(j)
    if j.shape != (3, 3):
        raise InertiaError(f"inertia must be a 3x3 tensor or 3 moments, got shape {j.shape}")
    if not np.all(np.isfinite(j)):
        raise InertiaError("inertia tensor has non-finite entries")
    scale = np.max(np.abs(j))
    if scale == 0:
        raise InertiaError("inertia tensor is zero")
    if np.max(np.abs(j - j.T)) > rtol * scale:
        raise InertiaError(f"inertia tensor is not symmetric: {j.tolist()}")
    moments = np.linalg.eigvalsh(0.5 * (j + j.T))
    if moments[0] <= 0:
        raise InertiaError(
            f"inertia tensor is not positive definite (principal moments {moments.tolist()})"
        )
    names = ("J1", "J2", "J3")
    for i in range(3):
        a, b = [k for k in range(3) if k != i]
        if moments[a] + moments[b] < moments[i] * (1 - rtol):
            raise InertiaError(
                f"triangle inequality {names[a]} + {names[b]} >= {names[i]} violated by the "
                f"principal moments {moments.tolist()}"
            )
    return j


def principal_axes(inertia: Any) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments (ascending) and axes of an inertia tensor.

    Parameters
    ----------
    inertia : (3, 3) array_like

    Returns
    -------
    moments : (3,) numpy.ndarray
    axes : (3, 3) numpy.ndarray
        Columns are the principal axes in the input frame, forming a right-handed frame;
        ``axes.T @ J @ axes = diag(moments)``.
    """
    j = validate_inertia(inertia)
    moments, axes = np.linalg.eigh(0.5 * (j + j.T))
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    return moments, axes


def normalized_from_inertia(inertia: Any) -> Any:
    """Free entries ``l = [Lxx, Lyy, Lxy, Lxz, Lyz]`` of ``L = J / Jzz`` (Deng et al. 2024).

    Parameters
    ----------
    inertia : (..., 3, 3) array

    Returns
    -------
    (..., 5) array
    """
    xp, (j,) = as_arrays(inertia)
    big_l = j / j[..., 2:3, 2:3]
    return xp.stack(
        [big_l[..., 0, 0], big_l[..., 1, 1], big_l[..., 0, 1], big_l[..., 0, 2], big_l[..., 1, 2]],
        axis=-1,
    )


def inertia_from_normalized(l: Any) -> Any:
    """The normalised tensor ``L`` (``Lzz = 1``) from its free entries.

    Parameters
    ----------
    l : (..., 5) array
        ``[Lxx, Lyy, Lxy, Lxz, Lyz]``.

    Returns
    -------
    (..., 3, 3) array
    """
    xp, (l,) = as_arrays(l)
    lxx, lyy, lxy, lxz, lyz = (l[..., i] for i in range(5))
    one = xp.ones_like(lxx)
    return xp.stack(
        [
            xp.stack([lxx, lxy, lxz], axis=-1),
            xp.stack([lxy, lyy, lyz], axis=-1),
            xp.stack([lxz, lyz, one], axis=-1),
        ],
        axis=-2,
    )


def inertia_ratios(inertia: Any) -> Any:
    """Ratios ``p = [(Jyy − Jzz)/Jxx, (Jzz − Jxx)/Jyy, (Jxx − Jyy)/Jzz]`` (Feng et al.).

    They satisfy ``px + py + pz + px py pz = 0`` and ``|p| ≤ 1`` for a physical body.

    Parameters
    ----------
    inertia : (..., 3) or (..., 3, 3) array
        Principal moments or a principal-axis (diagonal) tensor. A ``(3, 3)`` array is one
        tensor, never three moment vectors: a stack of moments goes to
        :func:`moment_ratios`.

    Returns
    -------
    (..., 3) array
    """
    xp, (j,) = as_arrays(inertia)
    if j.ndim >= 2 and j.shape[-2:] == (3, 3):
        j = xp.stack([j[..., 0, 0], j[..., 1, 1], j[..., 2, 2]], axis=-1)
    return moment_ratios(j)


def moment_ratios(moments: Any) -> Any:
    """The ratios of :func:`inertia_ratios` from principal moments only.

    Parameters
    ----------
    moments : (..., 3) array
        Principal moments ``[J1, J2, J3]``, any number of leading dimensions (a stack of
        three bodies is ``(3, 3)``, which :func:`inertia_ratios` would read as one tensor).

    Returns
    -------
    (..., 3) array
    """
    xp, (j,) = as_arrays(moments)
    jx, jy, jz = j[..., 0], j[..., 1], j[..., 2]
    return xp.stack([(jy - jz) / jx, (jz - jx) / jy, (jx - jy) / jz], axis=-1)


def ratios_from_tanh(k: Any) -> Any:
    """Inertia ratios ``[−tanh k2, tanh k1, tanh(k2 − k1)]`` of the tanh form (Feng et al.).

    Parameters
    ----------
    k : (..., 2) array

    Returns
    -------
    (..., 3) array
    """
    xp, (k,) = as_arrays(k)
    k1, k2 = k[..., 0], k[..., 1]
    return xp.stack([-xp.tanh(k2), xp.tanh(k1), xp.tanh(k2 - k1)], axis=-1)


def inertia_from_tanh(k: Any) -> Any:
    """Principal inertia ``diag(1 + e^{2k2}, 1 + e^{2k1}, e^{2k1} + e^{2k2}) / s``.

    The scale ``s = 1 + e^{2k1} + e^{2k2}`` normalises the trace to 2, which keeps the
    entries finite and order one for any ``k``.

    Parameters
    ----------
    k : (..., 2) array

    Returns
    -------
    (..., 3, 3) array
        A diagonal, always physical inertia tensor.
    """
    xp, (k,) = as_arrays(k)
    # Divide numerator and denominator by e^{2 m}, m = max(0, k1, k2), to avoid overflow.
    m = xp.maximum(xp.maximum(k[..., 0], k[..., 1]), xp.zeros_like(k[..., 0]))
    e0 = xp.exp(-2 * m)
    e1 = xp.exp(2 * (k[..., 0] - m))
    e2 = xp.exp(2 * (k[..., 1] - m))
    s = e0 + e1 + e2
    zero = xp.zeros_like(s)
    diag = [(e0 + e2) / s, (e0 + e1) / s, (e1 + e2) / s]
    return xp.stack(
        [
            xp.stack([diag[0], zero, zero], axis=-1),
            xp.stack([zero, diag[1], zero], axis=-1),
            xp.stack([zero, zero, diag[2]], axis=-1),
        ],
        axis=-2,
    )


def tanh_from_inertia(inertia: Any, margin: float = 0.0) -> Any:
    """Tanh parameters ``k = [atanh(py), −atanh(px)]`` of a principal-axis inertia.

    Parameters
    ----------
    inertia : (..., 3) or (..., 3, 3) array
        Principal moments, or a diagonal tensor in its principal frame (a ``(3, 3)`` array
        is one tensor, as for :func:`inertia_ratios`).
    margin : float
        With ``margin > 0`` the ratios are clipped to ``[−1 + margin, 1 − margin]`` instead
        of raising: the nearest tanh form of a degenerate (plate-like) body. A flat body
        (``J3 = J1 + J2``, both ``px = −1`` and ``py = 1``) keeps its third ratio
        ``pz = tanh(k2 − k1)``: ``k2 = −atanh(−1 + margin)``, ``k1 = k2 − atanh(pz)``
        (clipping ``py`` as well would make every flat body a disc, ``pz = 0``).

    Returns
    -------
    (..., 2) array

    Raises
    ------
    InertiaError
        For numpy input whose off-diagonal entries are not zero (rotate to principal axes
        first) or whose ratios are not strictly inside (−1, 1) (a degenerate, plate-like or
        unphysical body).
    """
    xp, (j,) = as_arrays(inertia)
    if isinstance(j, np.ndarray) and j.shape[-2:] == (3, 3):
        off = j - np.eye(3) * j
        if np.max(np.abs(off)) > 1e-12 * np.max(np.abs(j)):
            raise InertiaError("tanh form needs a principal-axis (diagonal) inertia tensor")
    p = inertia_ratios(j)
    if margin > 0:
        inside = (xp.abs(p[..., 0]) < 1.0 - margin) & (xp.abs(p[..., 1]) < 1.0 - margin)
        p = xp.clip(p, -1.0 + margin, 1.0 - margin)
        k2 = -xp.atanh(p[..., 0])
        k1 = xp.where(inside, xp.atanh(p[..., 1]), k2 - xp.atanh(p[..., 2]))
        return xp.stack([k1, k2], axis=-1)
    if isinstance(p, np.ndarray) and not np.all(np.abs(p[..., :2]) < 1):
        raise InertiaError(
            f"inertia ratios {p.tolist()} are not inside (-1, 1): the triangle inequalities "
            "must hold strictly for the tanh form"
        )
    return xp.stack([xp.atanh(p[..., 1]), -xp.atanh(p[..., 0])], axis=-1)
