"""The ride and the disc heated by it, stepped together.

The rider's plan is ridden through the brake chain while the truth disc is advanced one
thermal step at a time: the braking torque heats the disc, and the friction the chain
sees follows mu(T) of the rubbed face, frozen over each step at the temperature of its
start. This module owns that loop (:func:`_ride_and_heat`), what it needs (the day's air,
the run's context of slipstream reductions and crown weights, the compiled per-step
means of heat and h) and what comes out of it: the disc's temperatures and energies on
the thermal grid (:class:`ThermalRun`), and the run as it happened with its per-sample
wheel speed, heat, crown weights and h (:func:`_realised_run`, :func:`_derive`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from brakethermo.sim.brake_chain import (
    OUT_S,
    OUT_TORQUE,
    OUT_V,
    BrakeChain,
    S,
    advance,
    chain_params,
    hand_modulation,
)
from brakethermo.sim.effects import Effects
from brakethermo.sim.heat import HLaw, MuLaw, air_convection_factor, crown_overlap, crown_weights
from brakethermo.sim.track import TrackSpec
from brakethermo.sim.truth_disc import Boundary, DiscGrid, TruthDisc, make_grid
from brakethermo.sim.vehicle import G, RiderRun, VehicleSpec
from brakethermo.thermal.disc import KZ_REF_C, DiscSpec  # KZ_REF_C: the one every k_z uses

KMH = 3.6  # km/h per m/s


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


def _air(cooling: float, ambient_c: float | None, track: TrackSpec, h_law: HLaw,
         rng_env: np.random.Generator, t500: np.ndarray) -> tuple[float, float, np.ndarray]:
    """The day's air: mean ambient temperature (degC), the factor on the face h and the
    ambient temperature at every rider sample ``t500`` (s), degC. ``cooling`` and
    ``ambient_c`` are :class:`~brakethermo.sim.session.SimConfig`'s."""
    amb0 = track.ambient_c + float(rng_env.normal(0.0, 2.0))
    h_scale = cooling
    if ambient_c is not None:  # the same draws, another day's air
        h_scale *= air_convection_factor(ambient_c, amb0, h_law.n)
        amb0 = ambient_c
    phase = float(rng_env.uniform(0, 2 * np.pi))
    t_amb500 = amb0 + 0.4 * np.sin(2 * np.pi * t500 / 1800.0 + phase)
    return amb0, h_scale, t_amb500


def _context(laps: int, track: TrackSpec, disc: DiscSpec, veh: VehicleSpec,
             chain: BrakeChain, eff: Effects, h_law: HLaw, plan: RiderRun,
             rng_env: np.random.Generator, rng_heat: np.random.Generator) -> _Context:
    """The run's context: slipstream reductions per lap and segment and crown weights per
    braking drawn, the track's segments and corners laid out."""
    segs = track.segments
    slip_red = eff.slip_reduction * rng_env.uniform(0.8, 1.2, size=(laps + 1, len(segs)))
    return _Context(
        track=track,
        laps=laps,
        disc=disc,
        veh=veh,
        chain=chain,
        eff=eff,
        h_law=h_law,
        following=plan.following,
        slip_red=slip_red,
        w_event=crown_weights(
            laps + 1, len(track.corners), eff.crown_sigma_base, eff.crown_sigma_event,
            rng_heat,
        ),
        seg_ends=np.cumsum([sg.length for sg in segs]),
        seg_straight=np.array([sg.kind == "straight" for sg in segs]),
        corner_ends=track.corner_spans()[:, 1],
    )


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


def _ride_and_heat(ctx: _Context, plan: RiderRun, dt: float, nr: int, nz: int,
                   t_amb500: np.ndarray, h_scale: float, n_max: int,
                   rng_chain: np.random.Generator) -> _Coupled:
    """Rider, brake chain and disc, coupled through mu(T) of the rubbed face: mu is
    frozen over one thermal step (``dt``, s) at the face temperature of its start; the
    disc on an ``nr`` x ``nz`` truth grid."""
    disc, eff = ctx.disc, ctx.eff
    rate = plan.rate
    per = round(dt * rate)
    n500 = n_max * per + 1
    grid = make_grid(disc.r_int, disc.r_est, disc.thickness, nr, nz)
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
    total = (ctx.laps + 1) * ctx.track.length
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
        stepper.step(dt, q_face, h_step * h_scale, float(t_amb500[j0 + per]))
        if state[S] >= total:
            n_steps = k + 1
            break
    return _Coupled(stepper.result(dt), out, mu_step, n_steps, grid, kz_ratio, mu_law)


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


def _mu_per_sample(run: _Coupled, per: int) -> np.ndarray:
    """mu(T)/mu_nom at every rider sample of the realised run (``per`` samples a step)."""
    mu500 = np.repeat(run.mu_step[:run.n_steps], per)
    return np.append(mu500, mu500[-1])
