"""A reduced-order disc filter: the node temperatures on a few dominant thermal modes.

The unscented filter pushes ``2n + 1`` sigma points through the FE model each step, so
its cost grows with the square of the mesh. The temperature field of a braked disc is
smooth and moves in few patterns (a mean level, a radial tilt towards the contact band,
a skin-to-core gradient, ...), so the filter state can be the field's coordinates on
``r`` orthonormal modes ``Phi`` (n_temp, r) instead of the n_temp node temperatures
(proper orthogonal decomposition, Galerkin projection):

    T = Phi z,     z_{k+1} = Phi' f(Phi z_k)                       (projected transition)

with the augmented parameters and the sensor state carried as they are. The full model
still makes every step — its nonlinearity in the temperature (c(T), k(T), radiation)
and in the parameters is kept — but only ``2(r + p) + 1`` sigma points go through it.

The modes are the leading left singular vectors of the model's own open-loop run over
the session's first laps (its snapshots, not centred, so the first mode carries the mean
level), as many as keep the snapshots' projection error under :data:`MODE_TOLERANCE_C`,
at most :data:`MAX_MODES` (a 15 x 6 mesh at a thin-skin law's k_z ratio near 0.1 would
take 49-52: at 40 its basis holds 0.002-0.003 degC, and on nine development races run so
the estimate moved by at most 0.002 of the single-spot baseline, the decisions not at
all, 10-40 % faster). The
approximation — what the modes cannot represent is dropped each step, and so is the
process noise outside their span — is checked against the full filter on the same
session (``tests/test_reduced.py``) and reported in the run facts.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from brakethermo.models.disc import DiscStateSpace

MODE_TOLERANCE_C = 0.001  # degC, RMS projection error of the open-loop snapshots
MAX_MODES = 40
MIN_MODES = 4


def pod_modes(snapshots: np.ndarray, tolerance_c: float = MODE_TOLERANCE_C,
              max_modes: int = MAX_MODES) -> tuple[np.ndarray, float]:
    """Leading modes of temperature snapshots and the RMS error of projecting onto them.

    Parameters
    ----------
    snapshots : ndarray (K, n) — degC, one state per row.
    tolerance_c : float — degC; the fewest modes whose RMS projection error is below it.
    max_modes : int — at most this many (and at most n).

    Returns
    -------
    Phi : ndarray (n, r) — orthonormal columns.
    error_c : float — degC, RMS of ``T - Phi Phi' T`` over the snapshots.
    """
    X = np.asarray(snapshots, float)
    K, n = X.shape
    _, s, Vt = np.linalg.svd(X, full_matrices=False)
    tail = np.sqrt(np.maximum(np.cumsum((s**2)[::-1])[::-1], 0.0) / (K * n))  # tail[r]
    tail = np.append(tail, 0.0)
    top = min(max_modes, n)
    r = next((r for r in range(min(MIN_MODES, top), top + 1) if tail[r] <= tolerance_c), top)
    return Vt[:r].T.copy(), float(tail[r])


def with_directions(Phi: np.ndarray, D: np.ndarray, tol: float = 1e-6) -> np.ndarray:
    """``Phi`` (n, r) extended by the parts of the columns of ``D`` (n, d) outside its
    span (Gram-Schmidt, twice for round-off); columns already in the span add nothing."""
    out = [Phi]
    for d in np.asarray(D, float).T:
        v = d.copy()
        for _ in range(2):
            basis = np.column_stack(out)
            v -= basis @ (basis.T @ v)
        norm = np.linalg.norm(v)
        if norm > tol * max(np.linalg.norm(d), 1e-300):
            out.append((v / norm)[:, None])
    return np.column_stack(out)


class ReducedStateSpace:
    """The disc state space with its node temperatures on the modes ``Phi``.

    The filter interface of :class:`~brakethermo.models.disc.DiscStateSpace` (``f``,
    ``Q``, ``H``, ``H_measured``, ``selector``, ``prior``, ``index``, ``n``) over the
    state ``[z_1 .. z_r, theta_1 .. theta_p, s]``; :meth:`lift` maps states, means and
    covariances back to the full model's.

    Parameters
    ----------
    full : DiscStateSpace
    Phi : ndarray (n_temp, r) — orthonormal modes of the node temperatures.
    """

    def __init__(self, full: DiscStateSpace, Phi: np.ndarray) -> None:
        self.full = full
        self.Phi = np.ascontiguousarray(Phi, dtype=float)
        self.r = self.Phi.shape[1]
        n_t = full.n_temp
        self.n_temp = self.r
        self.n = full.n - n_t + self.r
        shift = self.r - n_t
        self.index = {name: i + shift for name, i in full.index.items()}
        self.sensor_index = None if full.sensor_index is None else full.sensor_index + shift
        # x_full = L x_red: the modes for the temperatures, identity for the rest
        L = np.zeros((full.n, self.n))
        L[:n_t, : self.r] = self.Phi
        L[n_t:, self.r:] = np.eye(full.n - n_t)
        self.L = L
        self._Q_base = L.T @ full._Q_base @ L
        self._S_crown = L.T @ full._S_crown @ L
        self._param_idx = full._param_idx + shift

    def lift(self, X: np.ndarray) -> np.ndarray:
        """Reduced states (..., n) to full ones (..., n_full)."""
        return np.asarray(X) @ self.L.T

    def project(self, X: np.ndarray) -> np.ndarray:
        """Full states (..., n_full) onto the reduced coordinates (..., n)."""
        return np.asarray(X) @ self.L

    def f(self, Z: np.ndarray, k: int) -> np.ndarray:
        """The projected transition ``Phi' f(Phi z)`` of every sigma point."""
        return self.project(self.full.f(self.lift(Z), k))

    def Q(self, k: int) -> np.ndarray:
        """The full process noise projected onto the reduced coordinates (its parts
        projected once: no full-size matrix per step)."""
        return self.full.noise(k, self._Q_base, self._S_crown, self._param_idx)

    def compiled_steps(self) -> Callable[..., None] | None:
        """The full model's compiled step loop on these coordinates
        (:meth:`DiscStateSpace.compiled_steps` with ``lift``)."""
        return self.full.compiled_steps((self._Q_base, self._S_crown, self._param_idx),
                                        lift=self.L)

    def H(self, radii: Sequence[float] | np.ndarray) -> np.ndarray:
        return self.full.H(radii) @ self.L

    def H_measured(self, radius: float) -> np.ndarray:
        return self.full.H_measured(radius) @ self.L

    def selector(self, name: str) -> np.ndarray:
        return self.full.selector(name) @ self.L

    def prior(self, t0_nodes: np.ndarray, init_sigma_temp: float
              ) -> tuple[np.ndarray, np.ndarray]:
        """The full prior's mean and covariance on the reduced coordinates."""
        x0, P0 = self.full.prior(t0_nodes, init_sigma_temp)
        return self.project(x0), self.L.T @ P0 @ self.L
