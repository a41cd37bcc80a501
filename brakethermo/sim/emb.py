"""Electro-mechanical caliper rig simulator: sessions for ``clamp-force``, and their truth.

Richer than the estimator's models (:mod:`brakethermo.rigs.emb`) on purpose, so the tests
measure what a real caliper would do to them:

- motion: the position loop tracks a motor-angle reference drawn uniformly at random
  every 100 ms (the paper's "uniform random data"), as a damped second-order response;
- caliper: a cubic static stiffness after the contact point, two viscoelastic
  (Maxwell) branches, rate-dependent hysteresis, pad stiffness falling with pad
  temperature, pad wear (later contact, stiffer thinner pads);
- drive: load-dependent Coulomb plus Stribeck gear friction, viscous friction, cogging
  torque ripple, rotor inertia;
- sensors: resolver quantisation, q-current noise, quantisation and offset, clamp-force
  sensor lag, noise and quantisation.

Scenarios: ``nominal`` (new pads, 40 °C), ``worn`` (worn pads and gearing) and
``heating`` (pads heating from 40 to 390 °C over the session).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pyarrow as pa
from scipy.signal import cont2discrete, lfilter

from brakethermo.errors import ConfigError
from brakethermo.io.writers import Channel, SessionData
from brakethermo.sim.writer import write_session_and_truth

SCENARIOS = ("nominal", "worn", "heating")


@dataclass(frozen=True)
class EmbCaliper:
    """Truth parameters of the simulated caliper and rig.

    Attributes
    ----------
    rate_hz : float — logging rate, Hz.
    ref_period_s : float — hold time of each random angle reference, s.
    theta_min, theta_max : float — range of the angle reference, rad.
    omega_n : float — position-loop natural frequency, rad/s.
    zeta : float — position-loop damping ratio, –.
    k1, k3 : float — static stiffness F = k1 x + k3 x³ at compression x = θ − θc, N/rad, N/rad³.
    theta_contact : float — motor angle at pad contact, rad.
    visco : tuple of (float, float) — Maxwell branches (gain –, time constant s).
    hysteresis : float — relative force drop when applying (rise when releasing), –.
    omega_h : float — angular speed of full hysteresis, rad/s.
    pad_temp_coeff : float — relative stiffness loss per kelvin above 40 °C, 1/K.
    pad_temp_start_c, pad_temp_end_c, pad_heat_tau_s : float — pad temperature ramp.
    stiffness_scale : float — pad stiffness factor (worn pads are thinner, stiffer), –.
    km : float — motor torque constant, N m/A.
    gamma : float — application torque per clamp force (gear and screw), N m/N.
    inertia : float — lumped inertia at the motor, kg m².
    coulomb_load : float — load-proportional gear friction, N m/N.
    coulomb_offset : float — load-independent Coulomb friction, N m.
    stribeck_extra : float — extra breakaway friction at standstill, N m.
    omega_stribeck : float — Stribeck speed, rad/s.
    viscous : float — viscous friction, N m s/rad.
    ripple : float — cogging torque amplitude, N m.
    ripple_order : int — ripple periods per motor revolution.
    current_offset : float — q-current sensor offset, A.
    current_noise, current_lsb : float — current noise std and resolution, A.
    resolver_counts : int — resolver counts per revolution.
    force_lag_s : float — clamp-force sensor time constant, s.
    force_noise, force_lsb : float — clamp-force sensor noise std and resolution, N.
    """

    rate_hz: float = 1000.0
    ref_period_s: float = 0.1
    theta_min: float = 1.0
    theta_max: float = 8.0
    omega_n: float = 45.0
    zeta: float = 0.9
    k1: float = 1500.0
    k3: float = 35.0
    theta_contact: float = 0.0
    visco: tuple[tuple[float, float], ...] = ((0.12, 0.05), (0.05, 0.8))
    hysteresis: float = 0.03
    omega_h: float = 2.0
    pad_temp_coeff: float = 8.0e-4
    pad_temp_start_c: float = 40.0
    pad_temp_end_c: float = 40.0
    pad_heat_tau_s: float = 40.0
    stiffness_scale: float = 1.0
    km: float = 0.05
    gamma: float = 8.0e-5
    inertia: float = 3.0e-5
    coulomb_load: float = 1.2e-5
    coulomb_offset: float = 0.05
    stribeck_extra: float = 0.04
    omega_stribeck: float = 1.5
    viscous: float = 2.0e-4
    ripple: float = 0.02
    ripple_order: int = 12
    current_offset: float = 0.4
    current_noise: float = 0.3
    current_lsb: float = 0.05
    resolver_counts: int = 8192
    force_lag_s: float = 0.001
    force_noise: float = 30.0
    force_lsb: float = 10.0


def scenario(name: str, base: EmbCaliper | None = None) -> EmbCaliper:
    """The caliper of a named scenario (``nominal``, ``worn``, ``heating``)."""
    base = base or EmbCaliper()
    if name == "nominal":
        return base
    if name == "worn":
        # thinner pads: contact 1.2 rad later and 12 % stiffer; worn gearing rubs more
        return replace(
            base,
            theta_contact=base.theta_contact + 1.2,
            theta_min=base.theta_min + 1.2,
            theta_max=base.theta_max + 1.2,
            stiffness_scale=1.12 * base.stiffness_scale,
            coulomb_load=1.3 * base.coulomb_load,
            coulomb_offset=1.3 * base.coulomb_offset,
        )
    if name == "heating":
        return replace(base, pad_temp_end_c=390.0)
    raise ConfigError(f"unknown EMB scenario '{name}'; use one of {', '.join(SCENARIOS)}")


@dataclass(frozen=True)
class EmbSimResult:
    """A simulated caliper session and its truth table (``time``, ``clamp_force`` kN, ...)."""

    session: SessionData
    truth: pa.Table


def _reference(n: int, dt: float, cal: EmbCaliper, rng: np.random.Generator) -> np.ndarray:
    hold = max(1, round(cal.ref_period_s / dt))
    levels = rng.uniform(cal.theta_min, cal.theta_max, size=n // hold + 2)
    ref = np.repeat(levels, hold)[:n]
    ref[:hold] = 0.5 * (cal.theta_min + cal.theta_max)
    return ref


def _position_loop(ref: np.ndarray, dt: float, cal: EmbCaliper) -> tuple[np.ndarray, ...]:
    """Exact zero-order-hold response of θ'' = ωn² (r − θ) − 2 ζ ωn θ' to the reference."""
    wn, z = cal.omega_n, cal.zeta
    A = np.array([[0.0, 1.0], [-wn * wn, -2.0 * z * wn]])
    B = np.array([[0.0], [wn * wn]])
    C = np.eye(2)
    D = np.zeros((2, 1))
    Ad, Bd, _, _, _ = cont2discrete((A, B, C, D), dt, method="zoh")
    n = ref.size
    x = np.empty((n, 2))
    state = np.array([ref[0], 0.0])
    for k in range(n):
        x[k] = state
        state = Ad @ state + Bd[:, 0] * ref[k]
    theta, omega = x[:, 0], x[:, 1]
    acc = wn * wn * (ref - theta) - 2.0 * z * wn * omega
    return theta, omega, acc


def _maxwell(F_s: np.ndarray, gain: float, tau: float, dt: float) -> np.ndarray:
    """Branch force with dFv/dt = −Fv/τ + g dFs/dt, exact for a ramp of Fs over each step."""
    a = np.exp(-dt / tau)
    dF = np.diff(F_s, prepend=F_s[0])
    return lfilter([gain * tau / dt * (1.0 - a)], [1.0, -a], dF)


def simulate_emb(
    name: str = "nominal",
    *,
    duration_s: float = 60.0,
    seed: int = 0,
    with_sensor: bool = True,
    caliper: EmbCaliper | None = None,
) -> EmbSimResult:
    """Simulate one caliper session.

    Parameters
    ----------
    name : str — scenario: ``nominal``, ``worn`` or ``heating``.
    duration_s : float — session length, s.
    seed : int — random seed; same seed, same session.
    with_sensor : bool — log the clamp-force sensor channel.
    caliper : EmbCaliper, optional — base parameters the scenario modifies.
    """
    if duration_s <= 0:
        raise ConfigError(f"duration must be positive, got {duration_s} s")
    cal = scenario(name, caliper)
    rng = np.random.default_rng(seed)
    dt = 1.0 / cal.rate_hz
    n = round(duration_s * cal.rate_hz)
    t = np.arange(n) * dt

    theta, omega, acc = _position_loop(_reference(n, dt, cal, rng), dt, cal)
    pad_temp = cal.pad_temp_end_c + (cal.pad_temp_start_c - cal.pad_temp_end_c) * np.exp(
        -t / cal.pad_heat_tau_s
    )
    soft = cal.stiffness_scale * (1.0 - cal.pad_temp_coeff * (pad_temp - 40.0))
    x = np.maximum(theta - cal.theta_contact, 0.0)
    F_s = soft * (cal.k1 * x + cal.k3 * x**3)
    F = F_s + sum(_maxwell(F_s, g, tau, dt) for g, tau in cal.visco)
    F = np.maximum(F * (1.0 - cal.hysteresis * np.tanh(omega / cal.omega_h)), 0.0)

    sgn = np.tanh(omega / 0.05)
    T_f = (
        (cal.coulomb_offset + cal.coulomb_load * F) * sgn
        + cal.stribeck_extra * np.exp(-((omega / cal.omega_stribeck) ** 2)) * sgn
        + cal.viscous * omega
    )
    T_ripple = cal.ripple * np.sin(cal.ripple_order * theta)
    T_m = cal.gamma * F + cal.inertia * acc + T_f + T_ripple
    current = T_m / cal.km + cal.current_offset + rng.normal(0.0, cal.current_noise, n)
    current = np.round(current / cal.current_lsb) * cal.current_lsb
    lsb = 2.0 * np.pi / cal.resolver_counts
    theta_meas = np.round(theta / lsb) * lsb

    channels = [
        Channel("motor_angle", "rad", t, theta_meas, decimals=6),
        Channel("motor_current", "A", t, current, decimals=3),
    ]
    if with_sensor:
        a = np.exp(-dt / cal.force_lag_s) if cal.force_lag_s > 0.0 else 0.0
        lagged = lfilter([1.0 - a], [1.0, -a], F, zi=[a * F[0]])[0]
        meas = lagged + rng.normal(0.0, cal.force_noise, n)
        meas = np.round(meas / cal.force_lsb) * cal.force_lsb
        channels.append(Channel("clamp_force", "kN", t, meas / 1e3, decimals=3))
    facts = {"rig": "emb", "scenario": name, "seed": str(seed), "date": "2026-01-01"}
    truth = pa.table(
        {
            "time": t,
            "clamp_force": F / 1e3,
            "motor_angle": theta,
            "pad_temp": pad_temp,
        }
    )
    return EmbSimResult(SessionData(tuple(channels), facts), truth)


@dataclass(frozen=True)
class EmbSimConfig:
    """What ``simulate --rig emb`` simulates (its fields are the ``--set`` keys).

    Attributes
    ----------
    scenario : str — ``nominal`` (new pads), ``worn`` (worn pads and gearing) or
        ``heating`` (pads heating from 40 to 390 °C).
    duration_s : float — session length, s.
    sensor : bool — log the clamp-force sensor channel (needed for ``--train`` sessions).
    force_lag_s : float — s, time constant of the clamp-force sensor (a load cell behind
        an amplifier filter; 0: an ideal sensor).
    seed : int
    """

    scenario: str = "nominal"
    duration_s: float = 60.0
    sensor: bool = True
    force_lag_s: float = EmbCaliper.force_lag_s
    seed: int = 0

    def __post_init__(self) -> None:
        if self.scenario not in SCENARIOS:
            raise ConfigError(
                f"emb simulation: scenario={self.scenario!r}; use one of {', '.join(SCENARIOS)}"
            )
        if not 0.1 <= self.duration_s <= 3600.0:
            raise ConfigError(
                f"emb simulation: duration_s={self.duration_s!r} out of range (0.1 to 3600 s)"
            )
        if not 0.0 <= self.force_lag_s <= 0.1:
            raise ConfigError(
                f"emb simulation: force_lag_s={self.force_lag_s!r} out of range (0 to 0.1 s)"
            )


def simulate_emb_config(cfg: EmbSimConfig) -> EmbSimResult:
    """:func:`simulate_emb` for a :class:`EmbSimConfig`."""
    return simulate_emb(
        cfg.scenario, duration_s=cfg.duration_s, seed=cfg.seed, with_sensor=cfg.sensor,
        caliper=EmbCaliper(force_lag_s=cfg.force_lag_s),
    )


def write_emb_simulation(
    result: EmbSimResult, out: str | Path, fmt: str | None = None
) -> tuple[Path, Path]:
    """Write the session through the session writers and ``<stem>.truth.parquet`` beside it."""
    return write_session_and_truth(out, result.session, result.truth, fmt)
