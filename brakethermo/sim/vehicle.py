"""Bike and rider: speed over a session, braking force and front-wheel speed.

The speed is integrated in time at 500 Hz: power-limited (and wheelie-limited)
acceleration against aero drag and rolling resistance, capped by a braking envelope
computed backwards along the track from every corner's apex speed. The envelope's
deceleration peaks near 1.5 g far above the apex speed and tapers towards it
(trail braking). A short moving average rounds the brake onset (pressure build-up).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brakethermo.sim.track import TrackSpec

G = 9.80665  # m/s^2
KMH = 1.0 / 3.6


@dataclass(frozen=True)
class VehicleSpec:
    """A MotoGP-like bike with rider.

    Attributes
    ----------
    name : str
    mass : float — kg, bike + rider
    power : float — W at the rear wheel
    cda : float — m^2, drag area
    rho_air : float — kg/m^3
    crr : float — rolling-resistance coefficient
    wheelie_g : float — acceleration limit, g
    brake_g : float — peak total deceleration, g
    trail_g : float — deceleration left at the apex, g
    trail_dv : float — m/s, speed above the apex over which braking tapers off
    front_share : float — share of the braking force on the front wheel
    slip_per_g : float — front-tyre braking slip per g of braking force
    onset_s : float — s, brake build-up time (width of the onset smoothing)
    """

    name: str = "motogp-like"
    mass: float = 228.0
    power: float = 192e3
    cda: float = 0.31
    rho_air: float = 1.18
    crr: float = 0.015
    wheelie_g: float = 1.0
    brake_g: float = 1.52
    trail_g: float = 0.45
    trail_dv: float = 60.0 * KMH
    front_share: float = 0.97
    slip_per_g: float = 0.03
    onset_s: float = 0.2

    def resistance(self, v: np.ndarray | float) -> np.ndarray | float:
        """Aero drag plus rolling resistance, N, at speed v (m/s)."""
        return 0.5 * self.rho_air * self.cda * v * v + self.crr * self.mass * G


@dataclass(frozen=True)
class RiderRun:
    """The session as driven, sampled at ``rate`` Hz from t = 0.

    Attributes
    ----------
    rate : float — Hz
    v : ndarray — m/s, forward speed
    s : ndarray — m, distance since the session start
    a : ndarray — m/s^2, longitudinal acceleration
    brake_force : ndarray — N, braking force of the whole bike (>= 0)
    slip : ndarray — braking slip of the front tyre
    lap : ndarray of int — lap number (0 = out-lap)
    lap_distance : ndarray — m, distance along the current lap
    next_corner : ndarray of int — index of the next corner (the one being braked for)
    beacon_times : ndarray — s, lap start times, lap 0 at t = 0
    following : ndarray of bool — per lap, following another bike
    """

    rate: float
    v: np.ndarray
    s: np.ndarray
    a: np.ndarray
    brake_force: np.ndarray
    slip: np.ndarray
    lap: np.ndarray
    lap_distance: np.ndarray
    next_corner: np.ndarray
    beacon_times: np.ndarray
    following: np.ndarray

    @property
    def time(self) -> np.ndarray:
        return np.arange(self.v.size) / self.rate


def _speed_limits(
    track: TrackSpec, laps: int, ds: float, rng: np.random.Generator, veh: VehicleSpec
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-grid-point speed limit, per-lap peak deceleration (g) and power factor."""
    L = track.length
    n = int(np.ceil((laps + 1) * L / ds)) + 1
    s = np.arange(n) * ds
    lap = np.minimum((s // L).astype(int), laps)
    s_lap = s - lap * L
    spans = track.corner_spans()
    apex = np.array([c.apex_speed for c in track.corners])
    # Lap-to-lap rider variation: apex speeds, braking force, throttle.
    apex_factor = rng.normal(1.0, 0.015, size=(laps + 1, apex.size))
    apex_factor[0] = 0.85  # out-lap: tyres and brakes warming up
    brake_g = np.clip(rng.normal(veh.brake_g, 0.03, size=laps + 1), 1.35, 1.6)
    brake_g[0] = 1.1
    power_f = rng.normal(1.0, 0.01, size=laps + 1)
    power_f[0] = 0.8
    corner = np.searchsorted(spans[:, 1], s_lap, side="right")
    in_corner = (corner < apex.size) & (s_lap >= spans[np.minimum(corner, apex.size - 1), 0])
    c = np.minimum(corner, apex.size - 1)
    v_lim = np.where(in_corner, apex[c] * apex_factor[lap, c], np.inf)
    v_lim[s < track.pit_lane] = track.pit_speed
    return v_lim, brake_g, power_f


def _brake_envelope(
    v_lim: np.ndarray, ds: float, brake_g_at: np.ndarray, veh: VehicleSpec
) -> np.ndarray:
    """Highest speed at every grid point from which the rider can still make every
    later speed limit, braking with the trail-braking deceleration profile."""
    env = v_lim.tolist()
    bg = brake_g_at.tolist()
    trail, dv = veh.trail_g * G, veh.trail_dv
    target = env[-1] if np.isfinite(env[-1]) else 1e9
    for i in range(len(env) - 2, -1, -1):
        v_next = env[i + 1]
        x = min(max((v_next - target) / dv, 0.0), 1.0)
        decel = trail + (bg[i] * G - trail) * x * x * (3.0 - 2.0 * x)
        reach = (v_next * v_next + 2.0 * decel * ds) ** 0.5
        if reach < env[i]:
            env[i] = reach
        else:
            target = env[i]  # the limit binds here: braking zones behind lead to it
    return np.asarray(env)


def _integrate_speed(
    track: TrackSpec, laps: int, veh: VehicleSpec, env: list[float], power_f: list[float],
    ds: float, dt: float,
) -> list[float]:
    """Speed (m/s) at every time step ``dt`` (s) from the pit lane to the end of the last
    lap: power-limited acceleration capped by the braking envelope ``env``
    (m/s on the distance grid of step ``ds``, m); ``power_f`` is the per-lap power factor."""
    L = track.length
    n_grid = len(env)
    total = (laps + 1) * L
    m, P = veh.mass, veh.power
    cd = 0.5 * veh.rho_air * veh.cda
    rr = veh.crr * veh.mass * G
    a_max = veh.wheelie_g * G
    v, s = track.pit_speed, 0.0
    vs = [v]
    while s < total:
        k = min(int(s // L), laps)
        a = min(a_max, (P * power_f[k] / max(v, 5.0) - cd * v * v - rr) / m)
        v_new = v + a * dt
        s_new = s + 0.5 * (v + v_new) * dt
        j = s_new / ds
        i0 = min(int(j), n_grid - 2)
        f = j - i0
        cap = env[i0] * (1.0 - f) + env[i0 + 1] * f
        if v_new > cap:
            v_new = cap
            s_new = s + 0.5 * (v + v_new) * dt
        v, s = v_new, s_new
        vs.append(v)
    return vs


def _brake_onset(
    vs: list[float], veh: VehicleSpec, rate: float, total: float
) -> tuple[np.ndarray, np.ndarray]:
    """Speed (m/s) with the brake onset rounded, and the distance (m) it covers, up to
    the first sample at or past ``total`` (m); ``rate`` in Hz."""
    dt = 1.0 / rate
    # Pressure build-up: a centred moving average over the onset time.
    w = max(1, round(veh.onset_s * rate))
    vraw = np.asarray(vs)
    padded = np.concatenate([np.full(w, vraw[0]), vraw, np.full(w, vraw[-1])])
    kernel = np.ones(w) / w
    v_s = np.convolve(padded, kernel, mode="same")[w:-w]
    s_s = np.concatenate([[0.0], np.cumsum(0.5 * (v_s[1:] + v_s[:-1]) * dt)])
    end = int(np.searchsorted(s_s, total))
    return v_s[: end + 1], s_s[: end + 1]


def _following_laps(
    laps: int, slip_fraction_laps: float, rng: np.random.Generator
) -> np.ndarray:
    """Per lap (the out-lap never), whether the rider follows another bike."""
    following = np.zeros(laps + 1, dtype=bool)
    # The order is drawn whatever the share, so a larger share adds following laps to
    # those of a smaller one.
    order = rng.permutation(laps)
    following[1 + order[: round(slip_fraction_laps * laps)]] = True
    return following


RIDER_RATE_HZ = 500.0  # the speed's integration and output rate


def drive_session(
    track: TrackSpec,
    laps: int,
    rng: np.random.Generator,
    veh: VehicleSpec | None = None,
    rate: float = RIDER_RATE_HZ,
    slip_fraction_laps: float = 0.2,
) -> RiderRun:
    """Drive an out-lap from the pit lane and ``laps`` flying laps.

    Parameters
    ----------
    track : TrackSpec
    laps : int
        Flying laps after the out-lap (lap 0).
    rng : numpy.random.Generator
    veh : VehicleSpec, optional
    rate : float — Hz, integration and output rate (>= 500)
    slip_fraction_laps : float
        Share of the flying laps spent following another bike.
    """
    veh = veh or VehicleSpec()
    ds = 0.5
    v_lim, brake_g, power_f = _speed_limits(track, laps, ds, rng, veh)
    L = track.length
    n_grid = v_lim.size
    lap_of_grid = np.minimum((np.arange(n_grid) * ds // L).astype(int), laps)
    env = _brake_envelope(v_lim, ds, brake_g[lap_of_grid], veh).tolist()

    dt = 1.0 / rate
    total = (laps + 1) * L
    vs = _integrate_speed(track, laps, veh, env, power_f.tolist(), ds, dt)
    v_s, s_s = _brake_onset(vs, veh, rate, total)
    acc = np.gradient(v_s, dt)
    brake_force = np.maximum(0.0, -veh.mass * acc - veh.resistance(v_s))
    slip = veh.slip_per_g * brake_force / (veh.mass * G)

    lap = np.minimum((s_s // L).astype(int), laps)
    lap_distance = s_s - lap * L
    crossings = [np.searchsorted(s_s, k * L) for k in range(1, laps + 1)]
    beacon_times = np.concatenate([[0.0], np.asarray(crossings, dtype=float) / rate])
    ends = track.corner_spans()[:, 1]
    next_corner = np.searchsorted(ends, lap_distance, side="right") % ends.size
    return RiderRun(
        rate=rate,
        v=v_s,
        s=s_s,
        a=acc,
        brake_force=brake_force,
        slip=slip,
        lap=lap,
        lap_distance=lap_distance,
        next_corner=next_corner,
        beacon_times=beacon_times,
        following=_following_laps(laps, slip_fraction_laps, rng),
    )
