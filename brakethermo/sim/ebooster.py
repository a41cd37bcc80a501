"""E-Booster bench simulator, richer than the observer's model (separate code).

Truth physics (units MPa, mm, N, s; 1 MPa x 1 mm^2 = 1 N):

* hydraulics: master cylinder with a dead stroke (central valve, port to the reservoir),
  fluid compliance, two circuits with nonlinear caliper compliance (soft at low pressure)
  behind ports with a turbulent sqrt law blended into laminar flow near zero; integrated
  by backward Euler on the volume balance (3x3 Newton), so the stiff chamber is stable;
* output force: pressure, return spring and seal friction (Coulomb + pressure-dependent,
  smoothed by tanh of the piston speed);
* reaction disk: generalized Maxwell rubber (eq. 5-7: odd quintic elastic spring plus two
  Maxwell branches, integrated exactly over each substep) with Berg friction (eq. 9,
  reference point reset at each reversal) and Mullins stiffness damage with exponential
  recovery (eq. 8); the compression delta solves the force balance implicitly;
* screw servo: first-order position loop with a speed limit; closed loop: a PI on the
  measured delta towards a pre-compression reference (the paper's closed-loop test);
* sensors: delta with first-order lag, noise and quantisation (the controller sees this
  signal), screw encoder quantisation, pressure and pedal-force noise and quantisation;
* driver: pedal force from a chi-square process (sum of squared Ornstein-Uhlenbeck
  processes), alone (bench tests) or modulating brake applications (vehicle-like).

Scenarios: ``train`` (constant screw speed up and down, the p-V training run),
``open`` (the paper's 2 mm/s ramp), ``closed`` (PI on delta) and ``vehicle`` (a sequence
of brake applications, closed loop).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numba
import numpy as np
import pyarrow as pa
from numpy.typing import NDArray
from scipy.signal import lfilter

from brakethermo.errors import ConfigError
from brakethermo.io.writers import Channel, SessionData
from brakethermo.sim.writer import write_session_and_truth

Array = NDArray[np.float64]
SCENARIOS = ("train", "open", "closed", "vehicle")
DEFAULT_DURATION_S = {"train": 24.0, "open": 20.0, "closed": 20.0, "vehicle": 40.0}


@dataclass(frozen=True)
class BenchTruth:
    """Truth parameters of the simulated bench (never read by the observer).

    Pressures MPa, lengths mm, volumes mm^3, forces N, times s.
    """

    area_mm2: float = 445.0
    dead_stroke_mm: float = 1.0
    dead_width_mm: float = 0.15
    port_conductance: float = 2.0e5  # mm^3/(s MPa), central-valve port when open
    chamber_compliance: float = 15.0  # mm^3/MPa, fluid and hose in the master cylinder
    orifice_k: tuple[float, float] = (4.0e4, 3.0e4)  # mm^3/(s MPa^0.5)
    laminar_mpa: float = 0.01  # below this pressure drop the port flow turns laminar
    caliper_c0: tuple[float, float] = (1500.0, 1000.0)  # mm^3/MPa at zero pressure
    caliper_pc: tuple[float, float] = (1.2, 1.0)  # MPa
    caliper_cinf: tuple[float, float] = (350.0, 250.0)  # mm^3/MPa at high pressure
    return_spring: float = 4.5  # N/mm
    seal_f0: float = 20.0  # N
    seal_mu: float = 3.0  # N/MPa
    seal_v: float = 0.5  # mm/s
    area_ratio: float = 0.1
    d10_intrinsic: float = 80.0  # N/mm (2 D10 is the linear stiffness, eq. 7)
    d10_damage: float = 62.0  # N/mm right after a compression (Mullins)
    k_recover: float = 0.25  # 1/s, eq. 8
    mullins_mm: float = 0.15  # compression that damages the stiffness
    d20: float = 15.0  # N/mm^3
    d30: float = 3.0  # N/mm^5
    maxwell_k: tuple[float, float] = (80.0, 40.0)  # N/mm
    maxwell_tau: tuple[float, float] = (0.015, 0.25)  # s
    berg_fmax: float = 12.0  # N
    berg_x2: float = 0.04  # mm
    servo_tau: float = 0.012  # s
    servo_vmax: float = 80.0  # mm/s
    stroke_max: float = 30.0  # mm
    kp: float = 1.0  # mm/mm
    ki: float = 100.0  # mm/(mm s)
    delta_ref: float = 0.3  # mm, pre-compression of the closed loop
    delta_lag: float = 0.002  # s
    delta_noise: float = 0.01  # mm
    delta_quant: float = 0.002  # mm
    s2_quant: float = 0.002  # mm
    pressure_noise: float = 0.004  # MPa
    pressure_quant: float = 0.001  # MPa
    pedal_noise: float = 2.0  # N
    pedal_dof: int = 1
    pedal_tau: float = 0.4  # s, correlation time of the chi-square process
    pedal_scale: float = 60.0  # N, mean per degree of freedom


@dataclass(frozen=True)
class EboosterSimConfig:
    """One simulated bench session."""

    scenario: str = "vehicle"
    seed: int = 0
    rate_hz: float = 1000.0
    duration_s: float | None = None
    truth: BenchTruth = BenchTruth()
    pv_shift_mm: float = 0.0  # mm, this session's dead stroke against the truth's (seals, fluid)

    def __post_init__(self) -> None:
        # checked when the settings are made, as the other rigs' configs are: a value
        # given by `simulate --set` is then a usage error, not one found while simulating
        if self.scenario not in SCENARIOS:
            raise ConfigError(f"unknown scenario '{self.scenario}'; use one of"
                              f" {', '.join(SCENARIOS)}")
        if not self.rate_hz > 0:
            raise ConfigError(f"rate must be positive, got {self.rate_hz} Hz")
        if self.duration_s is not None and not self.duration_s * self.rate_hz >= 10:
            raise ConfigError(f"duration must give at least 10 samples at {self.rate_hz:g} Hz,"
                              f" got {self.duration_s} s; set duration_s to a positive number"
                              " of seconds")
        if not -2.0 <= self.pv_shift_mm <= 2.0:
            raise ConfigError(f"pv_shift_mm must be within ±2 mm, got {self.pv_shift_mm}")


@dataclass(frozen=True)
class EboosterSim:
    """Simulated signals on the output grid (truth and sensor readings)."""

    config: EboosterSimConfig
    time: Array
    s2: Array
    delta: Array
    p_m: Array
    p_f: Array
    p_r: Array
    f_in: Array
    d10: Array
    meas: dict[str, Array]


@numba.njit(cache=True)
def _flow(k: float, dp: float, pt: float) -> tuple[float, float]:
    """Port flow mm^3/s and its derivative: sqrt law blended to laminar below pt."""
    r = (dp * dp + pt * pt) ** 0.25
    q = k * dp / r
    dq = k * (0.5 * dp * dp + pt * pt) / (r**5)
    return q, dq


@numba.njit(cache=True)
def _caliper_volume(p: float, c0: float, pc: float, cinf: float) -> tuple[float, float]:
    """Volume taken by a circuit (mm^3) and its compliance at pressure p >= -pc."""
    s = 1.0 + p / pc
    return c0 * pc * (1.0 - 1.0 / s) + cinf * p, c0 / (s * s) + cinf


@numba.njit(cache=True)
def _berg(x: float, xs: float, ffs: float, fmax: float, x2: float) -> tuple[float, float]:
    """Berg friction force and its slope (eq. 9) about the reference point (xs, ffs)."""
    a = ffs / fmax
    u = x - xs
    if u > 0.0:
        c = x2 * (1.0 - a)
        return ffs + u / (c + u) * (fmax - ffs), c / ((c + u) ** 2) * (fmax - ffs)
    if u < 0.0:
        c = x2 * (1.0 + a)
        return ffs + u / (c - u) * (fmax + ffs), c / ((c - u) ** 2) * (fmax + ffs)
    return ffs, (fmax - ffs) / (x2 * (1.0 - a)) if ffs >= 0.0 else (fmax + ffs) / (
        x2 * (1.0 + a))


@numba.njit(cache=True)
def _hydraulics(  # pragma: no cover - compiled; checked through its outputs
    pm: float, pf: float, pr: float, dvol: float, gp: float, h: float, cm: float, kf: float,
    kr_o: float, pt: float, c0f: float, pcf: float, cif: float, c0r: float, pcr: float,
    cir: float,
) -> tuple[float, float, float]:
    """Master-cylinder, front and rear pressures after one implicit substep (Newton on the
    volume balances of the three chambers, the port open by ``gp``), MPa."""
    vf0, _ = _caliper_volume(pf, c0f, pcf, cif)
    vr0, _ = _caliper_volume(pr, c0r, pcr, cir)
    p1, p2, p3 = pm, pf, pr
    for _ in range(20):
        qf, dqf = _flow(kf, p1 - p2, pt)
        qr, dqr = _flow(kr_o, p1 - p3, pt)
        vf1, cf1 = _caliper_volume(p2, c0f, pcf, cif)
        vr1, cr1 = _caliper_volume(p3, c0r, pcr, cir)
        r1 = cm * (p1 - pm) - dvol + h * (qf + qr + gp * p1)
        r2 = vf1 - vf0 - h * qf
        r3 = vr1 - vr0 - h * qr
        J = np.array([
            [cm + h * (dqf + dqr + gp), -h * dqf, -h * dqr],
            [-h * dqf, cf1 + h * dqf, 0.0],
            [-h * dqr, 0.0, cr1 + h * dqr],
        ])
        d = np.linalg.solve(J, np.array([r1, r2, r3]))
        p1 -= d[0]
        p2 -= d[1]
        p3 -= d[2]
        p2 = max(p2, -0.5 * pcf)
        p3 = max(p3, -0.5 * pcr)
        if abs(d[0]) + abs(d[1]) + abs(d[2]) < 1e-11:
            break
    return p1, p2, p3


@numba.njit(cache=True)
def _pi_control(  # pragma: no cover - compiled; checked through its outputs
    e: float, integ: float, kp: float, ki: float, h_out: float, smax: float
) -> tuple[float, float]:
    """Screw command of the PI on the delta error, and the integrator after the step.

    Parameters
    ----------
    e : float — mm, measured minus reference delta.
    integ : float — mm, integrator state.
    kp, ki : float — mm/mm and mm/(mm s), gains.
    h_out : float — s, controller step.
    smax : float — mm, stroke limit.
    """
    trial = integ + ki * e * h_out
    u = kp * e + trial
    # anti-windup: the integrator only moves while the command is inside the stroke
    if 0.0 < u < smax:
        integ = trial
    return min(max(kp * e + integ, 0.0), smax), integ


@numba.njit(cache=True)
def _displaced_volume(  # pragma: no cover - compiled; checked through its outputs
    s2: float, s2_new: float, s_dead: float, w_dead: float, area: float
) -> tuple[float, float]:
    """Volume displaced over a substep past the dead stroke (softplus), mm^3, and the
    central valve's port opening at its end (1 open, 0 closed).

    Parameters
    ----------
    s2, s2_new : float — mm, stroke at the start and end of the substep.
    s_dead, w_dead : float — mm, dead stroke and the width of its smoothing.
    area : float — mm^2, master-cylinder piston area.
    """
    z0 = (s2 - s_dead) / w_dead
    z1 = (s2_new - s_dead) / w_dead
    x0 = w_dead * (np.log1p(np.exp(-abs(z0))) + max(z0, 0.0))
    x1 = w_dead * (np.log1p(np.exp(-abs(z1))) + max(z1, 0.0))
    return area * (x1 - x0), 1.0 / (1.0 + np.exp(z1 * 4.0))


@numba.njit(cache=True)
def _output_force(  # pragma: no cover - compiled; checked through its outputs
    pm: float, s2: float, v: float, area: float, k_ret: float, f0: float, mu_s: float,
    v_s: float,
) -> float:
    """Force on the master-cylinder piston, N: pressure, return spring and seal friction.

    Parameters
    ----------
    pm : float — MPa, master-cylinder pressure.
    s2, v : float — mm and mm/s, stroke and its speed.
    area : float — mm^2.
    k_ret : float — N/mm, return spring.
    f0, mu_s : float — N and N/MPa, seal friction and its pressure dependence.
    v_s : float — mm/s, speed over which the seal friction reverses.
    """
    seal = (f0 + mu_s * pm) * np.tanh(v / v_s)
    return pm * area + k_ret * s2 + seal


@numba.njit(cache=True)
def _mullins(  # pragma: no cover - compiled; checked through its outputs
    delta: float, t_since: float, h: float, d_mull: float, d10i: float, d10d: float,
    k_rec: float,
) -> tuple[float, float]:
    """The time since the last damaging compression (s) and the rubber stiffness D10
    (N/mm) under Mullins damage (eq. 8), after a substep ``h`` (s) at compression
    ``delta`` (mm).

    The stiffness is damaged while compressed beyond ``d_mull`` (mm) and recovers
    exponentially at ``k_rec`` (1/s) from ``d10d`` towards ``d10i`` (N/mm).
    """
    if delta > d_mull:
        t_since = 0.0
    else:
        t_since += h
    return t_since, d10i + (d10d - d10i) * np.exp(-k_rec * t_since)


@numba.njit(cache=True)
def _disk_newton(  # pragma: no cover - compiled; checked through its outputs
    delta: float, f_net: float, d10: float, sig1: float, sig2: float, xs: float, ffs: float,
    rubber: tuple[float, float, float, float, float, float],
    maxwell: tuple[float, float, float, float],
) -> float:
    """Compression (mm) at which the rubber, its Maxwell branches and Berg friction
    carry the net force ``f_net`` (N), by Newton from the substep's start ``delta``.

    Parameters
    ----------
    d10 : float — N/mm, current linear stiffness coefficient.
    sig1, sig2 : float — N, Maxwell branch forces at the start of the substep.
    xs, ffs : float — mm and N, Berg friction's reference point.
    rubber : (d20, d30, k1, k2, fmax, x2) — N/mm^3, N/mm^5, N/mm, N/mm, N, mm.
    maxwell : (a1, b1, a2, b2) — exact-integration factors of the Maxwell branches.
    """
    d20, d30, k1, k2, fmax, x2 = rubber
    a1, b1, a2, b2 = maxwell
    x = delta
    for _ in range(40):
        fe = 6.0 * d30 * x**5 + 4.0 * d20 * x**3 + 2.0 * d10 * x  # eq. 7
        dfe = 30.0 * d30 * x**4 + 12.0 * d20 * x**2 + 2.0 * d10
        fb, dfb = _berg(x, xs, ffs, fmax, x2)
        g = fe + a1 * sig1 + k1 * b1 * (x - delta) + a2 * sig2 \
            + k2 * b2 * (x - delta) + fb - f_net
        dg = dfe + k1 * b1 + k2 * b2 + dfb
        step = g / dg
        step = min(max(step, -0.2), 0.2)
        x -= step
        if abs(step) < 1e-12:
            break
    return x


@numba.njit(cache=True)
def _reaction_disk(  # pragma: no cover - compiled; checked through its outputs
    delta: float, f_net: float, d10: float, sig1: float, sig2: float, xs: float, ffs: float,
    direction: float, rubber: tuple[float, float, float, float, float, float],
    maxwell: tuple[float, float, float, float],
) -> tuple[float, float, float, float]:
    """Reaction-disk compression after a substep (mm), with Berg's reference point (mm, N)
    and the motion's direction (+1 or -1) after it; arguments as :func:`_disk_newton`."""
    fmax, x2 = rubber[4], rubber[5]
    xs_try, ffs_try = xs, ffs
    x = delta
    for attempt in range(2):
        x = _disk_newton(delta, f_net, d10, sig1, sig2, xs_try, ffs_try, rubber, maxwell)
        moved = x - delta
        if attempt == 0 and moved * direction < -1e-12:
            # reversal: Berg's reference point moves to the turning point
            ffs_new, _ = _berg(delta, xs, ffs, fmax, x2)
            xs_try, ffs_try = delta, ffs_new
            direction = -direction
            continue
        break
    return x, xs_try, ffs_try, direction


@numba.njit(cache=True)
def _integrate(
    par: Array, f_in: Array, s2_prof: Array, dref: Array, noise_d: Array, closed: bool,
    h_out: float, nsub: int,
) -> Array:  # pragma: no cover - compiled; checked through its outputs
    (area, s_dead, w_dead, g_port, cm, kf, kr_o, pt, c0f, c0r, pcf, pcr, cif, cir, k_ret,
     f0, mu_s, v_s, ra, d10i, d10d, k_rec, d_mull, d20, d30, k1, k2, t1, t2, fmax, x2,
     tau_m, vmax, smax, kp, ki, tau_d, dq) = par  # fmt: skip
    K = f_in.shape[0]
    out = np.zeros((K, 8))  # s2, delta, p_m, p_f, p_r, d10, delta_meas, s2_cmd
    h = h_out / nsub
    s2 = s2_prof[0] if not closed else 0.0
    s2_cmd = s2
    pm = pf = pr = 0.0
    delta = 0.0
    sig1 = sig2 = 0.0
    xs, ffs, direction = 0.0, 0.0, 1.0
    t_since = 1.0e3
    d_lag = 0.0
    integ = 0.0
    a1, a2 = np.exp(-h / t1), np.exp(-h / t2)
    b1, b2 = t1 * (1.0 - a1) / h, t2 * (1.0 - a2) / h
    rubber = (d20, d30, k1, k2, fmax, x2)
    maxwell = (a1, b1, a2, b2)
    lag = np.exp(-h_out / tau_d)
    d_meas = 0.0
    for k in range(K):
        # controller at the output rate, on the sensor signal
        if closed:
            s2_cmd, integ = _pi_control(d_meas - dref[k], integ, kp, ki, h_out, smax)
        else:
            s2_cmd = s2_prof[k]
        fk0 = f_in[k - 1] if k > 0 else f_in[0]
        for j in range(nsub):
            fin = fk0 + (f_in[k] - fk0) * (j + 1) / nsub
            v = (s2_cmd - s2) / tau_m
            v = min(max(v, -vmax), vmax)
            s2_new = s2 + v * h
            dvol, open_port = _displaced_volume(s2, s2_new, s_dead, w_dead, area)
            p1, p2, p3 = _hydraulics(pm, pf, pr, dvol, g_port * open_port, h, cm, kf, kr_o, pt,
                                     c0f, pcf, cif, c0r, pcr, cir)
            pm, pf, pr = max(p1, 0.0), p2, p3
            s2 = s2_new
            f_net = fin - ra * _output_force(pm, s2, v, area, k_ret, f0, mu_s, v_s)
            t_since, d10 = _mullins(delta, t_since, h, d_mull, d10i, d10d, k_rec)
            x, xs, ffs, direction = _reaction_disk(delta, f_net, d10, sig1, sig2, xs, ffs,
                                                   direction, rubber, maxwell)
            sig1 = a1 * sig1 + k1 * b1 * (x - delta)  # eq. 5a over the substep
            sig2 = a2 * sig2 + k2 * b2 * (x - delta)
            delta = x
        d_lag = lag * d_lag + (1.0 - lag) * delta
        d_meas = np.round((d_lag + noise_d[k]) / dq) * dq
        out[k, 0] = s2
        out[k, 1] = delta
        out[k, 2] = pm
        out[k, 3] = pf
        out[k, 4] = pr
        out[k, 5] = d10
        out[k, 6] = d_meas
        out[k, 7] = s2_cmd
    return out


def _par(t: BenchTruth) -> Array:
    return np.array([
        t.area_mm2, t.dead_stroke_mm, t.dead_width_mm, t.port_conductance,
        t.chamber_compliance, t.orifice_k[0], t.orifice_k[1], t.laminar_mpa,
        t.caliper_c0[0], t.caliper_c0[1], t.caliper_pc[0], t.caliper_pc[1],
        t.caliper_cinf[0], t.caliper_cinf[1], t.return_spring, t.seal_f0, t.seal_mu,
        t.seal_v, t.area_ratio, t.d10_intrinsic, t.d10_damage, t.k_recover, t.mullins_mm,
        t.d20, t.d30, t.maxwell_k[0], t.maxwell_k[1], t.maxwell_tau[0], t.maxwell_tau[1],
        t.berg_fmax, t.berg_x2, t.servo_tau, t.servo_vmax, t.stroke_max, t.kp, t.ki,
        t.delta_lag, t.delta_quant,
    ], dtype=np.float64)  # fmt: skip


def chi_square_process(
    rng: np.random.Generator, K: int, dt: float, dof: int, tau: float
) -> Array:
    """Sum of ``dof`` squared unit Ornstein-Uhlenbeck processes (chi-square marginal).

    Parameters
    ----------
    rng : Generator
    K : int — samples.
    dt, tau : float — s, step and correlation time.
    dof : int — degrees of freedom.

    Returns
    -------
    ndarray (K,) — a process with chi-square(dof) marginal distribution, mean dof.
    """
    a = np.exp(-dt / tau)
    e = rng.normal(size=(K, dof)) * np.sqrt(1.0 - a * a)
    e[0] = rng.normal(size=dof)  # start in the stationary distribution
    g = lfilter([1.0], [1.0, -a], e, axis=0)  # g[k] = a g[k-1] + e[k]
    return np.sum(g * g, axis=1)


def _applications(rng: np.random.Generator, t: Array) -> tuple[Array, Array]:
    """Envelope (0..1) and per-application target force of a vehicle-like drive."""
    env = np.zeros_like(t)
    target = np.zeros_like(t)
    start = 0.5
    while start < t[-1]:
        rise, hold, fall = rng.uniform(0.2, 0.8), rng.uniform(0.5, 3.0), rng.uniform(0.2, 0.6)
        force = rng.uniform(80.0, 420.0)
        up = np.clip((t - start) / rise, 0.0, 1.0)
        down = np.clip((t - start - rise - hold) / fall, 0.0, 1.0)
        shape = 0.5 - 0.5 * np.cos(np.pi * up * (1.0 - down))
        inside = (t >= start) & (t <= start + rise + hold + fall)
        env = np.where(inside, shape, env)
        target = np.where(inside, force, target)
        start += rise + hold + fall + rng.uniform(1.0, 4.0)
    return env, target


def simulate_ebooster(cfg: EboosterSimConfig) -> EboosterSim:
    """Simulate one bench session.

    Parameters
    ----------
    cfg : EboosterSimConfig

    Returns
    -------
    EboosterSim
    """
    # the p-V curve of a real booster moves between sessions (seal and rubber state,
    # fluid): the dead stroke before the central valve closes shifts by tenths of a mm
    tr = replace(cfg.truth, dead_stroke_mm=cfg.truth.dead_stroke_mm + cfg.pv_shift_mm)
    dt = 1.0 / cfg.rate_hz
    duration = cfg.duration_s or DEFAULT_DURATION_S[cfg.scenario]
    K = round(duration * cfg.rate_hz) + 1
    t = np.arange(K) * dt
    rng = np.random.default_rng(cfg.seed)
    chi = chi_square_process(rng, K, dt, tr.pedal_dof, tr.pedal_tau)
    s2_prof = np.zeros(K)
    closed = cfg.scenario in ("closed", "vehicle")
    if cfg.scenario == "train":
        top, speed = 22.0, 4.0  # mm, mm/s: constant speed up and down, twice
        period = 2.0 * top / speed
        phase = np.clip(t - 1.0, 0.0, None) % period
        s2_prof = np.where(phase < period / 2, speed * phase, 2 * top - speed * phase)
        s2_prof[t > 1.0 + 2 * period] = 0.0
        f_in = tr.pedal_scale * 1.5 * chi
    elif cfg.scenario == "open":
        up = np.clip(t - 1.0, 0.0, 10.0) * 2.0  # the paper's 2 mm/s ramp for 10 s
        down = np.clip(t - 13.0, 0.0, 5.0) * 4.0
        s2_prof = up - down
        f_in = tr.pedal_scale * chi
    elif cfg.scenario == "closed":
        f_in = tr.pedal_scale * chi
    else:
        env, target = _applications(rng, t)
        f_in = env * (target + 0.4 * tr.pedal_scale * chi)
    dref = np.full(K, tr.delta_ref)
    noise_d = rng.normal(scale=tr.delta_noise, size=K)
    out = _integrate(_par(tr), f_in, s2_prof, dref, noise_d, closed, dt, 4)
    s2, delta, p_m, p_f, p_r, d10, d_meas = (out[:, i] for i in range(7))

    def quant(x: Array, q: float) -> Array:
        return np.round(x / q) * q

    meas = {
        "pushrod_displacement": quant(s2, tr.s2_quant),
        "reaction_disk_delta": d_meas,
        "master_cylinder_pressure": quant(
            p_m + rng.normal(scale=tr.pressure_noise, size=K), tr.pressure_quant),
        "front_circuit_pressure": quant(
            p_f + rng.normal(scale=tr.pressure_noise, size=K), tr.pressure_quant),
        "rear_circuit_pressure": quant(
            p_r + rng.normal(scale=tr.pressure_noise, size=K), tr.pressure_quant),
        "pedal_force": quant(f_in + rng.normal(scale=tr.pedal_noise, size=K), 0.1),
    }
    return EboosterSim(cfg, t, s2, delta, p_m, p_f, p_r, f_in, d10, meas)


UNITS = {
    "pushrod_displacement": "mm",
    "reaction_disk_delta": "mm",
    "master_cylinder_pressure": "MPa",
    "front_circuit_pressure": "MPa",
    "rear_circuit_pressure": "MPa",
    "pedal_force": "N",
}


def write_ebooster_session(
    sim: EboosterSim,
    path: str | Path,
    fmt: str | None = None,
    *,
    channels: tuple[str, ...] = tuple(UNITS),
) -> tuple[Path, Path]:
    """Write the sensor channels with the real session writers, and a truth file.

    Parameters
    ----------
    sim : EboosterSim
    path : str or Path — ``.mcap``, ``.parquet`` or ``.csv``.
    fmt : str, optional — format (default from the extension).
    channels : tuple of str — which sensor channels to write (a production car has no
        pressure or pedal-force sensor).

    Returns
    -------
    (session path, truth path) — the truth is ``<stem>.truth.parquet`` beside it.
    """
    path = Path(path)
    unknown = sorted(set(channels) - UNITS.keys())
    if unknown:
        raise ConfigError(f"unknown booster channel(s): {', '.join(unknown)}")
    decimals = {"mm": 4, "MPa": 4, "N": 1}
    data = SessionData(
        channels=tuple(
            Channel(name, UNITS[name], sim.time, sim.meas[name], decimals[UNITS[name]])
            for name in channels
        ),
        facts={
            "vehicle": "eb-bench-1",
            "track": "bench",
            "scenario": sim.config.scenario,
            "seed": str(sim.config.seed),
        },
    )
    truth = pa.table({
        "time": sim.time, "s2": sim.s2, "delta": sim.delta, "p_m": sim.p_m, "p_f": sim.p_f,
        "p_r": sim.p_r, "pedal_force": sim.f_in, "d10": sim.d10,
    })
    return write_session_and_truth(path, data, truth, fmt)


@dataclass(frozen=True)
class EboosterRigConfig:
    """``brakethermo simulate --rig ebooster --set KEY=VALUE``: what to simulate and log.

    Attributes
    ----------
    scenario : str — train, open, closed or vehicle.
    seed : int
    rate_hz : float — Hz, logging rate.
    duration_s : float or None — s (default per scenario).
    production : bool — log only s2 and delta (no pressure or pedal-force sensors).
    pv_shift_mm : float — mm, the session's p-V curve shifted along the stroke (a dead
        stroke longer by this much: seal and fluid state differ from the training day's).
    """

    scenario: str = "vehicle"
    seed: int = 0
    rate_hz: float = 1000.0
    duration_s: float | None = None
    production: bool = False
    pv_shift_mm: float = 0.0

    def __post_init__(self) -> None:
        self.session_config()  # the simulator's checks, when the settings are made

    def session_config(self) -> EboosterSimConfig:
        """The bench session these settings simulate."""
        return EboosterSimConfig(scenario=self.scenario, seed=self.seed, rate_hz=self.rate_hz,
                                 duration_s=self.duration_s, pv_shift_mm=self.pv_shift_mm)


PRODUCTION_CHANNELS = ("pushrod_displacement", "reaction_disk_delta")


def write_ebooster_simulation(
    cfg: EboosterRigConfig, path: str | Path, fmt: str | None = None
) -> tuple[Path, Path]:
    """Simulate one bench session and write it with its truth file (the rig registry's run).

    Returns
    -------
    (session path, truth path) — the truth is ``<stem>.truth.parquet`` beside it.
    """
    sim = simulate_ebooster(cfg.session_config())
    channels = PRODUCTION_CHANNELS if cfg.production else tuple(UNITS)
    return write_ebooster_session(sim, path, fmt, channels=channels)
