"""One simulated session: planned ride, rider and brake chain coupled to the disc truth
model through mu(T), sensors; channels and truth out."""

from __future__ import annotations

import json
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
from numba import njit

from brakethermo.errors import ConfigError
from brakethermo.io.writers import Channel, SessionData
from brakethermo.sim.brake_chain import (
    OUT_FORCE,
    OUT_P,
    OUT_S,
    OUT_TORQUE,
    OUT_V,
    BrakeChain,
    S,
    advance,
    chain_params,
    draw_brake_chain,
    hand_modulation,
)
from brakethermo.sim.effects import Effects, make_effects, strengths_of
from brakethermo.sim.heat import HLaw, MuLaw, air_convection_factor, crown_overlap, crown_weights
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
from brakethermo.sim.truth_disc import Boundary, DiscGrid, TruthDisc, make_grid
from brakethermo.sim.vehicle import G, RiderRun, VehicleSpec, drive_session
from brakethermo.sim.writer import write_session_and_truth
from brakethermo.thermal.disc import BAR, DiscSpec, load_disc

KMH = 3.6  # km/h per m/s
TRUTH_DT = 0.1  # s, the OUTPUTS.md grid
KZ_REF_C = 400.0  # degC, temperature at which the truth k_z is stated


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
    if not (np.isfinite(cfg.cooling) and 0.0 < cfg.cooling <= 10.0):
        raise ConfigError(f"cooling must be a finite factor in (0, 10], got {cfg.cooling}")
    if cfg.ambient_c is not None and not (np.isfinite(cfg.ambient_c)
                                          and -40.0 <= cfg.ambient_c <= 60.0):
        raise ConfigError(f"ambient_c must be an air temperature in [-40, 60] degC,"
                          f" got {cfg.ambient_c}")
    ratio = TRUTH_DT / cfg.dt
    if cfg.dt <= 0 or abs(ratio - round(ratio)) > 1e-9:
        raise ConfigError(f"the thermal step must divide {TRUTH_DT} s, got {cfg.dt}")


class ThermalStepper:
    """The truth disc advanced one thermal step at a time from ambient, recording the
    face, mid-plane and mean temperatures and the energy flows (whole disc)."""

    def __init__(self, model: TruthDisc, h_law: HLaw, t_amb0: float, n_max: int):
        self.model = model
        self.h_law = h_law
        grid = model.grid
        self.T = np.full((grid.nr, grid.nz), float(t_amb0))
        self.H0 = model.enthalpy(self.T)
        self.t_face, self.t_rims = model.initial_surfaces(self.T)
        self.faces = np.empty((n_max + 1, grid.nr))
        self.mids = np.empty((n_max + 1, grid.nr))
        self.means = np.empty(n_max + 1)
        self.vol = model.volume
        self.vol_total = self.vol.sum()
        self.k = 0
        self._record()
        self.flows = np.zeros(5)

    def _record(self) -> None:
        self.faces[self.k] = self.t_face
        self.mids[self.k] = self.model.mid_plane(self.T)
        self.means[self.k] = float(np.sum(self.T * self.vol) / self.vol_total)

    def step(self, dt: float, q_face: np.ndarray, h_face: float, t_amb: float) -> None:
        """One step with face flux ``q_face`` (W/m^2 per column), face h (W/(m^2 K))."""
        bc = Boundary(
            q_face=q_face,
            h_face=h_face,
            h_inner=self.h_law.inner_factor * h_face,
            h_outer=self.h_law.outer_factor * h_face,
            t_amb=t_amb,
        )
        self.T, self.t_face, self.t_rims, fl = self.model.step(
            self.T, dt, bc, self.t_face, self.t_rims
        )
        self.flows += fl
        self.k += 1
        self._record()

    def result(self, dt: float) -> ThermalRun:
        n = self.k
        # Both halves of the disc are alike: whole-disc energies are twice the half's.
        names = ("heat_in", "face_convection", "face_radiation", "rim_convection", "rim_radiation")
        energy = {n_: 2.0 * float(v) for n_, v in zip(names, self.flows, strict=True)}
        energy["stored"] = 2.0 * (self.model.enthalpy(self.T) - self.H0)
        energy["residual"] = (
            energy["heat_in"] - sum(energy[n_] for n_ in names[1:]) - energy["stored"]
        )
        return ThermalRun(
            time=np.arange(n + 1) * dt,
            t_face=self.faces[: n + 1],
            t_mid=self.mids[: n + 1],
            t_mean=self.means[: n + 1],
            energy=energy,
        )


@dataclass
class _Context:
    """What the per-sample derived quantities need (one run)."""

    track: TrackSpec
    laps: int
    disc: DiscSpec
    veh: VehicleSpec
    chain: BrakeChain
    eff: Effects
    h_law: HLaw
    following: np.ndarray
    slip_red: np.ndarray  # (laps + 1, n_segments) relative h reduction while following
    w_event: np.ndarray  # (laps + 1, n_corners, 3) crown weights per braking
    seg_ends: np.ndarray
    seg_straight: np.ndarray
    corner_ends: np.ndarray


def _derive(ctx: _Context, v: np.ndarray, s: np.ndarray, torque: np.ndarray) -> dict:
    """Per-sample quantities of the realised run: wheel speed, heat, crowns, h."""
    L = ctx.track.length
    lap = np.minimum((s // L).astype(np.int64), ctx.laps)
    lap_distance = s - lap * L
    f_front = 2.0 * torque / ctx.disc.tyre_rolling_radius
    slip = ctx.veh.slip_per_g * f_front / (ctx.veh.mass * G)
    omega = v * (1.0 - slip) / ctx.disc.tyre_rolling_radius
    q = ctx.chain.heat_share * torque * omega  # W into this disc
    corner = np.searchsorted(ctx.corner_ends, lap_distance, side="right") % ctx.corner_ends.size
    on = torque > 0.0
    w = np.where(on[:, None], ctx.w_event[lap, corner], np.nan)
    seg = np.minimum(
        np.searchsorted(ctx.seg_ends, lap_distance, side="right"), ctx.seg_ends.size - 1
    )
    slip_on = ctx.following[lap] & ctx.seg_straight[seg] & ~on & (v * KMH > 150.0)
    e = ctx.eff
    h = ctx.h_law.face(v, ctx.disc.v_ref, e.knee_gain, e.knee_frac, e.knee_exponent)
    h = h * np.where(slip_on, 1.0 - ctx.slip_red[lap, seg], 1.0)
    return dict(
        lap=lap,
        lap_distance=lap_distance,
        slip=slip,
        omega=omega,
        q=q,
        w=w,
        slip_on=slip_on,
        h=h,
        corner=corner,
        f_front=f_front,
    )


@njit(cache=True)
def _step_inputs(
    v: np.ndarray,
    s: np.ndarray,
    torque: np.ndarray,
    geo: np.ndarray,
    corner_ends: np.ndarray,
    seg_ends: np.ndarray,
    seg_straight: np.ndarray,
    following: np.ndarray,
    slip_red: np.ndarray,
    w_event: np.ndarray,
) -> tuple[np.ndarray, float]:  # pragma: no cover - compiled
    """Trapezoid means over one thermal step of the heat per crown (W) and the face h,
    the same per-sample quantities as :func:`_derive` (a test holds them equal)."""
    L, laps, R, slip_per_g, mg, share = geo[0], int(geo[1]), geo[2], geo[3], geo[4], geo[5]
    h0, ha, hn, v_ref, gain, frac, expo = geo[6], geo[7], geo[8], geo[9], geo[10], geo[11], geo[12]
    n = v.size
    qw = np.zeros(3)
    h_sum = 0.0
    v_k = frac * v_ref
    for j in range(n):
        wt = 0.5 if (j == 0 or j == n - 1) else 1.0
        lap = min(int(s[j] // L), laps)
        dist = s[j] - lap * L
        vj = max(v[j], 0.0)
        x = max(vj - v_k, 0.0) / (v_ref - v_k)
        h = (h0 + ha * vj**hn) * (1.0 + gain * x**expo)
        seg = min(np.searchsorted(seg_ends, dist, side="right"), seg_ends.size - 1)
        if torque[j] > 0.0:
            corner = np.searchsorted(corner_ends, dist, side="right") % corner_ends.size
            slip = slip_per_g * 2.0 * torque[j] / R / mg
            q = share * torque[j] * v[j] * (1.0 - slip) / R
            for c in range(3):
                qw[c] += wt * q * w_event[lap, corner, c]
        elif following[lap] and seg_straight[seg] and v[j] * 3.6 > 150.0:
            h *= 1.0 - slip_red[lap, seg]
        h_sum += wt * h
    return qw / (n - 1), h_sum / (n - 1)


def _geo(ctx: _Context) -> np.ndarray:
    """Scalar parameters of :func:`_step_inputs`."""
    e, hl = ctx.eff, ctx.h_law
    return np.array(
        [
            ctx.track.length,
            ctx.laps,
            ctx.disc.tyre_rolling_radius,
            ctx.veh.slip_per_g,
            ctx.veh.mass * G,
            ctx.chain.heat_share,
            hl.h0,
            hl.a,
            hl.n,
            ctx.disc.v_ref,
            e.knee_gain,
            e.knee_frac,
            e.knee_exponent,
        ]
    )


def _truth_frame(cfg: SimConfig, thermal: ThermalRun, ride: RiderRun, d: dict[str, np.ndarray],
                 disc: DiscSpec, spots_face: np.ndarray, spots_mid: np.ndarray,
                 p_line: np.ndarray, torque: np.ndarray, mu500: np.ndarray,
                 t_amb500: np.ndarray, rate: float) -> pd.DataFrame:
    """The truth on the 10 Hz grid (float32 but for the time)."""
    stride = round(TRUTH_DT / cfg.dt)
    g = slice(0, None, stride)
    t_grid = thermal.time[g]
    i500 = np.round(t_grid * rate).astype(int)
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
    truth["h"] = d["h"][i500]
    truth["q_brake"] = d["q"][i500]
    truth["q_brake_nominal"] = disc.braking_power(p_line * BAR, d["omega"])[i500]
    truth["mu_ratio"] = mu500[i500]
    truth["p_line_bar"] = p_line[i500]
    truth["brake_torque"] = torque[i500]
    for c_ in range(3):
        truth[f"w{c_ + 1}"] = d["w"][i500, c_]
    truth["slipstream"] = d["slip_on"][i500]
    truth["ambient"] = t_amb500[i500]

    df = pd.DataFrame(truth)
    # Truth values in float32 (0.1 mK at 1000 degC) keep the shipped files small.
    floats = [c for c in df.columns if c != "time" and df[c].dtype == np.float64]
    df[floats] = df[floats].astype(np.float32)
    return df


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


@dataclass(frozen=True)
class _Coupled:
    """The ride and the disc heated by it (:func:`_ride_and_heat`)."""

    thermal: ThermalRun
    out: np.ndarray  # (5, n500) chain outputs at the rider rate
    mu_step: np.ndarray  # mu(T)/mu_nom per thermal step
    n_steps: int
    grid: DiscGrid
    kz_ratio: float
    mu_law: MuLaw


def _ride_and_heat(cfg: SimConfig, ctx: _Context, plan: RiderRun, t_amb500: np.ndarray,
                   h_scale: float, n_max: int, rng_chain: np.random.Generator) -> _Coupled:
    """Rider, brake chain and disc, coupled through mu(T) of the rubbed face: mu is
    frozen over one thermal step at the face temperature of its start."""
    disc, eff = ctx.disc, ctx.eff
    rate = plan.rate
    per = round(cfg.dt * rate)
    n500 = n_max * per + 1
    grid = make_grid(disc.r_int, disc.r_est, disc.thickness, cfg.nr, cfg.nz)
    crown_area = np.pi * np.diff(disc.crown_edges**2)
    overlap = crown_overlap(grid.r_edges, disc.crown_edges)
    kz_ratio = eff.k_z / float(disc.conductivity(KZ_REF_C))
    model = TruthDisc(
        grid, disc.density, disc.specific_heat, disc.conductivity, kz_ratio, disc.emissivity
    )
    stepper = ThermalStepper(model, ctx.h_law, float(t_amb500[0]), n_max)
    mu_law = MuLaw(eff.mu_deficit, eff.mu_gain, eff.mu_t_mid, eff.mu_t_width)
    pad = (grid.r_centres >= disc.pad_r1) & (grid.r_centres <= disc.pad_r4)
    pad_area = grid.ring_areas[pad]

    prm = chain_params(ctx.chain, ctx.veh, disc, rate)
    mod = hand_modulation(ctx.chain, n500, rate, rng_chain)
    plan_s, plan_v, plan_a = plan.s, plan.v, plan.a
    plan_f = plan.brake_force
    out = np.zeros((5, n500))
    state = np.array([plan_v[0], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    out[OUT_V, 0] = plan_v[0]
    mu_step = np.empty(n_max)
    total = (cfg.laps + 1) * ctx.track.length
    n_steps = n_max
    kernel_args = (
        _geo(ctx),
        ctx.corner_ends,
        ctx.seg_ends,
        ctx.seg_straight,
        ctx.following,
        ctx.slip_red,
        ctx.w_event,
    )
    for k in range(n_max):
        j0 = k * per
        mu = float(mu_law.ratio(stepper.t_face[pad] @ pad_area / pad_area.sum()))
        mu_step[k] = mu
        advance(state, prm, plan_s, plan_v, plan_a, plan_f, mod, mu, j0, per, out)
        c = slice(j0, j0 + per + 1)
        qw, h_step = _step_inputs(out[OUT_V, c], out[OUT_S, c], out[OUT_TORQUE, c], *kernel_args)
        q_face = (0.5 * qw / crown_area) @ overlap.T  # W/m^2 per face
        stepper.step(cfg.dt, q_face, h_step * h_scale, float(t_amb500[j0 + per]))
        if state[S] >= total:
            n_steps = k + 1
            break
    return _Coupled(stepper.result(cfg.dt), out, mu_step, n_steps, grid, kz_ratio, mu_law)


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


def _bike_rng(cfg: SimConfig) -> np.random.Generator | None:
    """The generator of the bike's hardware draws when ``cfg.bike_seed`` is set, else None
    (the hardware is then drawn from the session's own stream)."""
    if cfg.bike_seed is None:
        return None
    return np.random.default_rng(np.random.SeedSequence(cfg.bike_seed).spawn(7)[6])


def _air(cfg: SimConfig, track: TrackSpec, h_law: HLaw, rng_env: np.random.Generator,
         t500: np.ndarray) -> tuple[float, float, np.ndarray]:
    """The day's air: mean ambient temperature (degC), the factor on the face h and the
    ambient temperature at every rider sample ``t500`` (s), degC."""
    amb0 = track.ambient_c + float(rng_env.normal(0.0, 2.0))
    h_scale = cfg.cooling
    if cfg.ambient_c is not None:  # the same draws, another day's air
        h_scale *= air_convection_factor(cfg.ambient_c, amb0, h_law.n)
        amb0 = cfg.ambient_c
    phase = float(rng_env.uniform(0, 2 * np.pi))
    t_amb500 = amb0 + 0.4 * np.sin(2 * np.pi * t500 / 1800.0 + phase)
    return amb0, h_scale, t_amb500


def _context(cfg: SimConfig, track: TrackSpec, disc: DiscSpec, veh: VehicleSpec,
             chain: BrakeChain, eff: Effects, h_law: HLaw, plan: RiderRun,
             rng_env: np.random.Generator, rng_heat: np.random.Generator) -> _Context:
    """The run's context: slipstream reductions per lap and segment and crown weights per
    braking drawn, the track's segments and corners laid out."""
    segs = track.segments
    slip_red = eff.slip_reduction * rng_env.uniform(0.8, 1.2, size=(cfg.laps + 1, len(segs)))
    return _Context(
        track=track,
        laps=cfg.laps,
        disc=disc,
        veh=veh,
        chain=chain,
        eff=eff,
        h_law=h_law,
        following=plan.following,
        slip_red=slip_red,
        w_event=crown_weights(
            cfg.laps + 1, len(track.corners), eff.crown_sigma_base, eff.crown_sigma_event,
            rng_heat,
        ),
        seg_ends=np.cumsum([sg.length for sg in segs]),
        seg_straight=np.array([sg.kind == "straight" for sg in segs]),
        corner_ends=track.corner_spans()[:, 1],
    )


def _mu_per_sample(run: _Coupled, per: int) -> np.ndarray:
    """mu(T)/mu_nom at every rider sample of the realised run (``per`` samples a step)."""
    mu500 = np.repeat(run.mu_step[:run.n_steps], per)
    return np.append(mu500, mu500[-1])


def _truth_table(truth: pd.DataFrame, params: dict[str, object]) -> pa.Table:
    """The truth frame as an Arrow table with the run's parameters in its metadata."""
    table = pa.Table.from_pandas(truth, preserve_index=False)
    return table.replace_schema_metadata({"brakethermo_truth": json.dumps(params, sort_keys=True)})


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

    amb0, h_scale, t_amb500 = _air(cfg, track, h_law, rng_env, t500)
    ctx = _context(cfg, track, disc, veh, chain, eff, h_law, plan, rng_env, rng_heat)

    run = _ride_and_heat(cfg, ctx, plan, t_amb500, h_scale, n_max, rng_chain)
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
    channels = _logged_channels(cfg, disc, ride, eff, chain, ir, thermal.time, spots_face,
                                p_line, d["omega"], t_amb500, run.n_steps * cfg.dt, rng_sens)
    clock.lap("sensors")
    groups = (
        {"disc_temp": {f"spot{i}": f"disc_temp_spot{i}" for i in range(1, 5)}}
        if cfg.sensor == "multi"
        else {}
    )
    facts = _session_facts(cfg, veh, track, disc, amb0, eff)
    truth = _truth_frame(cfg, thermal, ride, d, disc, spots_face, thermal.t_mid @ W.T, p_line,
                         torque, mu500, t_amb500, rate)
    params = _run_params(cfg, track, disc, eff, chain, h_law, run.kz_ratio, run.mu_law, veh,
                         amb0, ir, thermal, ride)
    table = _truth_table(truth, params)
    clock.lap("truth")
    return SimResult(
        session=SessionData(channels=channels, facts=facts), truth=table, groups=groups
    )


def _realised_run(
    plan: RiderRun,
    track: TrackSpec,
    laps: int,
    rate: float,
    v: np.ndarray,
    s: np.ndarray,
    brake_force: np.ndarray,
    d: dict,
) -> RiderRun:
    """The run as it happened (the plan bent by the brake chain)."""
    L = track.length
    crossings = np.searchsorted(s, np.arange(1, laps + 1) * L)
    return RiderRun(
        rate=rate,
        v=v,
        s=s,
        a=np.gradient(v, 1.0 / rate),
        brake_force=brake_force,
        slip=d["slip"],
        lap=d["lap"],
        lap_distance=d["lap_distance"],
        next_corner=d["corner"],
        beacon_times=np.concatenate([[0.0], crossings / rate]),
        following=plan.following,
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


def _logged_channels(
    cfg: SimConfig,
    disc: DiscSpec,
    ride: RiderRun,
    eff: Effects,
    chain: BrakeChain,
    ir: IRSensor,
    t_thermal: np.ndarray,
    spots_face: np.ndarray,
    p_line_bar: np.ndarray,
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
    p_bar = chain.logged_pressure_bar(np.interp(ts, t500, p_line_bar), rng)
    out.append(Channel("brake_pressure_front", "bar", ts, np.round(p_bar, 2), 2))

    # IR: the patch-averaged face seen through the sensor's lag, lens and emissivity setting.
    lagged = first_order_lag(spots_face, t_thermal[1] - t_thermal[0], eff.ir_lag_s)
    shown = pyrometer_reading(lagged, disc.emissivity * eff.lens_transmission, eff.emissivity_set)
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
    groups = result.groups if grouped else None
    return write_session_and_truth(out, result.session, result.truth, fmt, groups=groups or None)
