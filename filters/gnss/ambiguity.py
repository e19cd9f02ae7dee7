"""Double-difference ambiguities accumulated over epochs, keyed by satellite (PRN).

The ambiguity normal equations of the relative solver (:mod:`filters.gnss.relative`): each
epoch adds its block with the baseline reduced out (Teunissen & Kleusberg 1998, *GPS for
Geodesy*, ch. 8); satellites join and leave, the reference satellite changes without losing
the ambiguities (``a'_s = a_s − a_{q'}``, ``a'_q = −a_{q'}``), and the float solution of the
free ambiguities is conditional on the fixed ones.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["AmbiguityNormals"]


class AmbiguityNormals:
    """Accumulated normal equations of double-difference ambiguities, keyed by PRN.

    Parameters are ``a_s = N_s − N_q`` for the PRNs in :attr:`prns` and the reference PRN
    :attr:`reference`; :attr:`fixed` holds the accepted integers (NaN where float).
    """

    def __init__(self, reference: int) -> None:
        self.reference = int(reference)
        self.prns: list[int] = []
        self.normal = np.zeros((0, 0))
        self.rhs = np.zeros(0)
        self.fixed = np.zeros(0)
        self.epochs = 0

    def position(self, prns: Any) -> np.ndarray:
        """Indices of ``prns`` in the parameter order."""
        lookup = {p: i for i, p in enumerate(self.prns)}
        return np.array([lookup[int(p)] for p in prns], dtype=int)

    def add(self, prns: Any) -> None:
        """Append new parameters without information."""
        new = [int(p) for p in prns if int(p) not in self.prns and int(p) != self.reference]
        if not new:
            return
        n, k = len(self.prns), len(new)
        normal = np.zeros((n + k, n + k))
        normal[:n, :n] = self.normal
        self.normal = normal
        self.rhs = np.concatenate([self.rhs, np.zeros(k)])
        self.fixed = np.concatenate([self.fixed, np.full(k, np.nan)])
        self.prns.extend(new)

    def drop(self, prns: Any) -> None:
        """Marginalise parameters out (their information about the others is kept)."""
        gone = [int(p) for p in prns if int(p) in self.prns]
        if not gone:
            return
        j = self.position(gone)
        keep = np.setdiff1d(np.arange(len(self.prns)), j)
        n_jj = self.normal[np.ix_(j, j)]
        n_kj = self.normal[np.ix_(keep, j)]
        inv = np.linalg.pinv(n_jj, hermitian=True)
        self.normal = self.normal[np.ix_(keep, keep)] - n_kj @ inv @ n_kj.T
        self.rhs = self.rhs[keep] - n_kj @ inv @ self.rhs[j]
        self.fixed = self.fixed[keep]
        self.prns = [self.prns[i] for i in keep]

    def reset(self, prns: Any) -> None:
        """Re-initialise parameters (after a cycle slip): marginalise, then add afresh."""
        self.drop(prns)
        self.add(prns)

    def change_reference(self, new_reference: int) -> None:
        """Re-express the parameters relative to ``new_reference`` (one of :attr:`prns`).

        ``a'_s = a_s − a_{q'}`` and ``a'_q = −a_{q'}`` (the old reference takes the new one's
        place): an integer, self-inverse map ``T``, so ``N' = T N T`` and ``n' = T n``.
        """
        j = self.position([new_reference])[0]
        n = len(self.prns)
        t = np.eye(n)
        t[:, j] -= 1.0
        t[j, j] = -1.0
        self.normal = t.T @ self.normal @ t
        self.rhs = t.T @ self.rhs
        self.fixed = t @ self.fixed
        self.prns[j] = self.reference
        self.reference = int(new_reference)

    def accumulate(self, reduced_normal: Any, reduced_rhs: Any, prns: Any) -> None:
        """Add one epoch's reduced normal equations for the parameters ``prns``."""
        j = self.position(prns)
        self.normal[np.ix_(j, j)] += reduced_normal
        self.rhs[j] += reduced_rhs
        self.epochs += 1

    def float_solution(self, free: Any, conditional: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Float ambiguities of the ``free`` parameters (indices).

        Parameters
        ----------
        free : (k,) array_like of int
        conditional : bool
            Condition on the fixed parameters ``X`` outside ``free`` (``N_FF⁻¹ (n_F −
            N_FX a_X)``); otherwise the others are free too and the marginal float solution
            ``(N⁻¹ n)_F`` with covariance ``(N⁻¹)_FF`` is returned.

        Returns
        -------
        a : (k,) numpy.ndarray
        q : (k, k) numpy.ndarray
        """
        free = np.asarray(free, dtype=int)
        if not conditional:
            q_all = np.linalg.inv(self.normal)
            q = q_all[np.ix_(free, free)]
            return (q_all @ self.rhs)[free], 0.5 * (q + q.T)
        fixed = np.setdiff1d(np.flatnonzero(np.isfinite(self.fixed)), free)
        n_ff = self.normal[np.ix_(free, free)]
        rhs = self.rhs[free] - self.normal[np.ix_(free, fixed)] @ self.fixed[fixed]
        q = np.linalg.inv(n_ff)
        return q @ rhs, 0.5 * (q + q.T)
