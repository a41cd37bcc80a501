"""The disc as a state-space model for the sigma-point filters.

State ``x = [T_1 .. T_n, theta_1 .. theta_p, s]``: the node temperatures of a
:class:`~brakethermo.thermal.model.DiscFEModel` (degC), augmented parameters that
follow a Gaussian random walk (paper eq. 48–50) and, with a lagging pyrometer, the
sensor's own temperature ``s``. The parameters: the convection coefficient ``h``
(identify-h), the braking-power scale (the friction coefficient relative to nominal,
which the paper names as the main uncertainty of the braking power), and the online
forms of the registered effects (:mod:`brakethermo.models.effects`): an h multiplier
that moves only off the brakes (``slipstream``), a through-thickness conductivity
factor (``thickness_gradient``) and the balance ``b`` of the pad pressure between the
inner and the outer crown (``power_distribution``: crown weights ``w1 (1 + b), w2,
w3 (1 - b)``, renormalised to the same total power, eq. 8). Fixed effects from a test
session enter as :class:`DiscEffects`: μ(T) on the braking power and the sensor's time
constant.

Process noise has two parts: white noise on every node, and the uncertainty of how the
braking power splits over the three pad crowns (paper §2: the split changes from corner
to corner and lap to lap) at constant total. The second part scales with the braking
power of the step, so the filter trusts the model while cooling and lets the
measurement move the temperature profile while braking — and, since the split
conserves power, a crown read hotter than predicted makes its neighbours cooler.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from brakethermo.errors import DataError
from brakethermo.models import _disc_kernels
from brakethermo.models.effects import MU_SPAN_C, lag_alpha, mu_ratio
from brakethermo.thermal.model import DiscFEModel
from brakethermo.thermal.power import crown_areas, crown_load

H_PARAM = "h"
SCALE_PARAM = "power_scale"
H_FACTOR_PARAM = "h_factor"  # slipstream, online: moves off the brakes only
KZ_PARAM = "kz_factor"  # thickness_gradient, online
BALANCE_PARAM = "crown_balance"  # power_distribution, online: inner vs outer crown
PARAMS = (H_PARAM, SCALE_PARAM, H_FACTOR_PARAM, KZ_PARAM, BALANCE_PARAM)
BALANCE_MAX = 0.6  # |b| beyond which the outer (or inner) crown's load would vanish
BALANCE_STEP = 0.1  # finite-difference step of the load's derivative in b (it is linear)
C_TYPICAL_C = 500.0  # degC at which the crown-noise gain is evaluated
H_TYPICAL = 100.0  # W/(m² K), the same; the gain hardly depends on either
T_AMB_TYPICAL_C = 25.0


@dataclass(frozen=True)
class DiscEffects:
    """Effects fixed at their test-session values for a filter run.

    Attributes
    ----------
    mu_beta, mu_t_mid_c : float — dimensionless, degC
        ``friction_temperature``: braking power × μ(T)/μ_ref (:func:`effects.mu_ratio`)
        at the contact-band face temperature of each sigma point; ``mu_beta = 0`` = off.
    sensor_tau_s : float — s
        ``sensor_lag``: first-order pyrometer; the sensor temperature becomes a state and
        the measurement reads it. 0 = ideal sensor.
    """

    mu_beta: float = 0.0
    mu_t_mid_c: float = 400.0
    sensor_tau_s: float = 0.0


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
    off_brake_only : bool
        The walk moves only on steps without braking (``slipstream``: following another
        bike changes the cooling air on the straights).
    """

    name: str
    init: float
    init_sigma: float
    step_sigma: float
    lower: float = 0.0
    off_brake_only: bool = False


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
        Augmented parameters (names of :data:`PARAMS`).
    sigma_temp : float — degC per step
        White process noise on every node.
    sigma_crown : float — dimensionless
        Relative uncertainty of each crown's share of the braking power.
    effects : DiscEffects, optional
        Fixed effects (μ(T), sensor lag).
    spot_radius : float, optional — m
        The measured spot, needed when the sensor lags (its state follows that spot).
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
        effects: DiscEffects | None = None,
        spot_radius: float | None = None,
    ) -> None:
        names = [p.name for p in params]
        unknown = set(names) - set(PARAMS)
        if unknown:
            raise ValueError(f"unknown augmented parameters {sorted(unknown)}")
        if h is None and H_PARAM not in names:
            raise ValueError("h must be given per step or be a state")
        self.model = model
        self.q_brk = np.asarray(q_brk, dtype=float)
        self.t_amb = np.asarray(t_amb, dtype=float)
        self.h = None if h is None else np.asarray(h, dtype=float)
        self.params = tuple(params)
        self.effects = effects or DiscEffects()
        self.n_temp = model.n_state
        self.index = {p.name: self.n_temp + i for i, p in enumerate(self.params)}
        self._lower = np.array([p.lower for p in self.params])
        self.lagging = self.effects.sensor_tau_s > 0
        if self.lagging and spot_radius is None:
            raise ValueError("a lagging sensor needs the measured spot's radius")
        self.sensor_index = self.n_temp + len(self.params) if self.lagging else None
        self.n = self.n_temp + len(self.params) + int(self.lagging)
        if self.lagging:
            self._sensor_row = model.spot_matrix([spot_radius])[0]
            self._sensor_alpha = float(lag_alpha(np.array(self.effects.sensor_tau_s), model.dt))
        edges = model.disc.crown_edges
        contact = (model.radii >= edges[0] - 1e-9) & (model.radii <= edges[-1] + 1e-9)
        self._contact_face = model.face_index[contact]
        on_brake = self.q_brk > 0.01 * max(float(np.max(self.q_brk, initial=0.0)), 1.0)
        off_only = np.array([p.off_brake_only for p in self.params], dtype=bool)
        self._moving = ~(on_brake[:, None] & off_only[None, :])

        Q = np.zeros((self.n, self.n))
        Q[: self.n_temp, : self.n_temp] = np.eye(self.n_temp) * sigma_temp**2
        if self.lagging:
            # the sensor's own small model error, so its state is never over-trusted
            Q[self.sensor_index, self.sensor_index] = sigma_temp**2
        self._Q_base = Q
        self._step_var = np.array([p.step_sigma**2 for p in self.params])
        self._param_idx = self.n_temp + np.arange(len(self.params))
        S = np.zeros((self.n, self.n))
        S[: self.n_temp, : self.n_temp] = self._crown_covariance(model, sigma_crown)
        self._S_crown = S
        if BALANCE_PARAM in self.index:
            w = model.weights if np.isfinite(model.weights).all() else np.ones(3)
            self._load0 = crown_load(model.radii, edges, w)
            tilt = np.array([BALANCE_STEP, 0.0, -BALANCE_STEP])
            # the nodal load is linear in b: both crowns' shares move, the total stays 1
            self._dload = (crown_load(model.radii, edges, w * (1 + tilt))
                           - crown_load(model.radii, edges, w * (1 - tilt))) / (2 * BALANCE_STEP)

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

    def crown_directions(self) -> np.ndarray:
        """(n_temp, d) directions of the crown-split process noise (the eigenvectors of
        its covariance that carry it), each scaled to unit norm."""
        S = self._S_crown[: self.n_temp, : self.n_temp]
        w, V = np.linalg.eigh(S)
        keep = w > 1e-9 * max(float(w.max(initial=0.0)), 1e-300)
        return V[:, keep]

    # ----------------------------------------------------------- filter interface
    def _param(self, X: np.ndarray, name: str) -> np.ndarray | None:
        i = self.index.get(name)
        if i is None:
            return None
        return np.maximum(X[:, i], self._lower[i - self.n_temp])

    def f(self, X: np.ndarray, k: int) -> np.ndarray:
        """Advance every sigma point from step ``k`` to ``k + 1`` (eq. 15, 50)."""
        h = self._param(X, H_PARAM)
        h = self.h[k] if h is None else h
        factor = self._param(X, H_FACTOR_PARAM)
        if factor is not None:
            h = h * factor
        scale = self._param(X, SCALE_PARAM)
        scale = np.ones(X.shape[0]) if scale is None else scale
        if self.effects.mu_beta:
            T_contact = X[:, self._contact_face].mean(axis=1)
            scale = scale * mu_ratio(T_contact, self.effects.mu_beta, self.effects.mu_t_mid_c)
        kz = self._param(X, KZ_PARAM)
        balance = self._param(X, BALANCE_PARAM)
        load = None
        if balance is not None:
            load = self._load0 + np.minimum(balance, BALANCE_MAX)[:, None] * self._dload
        out = np.empty_like(X)
        try:
            out[:, : self.n_temp] = self.model.step(
                X[:, : self.n_temp],
                self.q_brk[k],
                h,
                self.t_amb[k],
                scale,
                kz_ratio=None if kz is None else kz * self.model.kz_ratio,
                load=load,
            )
        except (ZeroDivisionError, FloatingPointError):
            raise DataError(
                f"the disc model broke down at step {k} (t = {k * self.model.dt:.1f} s): the"
                " temperatures left any physical range; check the h law and tuning values"
            ) from None
        out[:, self.n_temp :] = X[:, self.n_temp :]
        if self.lagging:
            s = X[:, self.sensor_index]
            face = out[:, : self.n_temp] @ self._sensor_row
            out[:, self.sensor_index] = s + self._sensor_alpha * (face - s)
        return out

    def _kernel_spec(self) -> tuple[Any, ...]:
        """What :func:`_disc_kernels.disc_transition` takes after the step: the inputs
        as (K, 1) or (K, B) columns, the parameter columns and floors, the constants."""
        cols = np.full(6, -1, dtype=np.int64)
        for c, name in ((_disc_kernels.COL_H, H_PARAM), (_disc_kernels.COL_FACTOR, H_FACTOR_PARAM),
                        (_disc_kernels.COL_SCALE, SCALE_PARAM), (_disc_kernels.COL_KZ, KZ_PARAM),
                        (_disc_kernels.COL_BALANCE, BALANCE_PARAM)):
            cols[c] = self.index.get(name, -1)
        if self.lagging:
            cols[_disc_kernels.COL_SENSOR] = self.sensor_index
        lower = np.full(self.n, -np.inf)
        lower[self._param_idx] = self._lower
        load = np.ascontiguousarray(self.model.load[None, :], dtype=np.float64)
        tilt = ((self._load0, self._dload) if BALANCE_PARAM in self.index
                else (np.zeros(self.model.n_nodes), np.zeros(self.model.n_nodes)))

        def column(a: np.ndarray | None) -> np.ndarray:
            if a is None:
                return np.zeros((0, 1))
            return np.ascontiguousarray(a.reshape(a.shape[0], -1), dtype=np.float64)

        return (
            (column(self.q_brk), column(self.t_amb), column(self.h)),
            cols, lower,
            (float(self.model.kz_ratio), float(self.effects.mu_beta),
             float(self.effects.mu_t_mid_c), MU_SPAN_C, BALANCE_MAX,
             self._sensor_alpha if self.lagging else 0.0),
            self._contact_face.astype(np.int64),
            (load, *(np.ascontiguousarray(a[None, :], dtype=np.float64) for a in tilt)),
            self._sensor_row if self.lagging else np.zeros(self.n_temp),
            self.model.kernel_geometry,
        )

    def _breakdown(self, k0: int, k1: int) -> DataError:
        return DataError(
            f"the disc model broke down between t = {k0 * self.model.dt:.1f} and"
            f" {k1 * self.model.dt:.1f} s: the temperatures left any physical range; check"
            " the h law and tuning values")

    @staticmethod
    def _span(inputs: tuple[np.ndarray, ...]) -> tuple[int, set[int]]:
        """The steps ``inputs`` hold and their widths other than 1 (shared)."""
        given = [a for a in inputs if a.size]
        return min(a.shape[0] for a in given), {a.shape[1] for a in given} - {1}

    def _check_span(self, span: tuple[int, set[int]], k_end: int, B: int, n: int,
                    n_state: int | None = None) -> None:
        """The compiled loop reads its inputs unchecked: steps up to ``k_end`` must exist
        and the members be (B, n) with inputs shared or one column per member; ``n_state``
        the states of the coordinates run in (default :attr:`n`)."""
        K, widths = span
        n_state = self.n if n_state is None else n_state
        if k_end > K or n != n_state or widths - {B}:
            raise ValueError(
                f"compiled steps up to {k_end} of {K} on ({B}, {n}) members: the state space"
                f" has {n_state} states and inputs of width {sorted(widths) or [1]}")

    def compiled_steps(self, noise_parts: tuple[np.ndarray, np.ndarray, np.ndarray] | None
                       = None, lift: np.ndarray | None = None) -> Callable[..., None] | None:
        """:meth:`f` and :meth:`Q` fused into the UKF kernel's step loop
        (:mod:`brakethermo.models._disc_kernels`): ``steps(k0, k1, offset, work, *args)``
        runs filter steps ``k0 .. k1 - 1`` on model steps ``k + offset``. None where the
        model does not compile. The inputs, constants and model are taken now: change
        none of them after (``f`` and ``Q`` would see the change, these steps not).

        ``lift`` (n, r) runs the filter on reduced coordinates ``x = lift' x_full``
        (orthonormal columns; :class:`~brakethermo.models.reduced.ReducedStateSpace`),
        with the noise of :meth:`noise` from ``noise_parts`` (base, crown, parameter
        indices) in those coordinates: both or neither (the compiled loop indexes them
        unchecked)."""
        if (lift is None) != (noise_parts is None):
            raise ValueError("compiled steps on reduced coordinates need both the lift and"
                             " the noise in those coordinates")
        if not self.model.use_numba:
            return None
        *head, geometry = self._kernel_spec()
        base, crown, param_idx = noise_parts or (self._Q_base, self._S_crown, self._param_idx)
        r = self.n if lift is None else lift.shape[1]
        if ((lift is not None and lift.shape[0] != self.n) or base.shape != (r, r)
                or crown.shape != (r, r) or np.any((param_idx < 0) | (param_idx >= r))):
            shape = None if lift is None else lift.shape
            raise ValueError(f"reduced coordinates of {r} states: lift {shape} for {self.n}"
                             f" full states, noise {base.shape} / {crown.shape},"
                             f" parameter indices {param_idx.tolist()}")
        noise = (np.ascontiguousarray(base, dtype=np.float64),
                 np.ascontiguousarray(crown, dtype=np.float64), param_idx.astype(np.int64),
                 self._step_var.astype(np.float64), self._moving.astype(np.float64))
        spec = (*head, noise, geometry)
        span = self._span(head[0])
        L = None if lift is None else np.ascontiguousarray(lift, dtype=np.float64)

        def steps(k0: int, k1: int, offset: int, work: np.ndarray, *args: Any) -> None:
            # the last step reads its inputs at k1 - 1 + offset
            self._check_span(span, k1 + offset, 2 * work.shape[1] + 1, work.shape[1], r)
            try:
                _disc_kernels.run_steps(spec, k0, k1, offset, work, *args, lift=L)
            except ZeroDivisionError:
                raise self._breakdown(k0 + offset, k1 + offset) from None

        return steps

    def replay(self, X0: np.ndarray, w: np.ndarray, k0: int = 0) -> np.ndarray:
        """Members stepped through the session from step ``k0`` with a correction after
        each step: ``X[k + 1] = f(X[k], k0 + k) + w[k]`` from ``X[0] = X0`` (B, n); ``w``
        (K - 1, B, n). Returns (K, B, n). Compiled where the model compiles."""
        K = w.shape[0] + 1
        Xs = np.empty((K, *X0.shape))
        Xs[0] = X0
        if not self.model.use_numba:
            for k in range(K - 1):
                Xs[k + 1] = self.f(Xs[k], k0 + k) + w[k]
            return Xs
        B, n = X0.shape
        spec = self._kernel_spec()
        self._check_span(self._span(spec[0]), k0 + K - 1, B, n)
        if w.shape[1:] != (B, n):
            raise ValueError(f"corrections of shape {w.shape[1:]} for ({B}, {n}) members")
        try:
            _disc_kernels.disc_replay(Xs, np.ascontiguousarray(w, dtype=np.float64), k0,
                                      *spec)
        except ZeroDivisionError:
            raise self._breakdown(k0, k0 + K - 1) from None
        return Xs

    def Q(self, k: int) -> np.ndarray:
        """Process noise of the step ``k -> k + 1``, squared state units."""
        return self.noise(k, self._Q_base, self._S_crown, self._param_idx)

    def noise(self, k: int, base: np.ndarray, crown: np.ndarray, param_idx: np.ndarray
              ) -> np.ndarray:
        """:meth:`Q` from its parts in any coordinates that keep the parameters as they
        are (the reduced order's): white ``base``, the crown split's covariance per
        squared watt ``crown``, the parameters' random walks at ``param_idx``."""
        Q = base + self.q_brk[k] ** 2 * crown
        if self.params:
            Q[param_idx, param_idx] = self._step_var * self._moving[k]
        return Q

    def H(self, radii: Sequence[float] | np.ndarray) -> np.ndarray:
        """Face temperature at ``radii`` (m) by linear interpolation (eq. 53), (m, n)."""
        H = np.zeros((np.size(radii), self.n))
        H[:, : self.n_temp] = self.model.spot_matrix(radii)
        return H

    def H_measured(self, radius: float) -> np.ndarray:
        """What the pyrometer at ``radius`` reads, (1, n): its own state when it lags."""
        if not self.lagging:
            return self.H([radius])
        H = np.zeros((1, self.n))
        H[0, self.sensor_index] = 1.0
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
        t0 = np.asarray(t0_nodes, float)
        sensor = [float(self._sensor_row @ t0)] if self.lagging else []
        x0 = np.concatenate([t0, [p.init for p in self.params], sensor])
        P0 = np.zeros((self.n, self.n))
        var = init_sigma_temp**2
        T = slice(0, self.n_temp)
        P0[T, T] = 0.5 * var + 0.5 * var * np.eye(self.n_temp)
        for p in self.params:
            P0[self.index[p.name], self.index[p.name]] = p.init_sigma**2
        if self.lagging:
            i = self.sensor_index
            P0[i, T] = P0[T, T] @ self._sensor_row
            P0[T, i] = P0[i, T]
            P0[i, i] = float(self._sensor_row @ P0[T, T] @ self._sensor_row)
        return x0, P0
