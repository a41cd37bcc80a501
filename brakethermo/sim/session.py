"""One simulated session: what to simulate (:class:`SimConfig`), the run from the
planned ride to the logged channels and the truth (:func:`simulate`), the record of what
was simulated (the session's facts, the truth's parameters) and writing it.

The coupled ride and disc heating is :mod:`brakethermo.sim.ride_and_heat`; the logged
channels and the truth table are :mod:`brakethermo.sim.channels_and_truth`."""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa

from brakethermo.errors import ConfigError
from brakethermo.io.writers import SessionData
from brakethermo.sim.brake_chain import (
    OUT_FORCE,
    OUT_P,
    OUT_S,
    OUT_TORQUE,
    OUT_V,
    BrakeChain,
    draw_brake_chain,
)
from brakethermo.sim.channels_and_truth import (
    TRUTH_DT,
    _logged_channels,
    _truth_frame,
    _truth_table,
)
from brakethermo.sim.effects import Effects, make_effects, strengths_of
from brakethermo.sim.heat import HLaw, MuLaw
from brakethermo.sim.ride_and_heat import (
    KZ_REF_C,
    ThermalRun,
    _air,
    _context,
    _derive,
    _mu_per_sample,
    _realised_run,
    _ride_and_heat,
)
from brakethermo.sim.sensors import IRSensor, LoggerRates, patch_matrix
from brakethermo.sim.track import TrackSpec, load_track
from brakethermo.sim.vehicle import RIDER_RATE_HZ, RiderRun, VehicleSpec, drive_session
from brakethermo.sim.writer import write_session_and_truth
from brakethermo.thermal.disc import DiscSpec, load_disc


@dataclass(frozen=True)
class SimConfig:
    """What to simulate.

    Attributes
    ----------
    track : str — shipped track name or TOML path
    laps : int — flying laps after the out-lap
    effects : mapping of str to float, or tuple of str
        Strength of each named effect (0 = mild baseline, 1 = strong, up to 1.5); a
        bare name is strength 1; effects not named stay at 0. See
        :mod:`brakethermo.sim.effects`.
    sensor : {"multi", "single"} — four IR spots, or only ``disc_temp`` at spot 3
    seed : int
    disc : str — datasheet id or path
    nr, nz : int — truth grid, radial x half-thickness cells
    dt : float — s, thermal time step (divides 0.1 s)
    date : str — session date written in the facts
    model_errors : bool
        True: the true torque per bar, heat share, caliper nonlinearity and pressure
        sensor offset / gain differ from the datasheet by this seed's draw.
    bike_seed : int, optional
        Seed of the bike's hardware (true torque per bar, heat share, caliper
        nonlinearity, pressure-sensor gain): sessions with the same ``bike_seed`` share
        it, as a test and a race of one bike do. Default: drawn from ``seed``.
    cooling : float — dimensionless
        Factor on the disc's convection (1.2 = a duct with 20 % more cooling); the same
        seed replays the same drive, so a what-if prediction can be scored.
    ambient_c : float, optional — degC
        Air temperature instead of the track's drawn one (same drive); h follows the
        air's density, viscosity and conductivity (:func:`air_convection_factor`).
    """

    track: str = "mugello-like"
    laps: int = 5
    effects: Mapping[str, float] | tuple[str, ...] = ()
    sensor: str = "multi"
    seed: int = 0
    disc: str = "cc-340-8"
    nr: int = 36
    nz: int = 5
    dt: float = 0.05
    date: str = "2026-05-30"
    model_errors: bool = True
    bike_seed: int | None = None
    cooling: float = 1.0
    ambient_c: float | None = None

    @property
    def strengths(self) -> dict[str, float]:
        """Strength of every named effect (validated)."""
        return strengths_of(self.effects)


@dataclass(frozen=True)
class SimResult:
    """A simulated session: what the logger wrote and what really happened."""

    session: SessionData
    truth: pa.Table
    groups: dict[str, dict[str, str]] = field(default_factory=dict)


def check_air(cooling: float, ambient_c: float | None) -> None:
    """The simulator's range of its air settings (``simulate --set`` checks them before
    anything is simulated, as a usage error).

    Parameters
    ----------
    cooling : float — dimensionless
        Factor on the disc's convection.
    ambient_c : float or None — degC
        Air temperature (None: the track's).

    Raises
    ------
    ConfigError
        A value outside the range, or not finite.
    """
    if not (np.isfinite(cooling) and 0.0 < cooling <= 10.0):
        raise ConfigError(f"cooling must be a finite factor in (0, 10], got {cooling}")
    if ambient_c is not None and not (np.isfinite(ambient_c) and -40.0 <= ambient_c <= 60.0):
        raise ConfigError(f"ambient_c must be an air temperature in [-40, 60] degC,"
                          f" got {ambient_c}")


def _validate(cfg: SimConfig) -> None:
    if cfg.laps < 1:
        raise ConfigError(f"--laps must be at least 1, got {cfg.laps}")
    if cfg.sensor not in ("multi", "single"):
        raise ConfigError(f"--sensor must be 'multi' or 'single', got '{cfg.sensor}'")
    check_air(cfg.cooling, cfg.ambient_c)
    if not cfg.dt > 0 or abs(TRUTH_DT / cfg.dt - round(TRUTH_DT / cfg.dt)) > 1e-9:
        raise ConfigError(f"the thermal step must divide {TRUTH_DT} s, got {cfg.dt}")
    per = cfg.dt * RIDER_RATE_HZ  # the step is stepped on whole rider samples
    if abs(per - round(per)) > 1e-9:
        raise ConfigError(f"the thermal step must be a whole number of the rider's"
                          f" {1e3 / RIDER_RATE_HZ:g} ms samples, got {cfg.dt} s")


def _session_facts(cfg: SimConfig, veh: VehicleSpec, track: TrackSpec, disc: DiscSpec,
                   amb0: float, eff: Effects) -> dict[str, str]:
    """The session file's facts (what a team's logger would write beside the data)."""
    return {
        "vehicle": veh.name,
        "track": track.name,
        "date": cfg.date,
        "disc": disc.id,
        "ambient_temp_c": f"{amb0:.1f}",
        "seed": str(cfg.seed),
        "effects": ",".join(f"{n_}={eff.strength[n_]:g}" for n_ in eff.active) or "none",
        "laps": str(cfg.laps),
        "sensor": cfg.sensor,
        "simulator": "brakethermo.sim",
    }


def _run_params(cfg: SimConfig, track: TrackSpec, disc: DiscSpec, eff: Effects,
                chain: BrakeChain, h_law: HLaw, kz_ratio: float, mu_law: MuLaw,
                veh: VehicleSpec, amb0: float, ir: IRSensor, thermal: ThermalRun,
                ride: RiderRun) -> dict[str, object]:
    """The run's parameters, stored in the truth file's metadata."""
    strengths = eff.strength
    return {
        "track": track.name,
        "laps": cfg.laps,
        "seed": cfg.seed,
        "bike_seed": cfg.bike_seed,
        "sensor": cfg.sensor,
        "disc": disc.id,
        "date": cfg.date,
        "effects": list(eff.active),
        "effect_strengths": strengths,
        "effect_params": eff.params(),
        "effect_mild": dict(eff.mild),
        "model_errors": chain.as_dict(),
        "h_law": {
            **h_law.as_dict(),
            "knee_gain": eff.knee_gain,
            "knee_frac": eff.knee_frac,
            "knee_exponent": eff.knee_exponent,
            "v_ref_m_s": disc.v_ref,
            "formula": "(h0 + a*V^n) * (1 + knee_gain*(max(V - knee_frac*V_ref, 0)"
            " / ((1 - knee_frac)*V_ref))^knee_exponent), V in m/s",
        },
        "k_z_w_mk": eff.k_z,
        "k_z_ref_c": KZ_REF_C,
        "k_z_ratio": kz_ratio,
        "mu_law": {
            **asdict(mu_law),
            "formula": "1 - deficit + (deficit + gain) / (1 + exp(-(T - t_mid) / t_width))",
        },
        "grid": {"nr": cfg.nr, "nz": cfg.nz, "dt_s": cfg.dt},
        "vehicle": asdict(veh),
        "ambient_temp_c": amb0,
        "ir_sensor": ir.as_dict(),
        "logger_rates": LoggerRates().as_dict(),
        "energy_J": thermal.energy,
        "beacon_times_s": ride.beacon_times.tolist(),
        "following_laps": np.flatnonzero(ride.following).tolist(),
    }


def _bike_rng(cfg: SimConfig) -> np.random.Generator | None:
    """The generator of the bike's hardware draws when ``cfg.bike_seed`` is set, else None
    (the hardware is then drawn from the session's own stream)."""
    if cfg.bike_seed is None:
        return None
    return np.random.default_rng(np.random.SeedSequence(cfg.bike_seed).spawn(7)[6])


def simulate(cfg: SimConfig, timings: dict[str, float] | None = None) -> SimResult:
    """Simulate one session; see :class:`SimConfig`. Deterministic for a given config.

    ``timings``, when given, receives the wall time of each stage in seconds
    (``rider``, ``thermal``, ``sensors``, ``truth``); ``thermal`` includes the rider's
    braking, which is coupled to the disc through mu(T).
    """
    clock = _StageClock(timings)
    _validate(cfg)
    disc = load_disc(cfg.disc)
    track = load_track(cfg.track)
    rng_rider, rng_heat, rng_sens, rng_env, rng_eff, rng_chain = (
        np.random.default_rng(s) for s in np.random.SeedSequence(cfg.seed).spawn(6)
    )
    eff = make_effects(cfg.strengths, rng_eff)
    chain = draw_brake_chain(disc, rng_chain, cfg.model_errors, _bike_rng(cfg))
    veh = VehicleSpec()
    h_law = HLaw()

    plan = drive_session(track, cfg.laps, rng_rider, veh, slip_fraction_laps=eff.slip_fraction_laps)
    clock.lap("rider")
    rate = plan.rate
    per = round(cfg.dt * rate)  # rider samples per thermal step
    n_max = int(1.25 * plan.v.size / per) + 10  # steps; the realised run is a little longer
    n500 = n_max * per + 1
    t500 = np.arange(n500) / rate

    amb0, h_scale, t_amb500 = _air(cfg.cooling, cfg.ambient_c, track, h_law, rng_env, t500)
    ctx = _context(cfg.laps, track, disc, veh, chain, eff, h_law, plan, rng_env, rng_heat)

    run = _ride_and_heat(ctx, plan, cfg.dt, cfg.nr, cfg.nz, t_amb500, h_scale, n_max,
                         rng_chain)
    thermal = run.thermal
    clock.lap("thermal")

    n = run.n_steps * per + 1
    v, s_real, p_line, torque = (run.out[r, :n] for r in (OUT_V, OUT_S, OUT_P, OUT_TORQUE))
    t_amb500 = t_amb500[:n]
    d = _derive(ctx, v, s_real, torque)
    d["h"] = d["h"] * h_scale
    ride = _realised_run(plan, track, cfg.laps, rate, v, s_real, run.out[OUT_FORCE, :n], d)
    mu500 = _mu_per_sample(run, per)

    ir = IRSensor()
    W = patch_matrix(run.grid.r_centres, np.asarray(disc.spot_radii), ir.patch_radius)
    spots_face = thermal.t_face @ W.T
    channels = _logged_channels(cfg.sensor, disc, ride, eff, chain, ir, thermal.time, spots_face,
                                p_line, d["omega"], t_amb500, run.n_steps * cfg.dt, rng_sens)
    clock.lap("sensors")
    groups = (
        {"disc_temp": {f"spot{i}": f"disc_temp_spot{i}" for i in range(1, 5)}}
        if cfg.sensor == "multi"
        else {}
    )
    facts = _session_facts(cfg, veh, track, disc, amb0, eff)
    truth = _truth_frame(cfg.dt, thermal, ride, d, disc, spots_face, thermal.t_mid @ W.T, p_line,
                         torque, mu500, t_amb500, rate)
    params = _run_params(cfg, track, disc, eff, chain, h_law, run.kz_ratio, run.mu_law, veh,
                         amb0, ir, thermal, ride)
    table = _truth_table(truth, params)
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


def write_simulation(
    result: SimResult, out: str | Path, fmt: str | None = None, *, grouped: bool = False
) -> tuple[Path, Path]:
    """Write the session and ``<stem>.truth.parquet`` beside it; returns both paths.

    ``grouped`` writes the IR spots of a multi-spot MCAP session as one grouped topic
    ``disc_temp`` with fields ``spot1..spot4`` instead of one topic per spot.
    """
    groups = result.groups if grouped else None
    return write_session_and_truth(out, result.session, result.truth, fmt, groups=groups or None)
