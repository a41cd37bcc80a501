"""Tyre μ–slip rig simulator: a braked wheel on a constant-speed carriage, and its truth.

The truth tyre is a brush model (Pacejka, *Tyre and Vehicle Dynamics*, 3rd ed., §3.2:
parabolic contact pressure, pure longitudinal slip) whose friction falls with the
sliding speed (a Stribeck-like decay) and with the load. It shares no code and no curve
family with the estimator's fits (Rudd, Burckhardt, Magic Formula in ``rigs/tyre.py``):
its μ(s) depends on the carriage speed and the load, its peak comes from the brush
saturating while the friction decays. The force builds up over a relaxation length; the
wheel has inertia and is braked by a torque ramp until it locks; the normal load
oscillates; the drag and load cells, the speed sensors and the wheel encoder are noisy.
The session runs free rolling, then the ramp to lock, a short locked slide and the
release back to rolling.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
from scipy.optimize import brentq, minimize_scalar

from brakethermo.errors import ConfigError
from brakethermo.io.writers import Channel, SessionData
from brakethermo.sim.writer import write_session_and_truth


@dataclass(frozen=True)
class BrushTyre:
    """A brush-model tyre with sliding-speed and load dependent friction.

    Attributes
    ----------
    mu_static : float — friction coefficient at zero sliding speed and nominal load, –.
    mu_sliding : float — friction coefficient at high sliding speed, –.
    v_stribeck : float — sliding speed over which the friction decays, m/s.
    stiffness_per_load : float — longitudinal slip stiffness C_κ / F_z, –.
    load_sensitivity : float — relative fall of the friction per relative load rise, –.
    load_nominal : float — load at which ``mu_static`` holds, N.
    """

    mu_static: float
    mu_sliding: float
    v_stribeck: float
    stiffness_per_load: float
    load_sensitivity: float = 0.1
    load_nominal: float = 4000.0

    def mu(self, s: float, speed: float, load: float) -> float:
        """F_x / F_z at braking slip ``s`` (0 rolling, 1 locked), carriage ``speed`` (m/s)
        and normal ``load`` (N)."""
        s = min(max(s, 0.0), 1.0)
        mu_f = (self.mu_sliding + (self.mu_static - self.mu_sliding)
                * math.exp(-s * speed / self.v_stribeck))
        mu_f *= 1.0 - self.load_sensitivity * (load / self.load_nominal - 1.0)
        if s >= 1.0:
            return mu_f
        sigma = s / (1.0 - s)  # theoretical slip of the brush model
        x = min(self.stiffness_per_load * sigma / (3.0 * mu_f), 1.0)  # θ σ; 1: all sliding
        return mu_f * (3.0 * x - 3.0 * x * x + x ** 3)

    def peak(self, speed: float, load: float) -> tuple[float, float]:
        """The curve's peak (μ, slip) at ``speed`` (m/s) and ``load`` (N)."""
        res = minimize_scalar(lambda s: -self.mu(s, speed, load), bounds=(1e-4, 0.999),
                              method="bounded", options={"xatol": 1e-7})
        return -float(res.fun), float(res.x)


# Dry asphalt, a wet road, a low-friction surface: peaks near the reference figures of
# each (shared/reference/README.md) without being any of the estimator's curve families.
TYRE_PRESETS: dict[str, BrushTyre] = {
    "dry": BrushTyre(1.30, 0.90, 6.0, 20.0),
    "wet": BrushTyre(0.85, 0.55, 4.0, 16.0),
    "low-mu": BrushTyre(0.40, 0.28, 3.0, 10.0),
}
TYRES = tuple(TYRE_PRESETS)


def tyre_curve(tyre: str, speed: float = 20.0, load: float = 4000.0
               ) -> tuple[Callable[[float, float], float], tuple[float, float]]:
    """μ(s, F_z) of a named truth tyre at carriage ``speed`` (m/s), and its peak (μ, slip)
    at that speed and the ``load`` (N)."""
    if tyre not in TYRE_PRESETS:
        raise ConfigError(f"unknown tyre '{tyre}'; use one of {', '.join(TYRES)}")
    model = TYRE_PRESETS[tyre]
    return (lambda s, fz: model.mu(s, speed, fz)), model.peak(speed, load)


@dataclass(frozen=True)
class TyreRig:
    """Rig and sensor parameters.

    Attributes
    ----------
    rate_hz : float — logging rate, Hz.
    substeps : int — integration steps per logged sample.
    speed : float — carriage speed, m/s.
    radius : float — wheel rolling radius, m.
    inertia : float — wheel and brake inertia, kg m².
    load : float — mean normal force, N.
    load_ripple, load_freq_hz : float — relative normal-load oscillation, –, and its frequency.
    relaxation_m : float — longitudinal relaxation length, m.
    rolling_resistance : float — rolling-resistance coefficient, –.
    free_s, hold_s, tail_s : float — free rolling before, locked slide, rolling after, s.
    torque_rate : float — brake-torque ramp rate, N m/s.
    drag_noise, load_noise : float — force-cell noise std, N.
    speed_noise : float — carriage speed noise std, m/s.
    wheel_noise : float — wheel speed noise std, rad/s.
    """

    rate_hz: float = 1000.0
    substeps: int = 10
    speed: float = 20.0
    radius: float = 0.30
    inertia: float = 1.2
    load: float = 4000.0
    load_ripple: float = 0.02
    load_freq_hz: float = 3.0
    relaxation_m: float = 0.15
    rolling_resistance: float = 0.012
    free_s: float = 2.0
    hold_s: float = 0.5
    tail_s: float = 2.0
    torque_rate: float = 700.0
    drag_noise: float = 120.0
    load_noise: float = 20.0
    speed_noise: float = 0.02
    wheel_noise: float = 0.05


@dataclass(frozen=True)
class TyreSimResult:
    """A simulated session, its truth table and the true peak (μ, slip) of the tyre."""

    session: SessionData
    truth: pa.Table
    peak: tuple[float, float]


def _ramp_to_lock(
    rig: TyreRig, mu_of: Callable[[float, float], float], omega0: float, phase: float
) -> np.ndarray:
    """The braking ramp, the locked slide and the spin-up back to free rolling, integrated.

    Parameters
    ----------
    rig : TyreRig
    mu_of : callable — μ(s, F_z) of the truth tyre at the carriage speed (F_z in N).
    omega0 : float — free-rolling wheel speed, rad/s.
    phase : float — phase of the normal-load oscillation, rad.

    Returns
    -------
    ndarray, shape (n, 4) — per logged sample from ``rig.free_s``: time (s), wheel speed
        (rad/s), drag force and normal force (N).
    """
    dt = 1.0 / rig.rate_hz
    h = dt / rig.substeps
    V, R, J = rig.speed, rig.radius, rig.inertia
    w, Fx, Tb = omega0, rig.rolling_resistance * rig.load, 0.0
    t_lock: float | None = None
    rows: list[tuple[float, float, float, float]] = []
    t = rig.free_s
    k = 0
    released = False
    while True:
        Fz = rig.load * (
            1.0 + rig.load_ripple * math.sin(2 * math.pi * rig.load_freq_hz * t + phase)
        )
        for _ in range(rig.substeps):
            s = min((V - w * R) / V, 1.0)
            mu = mu_of(abs(s), Fz) * math.copysign(1.0, s)  # driving slip: odd extension
            Fx += (mu * Fz - Fx) * V / rig.relaxation_m * h  # builds over the relaxation length
            Tb = 0.0 if released else Tb + rig.torque_rate * h
            # rolling resistance is a moment at the axle; the brake cannot turn the wheel back
            resist = Tb + R * rig.rolling_resistance * Fz
            if w <= 0.0:
                resist = min(resist, R * Fx)
            w = max(w + (R * Fx - resist) * h / J, 0.0)
        rows.append((t, w, Fx, Fz))
        k += 1
        t += dt
        if t_lock is None and w <= 1e-9:
            t_lock = t
        if t_lock is not None and not released and t >= t_lock + rig.hold_s:
            released = True
        if released and abs(w - omega0) < 1e-3 * omega0:
            break
        if k > 60 * rig.rate_hz:
            raise ConfigError("the brake ramp never locked the wheel; raise torque_rate")
    return np.array(rows)


def _whole_session(
    rig: TyreRig, core: np.ndarray, omega0: float, phase: float, duration_s: float | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The integrated ``core`` (:func:`_ramp_to_lock`) framed by steady free rolling.

    Parameters
    ----------
    rig : TyreRig
    core : ndarray, shape (n, 4) — from :func:`_ramp_to_lock`.
    omega0 : float — free-rolling wheel speed, rad/s.
    phase : float — phase of the normal-load oscillation, rad.
    duration_s : float, optional — pad the tail with free rolling to this length, s.

    Returns
    -------
    time (s), wheel speed (rad/s), drag force and normal force (N), per logged sample.
    """
    n_free = round(rig.free_s * rig.rate_hz)
    n_tail = round(rig.tail_s * rig.rate_hz)
    if duration_s is not None:
        n_tail = max(n_tail, round(duration_s * rig.rate_hz) - n_free - core.shape[0])
    n = n_free + core.shape[0] + n_tail
    dt = 1.0 / rig.rate_hz
    time = np.arange(n) * dt
    omega = np.full(n, omega0)
    Fz_t = rig.load * (1.0 + rig.load_ripple * np.sin(2 * np.pi * rig.load_freq_hz * time + phase))
    Fx_t = rig.rolling_resistance * Fz_t
    sl = slice(n_free, n_free + core.shape[0])
    omega[sl], Fx_t[sl], Fz_t[sl] = core[:, 1], core[:, 2], core[:, 3]
    return time, omega, Fx_t, Fz_t


def _rig_channels(
    rig: TyreRig, time: np.ndarray, omega: np.ndarray, Fx_t: np.ndarray, Fz_t: np.ndarray,
    rng: np.random.Generator,
) -> list[Channel]:
    """What the rig's sensors log: carriage and wheel speed (m/s, rad/s), drag and normal
    force (N), each with its noise (drawn in this order)."""
    n = time.size
    v_meas = rig.speed + rng.normal(0.0, rig.speed_noise, n)
    w_meas = omega + rng.normal(0.0, rig.wheel_noise, n)
    return [
        Channel("vehicle_speed", "m/s", time, v_meas, decimals=4),
        Channel("wheel_speed", "rad/s", time, w_meas, decimals=4),
        Channel("drag_force", "N", time, Fx_t + rng.normal(0.0, rig.drag_noise, n), decimals=2),
        Channel("normal_force", "N", time, Fz_t + rng.normal(0.0, rig.load_noise, n), decimals=2),
    ]


def _braking(tyre: str, seed: int, rig: TyreRig) -> tuple[
        tuple[float, float], np.random.Generator, float, float, np.ndarray]:
    """The truth tyre's peak (μ, slip), the session's generator (its phase drawn), the
    free-rolling wheel speed (rad/s), the load's phase (rad) and the integrated ramp to
    lock, release and spin-up (:func:`_ramp_to_lock`)."""
    mu_of, peak = tyre_curve(tyre, rig.speed, rig.load)
    rng = np.random.default_rng(seed)
    # free rolling: the slip at which the tyre force balances the rolling resistance
    s_free = brentq(lambda x: mu_of(x, rig.load) - rig.rolling_resistance, 0.0,
                    peak[1])
    omega0 = rig.speed * (1.0 - s_free) / rig.radius
    phase = rng.uniform(0.0, 2.0 * math.pi)
    # ramp, slide and spin-up integrated; free rolling before and after is steady
    return peak, rng, omega0, phase, _ramp_to_lock(rig, mu_of, omega0, phase)


def least_duration_s(tyre: str, seed: int = 0, rig: TyreRig | None = None) -> float:
    """The shortest session the ramp needs, s: free rolling, the ramp to lock, the
    locked slide, the spin-up and the tail (the length written without ``duration_s``).

    Parameters
    ----------
    tyre : str — a truth tyre (:data:`TYRES`).
    seed : int — random seed (the load's phase moves the lock by a few ms).
    rig : TyreRig, optional
    """
    rig = rig or TyreRig()
    core = _braking(tyre, seed, rig)[4]
    n = round(rig.free_s * rig.rate_hz) + core.shape[0] + round(rig.tail_s * rig.rate_hz)
    return (n - 1) / rig.rate_hz


def simulate_tyre_rig(
    tyre: str = "dry",
    *,
    seed: int = 0,
    rig: TyreRig | None = None,
    duration_s: float | None = None,
    log_slip: bool = False,
) -> TyreSimResult:
    """Simulate a braking ramp to wheel lock on a μ–slip rig.

    Parameters
    ----------
    tyre : str — a truth tyre: ``dry``, ``wet`` or ``low-mu`` (brush models).
    seed : int — random seed.
    rig : TyreRig, optional
    duration_s : float, optional — pad the session with free rolling to this length, s.
    log_slip : bool — also log the rig's own ``slip_ratio`` channel.
    """
    rig = rig or TyreRig()
    peak, rng, omega0, phase, core = _braking(tyre, seed, rig)
    V, R = rig.speed, rig.radius
    time, omega, Fx_t, Fz_t = _whole_session(rig, core, omega0, phase, duration_s)
    slip = np.clip((V - omega * R) / V, 0.0, 1.0)

    channels = _rig_channels(rig, time, omega, Fx_t, Fz_t, rng)
    if log_slip:
        channels.append(Channel("slip_ratio", "-", time, slip, decimals=6))
    facts = {
        "rig": "tyre",
        "tyre": tyre,
        "seed": str(seed),
        "wheel_radius_m": f"{R:g}",
        "date": "2026-01-01",
    }
    truth = pa.table(
        {"time": time, "slip": slip, "mu": Fx_t / Fz_t, "omega": omega},
        metadata={"peak_mu": f"{peak[0]:.6f}", "peak_slip": f"{peak[1]:.6f}", "tyre": tyre},
    )
    return TyreSimResult(SessionData(tuple(channels), facts), truth, peak)


@dataclass(frozen=True)
class TyreRigSimConfig:
    """What ``simulate --rig tyre`` simulates (its fields are the ``--set`` keys).

    Attributes
    ----------
    tyre : str — the truth tyre, a brush model: ``dry`` (asphalt), ``wet`` or ``low-mu``.
    duration_s : float or None — pad the session with free rolling to this length, s
        (default: free rolling, ramp to lock, release and a short tail); shorter than
        that (:func:`least_duration_s`) is refused.
    log_slip : bool — also log the rig's own ``slip_ratio`` channel.
    seed : int
    """

    tyre: str = "dry"
    duration_s: float | None = None
    log_slip: bool = False
    seed: int = 0

    def __post_init__(self) -> None:
        if self.tyre not in TYRES:
            raise ConfigError(f"tyre simulation: tyre={self.tyre!r}; use one of {', '.join(TYRES)}")
        if self.duration_s is not None and not 0.0 < self.duration_s <= 3600.0:
            raise ConfigError(
                f"tyre simulation: duration_s={self.duration_s!r} out of range (0 to 3600 s)"
            )
        # the ramp to lock cannot be cut short: a shorter duration was written at the
        # ramp's own length while the summary echoed the value asked
        if self.duration_s is not None:
            least = least_duration_s(self.tyre, self.seed)
            if self.duration_s < least:
                raise ConfigError(
                    f"tyre simulation: duration_s={self.duration_s:g} s is shorter than the"
                    f" session needs: free rolling, the ramp to lock, the release and the"
                    f" tail take {least:.3f} s ({self.tyre} tyre, seed {self.seed}); give"
                    f" duration_s of at least {math.ceil(least * 10) / 10:g} or leave it out"
                )


def simulate_tyre_config(cfg: TyreRigSimConfig) -> TyreSimResult:
    """:func:`simulate_tyre_rig` for a :class:`TyreRigSimConfig`."""
    return simulate_tyre_rig(
        cfg.tyre, seed=cfg.seed, duration_s=cfg.duration_s, log_slip=cfg.log_slip
    )


def write_tyre_simulation(
    result: TyreSimResult, out: str | Path, fmt: str | None = None
) -> tuple[Path, Path]:
    """Write the session through the session writers and ``<stem>.truth.parquet`` beside it."""
    return write_session_and_truth(out, result.session, result.truth, fmt)
