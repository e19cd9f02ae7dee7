"""Common-view selection, single and double differences and their correlated covariance.

Between-receiver single differences ``SD^s = y_rover^s − y_base^s`` remove the satellite clock
(and, over short baselines, orbit and atmospheric errors); differencing them against a
reference satellite ``q``, ``DD^s = SD^s − SD^q``, removes the receiver clocks and the
fractional initial phases, leaving integer carrier-phase ambiguities ``N^s_rb − N^q_rb``
(Teunissen & Kleusberg, *GPS for Geodesy*, 1998, ch. 7; Misra & Enge 2006, ch. 7).

With independent undifferenced errors of variances ``σ²_{r,s}``, the single differences are
independent with variances ``v_s = σ²_{rover,s} + σ²_{base,s}``, and the ``m − 1`` double
differences share the reference satellite's error:

``Q_DD = D diag(v) Dᵀ = diag(v_s, s ≠ q) + v_q 1 1ᵀ``,

with ``D`` the ``(m − 1) × m`` operator with ``+1`` for satellite ``s`` and ``−1`` for ``q``.
The paper's receiver (Shi, Zhang, Li, Lang & Zheng, *Relative navigation architecture for
aerospace vehicles based on multimodal measurement*, sec. 2.2.1.1) keeps the satellites seen
by both receivers, needs at least five of them for a relative fix, and takes the highest one
as the reference.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = [
    "MIN_COMMON_SATELLITES",
    "common_view",
    "double_difference_covariance",
    "double_difference_operator",
    "double_differences",
    "reference_satellite",
    "single_differences",
]

MIN_COMMON_SATELLITES = 5
"""Fewest satellites seen by both receivers for a relative fix (four double differences)."""


def common_view(*tracked: Any) -> np.ndarray:
    """Satellites tracked by every receiver.

    Parameters
    ----------
    *tracked : (..., n) array_like of bool
        Per receiver, whether each satellite has valid measurements.

    Returns
    -------
    (..., n) bool numpy.ndarray
    """
    if not tracked:
        raise ValueError("common_view needs at least one receiver")
    out = np.asarray(tracked[0], dtype=bool)
    for t in tracked[1:]:
        out = out & np.asarray(t, dtype=bool)
    return out


def reference_satellite(elevation: Any, current: int | None = None, allowed: Any = None) -> int:
    """Index of the reference satellite: ``current`` while it is ``allowed``, else the
    highest ``allowed`` one.

    Parameters
    ----------
    elevation : (m,) array_like
        Elevations of the candidate satellites (rad).
    current : int, optional
        Index of the present reference.
    allowed : (m,) array_like of bool, optional
        Candidates (all by default).

    Returns
    -------
    int
    """
    el = np.asarray(elevation, dtype=float)
    ok = np.ones(el.shape, bool) if allowed is None else np.asarray(allowed, dtype=bool)
    if not ok.any():
        raise ValueError("no satellite can be the reference")
    if current is not None and ok[current]:
        return int(current)
    return int(np.argmax(np.where(ok, el, -np.inf)))


def single_differences(rover: Any, base: Any) -> np.ndarray:
    """Between-receiver single differences ``rover − base`` (same units)."""
    return np.asarray(rover, dtype=float) - np.asarray(base, dtype=float)


def double_difference_operator(m: int, reference: int) -> np.ndarray:
    """The ``(m − 1) × m`` matrix ``D`` mapping single to double differences.

    Row ``i`` belongs to the ``i``-th non-reference satellite (in index order) and holds
    ``+1`` at that satellite and ``−1`` at the reference.
    """
    if not 0 <= reference < m:
        raise ValueError(f"reference {reference} outside 0…{m - 1}")
    others = np.delete(np.arange(m), reference)
    d = np.zeros((m - 1, m))
    d[np.arange(m - 1), others] = 1.0
    d[:, reference] = -1.0
    return d


def double_differences(single: Any, reference: int) -> np.ndarray:
    """Double differences ``SD^s − SD^q`` of single differences along the last axis.

    Parameters
    ----------
    single : (..., m) array_like
    reference : int
        Index of the reference satellite ``q``.

    Returns
    -------
    (..., m − 1) numpy.ndarray
        Non-reference satellites in index order.
    """
    sd = np.asarray(single, dtype=float)
    return np.delete(sd, reference, axis=-1) - sd[..., reference : reference + 1]


def double_difference_covariance(var_rover: Any, var_base: Any, reference: int) -> np.ndarray:
    """Covariance ``Q_DD = diag(v_s, s ≠ q) + v_q 1 1ᵀ`` of double differences.

    Parameters
    ----------
    var_rover, var_base : (m,) array_like
        Variances of the undifferenced measurements of each receiver (m² or cycles²).
    reference : int
        Index of the reference satellite.

    Returns
    -------
    (m − 1, m − 1) numpy.ndarray
    """
    v = np.asarray(var_rover, dtype=float) + np.asarray(var_base, dtype=float)
    others = np.delete(v, reference)
    return np.diag(others) + v[reference]
