"""The roller rig's state-space model for the joint UKF: state [omega_w, omega_r, r_w].

Torsional dynamics of wheel and roller (paper eq. 10) with the contact force from
Polach's creep law on the Hertz ellipse (spin included), the roller's induction
motor under V/f control (eq. 1), bearing losses, and the PMSM torque taken from the
logged request. The rolling radius is a random-walk parameter (eq. 11-13). Each
sample interval is integrated by RK4 at the paper's 0.25 ms substep, all sigma points
in one compiled call (the contact is stiff: its time constant is ~0.3 ms, so the
substep is needed for stability, not only accuracy).

Sign convention of :mod:`brakethermo.rigs`: creepage s = (v_w - v_r)/V, the contact
force F > 0 when the wheel drives the roller::

    J_w d(omega_w)/dt = T_P - F r_w - T_bw(omega_w)
    J_r d(omega_r)/dt = F R_r + T_A(omega_r) - T_br(omega_r)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numba import njit
from numpy.typing import NDArray

from brakethermo.errors import ConfigError
from brakethermo.rigs.fastsim import PARABOLIC, fastsim_table, fastsim_table_force
from brakethermo.rigs.kalker import flexibilities
from brakethermo.rigs.motor import motor_torque, motor_torque_scalar
from brakethermo.rigs.polach import friction_coefficient, polach_force, polach_force_scalar
from brakethermo.rigs.roller_rig import RollerRigSpec

Array = NDArray[np.float64]
V_MIN = 0.05  # m/s, floor of the rolling speed in the creepage (standstill)
OMEGA_EPS = 0.05  # rad/s, width of the smoothed sign of the Coulomb bearing loss
# Layout of the compiled parameter vector (see RollerRigModel.params).
(J_W, J_R, R_R, PSI, A_REF, B_REF, N_REF, G, C11, C22, MU0, FA, FB, KA, KS, MV, MRTH, MX, MR2,
 MF, MP, BW0, BW1, BR0, BR1, LAW, U_MAX, V_LO, V_HI,
 EF_GAIN, EF_OFF, EF_MU) = range(32)  # fmt: skip
CREEP_LAWS = ("polach", "fastsim")
FASTSIM_GRID = 20  # elements per strip and strips (the paper's 20 x 20)


@dataclass(frozen=True)
class CreepEffects:
    """Departures of the creep curve from the datasheet's law, as ``diagnose`` fits them
    (:data:`brakethermo.models.rig_effects.ROLLER_EFFECTS`) and the estimator carries them::

        F(ξ) = (1 + m) f((1 + a) (ξ - d) / (1 + m))

    Attributes
    ----------
    slope_change : float — a, the initial slope's change, - (``creep_slope``).
    mu_change : float — m, the friction level's change, - (``friction_level``; Kalker's
        similarity: F / (μN) depends on ξ / μ).
    offset : float — d, a creepage the speeds carry at zero force, - (``creepage_offset``).
    """

    slope_change: float = 0.0
    mu_change: float = 0.0
    offset: float = 0.0

    def __post_init__(self) -> None:
        if not (self.slope_change > -1.0 and self.mu_change > -1.0
                and abs(self.offset) < 0.05):
            raise ConfigError(
                f"creep effects out of range (slope_change {self.slope_change:g} and"
                f" mu_change {self.mu_change:g} must exceed -1, |offset| {self.offset:g}"
                " below 0.05)")

    @property
    def gain(self) -> float:
        """(1 + a) / (1 + m): the factor on the creepage inside the law."""
        return (1.0 + self.slope_change) / (1.0 + self.mu_change)


@dataclass(frozen=True)
class RollerRigModel:
    """The estimator's model of one roller rig.

    Attributes
    ----------
    spec : RollerRigSpec — the datasheet.
    substep : float — RK4 step inside a sample interval, s.
    creep_law : {"polach", "fastsim"} — Polach's closed-form law (default), or Kalker's
        FASTSIM (20 x 20, parabolic bound, tabulated once per run) with Polach's
        slip-velocity friction: the richer alternative.
    effects : CreepEffects — the creep curve's diagnosed departures (none by default).
    """

    spec: RollerRigSpec
    substep: float
    creep_law: str = "polach"
    effects: CreepEffects = CreepEffects()

    @classmethod
    def from_spec(
        cls, spec: RollerRigSpec, substep: float | None = None, creep_law: str = "polach",
        effects: CreepEffects | None = None,
    ) -> RollerRigModel:
        """The model with the datasheet's substep unless one is given (s)."""
        h = spec.filter.substep if substep is None else substep
        if not 0.0 < h <= 0.01:
            raise ConfigError(f"RK4 substep must be in (0, 10 ms], got {h} s")
        if creep_law not in CREEP_LAWS:
            raise ConfigError(
                f"creep law must be one of {', '.join(CREEP_LAWS)}, got {creep_law!r}"
            )
        return cls(spec, h, creep_law, effects or CreepEffects())

    def params(self) -> Array:
        """The compiled kernels' parameter vector (layout of the module constants)."""
        return self._params

    def table(self) -> Array:
        """FASTSIM's normalised force table for the ``fastsim`` law (a dummy for Polach)."""
        return self._table

    @cached_property
    def _params(self) -> Array:
        s = self.spec
        c, k, fr, b = s.contact(), s.kalker(), s.friction, s.bearings
        phi = s.spin()
        # FASTSIM table range: full sliding near xi = 3 mu N/(G a b c11), spin over mu's range
        u_max = 9.0 * c.normal_force / (s.shear_modulus * c.a * c.b * k.c11)
        return np.array([
            s.wheel_inertia, s.roller_inertia, s.roller_radius, phi, c.a, c.b,
            c.normal_force, s.shear_modulus, k.c11, k.c22, fr.mu0, fr.A, fr.B, fr.k_a, fr.k_s,
            *s.motor.params(), b.wheel_coulomb, b.wheel_viscous, b.roller_coulomb,
            b.roller_viscous, CREEP_LAWS.index(self.creep_law), u_max, phi / fr.mu0,
            phi / (fr.mu0 * fr.A), self.effects.gain, self.effects.offset,
            1.0 + self.effects.mu_change,
        ])  # fmt: skip

    @cached_property
    def _table(self) -> Array:
        if self.creep_law != "fastsim":
            return np.zeros((1, 1))
        s, p = self.spec, self.params()
        c = s.contact()
        L1, L2, L3 = flexibilities(c.a, c.b, s.shear_modulus, s.kalker())
        return fastsim_table(c.a, c.b, L1, L2, L3, c.normal_force, p[U_MAX], p[V_LO], p[V_HI],
                             FASTSIM_GRID, PARABOLIC)  # fmt: skip

    def creep(
        self, omega_w: Array, omega_r: Array, r_w: Array, normal_force: Array
    ) -> tuple[Array, Array]:
        """Creepage (-) and contact force (N) of states, vectorised (same law as the kernel)."""
        s, p = self.spec, self.params()
        v_w = np.asarray(omega_w) * np.asarray(r_w)
        v_r = np.asarray(omega_r) * p[R_R]
        V = np.maximum(0.5 * (np.abs(v_w) + np.abs(v_r)), V_MIN)
        s_x = (v_w - v_r) / V
        s_law = p[EF_GAIN] * (s_x - p[EF_OFF])  # CreepEffects
        fr = s.friction
        if self.creep_law == "fastsim":
            mu = friction_coefficient(s_law * V, fr.mu0, fr.A, fr.B)
            lookup = np.vectorize(fastsim_table_force, otypes=[float], excluded={"tab"})
            F = lookup(s_law, p[PSI], mu, normal_force, p[N_REF], p[U_MAX], p[V_LO], p[V_HI],
                       tab=self.table())  # fmt: skip
            return s_x, p[EF_MU] * F
        scale = np.cbrt(np.asarray(normal_force, dtype=float) / p[N_REF])
        F, _ = polach_force(
            s_law, p[PSI], V, normal_force, p[A_REF] * scale, p[B_REF] * scale, p[G], p[C11],
            p[C22], fr.mu0, fr.A, fr.B, fr.k_a, fr.k_s,
        )  # fmt: skip
        return s_x, p[EF_MU] * F

    def derivatives(
        self, X: Array, torque: Array | float, normal_force: Array | float, supply_hz: float
    ) -> Array:
        """dX/dt of states X (B, 3), vectorised numpy (the reference of the kernel)."""
        s, p = self.spec, self.params()
        w_w, w_r, r_w = X[:, 0], X[:, 1], X[:, 2]
        _, F = self.creep(w_w, w_r, r_w, np.broadcast_to(normal_force, w_w.shape))
        T_A = motor_torque(s.motor, w_r, supply_hz)
        T_bw = p[BW0] * np.tanh(w_w / OMEGA_EPS) + p[BW1] * w_w
        T_br = p[BR0] * np.tanh(w_r / OMEGA_EPS) + p[BR1] * w_r
        d = np.zeros_like(X)
        d[:, 0] = (torque - F * r_w - T_bw) / p[J_W]  # eq. 10b
        d[:, 1] = (F * p[R_R] + T_A - T_br) / p[J_R]  # eq. 10a
        return d

    def propagate_numpy(
        self,
        X: Array,
        dt: float,
        torque: tuple[float, float],
        normal: tuple[float, float],
        supply_hz: float,
    ) -> Array:
        """RK4 over one sample interval, vectorised numpy (slow; the kernel's reference)."""
        n_sub = max(1, math.ceil(dt / self.substep - 1e-9))
        h = dt / n_sub
        X = np.array(X, dtype=float)
        for j in range(n_sub):
            u = [
                (
                    torque[0] + (torque[1] - torque[0]) * (j + c) / n_sub,
                    normal[0] + (normal[1] - normal[0]) * (j + c) / n_sub,
                )
                for c in (0, 0.5, 1)
            ]
            k1 = self.derivatives(X, *u[0], supply_hz)
            k2 = self.derivatives(X + 0.5 * h * k1, *u[1], supply_hz)
            k3 = self.derivatives(X + 0.5 * h * k2, *u[1], supply_hz)
            k4 = self.derivatives(X + h * k3, *u[2], supply_hz)
            X = X + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        return X

    def transition(
        self, dt: float, torque: Array, normal_force: Array, supply_hz: Array
    ) -> RollerRigTransition:
        """The batched ``f(X, k)`` of the filter engine over one session's inputs.

        Parameters
        ----------
        dt : float — sample interval, s.
        torque : ndarray (K,) — PMSM torque request on the grid, N m (held linearly
            between samples).
        normal_force : ndarray (K,) — normal load, N.
        supply_hz : ndarray (K,) — roller-motor supply frequency, Hz.
        """
        return RollerRigTransition(
            self.params(), self.table(), float(dt), max(1, math.ceil(dt / self.substep - 1e-9)),
            np.ascontiguousarray(torque, dtype=float),
            np.ascontiguousarray(normal_force, dtype=float),
            np.ascontiguousarray(supply_hz, dtype=float),
        )  # fmt: skip


@dataclass(frozen=True)
class RollerRigTransition:
    """``f(X (B, 3), k) -> (B, 3)``: all sigma points over interval k -> k+1 in one call."""

    params: Array
    table: Array
    dt: float
    n_sub: int
    torque: Array
    normal_force: Array
    supply_hz: Array

    def __call__(self, X: Array, k: int) -> Array:
        out = np.empty_like(X)
        k1 = min(k + 1, self.torque.shape[0] - 1)
        propagate(
            np.ascontiguousarray(X, dtype=float), out, self.torque[k], self.torque[k1],
            self.normal_force[k], self.normal_force[k1], self.supply_hz[k], self.params,
            self.table, self.n_sub, self.dt / self.n_sub,
        )  # fmt: skip
        return out


@njit(cache=True, nogil=True)
def _rhs(w_w, w_r, r_w, u, q, fsyn, p, tab):  # pragma: no cover - compiled
    tq, N, a, b = u[q, 0], u[q, 1], u[q, 2], u[q, 3]
    v_w = w_w * r_w
    v_r = w_r * p[R_R]
    V = max(0.5 * (abs(v_w) + abs(v_r)), V_MIN)
    s_law = p[EF_GAIN] * ((v_w - v_r) / V - p[EF_OFF])  # CreepEffects
    if p[LAW] == 1.0:
        mu = p[MU0] * ((1.0 - p[FA]) * math.exp(-p[FB] * abs(s_law * V)) + p[FA])
        F = fastsim_table_force(s_law, p[PSI], mu, N, p[N_REF], p[U_MAX], p[V_LO], p[V_HI],
                                tab)  # fmt: skip
    else:
        F = polach_force_scalar(
            s_law, p[PSI], V, N, a, b, p[G], p[C11], p[C22], p[MU0], p[FA], p[FB], p[KA], p[KS]
        )  # fmt: skip
    F *= p[EF_MU]
    T_A = motor_torque_scalar(w_r, fsyn, p[MV], p[MRTH], p[MX], p[MR2], p[MF], p[MP])
    T_bw = p[BW0] * _smooth_sign(w_w) + p[BW1] * w_w
    T_br = p[BR0] * _smooth_sign(w_r) + p[BR1] * w_r
    return (tq - F * r_w - T_bw) / p[J_W], (F * p[R_R] + T_A - T_br) / p[J_R]


@njit(cache=True, nogil=True)
def _smooth_sign(w):  # pragma: no cover - compiled
    """tanh(w / OMEGA_EPS); its exact +-1 beyond 20 widths, where tanh rounds to it anyway."""
    if w > 20.0 * OMEGA_EPS:
        return 1.0
    if w < -20.0 * OMEGA_EPS:
        return -1.0
    return math.tanh(w / OMEGA_EPS)


@njit(cache=True, nogil=True)
def propagate(X, out, tq0, tq1, n0, n1, fsyn, p, tab, n_sub, h):  # pragma: no cover - compiled
    """RK4 of every row of X over n_sub substeps h, inputs linear in time, into out."""
    # inputs and contact size at the substep start, middle and end, the same for all rows:
    # torque, normal force and the contact's semi-axes a, b
    u = np.empty((2 * n_sub + 1, 4))
    for q in range(u.shape[0]):
        c = q / (2.0 * n_sub)
        u[q, 0] = tq0 + (tq1 - tq0) * c
        u[q, 1] = n0 + (n1 - n0) * c
        scale = (u[q, 1] / p[N_REF]) ** (1.0 / 3.0)  # Hertz: size ~ N^(1/3), shape fixed
        u[q, 2] = p[A_REF] * scale
        u[q, 3] = p[B_REF] * scale
    for i in range(X.shape[0]):
        w_w = X[i, 0]
        w_r = X[i, 1]
        r_w = X[i, 2]
        for j in range(n_sub):
            q0, q1, q2 = 2 * j, 2 * j + 1, 2 * j + 2
            a1, b1 = _rhs(w_w, w_r, r_w, u, q0, fsyn, p, tab)
            a2, b2 = _rhs(w_w + 0.5 * h * a1, w_r + 0.5 * h * b1, r_w, u, q1, fsyn, p, tab)
            a3, b3 = _rhs(w_w + 0.5 * h * a2, w_r + 0.5 * h * b2, r_w, u, q1, fsyn, p, tab)
            a4, b4 = _rhs(w_w + h * a3, w_r + h * b3, r_w, u, q2, fsyn, p, tab)
            w_w += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
            w_r += h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
        out[i, 0] = w_w
        out[i, 1] = w_r
        out[i, 2] = r_w
