"""E-Booster state space for the UKF and EKF (paper 004, eq. 3-4, 10, 13-14, section 3.4).

State [p_m, p_f, p_r (MPa), zeta1 (mm), zeta2 (mm/s)] plus the pedal state (F_in, or N w_i),
input the screw displacement s2 (mm, one value per step), measurement delta = zeta1 (mm).

* p_m follows the fitted p-V curve of s2 (eq. 13: dp_m = d f_RLS(s2)); a deviation from
  the curve relaxes with ``pv_relax_s`` (a bounded random walk instead of eq. 13's
  unbounded one, so the band cannot grow without limit between corrections);
* p_f, p_r fill through their ports (eq. 13, integrated exactly over the step);
* the pedal force (the paper's chi-square disturbance, N degrees of freedom) enters as
  one Gaussian state F_in (N), an Ornstein-Uhlenbeck process with the chi-square's
  first two moments (mean N F_scale, variance 2 N F_scale^2) and the correlation time of
  the square of the Gaussian processes behind it (``pedal_tau_s / 2``), clipped at zero
  in eq. 10 (a driver only pushes). With the 5 process noises of the physical states
  these are the paper's Gaussian process noises folded into the process noise; a
  driver's force is correlated over tenths of a second, so it is carried as a state
  rather than redrawn every step;
* the leverage (eq. 10, quasi-static) gives the net disk force, the three-slope fit
  (eq. 14) its quasi-static compression, the two-pole one-zero fit its dynamics.

``pedal_state = "chi_square"`` keeps the literal F_in = F_scale sum_i w_i^2 with N unit
Gaussian states w_i. It is biased for a sigma-point filter: the mean of F_scale w^2 over
the sigma points is F_scale (m^2 + P_w), and near zero force, where delta carries no
information on w (dF/dw = 0), P_w stays large, so the UKF predicts a force F_scale P_w
too high while the EKF (linearised at m) ignores it. Both filters run on the same model
either way. The force state is the default: linear in F_in wherever the driver pushes,
so there the sigma points' mean and the linearisation agree, and the clip at zero is the
only nonlinearity it adds (measured with ``benchmarks/bench_ebooster_accuracy.py``).

Known limit of the clip: while the driver is off the pedal, the measurement pulls the UKF's
force mean down until its upper sigma point reaches zero (about -sqrt(n + kappa) sigma,
-150 to -200 N), where every sigma point sits on the flat side of the clip; the force is
then unobservable and the filter's path follows round-off (two correct UKFs, ours and
filterpy's, part there by up to ~130 N in F_in and a few micrometres in zeta1, see
``benchmarks/bench_ebooster.py``), and the next brake onset starts from that deep mean.
A smooth floor (softplus of width 8 N) makes the path reproducible (ours equals filterpy's
to 1e-12) but keeps the deep mean: on development seeds 1-8 (12 s vehicle sessions at
500 Hz, not the reporting seeds) it was no better (UKF residual 1.6 % above the EKF's on
average, against 0.8 % with the clip), so the clip stays.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numba
import numpy as np
from numpy.typing import NDArray

from brakethermo.config import load_toml
from brakethermo.errors import ConfigError
from brakethermo.rigs.booster import (
    discretise,
    disk_quasi_static,
    disk_transfer,
    leverage_force,
    orifice_coefficient,
    orifice_step,
    pv_pressure,
)
from brakethermo.rigs.booster_datasheet import BoosterSpec
from brakethermo.rigs.pv_curve import candidate_names, knots_pressure
from brakethermo.rigs.signals import SPEED_WINDOW_S, smoothed_rate

Array = NDArray[np.float64]
STATE_NAMES = ("p_m", "p_f", "p_r", "zeta1", "zeta2")
N_PHYS = 5
V_REF_MM_S = 50.0  # screw speed at which q_pm_speed applies


@dataclass(frozen=True)
class BoosterFit:
    """What a training session identifies.

    Attributes
    ----------
    pv_coeffs : tuple of 4 float — MPa, weights of (s2/stroke)^2 ... ^8 (RLS, eq. 12).
    stroke_mm : float — mm, regressor scale.
    disk : tuple of 5 float — eq. 14 on |F|: breakpoints p1, p2 (N), slopes p3-p5 (mm/N).
    omega_n : float — rad/s, disk dynamics natural frequency.
    damping : float — disk dynamics damping ratio.
    tau_z : float — s, disk dynamics zero time constant.
    pedal_scale_n : float — N, F_scale of the chi-square pedal force (mean / N).
    train_session : str — the training file.
    pv_rmse_mpa : float — MPa, p-V fit residual on the training session.
    disk_rmse_mm : float — mm, disk fit residual on the training session.
    q_factor : float — factor on the datasheet's process noise of the physical states,
        chosen by the held-out likelihood of the training session's pressure sensor
        (1: the datasheet's, or no choice made).
    q_heldout_nats : tuple of float — that likelihood per reading for each factor tried
        (empty when no choice was made).
    s2_max_mm : float — mm, the furthest screw travel of the training data; beyond it
        the p-V curve follows its tangent (inf: a fit saved before this was recorded).
    pv_knots_mm, pv_knot_mpa : tuple of float — mm, MPa; when given, the p-V curve is
        these pressures at these travels joined by straight lines
        (:mod:`brakethermo.rigs.pv_curve`) and ``pv_coeffs`` is the polynomial it beat;
        empty: the polynomial.
    pv_heldout_mpa : tuple of float — MPa, each p-V candidate's held-out RMSE on the
        training session, the polynomial first, then
        :data:`~brakethermo.rigs.pv_curve.KNOT_COUNTS` (empty: no choice made).
    """

    pv_coeffs: tuple[float, float, float, float]
    stroke_mm: float
    disk: tuple[float, float, float, float, float]
    omega_n: float
    damping: float
    tau_z: float
    pedal_scale_n: float
    train_session: str
    pv_rmse_mpa: float
    disk_rmse_mm: float
    q_factor: float = 1.0
    q_heldout_nats: tuple[float, ...] = ()
    s2_max_mm: float = math.inf
    pv_knots_mm: tuple[float, ...] = ()
    pv_knot_mpa: tuple[float, ...] = ()
    pv_heldout_mpa: tuple[float, ...] = ()

    def pressure(self, s2_mm: Array | float) -> Array:
        """MPa, the static pressure of the fitted p-V curve at screw travel ``s2_mm``."""
        if self.pv_knots_mm:
            return knots_pressure(s2_mm, np.array(self.pv_knots_mm), np.array(self.pv_knot_mpa))
        return pv_pressure(s2_mm, np.array(self.pv_coeffs), self.stroke_mm, self.s2_max_mm)

    @property
    def pv_curve(self) -> str:
        """The p-V curve in words."""
        if self.pv_knots_mm:
            return (f"pressures at {len(self.pv_knots_mm)} travels (knots merged where"
                    " closer than a thousandth of the travel) joined by straight lines, never"
                    " falling (NNLS)")
        return "the paper's even polynomial of the travel (eq. 12, RLS)"

    def toml_text(self) -> str:
        """The fit as TOML (round-trips through :func:`load_fit`; io writes it)."""
        lines = ["# E-Booster training result (brakethermo ebooster --train)"]
        for key, value in asdict(self).items():
            if isinstance(value, str):
                lines.append(f'{key} = "{value}"')
            elif isinstance(value, tuple):
                lines.append(f"{key} = [{', '.join(repr(float(v)) for v in value)}]")
            else:
                lines.append(f"{key} = {float(value)!r}")
        return "\n".join(lines) + "\n"


def load_fit(path: str | Path) -> BoosterFit:
    """Read a training result written by :meth:`BoosterFit.write`."""
    raw = load_toml(path)
    try:
        fit = BoosterFit(
            pv_coeffs=tuple(float(v) for v in raw["pv_coeffs"]),  # type: ignore[arg-type]
            stroke_mm=float(raw["stroke_mm"]),
            disk=tuple(float(v) for v in raw["disk"]),  # type: ignore[arg-type]
            omega_n=float(raw["omega_n"]),
            damping=float(raw["damping"]),
            tau_z=float(raw["tau_z"]),
            pedal_scale_n=float(raw["pedal_scale_n"]),
            train_session=str(raw["train_session"]),
            pv_rmse_mpa=float(raw["pv_rmse_mpa"]),
            disk_rmse_mm=float(raw["disk_rmse_mm"]),
            q_factor=float(raw.get("q_factor", 1.0)),
            q_heldout_nats=tuple(float(v) for v in raw.get("q_heldout_nats", ())),
            s2_max_mm=float(raw.get("s2_max_mm", math.inf)),
            pv_knots_mm=tuple(float(v) for v in raw.get("pv_knots_mm", ())),
            pv_knot_mpa=tuple(float(v) for v in raw.get("pv_knot_mpa", ())),
            pv_heldout_mpa=tuple(float(v) for v in raw.get("pv_heldout_mpa", ())),
        )
    except (KeyError, TypeError, ValueError) as exc:
        what = f"missing key {exc}" if isinstance(exc, KeyError) else str(exc)
        raise ConfigError(f"not a valid training result ({what}); write one with"
                          " `brakethermo ebooster TRAIN --train TRAIN --save-fit FILE`",
                          path=Path(path)) from None
    problem = _fit_problem(fit)
    if problem:
        raise ConfigError(f"not a valid training result: {problem}; write one with"
                          " `brakethermo ebooster TRAIN --train TRAIN --save-fit FILE`",
                          path=Path(path))
    return fit


# what a training result holds: (key, count or None for a scalar, must be > 0)
_FIT_SHAPE = (("pv_coeffs", 4, False), ("disk", 5, False), ("stroke_mm", None, True),
              ("omega_n", None, True), ("damping", None, False), ("tau_z", None, False),
              ("pedal_scale_n", None, True), ("q_factor", None, True))


def _fit_problem(fit: BoosterFit) -> str | None:
    """What makes ``fit`` unusable (wrong counts, non-finite or impossible values)."""
    for key, count, positive in _FIT_SHAPE:
        value = getattr(fit, key)
        values = value if count is not None else (value,)
        if count is not None and len(values) != count:
            return f"'{key}' holds {len(values)} values, the model takes {count}"
        if not all(math.isfinite(v) for v in values):
            return f"'{key}' is not finite"
        if count is None and positive and not value > 0:
            return f"'{key}' = {value:g} is not > 0"
        if count is None and value < 0:
            return f"'{key}' = {value:g} is negative"
    if not fit.s2_max_mm > 0.0:  # inf (not recorded) is fine; nan, 0 and below are not
        return (f"'s2_max_mm' = {fit.s2_max_mm:g} is no screw travel (the training data's"
                " furthest, mm > 0; leave it out of an older fit)")
    if fit.pv_heldout_mpa and len(fit.pv_heldout_mpa) != len(candidate_names()):
        return (f"'pv_heldout_mpa' holds {len(fit.pv_heldout_mpa)} values, one per p-V"
                f" candidate ({', '.join(candidate_names())}) or none")
    knots, values = np.array(fit.pv_knots_mm), np.array(fit.pv_knot_mpa)
    if knots.size or values.size:
        if not (knots.size == values.size >= 2 and np.all(np.isfinite(knots))
                and np.all(np.isfinite(values)) and np.all(np.diff(knots) > 0.0)
                and np.all(np.diff(values) >= 0.0)):
            return ("'pv_knots_mm' and 'pv_knot_mpa' are no p-V curve (as many pressures as"
                    " travels, at least 2, travels increasing and pressures never falling)")
    p1, p2, *slopes = fit.disk  # eq. 14: breakpoints 0 <= p1 <= p2 (N), slopes >= 0 (mm/N)
    if not (0.0 <= p1 <= p2 and all(k >= 0.0 for k in slopes)):
        return (f"'disk' = {list(fit.disk)} is no reaction-disk curve (breakpoints"
                " 0 <= p1 <= p2 in N, then three slopes >= 0 in mm/N)")
    return None


@numba.njit(cache=True)
def _transition(
    X: Array, out: Array, pv0: float, pv1: float, s2: float, c: Array, disk: Array,
    Ad: Array, Bd: Array, n_pedal: int, chi: bool,
) -> None:  # pragma: no cover - compiled; equal to EboosterModel.f_reference (tested)
    decay, k_f, k_r, dt, f_scale, area, k_ret, ratio, a_w, f_mean = c
    p1, p2, p3, p4, p5 = disk
    off2 = (p3 - p4) * p1
    off3 = (p4 - p5) * p2 + off2
    for b in range(X.shape[0]):
        pm, pf, pr = X[b, 0], X[b, 1], X[b, 2]
        out[b, 0] = pv1 + (pm - pv0) * decay  # eq. 13 + relaxation
        for j, (p, k) in enumerate(((pf, k_f), (pr, k_r))):
            e = pm - p  # eq. 13, exact over the step (rigs.booster.orifice_step)
            root = max(np.sqrt(abs(e)) - 0.5 * k * dt, 0.0)
            out[b, 1 + j] = pm - np.sign(e) * root * root
        if chi:
            f_in = 0.0
            for i in range(n_pedal):
                w = X[b, 5 + i]
                f_in += w * w
                out[b, 5 + i] = a_w * w
            f_in *= f_scale
        else:
            f = X[b, 5]
            out[b, 5] = f_mean + a_w * (f - f_mean)
            f_in = max(f, 0.0)  # a driver only pushes
        force = f_in - ratio * (pm * area + k_ret * s2)  # eq. 10
        x = abs(force)
        u = min(p3 * x, p4 * x + off2, p5 * x + off3)  # eq. 14
        u = u if force >= 0.0 else -u
        z1, z2 = X[b, 3], X[b, 4]
        out[b, 3] = Ad[0, 0] * z1 + Ad[0, 1] * z2 + Bd[0] * u
        out[b, 4] = Ad[1, 0] * z1 + Ad[1, 1] * z2 + Bd[1] * u


class EboosterModel:
    """Batched transition of the booster observer over a session's input s2.

    Parameters
    ----------
    spec : BoosterSpec — bench datasheet and observer settings.
    fit : BoosterFit — identified p-V and disk.
    s2_mm : ndarray (K,) — mm, screw displacement per step.
    pv : ndarray (K,), optional — MPa, the static pressure per step; default the fit's
        p-V curve at s2 (a carried effect replaces it: ``ebooster --with-effect``).
    dt : float — s, step.
    """

    def __init__(self, spec: BoosterSpec, fit: BoosterFit, s2_mm: Array, dt: float,
                 pv: Array | None = None) -> None:
        self.spec, self.fit, self.dt = spec, fit, float(dt)
        self.s2 = np.ascontiguousarray(s2_mm, dtype=np.float64)
        self.K = self.s2.shape[0]
        self.chi = spec.pedal_state == "chi_square"
        self.N = spec.pedal_dof if self.chi else 1
        self.n = N_PHYS + self.N
        self.pv = (fit.pressure(self.s2) if pv is None
                   else np.ascontiguousarray(pv, dtype=np.float64))
        self.decay = float(np.exp(-self.dt / spec.pv_relax_s))
        self.k_port = tuple(
            orifice_coefficient(spec.stiffness_mpa_per_cm3[i], spec.discharge_coeff,
                                spec.orifice_area_mm2[i], spec.fluid_density)
            for i in range(2)
        )
        A, B = disk_transfer(fit.omega_n, fit.damping, fit.tau_z)
        self.Ad, self.Bd = discretise(A, B, self.dt)
        self.disk = np.array(fit.disk)
        # chi-square moments: mean N F_scale, variance 2 N F_scale^2; the square of an OU
        # process with correlation exp(-dt/tau) has correlation exp(-2 dt/tau)
        self.f_mean = fit.pedal_scale_n * spec.pedal_dof
        self.f_var = 2.0 * spec.pedal_dof * fit.pedal_scale_n**2
        tau = spec.pedal_tau_s if self.chi else 0.5 * spec.pedal_tau_s
        self.a_pedal = float(np.exp(-self.dt / tau))
        self._c = np.array([
            self.decay, self.k_port[0], self.k_port[1], self.dt, fit.pedal_scale_n,
            spec.area_mm2, spec.return_spring_n_per_mm, spec.area_ratio, self.a_pedal,
            self.f_mean,
        ])
        self.H = np.zeros((1, self.n))
        self.H[0, 3] = 1.0  # delta = zeta1

    def f(self, X: Array, k: int) -> Array:
        """Advance B states from step k to k + 1; X (B, n) -> (B, n) (compiled)."""
        out = np.empty_like(X)
        k1 = min(k + 1, self.K - 1)
        _transition(np.ascontiguousarray(X), out, self.pv[k], self.pv[k1], self.s2[k],
                    self._c, self.disk, self.Ad, self.Bd, self.N, self.chi)
        return out

    def f_reference(self, X: Array, k: int) -> Array:
        """:meth:`f` composed of the numpy physics of :mod:`brakethermo.rigs.booster`."""
        spec = self.spec
        pm, pf, pr = X[:, 0], X[:, 1], X[:, 2]
        out = np.empty_like(X)
        k1 = min(k + 1, self.K - 1)
        out[:, 0] = self.pv[k1] + (pm - self.pv[k]) * self.decay  # eq. 13 + relaxation
        out[:, 1] = orifice_step(pm, pf, self.k_port[0], self.dt)  # eq. 13
        out[:, 2] = orifice_step(pm, pr, self.k_port[1], self.dt)
        w = X[:, N_PHYS:]
        if self.chi:
            f_in = self.fit.pedal_scale_n * np.sum(w * w, axis=1)  # chi-square, N dof
            out[:, N_PHYS:] = w * self.a_pedal  # OU decay; Q refills the variance
        else:
            f_in = np.maximum(w[:, 0], 0.0)
            out[:, N_PHYS:] = self.f_mean + (w - self.f_mean) * self.a_pedal
        force = leverage_force(pm, self.s2[k], f_in, spec.area_mm2,
                               spec.return_spring_n_per_mm, spec.area_ratio)  # eq. 10
        u = disk_quasi_static(force, self.disk)  # eq. 14
        z = X[:, 3:5]
        out[:, 3:5] = z @ self.Ad.T + u[:, None] * self.Bd
        return out

    def Q(self) -> Array:
        """Process-noise covariance of a step with the screw at rest (n, n).

        The datasheet gives the physical states' noise per millisecond; a white-noise
        intensity scales with the step, so the bands do not depend on the log rate.
        """
        s = self.spec
        per_ms = self.dt / 1e-3
        # keeps each w_i at unit variance, or the force at the chi-square's variance
        q_w = (1.0 - self.a_pedal**2) * (1.0 if self.chi else self.f_var)
        physical = np.array([*s.q_pressure_mpa, *s.q_zeta]) * per_ms * self.fit.q_factor
        return np.diag(np.r_[physical, np.full(self.N, q_w)])

    def Q_of_step(self) -> Callable[[int], Array]:
        """Q(k): the rest value plus a p_m term proportional to the screw speed.

        The static p-V curve misses the flow-dependent pressure drops and the hysteresis
        of a moving piston, which grow with the displacement rate; the speed is that of
        the measured input s2 (a 20 ms moving average, which also removes the encoder's
        quantisation steps).
        """
        base = self.Q()
        speed = np.abs(smoothed_rate(self.s2, self.dt, SPEED_WINDOW_S))
        extra = (self.spec.q_pm_speed * (speed / V_REF_MM_S) * (self.dt / 1e-3)
                 * self.fit.q_factor)
        stack = base.copy()

        def Q(k: int) -> Array:
            stack[0, 0] = base[0, 0] + extra[k]
            return stack

        return Q

    def R(self) -> Array:
        """Measurement-noise covariance (1, 1), mm^2."""
        return np.array([[self.spec.delta_noise_mm**2]])

    def prior(self, delta0_mm: float) -> tuple[Array, Array]:
        """Prior mean and covariance at step 0, at rest on the p-V curve."""
        s = self.spec
        p0 = self.pv[0]
        d0 = float(delta0_mm) if np.isfinite(delta0_mm) else 0.0
        A, B = disk_transfer(self.fit.omega_n, self.fit.damping, self.fit.tau_z)
        zeta2 = -A[0, 0] * d0 - B[0] * d0  # rest: zeta2 = (a1 - b1) zeta1
        if self.chi:
            # w = 0 is a stationary point of w^2 where no filter can learn the force:
            # start on the positive branch (the sign of w is immaterial)
            w0, w_sd = np.ones(self.N), np.ones(self.N)
        else:
            w0, w_sd = np.array([self.f_mean]), np.array([np.sqrt(self.f_var)])
        x0 = np.r_[p0, p0, p0, d0, zeta2, w0]
        sd = np.r_[np.full(3, s.p0_pressure_mpa), s.p0_zeta, w_sd]
        return x0, np.diag(sd**2)
