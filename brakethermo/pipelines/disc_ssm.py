"""The disc as a state-space model for the sigma-point filters.

State ``x = [T_1 .. T_n, theta_1 .. theta_p]``: the node temperatures of a
:class:`~brakethermo.thermal.model.DiscFEModel` (degC) and augmented parameters that
follow a Gaussian random walk (paper eq. 48–50). Known parameters so far are the
convection coefficient ``h`` (identify-h) and the braking-power scale (the friction
coefficient relative to nominal, which the paper names as the main uncertainty of the
braking power). Further effects plug in as further parameters.

Process noise has two parts: white noise on every node, and the uncertainty of how the
braking power splits over the three pad crowns (paper §2: the split changes from corner
to corner and lap to lap) at constant total. The second part scales with the braking
power of the step, so the filter trusts the model while cooling and lets the
measurement move the temperature profile while braking — and, since the split
conserves power, a crown read hotter than predicted makes its neighbours cooler.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from brakethermo.errors import DataError
from brakethermo.thermal.model import DiscFEModel
from brakethermo.thermal.power import crown_areas, crown_load

H_PARAM = "h"
SCALE_PARAM = "power_scale"
C_TYPICAL_C = 500.0  # degC at which the crown-noise gain is evaluated
H_TYPICAL = 100.0  # W/(m² K), the same; the gain hardly depends on either
T_AMB_TYPICAL_C = 25.0


@dataclass(frozen=True)
class RandomWalkParam:
    """An augmented scalar state.

    Attributes
    ----------
    name : str
    init, init_sigma : float
        Prior mean and standard deviation, in the parameter's unit.
    step_sigma : float
        Random-walk standard deviation per 0.1 s step.
    lower : float
        The model sees ``max(theta, lower)``, so a sigma point cannot make it unphysical.
    """

    name: str
    init: float
    init_sigma: float
    step_sigma: float
    lower: float = 0.0


class DiscStateSpace:
    """Batched transition, process noise and measurement matrices of the disc filter.

    Parameters
    ----------
    model : DiscFEModel
    q_brk : ndarray (K,) — W
        Braking power at nominal friction of each step.
    t_amb : ndarray (K,) — degC
    h : ndarray (K,) or None — W/(m² K)
        Convection coefficient per step; ``None`` when ``h`` is a state.
    params : sequence of RandomWalkParam
        Augmented parameters (names :data:`H_PARAM`, :data:`SCALE_PARAM`).
    sigma_temp : float — degC per step
        White process noise on every node.
    sigma_crown : float — dimensionless
        Relative uncertainty of each crown's share of the braking power.
    """

    def __init__(
        self,
        model: DiscFEModel,
        q_brk: np.ndarray,
        t_amb: np.ndarray,
        h: np.ndarray | None,
        params: Sequence[RandomWalkParam] = (),
        *,
        sigma_temp: float,
        sigma_crown: float,
    ) -> None:
        names = [p.name for p in params]
        unknown = set(names) - {H_PARAM, SCALE_PARAM}
        if unknown:
            raise ValueError(f"unknown augmented parameters {sorted(unknown)}")
        if h is None and H_PARAM not in names:
            raise ValueError("h must be given per step or be a state")
        self.model = model
        self.q_brk = np.asarray(q_brk, dtype=float)
        self.t_amb = np.asarray(t_amb, dtype=float)
        self.h = None if h is None else np.asarray(h, dtype=float)
        self.params = tuple(params)
        self.n_temp = model.n_state
        self.n = self.n_temp + len(self.params)
        self.index = {p.name: self.n_temp + i for i, p in enumerate(self.params)}
        self._lower = np.array([p.lower for p in self.params])

        Q = np.zeros((self.n, self.n))
        Q[: self.n_temp, : self.n_temp] = np.eye(self.n_temp) * sigma_temp**2
        for p in self.params:
            Q[self.index[p.name], self.index[p.name]] = p.step_sigma**2
        self._Q_base = Q
        S = np.zeros((self.n, self.n))
        S[: self.n_temp, : self.n_temp] = self._crown_covariance(model, sigma_crown)
        self._S_crown = S

    @staticmethod
    def _crown_covariance(model: DiscFEModel, sigma_crown: float) -> np.ndarray:
        """Covariance of one step's temperature change per squared watt of braking power.

        The split over the crowns changes at constant total power (paper §2), so the
        shares ``s`` get the multinomial covariance ``sigma² (diag(s) - s s')`` whose rows
        sum to zero; an error in the total is the power-scale state's job. Column ``i``
        of ``G`` is the change one backward-Euler step makes for a watt on crown ``i``
        (K/W), at a typical temperature: it carries the heat through the layers as the
        model itself does.
        """
        edges = model.disc.crown_edges
        w = model.weights if np.isfinite(model.weights).all() else np.ones(3)
        share = crown_areas(edges) * w / np.dot(crown_areas(edges), w)
        T = np.tile(model.initial_state(C_TYPICAL_C), (3, 1))
        load = np.stack([crown_load(model.radii, edges, e) for e in np.eye(3)])
        args = dict(h=H_TYPICAL, t_amb=T_AMB_TYPICAL_C, load=load)
        G = (model.step(T, 1.0, **args) - model.step(T, 0.0, **args)).T
        C_share = sigma_crown**2 * (np.diag(share) - np.outer(share, share))
        return G @ C_share @ G.T

    # ----------------------------------------------------------- filter interface
    def _param(self, X: np.ndarray, name: str) -> np.ndarray | None:
        i = self.index.get(name)
        if i is None:
            return None
        return np.maximum(X[:, i], self._lower[i - self.n_temp])

    def f(self, X: np.ndarray, k: int) -> np.ndarray:
        """Advance every sigma point from step ``k`` to ``k + 1`` (eq. 15, 50)."""
        h = self._param(X, H_PARAM)
        scale = self._param(X, SCALE_PARAM)
        out = np.empty_like(X)
        try:
            out[:, : self.n_temp] = self.model.step(
                X[:, : self.n_temp],
                self.q_brk[k],
                self.h[k] if h is None else h,
                self.t_amb[k],
                1.0 if scale is None else scale,
            )
        except (ZeroDivisionError, FloatingPointError):
            raise DataError(
                f"the disc model broke down at step {k} (t = {k * self.model.dt:.1f} s): the"
                " temperatures left any physical range; check the h law and tuning values"
            ) from None
        out[:, self.n_temp :] = X[:, self.n_temp :]
        return out

    def Q(self, k: int) -> np.ndarray:
        """Process noise of the step ``k -> k + 1``, squared state units."""
        return self._Q_base + self.q_brk[k] ** 2 * self._S_crown

    def H(self, radii: Sequence[float] | np.ndarray) -> np.ndarray:
        """Face temperature at ``radii`` (m) by linear interpolation (eq. 53), (m, n)."""
        H = np.zeros((np.size(radii), self.n))
        H[:, : self.n_temp] = self.model.spot_matrix(radii)
        return H

    def selector(self, name: str) -> np.ndarray:
        """Row vector picking parameter ``name`` out of the state, (1, n)."""
        row = np.zeros((1, self.n))
        row[0, self.index[name]] = 1.0
        return row

    def prior(self, t0_nodes: np.ndarray, init_sigma_temp: float) -> tuple[np.ndarray, np.ndarray]:
        """Prior mean and covariance at step 0.

        Temperatures get a common offset uncertainty plus an independent part, which
        keeps the prior smooth across the radius.
        """
        x0 = np.concatenate([np.asarray(t0_nodes, float), [p.init for p in self.params]])
        P0 = np.zeros((self.n, self.n))
        var = init_sigma_temp**2
        P0[: self.n_temp, : self.n_temp] = 0.5 * var + 0.5 * var * np.eye(self.n_temp)
        for p in self.params:
            P0[self.index[p.name], self.index[p.name]] = p.init_sigma**2
        return x0, P0
