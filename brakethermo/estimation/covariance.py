"""Keeping covariances symmetric positive definite: symmetrise, factor, repair and count."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray


def symmetrise(P: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return (P + P') / 2, in place for a C-contiguous square ``P``."""
    P += P.T
    P *= 0.5
    return P


@dataclass
class CovarianceGuard:
    """Cholesky factorisation with eigenvalue-clipping repair when it fails.

    A covariance that lost positive definiteness (round-off, a negative Q, a bad P0)
    is replaced by its eigen-decomposition with eigenvalues clipped to
    ``max(rel_floor * max(|eig|), abs_floor)``; every repair is counted with its step.

    Attributes
    ----------
    rel_floor : float — relative eigenvalue floor.
    abs_floor : float — absolute eigenvalue floor, in the squared state units.
    n_repairs : int — repairs so far.
    repair_steps : list[int] — step index of each repair.
    """

    rel_floor: float = 1e-12
    abs_floor: float = 1e-12
    n_repairs: int = 0
    repair_steps: list[int] = field(default_factory=list)

    def repair(self, P: NDArray[np.float64], k: int) -> NDArray[np.float64]:
        """Return the nearest-by-clipping SPD matrix to ``P`` and count the repair."""
        self.n_repairs += 1
        self.repair_steps.append(k)
        P = np.where(np.isfinite(P), P, 0.0)
        w, V = np.linalg.eigh(0.5 * (P + P.T))
        floor = max(self.rel_floor * float(np.max(np.abs(w), initial=0.0)), self.abs_floor)
        w = np.maximum(w, floor)
        return symmetrise((V * w) @ V.T)

    def cholesky(
        self, P: NDArray[np.float64], k: int
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lower Cholesky factor of ``P``, repairing ``P`` first if it is not SPD.

        Returns
        -------
        L : ndarray (n, n) — lower factor, P = L L'.
        P : ndarray (n, n) — the matrix actually factored (``P`` itself when no repair).
        """
        try:
            L = np.linalg.cholesky(P)
            # a NaN anywhere in P reaches the last pivot, and LAPACK does not flag it
            if math.isfinite(L[-1, -1]):
                return L, P
        except np.linalg.LinAlgError:
            pass
        P = self.repair(P, k)
        try:
            return np.linalg.cholesky(P), P
        except np.linalg.LinAlgError:
            # eigh round-off can leave a tiny negative pivot; a diagonal jitter settles it
            P = P + np.eye(P.shape[0]) * (self.abs_floor + 1e-9 * float(np.max(np.diag(P))))
            return np.linalg.cholesky(P), P
