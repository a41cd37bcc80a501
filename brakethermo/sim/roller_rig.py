"""A roller-rig session simulator, deliberately richer than the estimator's model.

What the estimator (:mod:`brakethermo.models.roller_rig`) does not know about, and this
simulator has:

- the contact: its own Hertz ellipse (Carlson's integrals, not the estimator's ratio
  of complete elliptic integrals) and Haines-Ollerton strip theory with Carter's exact
  2-D solution in every strip, the spin entering as a creepage varying across the
  strips -- not the estimator's Kalker/FASTSIM family, whose small-creep slope it
  undercuts by some 15 %, as measured creep curves do; friction falling with the slip
  velocity by a law with other parameters than the datasheet's;
- an out-of-round roller (its radius varies once per revolution) and an eccentric
  roller encoder: periodic noise at the roller's rotation frequency, as the paper saw;
- incremental encoders (16384 counts per revolution after X4) read every sample, the
  speed being the difference of counts over the sample interval: quantisation and
  the noise of differentiating angle;
- the PMSM torque delivered is not the logged request: a dead time, a first-order lag
  and a gain error;
- the induction motor's torque lags its steady-state value (rotor flux) and its rotor
  resistance is warmer than the datasheet's;
- bearing losses and inertias off the datasheet's values; a normal load that wanders
  (air spring) and a noisy load transmitter.

The truth is integrated by RK4 at 0.2 ms (not the estimator's 0.25 ms) in compiled
code; the session is written with the real writers of :mod:`brakethermo.io.writers`.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
from numba import njit

from brakethermo.errors import ConfigError
from brakethermo.io.writers import Channel, SessionData
from brakethermo.sim.roller_contact import Machine, contact_strips, load_machine, strip_force
from brakethermo.sim.writer import write_session_and_truth

ENCODER_COUNTS = 16384  # per revolution, 4096 PPR in X4 evaluation (paper)
SIM_STEP = 2.0e-4  # s, the truth's RK4 step
WARMUP_S = 3.0  # s of free rolling integrated before the log starts


@dataclass(frozen=True)
class RollerRigSimConfig:
    """What to simulate.

    Attributes
    ----------
    speed_kmh : float — nominal speed; the roller motor's supply is 7.5 Hz per 15 km/h
        (paper).
    duration_s : float — logged length, s.
    rate_hz : float — logging rate, Hz.
    radius_m : float — true wheel rolling radius, m (a re-profiled wheel: not nominal).
    torque_max : float or None — peak torque request, N m (default: the paper's 500 N m
        at 15 km/h, 852 N m above).
    free_s : float — free rolling at the start and at the end, s.
    reference : bool — log ``rolling_radius_ref`` (one sample, mm).
    traction : bool — False: the PMSM never pulls (a session without traction).
    seed : int
    rig : str — datasheet of the nominal machine.
    """

    speed_kmh: float = 15.0
    duration_s: float = 260.0
    rate_hz: float = 200.0
    radius_m: float = 0.3482
    torque_max: float | None = None
    free_s: float = 30.0
    reference: bool = True
    traction: bool = True
    seed: int = 0
    rig: str = "roller-rig"

    def __post_init__(self) -> None:
        # checked when the settings are made, as the other rigs' configs are: a value
        # given by `simulate --set` is then a usage error (exit 2), not one found while
        # simulating (it exited 1 with speed_kmh=500)
        self.validated()

    def validated(self) -> RollerRigSimConfig:
        """Self, after range checks (ConfigError naming the field)."""
        checks = {
            "speed_kmh": (1.0 <= self.speed_kmh <= 80.0, "1 to 80 km/h"),
            "duration_s": (5.0 <= self.duration_s <= 3600.0, "5 to 3600 s"),
            "rate_hz": (20.0 <= self.rate_hz <= 5000.0, "20 to 5000 Hz"),
            "radius_m": (0.2 <= self.radius_m <= 0.5, "0.2 to 0.5 m"),
            "free_s": (0.0 <= 2.0 * self.free_s < self.duration_s,
                       f"0 to under half of duration_s={self.duration_s:g} s: the free"
                       " rolling at the start and at the end leave time for traction;"
                       " lower free_s or raise duration_s"),
        }
        for key, (ok, allowed) in checks.items():
            if not ok:
                raise ConfigError(
                    f"roller-rig simulation: {key}={getattr(self, key)!r} out of range"
                    f" ({allowed})"
                )
        if self.torque_max is not None and not 0.0 < self.torque_max <= 2000.0:
            raise ConfigError(
                f"roller-rig simulation: torque_max={self.torque_max!r} out of range (0, 2000] N m"
            )
        return self

    @property
    def supply_hz(self) -> float:
        """Roller-motor supply frequency, Hz (7.5 Hz at 15 km/h, paper)."""
        return 7.5 * self.speed_kmh / 15.0

    @property
    def peak_torque(self) -> float:
        """Peak torque request, N m."""
        if self.torque_max is not None:
            return self.torque_max
        return 500.0 if self.speed_kmh <= 20.0 else 852.0


@dataclass(frozen=True)
class RollerRigSimResult:
    """A simulated session and its truth."""

    session: SessionData
    truth: pa.Table
    config: RollerRigSimConfig


def torque_request(cfg: RollerRigSimConfig, t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Traction request profile: free rolling, then ramps and plateaus, free rolling, N m."""
    T = np.zeros_like(t)
    if not cfg.traction:
        return T
    t0, t1 = cfg.free_s, cfg.duration_s - cfg.free_s
    n_blocks = max(1, int((t1 - t0) // 40.0))
    edges = np.linspace(t0, t1, n_blocks + 1)
    for lo, hi in itertools.pairwise(edges):
        span = hi - lo
        level = cfg.peak_torque * rng.uniform(0.45, 1.0)
        ramp = rng.uniform(0.12, 0.25) * span
        hold = rng.uniform(0.3, 0.45) * span
        knots_t = [lo, lo + ramp, lo + ramp + hold, lo + 2 * ramp + hold, hi]
        knots_v = [0.0, level, level, 0.0, 0.0]
        T = np.maximum(T, np.interp(t, knots_t, knots_v, left=0.0, right=0.0))
    T[t >= t1] = 0.0
    return T


def _ou(rng: np.random.Generator, n: int, dt: float, tau: float, sigma: float) -> np.ndarray:
    """Ornstein-Uhlenbeck path with correlation time tau and stationary std sigma."""
    phi = math.exp(-dt / tau)
    e = rng.normal(0.0, sigma * math.sqrt(1.0 - phi * phi), n)
    x = np.empty(n)
    x[0] = rng.normal(0.0, sigma)
    for i in range(1, n):
        x[i] = phi * x[i - 1] + e[i]
    return x


# Layout of the truth parameter vector.
(P_JW, P_JR, P_RW, P_RR, P_ECC, P_NREF, P_PHI, P_MU0, P_FA, P_FB, P_GAIN, P_TAUP, P_MV, P_MRTH,
 P_MX, P_MR2, P_MF, P_MP, P_TAUM, P_FSYN, P_BW0, P_BW1, P_BR0, P_BR1) = range(24)  # fmt: skip


@njit(cache=True, nogil=True)
def _truth_rhs(th_r, w_w, w_r, t_del, t_a, tq, N, p, strips):  # pragma: no cover - compiled
    r_r = p[P_RR] * (1.0 + p[P_ECC] * math.cos(th_r))  # out-of-round roller
    v_w = w_w * p[P_RW]
    v_r = w_r * r_r
    V = max(0.5 * (abs(v_w) + abs(v_r)), 0.05)
    mu = p[P_MU0] * ((1.0 - p[P_FA]) * math.exp(-p[P_FB] * abs(v_w - v_r)) + p[P_FA])
    xi = (v_w - v_r) / V
    F = strip_force(xi, mu, N, p[P_NREF], p[P_PHI], strips)
    ratio = p[P_FSYN] / p[P_MF]
    w_syn = 2.0 * math.pi * p[P_FSYN] / p[P_MP]
    slip = (w_syn - w_r) / w_syn
    v = p[P_MV] * ratio
    x = p[P_MX] * ratio
    t_static = (
        3.0
        * v
        * v
        * p[P_MR2]
        * slip
        / (w_syn * ((p[P_MRTH] * slip + p[P_MR2]) ** 2 + (x * slip) ** 2))
    )
    t_bw = p[P_BW0] * math.tanh(w_w / 0.01) + p[P_BW1] * w_w
    t_br = p[P_BR0] * math.tanh(w_r / 0.01) + p[P_BR1] * w_r
    return (
        w_w,
        w_r,
        (t_del - F * p[P_RW] - t_bw) / p[P_JW],
        (F * r_r + t_a - t_br) / p[P_JR],
        (p[P_GAIN] * tq - t_del) / p[P_TAUP],
        (t_static - t_a) / p[P_TAUM],
        F,
        xi,
    )


@njit(cache=True, nogil=True)
def _integrate(y0, tq, nf, dt, n_sub, p, strips, out, force, creep):  # pragma: no cover
    """RK4 of the truth over len(tq) - 1 samples; inputs linear inside an interval."""
    h = dt / n_sub
    y = y0.copy()
    k1 = np.empty(6)
    k2 = np.empty(6)
    k3 = np.empty(6)
    k4 = np.empty(6)
    z = np.empty(6)
    for k in range(tq.shape[0]):
        r = _truth_rhs(y[1], y[2], y[3], y[4], y[5], tq[k], nf[k], p, strips)
        out[k] = y
        force[k] = r[6]
        creep[k] = r[7]
        if k == tq.shape[0] - 1:
            break
        for j in range(n_sub):
            ca, cm, cb = j / n_sub, (j + 0.5) / n_sub, (j + 1.0) / n_sub
            dq, dn = tq[k + 1] - tq[k], nf[k + 1] - nf[k]
            r = _truth_rhs(
                y[1], y[2], y[3], y[4], y[5], tq[k] + dq * ca, nf[k] + dn * ca, p, strips
            )
            for i in range(6):
                k1[i] = r[i]
                z[i] = y[i] + 0.5 * h * r[i]
            r = _truth_rhs(
                z[1], z[2], z[3], z[4], z[5], tq[k] + dq * cm, nf[k] + dn * cm, p, strips
            )
            for i in range(6):
                k2[i] = r[i]
                z[i] = y[i] + 0.5 * h * r[i]
            r = _truth_rhs(
                z[1], z[2], z[3], z[4], z[5], tq[k] + dq * cm, nf[k] + dn * cm, p, strips
            )
            for i in range(6):
                k3[i] = r[i]
                z[i] = y[i] + h * r[i]
            r = _truth_rhs(
                z[1], z[2], z[3], z[4], z[5], tq[k] + dq * cb, nf[k] + dn * cb, p, strips
            )
            for i in range(6):
                k4[i] = r[i]
                y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


def _truth_params(
    machine: Machine, cfg: RollerRigSimConfig, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """The machine as it really is (datasheet values perturbed) and its contact strips."""
    spin = math.sin(machine.contact_angle) * (1.0 / cfg.radius_m + 1.0 / machine.roller_radius)
    v_th, r_th, x_th, r2, x2, f_rated, pole_pairs = machine.motor
    bw0, bw1, br0, br1 = machine.bearings
    u = rng.uniform
    p = np.array([
        machine.wheel_inertia * u(0.98, 1.03), machine.roller_inertia * u(0.98, 1.03),
        cfg.radius_m, machine.roller_radius, u(1.0e-4, 2.5e-4), machine.nominal_load, spin,
        machine.mu0 * u(0.9, 1.1), u(0.35, 0.5), u(0.4, 0.9), u(0.95, 0.99), u(0.008, 0.015),
        v_th, r_th, x_th + x2, r2 * u(1.02, 1.08), f_rated, pole_pairs, u(0.015, 0.03),
        cfg.supply_hz, bw0 * u(0.8, 1.3), bw1 * u(0.8, 1.3), br0 * u(0.8, 1.3),
        br1 * u(0.8, 1.3),
    ])  # fmt: skip
    return p, contact_strips(machine, cfg.radius_m)


def _encoder_speed(theta: np.ndarray, dt: float, ecc: float, phase: float) -> np.ndarray:
    """Speed from an incremental encoder: counts of an eccentric disc, differenced, rad/s."""
    seen = theta + ecc * np.sin(theta + phase)  # mounting eccentricity: once-per-rev error
    counts = np.floor(seen * ENCODER_COUNTS / (2.0 * np.pi))
    w = np.empty_like(theta)
    w[1:] = np.diff(counts) * (2.0 * np.pi / ENCODER_COUNTS) / dt
    w[0] = w[1]
    return w


def simulate_roller_rig(cfg: RollerRigSimConfig) -> RollerRigSimResult:
    """Simulate one roller-rig session (same config and seed, same result).

    Returns
    -------
    RollerRigSimResult
        The channels of CHANNELS.md "Roller rig" and a truth table (``time``,
        ``wheel_omega``, ``roller_omega``, ``radius_m``, ``creep_force``, ``creepage``,
        ``torque_delivered``).
    """
    cfg = cfg.validated()
    machine = load_machine(cfg.rig)
    rng = np.random.default_rng(cfg.seed)
    p, strips = _truth_params(machine, cfg, rng)
    dt = 1.0 / cfg.rate_hz
    n_sub = max(1, math.ceil(dt / SIM_STEP - 1e-9))
    n_warm = round(WARMUP_S / dt)
    n_log = round(cfg.duration_s * cfg.rate_hz) + 1
    n = n_warm + n_log
    t_all = (np.arange(n) - n_warm) * dt
    t_log = t_all[n_warm:]
    request = np.zeros(n)
    request[n_warm:] = torque_request(cfg, t_log, rng)
    # the PMSM acts on the request after its dead time (one to three samples)
    dead = int(rng.integers(1, 4))
    acting = np.concatenate([np.zeros(dead), request[:-dead]])
    load = machine.nominal_load * (1.0 + _ou(rng, n, dt, 2.0, 0.015))
    w_syn = 2.0 * math.pi * cfg.supply_hz / machine.motor[6]
    w_r0 = w_syn * (1.0 - 0.005)
    w_w0 = w_r0 * machine.roller_radius / cfg.radius_m
    y0 = np.array([0.0, rng.uniform(0, 2 * np.pi), w_w0, w_r0, 0.0, 0.0])
    states = np.empty((n, 6))
    force, creep = np.empty(n), np.empty(n)
    _integrate(y0, acting, load, dt, n_sub, p, strips, states, force, creep)
    states, force, creep, load = states[n_warm:], force[n_warm:], creep[n_warm:], load[n_warm:]
    th_w, th_r, w_w, w_r, t_del = (states[:, i] for i in range(5))

    meas_w = _encoder_speed(th_w, dt, rng.uniform(5e-4, 1.5e-3), rng.uniform(0, 2 * np.pi))
    meas_r = _encoder_speed(th_r, dt, rng.uniform(1e-3, 2.5e-3), rng.uniform(0, 2 * np.pi))
    load_meas = load + rng.normal(0.0, 0.004 * machine.nominal_load, load.size)
    shaft = force * machine.roller_radius + rng.normal(0.0, 8.0, load.size)  # transducer
    channels = [
        Channel("wheel_omega", "rad/s", t_log, meas_w, decimals=5),
        Channel("roller_omega", "rad/s", t_log, meas_r, decimals=5),
        Channel("wheel_torque", "N m", t_log, request[n_warm:], decimals=2),
        Channel("normal_force", "N", t_log, load_meas, decimals=1),
        Channel("roller_torque", "N m", t_log, shaft, decimals=2),
    ]
    if cfg.reference:
        channels.append(
            Channel(
                "rolling_radius_ref",
                "mm",
                np.zeros(1),
                np.array([round(cfg.radius_m * 1e3, 2)]),
                decimals=2,
            )
        )
    facts = {
        "rig": "roller-rig",
        "rig_datasheet": machine.id,
        # the roller radius simulated, so that a reader without this datasheet still
        # turns the speed ratio into the right wheel radius
        "roller_radius_m": f"{machine.roller_radius:g}",
        "roller_supply_hz": f"{cfg.supply_hz:g}",
        "speed_kmh": f"{cfg.speed_kmh:g}",
        "simulated": "true",
        "seed": str(cfg.seed),
    }
    truth = pa.table({
        "time": t_log, "wheel_omega": w_w, "roller_omega": w_r,
        "radius_m": np.full(t_log.size, cfg.radius_m), "creep_force": force,
        "creepage": creep, "torque_delivered": t_del, "normal_force": load,
    })  # fmt: skip
    return RollerRigSimResult(SessionData(tuple(channels), facts), truth, cfg)


def write_roller_rig_simulation(
    result: RollerRigSimResult, out: str | Path, fmt: str | None = None
) -> tuple[Path, Path]:
    """Write the session and ``<stem>.truth.parquet`` beside it; returns both paths."""
    return write_session_and_truth(out, result.session, result.truth, fmt)
