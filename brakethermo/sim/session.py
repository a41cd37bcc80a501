"""One simulated session: rider, disc truth model, sensors; channels and truth out."""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa

from brakethermo.errors import ConfigError
from brakethermo.io.writers import Channel, SessionData, write_session, write_table_parquet
from brakethermo.sim.effects import Effects, make_effects
from brakethermo.sim.heat import HLaw, MuLaw, crown_overlap, crown_weights
from brakethermo.sim.sensors import (
    IRSensor,
    LoggerRates,
    finish_ir,
    first_order_lag,
    noisy,
    patch_matrix,
    pyrometer_reading,
    sample_clock,
)
from brakethermo.sim.track import TrackSpec, load_track
from brakethermo.sim.truth_disc import Boundary, TruthDisc, make_grid
from brakethermo.sim.vehicle import RiderRun, VehicleSpec, drive_session
from brakethermo.thermal.disc import BAR, DiscSpec, load_disc

KMH = 3.6  # km/h per m/s
TRUTH_DT = 0.1  # s, the OUTPUTS.md grid


@dataclass(frozen=True)
class SimConfig:
    """What to simulate.

    Attributes
    ----------
    track : str — shipped track name or TOML path
    laps : int — flying laps after the out-lap
    effects : tuple of str — effects at their strong level
    sensor : {"multi", "single"} — four IR spots, or only ``disc_temp`` at spot 3
    seed : int
    disc : str — datasheet id or path
    nr, nz : int — truth grid, radial x half-thickness cells
    dt : float — s, thermal time step (divides 0.1 s)
    date : str — session date written in the facts
    """

    track: str = "mugello-like"
    laps: int = 5
    effects: tuple[str, ...] = ()
    sensor: str = "multi"
    seed: int = 0
    disc: str = "cc-340-8"
    nr: int = 36
    nz: int = 5
    dt: float = 0.05
    date: str = "2026-05-30"


@dataclass(frozen=True)
class ThermalRun:
    """Disc truth on the thermal grid (``n_steps + 1`` instants, both faces alike).

    Attributes
    ----------
    time : ndarray — s
    t_face, t_mid : ndarray, shape (n, nr) — degC, face and mid-plane temperature
    t_mean : ndarray — degC, mass-averaged disc temperature
    energy : dict of str to float — J over the session, whole disc
    """

    time: np.ndarray
    t_face: np.ndarray
    t_mid: np.ndarray
    t_mean: np.ndarray
    energy: dict[str, float]


@dataclass(frozen=True)
class SimResult:
    """A simulated session: what the logger wrote and what really happened."""

    session: SessionData
    truth: pa.Table
    groups: dict[str, dict[str, str]] = field(default_factory=dict)


def _validate(cfg: SimConfig) -> None:
    if cfg.laps < 1:
        raise ConfigError(f"--laps must be at least 1, got {cfg.laps}")
    if cfg.sensor not in ("multi", "single"):
        raise ConfigError(f"--sensor must be 'multi' or 'single', got '{cfg.sensor}'")
    ratio = TRUTH_DT / cfg.dt
    if cfg.dt <= 0 or abs(ratio - round(ratio)) > 1e-9:
        raise ConfigError(f"the thermal step must divide {TRUTH_DT} s, got {cfg.dt}")


def _braking_events(brake: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Event index of every sample (-1 off the brakes) and each event's first sample."""
    on = brake > 0.0
    starts = np.flatnonzero(on & ~np.concatenate([[False], on[:-1]]))
    event = np.cumsum(on & ~np.concatenate([[False], on[:-1]])) - 1
    return np.where(on, event, -1), starts


def _step_mean(x: np.ndarray, per: int, n_steps: int) -> np.ndarray:
    """Mean of a 500 Hz signal over each thermal step (trapezoid, both ends included)."""
    body = x[: n_steps * per].reshape(n_steps, per, *x.shape[1:])
    ends = x[per : n_steps * per + 1 : per]
    return (body.sum(axis=1) - 0.5 * body[:, 0] + 0.5 * ends) / per


def run_thermal(
    model: TruthDisc,
    dt: float,
    q_face: np.ndarray,
    h_face: np.ndarray,
    h_law: HLaw,
    t_amb: np.ndarray,
) -> ThermalRun:
    """Integrate the truth disc from ambient through the given boundary histories.

    Parameters
    ----------
    model : TruthDisc
    dt : float — s
    q_face : ndarray, shape (n_steps, nr) — W/m^2 into each face
    h_face : ndarray, shape (n_steps,) — W/(m^2 K)
    h_law : HLaw — rim factors
    t_amb : ndarray, shape (n_steps + 1,) — degC
    """
    grid = model.grid
    T = np.full((grid.nr, grid.nz), float(t_amb[0]))
    H0 = model.enthalpy(T)
    t_face, t_rims = model.initial_surfaces(T)
    n = h_face.size
    faces = np.empty((n + 1, grid.nr))
    mids = np.empty((n + 1, grid.nr))
    means = np.empty(n + 1)
    faces[0], mids[0] = t_face, model.mid_plane(T)
    vol = model.volume
    means[0] = float(np.sum(T * vol) / vol.sum())
    flows = np.zeros(5)
    for k in range(n):
        bc = Boundary(
            q_face=q_face[k],
            h_face=float(h_face[k]),
            h_inner=h_law.inner_factor * h_face[k],
            h_outer=h_law.outer_factor * h_face[k],
            t_amb=float(t_amb[k + 1]),
        )
        T, t_face, t_rims, fl = model.step(T, dt, bc, t_face, t_rims)
        flows += fl
        faces[k + 1], mids[k + 1] = t_face, model.mid_plane(T)
        means[k + 1] = float(np.sum(T * vol) / vol.sum())
    # Both halves of the disc are alike: whole-disc energies are twice the half's.
    names = ("heat_in", "face_convection", "face_radiation", "rim_convection", "rim_radiation")
    energy = {n_: 2.0 * float(v) for n_, v in zip(names, flows, strict=True)}
    energy["stored"] = 2.0 * (model.enthalpy(T) - H0)
    energy["residual"] = energy["heat_in"] - sum(energy[n_] for n_ in names[1:]) - energy["stored"]
    return ThermalRun(
        time=np.arange(n + 1) * dt, t_face=faces, t_mid=mids, t_mean=means, energy=energy
    )


def simulate(cfg: SimConfig, timings: dict[str, float] | None = None) -> SimResult:
    """Simulate one session; see :class:`SimConfig`. Deterministic for a given config.

    ``timings``, when given, receives the wall time of each stage in seconds
    (``rider``, ``thermal``, ``sensors``, ``truth``).
    """
    clock = _StageClock(timings)
    _validate(cfg)
    disc = load_disc(cfg.disc)
    track = load_track(cfg.track)
    eff = make_effects(cfg.effects)
    veh = VehicleSpec()
    h_law = HLaw()
    rng_rider, rng_heat, rng_sens, rng_env = (
        np.random.default_rng(s) for s in np.random.SeedSequence(cfg.seed).spawn(4)
    )

    ride = drive_session(track, cfg.laps, rng_rider, veh, slip_fraction_laps=eff.slip_fraction_laps)
    clock.lap("rider")
    per = round(cfg.dt * ride.rate)  # rider samples per thermal step
    n_steps = (ride.v.size - 1) // per
    duration = n_steps * cfg.dt
    t500 = ride.time

    # Braking: the torque the deceleration needs, on this one front disc.
    f_disc = veh.front_share * ride.brake_force / 2.0  # N at the tyre contact
    torque = f_disc * disc.tyre_rolling_radius  # N m
    omega = ride.v * (1.0 - ride.slip) / disc.tyre_rolling_radius  # rad/s
    q_brake = disc.heat_share * torque * omega  # W into the disc

    # Pad crowns: weights per braking event, per corner.
    event, starts = _braking_events(ride.brake_force)
    w_event = crown_weights(
        ride.next_corner[starts],
        len(track.corners),
        eff.crown_base_concentration,
        eff.crown_event_concentration,
        rng_heat,
    )
    w500 = np.where(event[:, None] >= 0, w_event[np.maximum(event, 0)], np.nan)
    qw = _step_mean(np.nan_to_num(w500) * q_brake[:, None], per, n_steps)  # W per crown
    crown_edges = disc.crown_edges
    crown_area = np.pi * np.diff(crown_edges**2)
    grid = make_grid(disc.r_int, disc.r_est, disc.thickness, cfg.nr, cfg.nz)
    overlap = crown_overlap(grid.r_edges, crown_edges)
    q_face = (0.5 * qw / crown_area) @ overlap.T  # W/m^2 per face

    # Convection: true h(V), knee, slipstream while following on straights.
    amb0 = track.ambient_c + float(rng_env.normal(0.0, 2.0))
    phase = float(rng_env.uniform(0, 2 * np.pi))
    t_amb500 = amb0 + 0.4 * np.sin(2 * np.pi * t500 / 1800.0 + phase)
    slip_red = rng_env.uniform(*eff.slip_reduction, size=cfg.laps + 1)
    seg_kind = _on_straight(track, ride.lap_distance)
    slip_on = ride.following[ride.lap] & seg_kind & (ride.brake_force <= 0) & (ride.v * KMH > 150.0)
    h500 = h_law.face(ride.v, disc.v_ref, eff.knee_gain) * np.where(
        slip_on, 1.0 - slip_red[ride.lap], 1.0
    )
    h_step = _step_mean(h500, per, n_steps)
    t_amb_steps = t_amb500[::per][: n_steps + 1]

    model = TruthDisc(
        grid, disc.density, disc.specific_heat, disc.conductivity, eff.kz_ratio, disc.emissivity
    )
    thermal = run_thermal(model, cfg.dt, q_face, h_step, h_law, t_amb_steps)
    clock.lap("thermal")

    # Friction: mu follows the rubbed-face temperature; the rider asks for the torque,
    # so the line pressure carries mu: p = torque / (torque_per_Pa * mu/mu_nom).
    pad = (grid.r_centres >= disc.pad_r1) & (grid.r_centres <= disc.pad_r4)
    area = grid.ring_areas
    t_rub = thermal.t_face[:, pad] @ area[pad] / area[pad].sum()
    mu = MuLaw(eff.mu_amplitude)
    mu500 = mu.ratio(np.interp(t500, thermal.time, t_rub))
    p500 = torque / (disc.torque_per_pa * mu500)  # Pa

    spot_r = np.asarray(disc.spot_radii)
    ir = IRSensor()
    W = patch_matrix(grid.r_centres, spot_r, ir.patch_radius)
    spots_face = thermal.t_face @ W.T
    spots_mid = thermal.t_mid @ W.T

    channels = _logged_channels(
        cfg,
        disc,
        ride,
        eff,
        ir,
        thermal.time,
        spots_face,
        p500,
        omega,
        t_amb500,
        duration,
        rng_sens,
    )
    clock.lap("sensors")
    groups = (
        {"disc_temp": {f"spot{i}": f"disc_temp_spot{i}" for i in range(1, 5)}}
        if cfg.sensor == "multi"
        else {}
    )
    facts = {
        "vehicle": veh.name,
        "track": track.name,
        "date": cfg.date,
        "disc": disc.id,
        "ambient_temp_c": f"{amb0:.1f}",
        "seed": str(cfg.seed),
        "effects": ",".join(eff.strong) or "none",
        "laps": str(cfg.laps),
        "sensor": cfg.sensor,
        "simulator": "brakethermo.sim",
    }

    # Truth on the 10 Hz grid.
    stride = round(TRUTH_DT / cfg.dt)
    g = slice(0, None, stride)
    t_grid = thermal.time[g]
    i500 = np.round(t_grid * ride.rate).astype(int)
    lap_grid = np.searchsorted(ride.beacon_times, t_grid + 1e-9, side="right") - 1
    truth = {
        "time": t_grid,
        "lap": lap_grid.astype(np.int64),
        "speed": ride.v[i500] * KMH,
    }
    for i in range(4):
        truth[f"spot{i + 1}"] = spots_face[g, i]
    truth["contact_avg"] = spots_face[g, 1:].mean(axis=1)
    for i in range(4):
        truth[f"spot{i + 1}_mid"] = spots_mid[g, i]
    truth["disc_mean"] = thermal.t_mean[g]
    truth["h"] = h500[i500]
    truth["q_brake"] = q_brake[i500]
    truth["q_brake_nominal"] = disc.braking_power(p500, omega)[i500]
    truth["mu_ratio"] = mu500[i500]
    for c in range(3):
        truth[f"w{c + 1}"] = w500[i500, c]
    truth["slipstream"] = slip_on[i500]
    truth["ambient"] = t_amb500[i500]

    params = {
        "track": track.name,
        "laps": cfg.laps,
        "seed": cfg.seed,
        "sensor": cfg.sensor,
        "disc": disc.id,
        "date": cfg.date,
        "effects": list(eff.strong),
        "effect_levels": eff.levels(),
        "effect_params": eff.as_dict(),
        "h_law": {
            **h_law.as_dict(),
            "v_ref_m_s": disc.v_ref,
            "formula": "(h0 + a*V^n) * (1 + knee_gain*max(V - knee_frac*V_ref, 0)^2"
            " / ((1 - knee_frac)*V_ref)^2), V in m/s",
        },
        "k_z_ratio": eff.kz_ratio,
        "mu_law": asdict(mu),
        "grid": {"nr": cfg.nr, "nz": cfg.nz, "dt_s": cfg.dt},
        "vehicle": asdict(veh),
        "ambient_temp_c": amb0,
        "ir_sensor": ir.as_dict(),
        "logger_rates": LoggerRates().as_dict(),
        "energy_J": thermal.energy,
        "beacon_times_s": ride.beacon_times.tolist(),
        "following_laps": np.flatnonzero(ride.following).tolist(),
    }
    df = pd.DataFrame(truth)
    # Truth values in float32 (0.1 mK at 1000 degC) keep the shipped files small.
    floats = [c for c in df.columns if c != "time" and df[c].dtype == np.float64]
    df[floats] = df[floats].astype(np.float32)
    table = pa.Table.from_pandas(df, preserve_index=False)
    table = table.replace_schema_metadata({"brakethermo_truth": json.dumps(params, sort_keys=True)})
    clock.lap("truth")
    return SimResult(
        session=SessionData(channels=channels, facts=facts), truth=table, groups=groups
    )


class _StageClock:
    """Records the wall time between successive :meth:`lap` calls into a dict."""

    def __init__(self, sink: dict[str, float] | None):
        self.sink = sink
        self.t = time.perf_counter()

    def lap(self, stage: str) -> None:
        now = time.perf_counter()
        if self.sink is not None:
            self.sink[stage] = now - self.t
        self.t = now


def _on_straight(track: TrackSpec, lap_distance: np.ndarray) -> np.ndarray:
    ends = np.cumsum([s.length for s in track.segments])
    seg = np.minimum(np.searchsorted(ends, lap_distance, side="right"), ends.size - 1)
    return np.array([s.kind == "straight" for s in track.segments])[seg]


def _logged_channels(
    cfg: SimConfig,
    disc: DiscSpec,
    ride: RiderRun,
    eff: Effects,
    ir: IRSensor,
    t_thermal: np.ndarray,
    spots_face: np.ndarray,
    p500: np.ndarray,
    omega: np.ndarray,
    t_amb500: np.ndarray,
    duration: float,
    rng: np.random.Generator,
) -> tuple[Channel, ...]:
    rates = LoggerRates()
    t500 = ride.time

    def clock(rate: float) -> np.ndarray:
        return sample_clock(rate, duration, rates.jitter_s, rng)

    out: list[Channel] = []
    # One 50 Hz logger task samples speed, wheel speed and distance together.
    ts = clock(rates.speed)
    out.append(
        Channel("speed", "km/h", ts, noisy(np.interp(ts, t500, ride.v) * KMH, 0.15, 0.01, rng), 2)
    )
    out.append(
        Channel(
            "wheel_speed_front", "rad/s", ts, noisy(np.interp(ts, t500, omega), 0.05, 0.01, rng), 2
        )
    )
    out.append(
        Channel(
            "distance",
            "m",
            ts,
            np.round(ride.lap_distance[np.floor(ts * ride.rate).astype(int)], 1),
            1,
        )
    )
    ts = clock(rates.pressure)
    p_bar = np.interp(ts, t500, p500) / BAR
    p_bar = np.maximum(
        noisy(p_bar, 0.01, 0.01, rng) + 0.005 * p_bar * rng.normal(size=ts.size), 0.0
    )
    out.append(Channel("brake_pressure_front", "bar", ts, np.round(p_bar, 2), 2))

    # IR: the patch-averaged face seen through the sensor's lag and emissivity setting.
    lagged = first_order_lag(spots_face, t_thermal[1] - t_thermal[0], eff.ir_lag_s)
    shown = pyrometer_reading(lagged, disc.emissivity, eff.emissivity_set)
    ts = clock(ir.rate)
    spots = [finish_ir(np.interp(ts, t_thermal, shown[:, i]), ir, rng) for i in range(4)]
    if cfg.sensor == "multi":
        out += [Channel(f"disc_temp_spot{i + 1}", "degC", ts, spots[i], 1) for i in range(4)]
    else:
        out.append(Channel("disc_temp", "degC", ts, spots[2], 1))

    ts = clock(rates.ambient)
    out.append(
        Channel("ambient_temp", "degC", ts, noisy(np.interp(ts, t500, t_amb500), 0.05, 0.1, rng), 1)
    )
    beacons = ride.beacon_times
    out.append(
        Channel("lap_beacon", "", np.round(beacons, 6), np.arange(beacons.size, dtype=float), 0)
    )
    return tuple(out)


def write_simulation(
    result: SimResult, out: str | Path, fmt: str | None = None, *, grouped: bool = False
) -> tuple[Path, Path]:
    """Write the session and ``<stem>.truth.parquet`` beside it; returns both paths.

    ``grouped`` writes the IR spots of a multi-spot MCAP session as one grouped topic
    ``disc_temp`` with fields ``spot1..spot4`` instead of one topic per spot.
    """
    out = Path(out)
    groups = result.groups if grouped else None
    session_path = write_session(out, result.session, fmt, groups=groups or None)
    truth_path = out.with_name(f"{out.stem}.truth.parquet")
    write_table_parquet(truth_path, result.truth)
    return session_path, truth_path
