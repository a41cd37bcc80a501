"""Rider, brake hydraulics, caliper and pressure sensor of the front brake.

The rider brakes towards the planned speed at every point of the track: a feed-forward
pressure from the force the plan needs and the brake as the rider knows it (datasheet
torque per bar at nominal friction), slow hand modulation, and a lagged PI correction
on the speed error. The line pressure follows the command through second-order
hydraulics (overshoot). The caliper turns it into torque through seal play
(hysteresis), the pressure taking up the pad clearance and a small nonlinearity,
times the TRUE torque per bar and mu(T)/mu_nom. The bike decelerates with what the
front delivers; engine braking and the rear brake carry the rest of the plan's force.
So the logged pressure is not the inverse of the estimator's braking-power formula.

The model errors the datasheet cannot know (true torque per bar, true heat share into
this disc, the caliper nonlinearity, the sensor's offset and gain) are drawn per seed.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numba import njit
from scipy.signal import butter, lfilter

from brakethermo.sim.vehicle import G, VehicleSpec
from brakethermo.thermal.disc import BAR, DiscSpec


@dataclass(frozen=True)
class BrakeChain:
    """Front brake chain of one run.

    Attributes
    ----------
    torque_per_bar : float — N m/bar
        True brake torque on this disc per bar at nominal friction.
    heat_share : float
        True share of the friction heat entering this disc.
    torque_per_bar_datasheet, heat_share_datasheet : float
        What the datasheet says (and what the rider's feel is built on).
    torque_nonlinearity : float
        Relative change of torque per bar per ``p_ref_bar`` of pressure above it.
    p_ref_bar : float — bar
    seal_play_bar : float — bar
        Half width of the play (hysteresis) between line and clamping pressure.
    knock_back_bar : float — bar
        Pressure that only takes up the pad clearance (no torque below it).
    rider_lag_s : float — s
        First-order lag of the rider's perception of the speed error.
    rider_correction_s : float — s
        Time the rider's proportional correction takes to cancel a speed error.
    rider_integral_s : float — s
        Integral time of the rider's correction within one braking.
    modulation : float
        1-sigma relative hand modulation of the commanded pressure.
    modulation_hz : float — Hz
        Corner frequency of the modulation.
    hydraulic_hz : float — Hz
        Natural frequency of the line pressure following the command.
    hydraulic_damping : float
    engine_brake_g : float — g
        Engine braking taken first from the plan's braking force.
    rear_share : float
        Share of the remaining braking force on the rear brake.
    throttle_gain : float — 1/s
        Off the front brake the throttle brings the speed back to the plan at this rate.
    sensor_offset_bar : float — bar
    sensor_gain : float
        Logged pressure = gain * line pressure + offset + noise.
    sensor_noise_bar : float — bar, 1 sigma
    model_errors : bool
        False: true torque per bar and heat share equal the datasheet, no nonlinearity,
        ideal sensor gain and offset (the rider, hydraulics and caliper play remain).
    """

    torque_per_bar: float
    heat_share: float
    torque_per_bar_datasheet: float
    heat_share_datasheet: float
    torque_nonlinearity: float
    sensor_offset_bar: float
    sensor_gain: float
    rider_lag_s: float
    modulation: float
    model_errors: bool
    p_ref_bar: float = 10.0
    seal_play_bar: float = 0.12
    knock_back_bar: float = 0.15
    rider_correction_s: float = 0.6
    rider_integral_s: float = 1.0
    modulation_hz: float = 1.5
    hydraulic_hz: float = 5.0
    hydraulic_damping: float = 0.6
    engine_brake_g: float = 0.05
    rear_share: float = 0.03
    throttle_gain: float = 2.0
    sensor_noise_bar: float = 0.02

    def as_dict(self) -> dict[str, float | bool]:
        out = asdict(self)
        out["torque_per_bar_error_pct"] = 100.0 * (
            self.torque_per_bar / self.torque_per_bar_datasheet - 1.0
        )
        out["heat_share_error_pct"] = 100.0 * (self.heat_share / self.heat_share_datasheet - 1.0)
        return out

    def logged_pressure_bar(
        self, p_line_bar: np.ndarray, rng: np.random.Generator
    ) -> np.ndarray:
        """What the logger records: gain, offset, noise (absolute and 0.5 %), no negatives."""
        p = np.asarray(p_line_bar, dtype=float)
        noise = self.sensor_noise_bar * rng.normal(size=p.shape) + 0.005 * p * rng.normal(
            size=p.shape
        )
        return np.maximum(self.sensor_gain * p + self.sensor_offset_bar + noise, 0.0)


def _signed(rng: np.random.Generator, lo: float, hi: float) -> float:
    """A relative error of random sign with magnitude uniform in [lo, hi]."""
    return float(rng.choice((-1.0, 1.0)) * rng.uniform(lo, hi))


def draw_brake_chain(
    disc: DiscSpec,
    rng: np.random.Generator,
    model_errors: bool = True,
    bike_rng: np.random.Generator | None = None,
) -> BrakeChain:
    """This run's brake chain; the model errors are 3-6 % on torque per bar and heat
    share. All draws happen whatever ``model_errors`` so the rider stays the same.

    ``bike_rng`` draws the hardware (true torque per bar, heat share, caliper
    nonlinearity, sensor gain), so sessions of one bike can share it; the session
    (sensor offset after zeroing, rider) always comes from ``rng``. Without it both
    come from ``rng``.
    """
    k_nom = disc.torque_per_pa * BAR
    hw = rng if bike_rng is None else bike_rng
    dk = _signed(hw, 0.03, 0.06)
    ds = _signed(hw, 0.03, 0.06)
    nonlin = float(hw.uniform(-0.05, 0.05))
    gain = float(1.0 + np.clip(hw.normal(0.0, 0.01), -0.02, 0.02))
    offset = float(rng.uniform(-0.03, 0.03))
    rider_lag = float(rng.uniform(0.12, 0.2))
    modulation = float(rng.uniform(0.02, 0.04))
    if not model_errors:
        dk = ds = nonlin = offset = 0.0
        gain = 1.0
    return BrakeChain(
        torque_per_bar=k_nom * (1.0 + dk),
        heat_share=min(disc.heat_share * (1.0 + ds), 0.98),
        torque_per_bar_datasheet=k_nom,
        heat_share_datasheet=disc.heat_share,
        torque_nonlinearity=nonlin,
        sensor_offset_bar=offset,
        sensor_gain=gain,
        rider_lag_s=rider_lag,
        modulation=modulation,
        model_errors=model_errors,
    )


def hand_modulation(
    chain: BrakeChain, n: int, rate: float, rng: np.random.Generator
) -> np.ndarray:
    """Relative modulation of the commanded pressure: band-limited noise, 1-sigma
    ``chain.modulation``, clipped to +-3 sigma."""
    b, a = butter(2, chain.modulation_hz / (0.5 * rate))
    white = rng.standard_normal(n + 2000)
    x = lfilter(b, a, white)[2000:]
    x *= chain.modulation / max(float(np.std(x)), 1e-12)
    return np.clip(x, -3 * chain.modulation, 3 * chain.modulation)


# Indices of the state vector advanced by :func:`advance`.
V, S, P, DP, PE, EF, EI, IP = range(8)
# Rows of the per-sample output of :func:`advance`.
OUT_V, OUT_S, OUT_P, OUT_TORQUE, OUT_FORCE = range(5)


def chain_params(chain: BrakeChain, veh: VehicleSpec, disc: DiscSpec, rate: float) -> np.ndarray:
    """Flat parameter vector of :func:`advance` (SI units, pressures in bar)."""
    R = disc.tyre_rolling_radius
    k_rider = chain.torque_per_bar_datasheet
    wn = 2.0 * np.pi * chain.hydraulic_hz
    return np.array(
        [
            1.0 / rate,
            veh.mass,
            R,
            0.5 * veh.rho_air * veh.cda,
            veh.crr * veh.mass * G,
            chain.torque_per_bar,
            k_rider,
            chain.rider_lag_s,
            veh.mass * R / (2.0 * k_rider * chain.rider_correction_s),  # bar per m/s
            chain.rider_integral_s,
            wn,
            chain.hydraulic_damping,
            chain.seal_play_bar,
            chain.knock_back_bar,
            chain.torque_nonlinearity,
            chain.p_ref_bar,
            chain.engine_brake_g * veh.mass * G,
            chain.rear_share,
            chain.throttle_gain,
        ]
    )


@njit(cache=True)
def advance(
    st: np.ndarray,
    prm: np.ndarray,
    plan_s: np.ndarray,
    plan_v: np.ndarray,
    plan_a: np.ndarray,
    plan_f: np.ndarray,
    mod: np.ndarray,
    mu: float,
    j0: int,
    n: int,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Advance rider, hydraulics, caliper and bike ``n`` samples from sample ``j0``
    with friction ratio ``mu`` (mu/mu_nom, frozen over the call); writes samples
    ``j0 + 1 .. j0 + n`` of ``out`` and updates the state ``st`` in place.

    The plan (``plan_*`` on the planned run's samples: distance, speed, acceleration,
    braking force) is looked up by the realised distance: the rider aims at the
    planned speed at each point of the track.
    """
    dt, m, R, cd, rr, k_true, k_rider, tau_r, kfb, ti = prm[:10]
    wn, zeta, play, p0, nl, pref, f_eng, rear, kthr = prm[10:19]
    v, s, p, dp, pe, ef, ei = st[0], st[1], st[2], st[3], st[4], st[5], st[6]
    ip = int(st[7])
    last = plan_s.size - 2
    for j in range(j0 + 1, j0 + n + 1):
        while ip < last and plan_s[ip + 1] <= s:
            ip += 1
        f = (s - plan_s[ip]) / (plan_s[ip + 1] - plan_s[ip])
        f = min(max(f, 0.0), 1.0)
        vp = plan_v[ip] + f * (plan_v[ip + 1] - plan_v[ip])
        ap = plan_a[ip] + f * (plan_a[ip + 1] - plan_a[ip])
        freq = plan_f[ip] + f * (plan_f[ip + 1] - plan_f[ip])
        if freq > 0.0:
            f_rest = min(freq, f_eng) + rear * max(freq - f_eng, 0.0)
            ef += (v - vp - ef) * dt / tau_r
            ei += ef * dt
            p_cmd = (freq - f_rest) * R / (2.0 * k_rider) * (1.0 + mod[j])
            p_cmd = max(p_cmd + kfb * (ef + ei / ti), 0.0)
        else:
            f_rest = 0.0
            p_cmd = 0.0
            ef = 0.0
            ei = 0.0
        dp += dt * (wn * wn * (p_cmd - p) - 2.0 * zeta * wn * dp)
        p += dt * dp
        if p < 0.0:
            p = 0.0
            dp = max(dp, 0.0)
        pe = min(max(pe, p - play), p + play)
        torque = k_true * mu * max(pe - p0, 0.0) * (1.0 + nl * (pe - pref) / pref)
        torque = max(torque, 0.0)
        f_front = 2.0 * torque / R  # two front discs
        if freq > 0.0:
            a = -(f_front + f_rest + cd * v * v + rr) / m
        else:
            a = ap + kthr * (vp - v) - f_front / m
        v_new = max(v + a * dt, 1.0)
        s += 0.5 * (v + v_new) * dt
        v = v_new
        out[0, j] = v
        out[1, j] = s
        out[2, j] = p
        out[3, j] = torque
        out[4, j] = f_front + f_rest
    st[0], st[1], st[2], st[3], st[4], st[5], st[6] = v, s, p, dp, pe, ef, ei
    st[7] = ip
