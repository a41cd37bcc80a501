"""``diagnose``: where the disc model parts from the measurement, which unmodelled effect
causes it, and how far the gap shrinks once that effect is modelled — on held-out laps.

1. **Reference model**, the one an engineer has before knowing of any effect: the
   datasheet structure (nominal through-thickness conductivity k_z), one pad-crown
   weighting for every stop, constant friction, a power-law h(V) without a knee and an
   ideal pyrometer. Fitted on the training laps by output error over all four spots:
   h(V) (``a``, ``b``), the constant friction level (braking-power scale) and the mean
   crown weights — the datasheet torque per bar is a nominal figure and uniform pad
   pressure misses the radial heat split of any real disc by tens of °C; without these
   numbers every disc would be "diagnosed" with an effect.
2. **Split**: flying laps alternate between training and held-out (or ``holdout_laps``);
   the out-lap is used by neither. Every "after" figure is measured on held-out laps.
3. **Where**: residuals of the reference model (open loop, all spots) by spot × phase ×
   braking zone × speed band × temperature band, ranked by their share of the squared
   error; a consistency header from the reference model's four-spot UKF first (mean NIS
   per spot against its χ² band, innovation autocorrelation).
4. **Which**: each registered effect fitted alone (jointly with the reference
   parameters) on the training laps, scored on the held-out laps. Effects with a latent
   value per straight (slipstream) get those values on held-out laps from spot 3 only
   (the race sensor), and are scored on the other spots. Ranked by held-out RMSE shrink
   and held-out log-likelihood; the evidence is the residual signature each removes.
5. **Verdict**: the best effect when its shrink is significant — the lower end of a
   95 % bootstrap interval over held-out braking cycles above :data:`MIN_SHRINK_PCT` —
   else ``"none"``. A greedy forward selection gives the combined model; two effects
   whose held-out corrections correlate above :data:`CORRELATED` are flagged.
"""

from __future__ import annotations

import itertools
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import chi2

from brakethermo import __version__
from brakethermo.diagnosis.verdict import (
    CandidateEvidence,
    VerdictRule,
    decide,
    shrink_interval,
    unit_sse,
)
from brakethermo.errors import DataError
from brakethermo.estimation import UnscentedKalmanFilter
from brakethermo.io.session import Session
from brakethermo.models.disc import DiscStateSpace
from brakethermo.models.disc_effects import N_REFERENCE, ExtendedDisc, Segments
from brakethermo.models.effects import EFFECTS, mu_ratio, parse_effects
from brakethermo.pipelines import scoring
from brakethermo.pipelines.data_power import disc_data_power
from brakethermo.pipelines.estimate import SIGMA_MEAS_FLOOR_C
from brakethermo.pipelines.inputs import DiscInputs, disc_inputs, load_timed
from brakethermo.pipelines.models import disc_for, shipped_h_law
from brakethermo.pipelines.tuning import load_tuning
from brakethermo.report.braking_zones import detect_zones
from brakethermo.thermal.disc import DiscSpec
from brakethermo.thermal.hlaw import read_h_law
from brakethermo.thermal.model import DiscFEModel

SENSOR_FLOOR_C = 101.0  # degC: readings at the pyrometer's floor carry no information
MIN_SHRINK_PCT = 10.0  # % — lower bootstrap bound a verdict needs
CORRELATED = 0.8  # correlation of two effects' held-out corrections flagged as ambiguous
PRIOR_WEIGHT_C = 5.0  # degC: one prior sigma costs like one residual of this size
BOOTSTRAP = 2000
ZONE_MATCH_M = 120.0  # m: braking starts closer than this on different laps are one zone
MIN_STRAIGHT_S = 3.0  # s: shorter off-brake stretches join their neighbour's latent value
SPEED_BANDS_KMH = (0.0, 100.0, 200.0, 280.0)  # the last band ends at the session's top speed
TEMP_BANDS_C = (0.0, 250.0, 450.0, 650.0, 2000.0)
SETTLE_S = 5.0  # s after release counted as the "release" phase
RACE_SPOT = 3
RULE = VerdictRule(min_shrink_pct=MIN_SHRINK_PCT, correlated=CORRELATED, n_boot=BOOTSTRAP)


@dataclass(frozen=True)
class DiagnoseOptions:
    """Command-line choices of ``diagnose``."""

    effects: str | None = "all"
    holdout_laps: tuple[int, ...] | None = None
    h_law: str | Path | None = None
    disc: str | Path | None = None
    tuning: str | Path | None = None
    aliases: str | Path | None = None
    ambient_c: float | None = None
    max_nfev: int = 25


@dataclass
class Candidate:
    """One effect fitted alone (or a combination): parameters and held-out scores."""

    name: str
    effects: tuple[str, ...]
    p: np.ndarray
    pred: np.ndarray  # (K, 4) held-out-ready prediction
    scored_spots: tuple[int, ...]
    fit_s: float
    scores: dict[str, Any] = field(default_factory=dict)


@dataclass
class DiagnoseResult:
    """Everything ``diagnose`` found; :attr:`summary` is ``diagnosis.json``."""

    session: Session
    summary: dict[str, Any]
    time: np.ndarray
    lap: np.ndarray
    y: np.ndarray
    reference_pred: np.ndarray
    best_pred: np.ndarray | None
    lap_distance: np.ndarray
    nis: np.ndarray
    timings: dict[str, float]
    reference_sse: np.ndarray | None = None  # (U, 4) held-out SSE per braking cycle
    evidence: list[CandidateEvidence] = field(default_factory=list)

    @property
    def stem(self) -> str:
        return self.session.path.stem


# ------------------------------------------------------------------ session layout
def lap_distance(inputs: DiscInputs, session: Session) -> np.ndarray:
    """Distance along the lap, m: the ``distance`` channel, else integrated speed."""
    if session.has("distance"):
        d = session.values("distance")
        if np.isfinite(d).all():
            laps, which = np.unique(inputs.lap, return_inverse=True)
            start = np.array([d[which == j].min() for j in range(laps.size)])
            return d - start[which]  # each lap from its own least distance
    dt = session.dt
    out = np.zeros(inputs.speed.size)
    for lap in np.unique(inputs.lap):
        m = inputs.lap == lap
        out[m] = np.cumsum(np.abs(inputs.speed[m])) * dt
    return out


def build_segments(inputs: DiscInputs, zones: np.ndarray, dist: np.ndarray) -> Segments:
    """Braking zones matched across laps by lap distance; straights per lap."""
    K = inputs.speed.size
    starts = zones[:, 0] if zones.size else np.empty(0, int)
    flying = inputs.lap[starts] >= 1 if starts.size else np.empty(0, bool)
    # One zone = a cluster of braking starts at nearly the same lap distance.
    centres: list[float] = []
    for d in np.sort(dist[starts[flying]]):
        if not centres or d - centres[-1] > ZONE_MATCH_M:
            centres.append(float(d))
    zone = np.full(K, -1)
    for start in starts:
        if centres:
            z = int(np.argmin(np.abs(np.asarray(centres) - dist[start])))
            if abs(centres[z] - dist[start]) <= ZONE_MATCH_M:
                zone[start:] = z  # the zone owns its cycle until the next start
                continue
        zone[start:] = -1
    braking = np.zeros(K, bool)
    for a, b in zones:
        braking[a:b] = True
    straight = np.full(K, -1)
    laps: list[int] = []
    edges = np.diff(np.concatenate(([1], braking.astype(np.int8), [1])))
    run_starts, run_stops = np.flatnonzero(edges == -1), np.flatnonzero(edges == 1)
    for a, b in zip(run_starts, run_stops, strict=True):
        if (b - a) * 0.1 < MIN_STRAIGHT_S and laps:
            straight[a:b] = len(laps) - 1
            continue
        straight[a:b] = len(laps)
        laps.append(int(inputs.lap[a]))
    return Segments(zone=zone, n_zones=len(centres), straight=straight,
                    n_straights=len(laps), straight_lap=np.asarray(laps, int))


def session_segments(session: Session, inputs: DiscInputs
                     ) -> tuple[np.ndarray, np.ndarray, Segments]:
    """The session's braking zones (``[start, stop)`` rows), lap distance (m) and segments."""
    pressure = np.nan_to_num(session.values("brake_pressure_front"), nan=0.0)
    zones = detect_zones(inputs.time, pressure)
    dist = lap_distance(inputs, session)
    return zones, dist, build_segments(inputs, zones, dist)


def split_laps(session: Session, inputs: DiscInputs, holdout: Sequence[int] | None
               ) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """Training and held-out flying laps (out-lap and partial last lap excluded)."""
    present = sorted(int(v) for v in np.unique(inputs.lap) if v >= 1)
    durations = {lap.lap: lap.duration_s for lap in session.laps}
    full = [lap for lap in present if durations.get(lap, 0.0) > 0]
    if len(full) >= 3:
        typical = float(np.median([durations[lap] for lap in full]))
        full = [lap for lap in full if durations[lap] >= 0.8 * typical]
    if len(full) < 2:
        raise DataError(
            f"diagnose needs at least two flying laps to fit on some and check on others; the"
            f" session has {len(full)} (lap_beacon marks laps; the out-lap is lap 0)",
            path=session.path, channel="lap_beacon",
        )
    if holdout:
        bad = [lap for lap in holdout if lap not in full]
        if bad:
            raise DataError(
                f"--holdout-laps {', '.join(map(str, bad))}: not flying laps of this session"
                f" (flying laps: {', '.join(map(str, full))})", path=session.path,
            )
        held = tuple(sorted(holdout))
        train = tuple(lap for lap in full if lap not in held)
        if not train:
            raise DataError("--holdout-laps leaves no lap to fit on", path=session.path)
        return train, held
    return tuple(full[0::2]), tuple(full[1::2])


# ------------------------------------------------------------------ fitting
def _fit(
    ext: ExtendedDisc,
    p0: np.ndarray,
    y: np.ndarray,
    mask: np.ndarray,
    free: np.ndarray,
    max_nfev: int,
) -> np.ndarray:
    """Output-error least squares of the free parameters on ``mask`` (K, 4) readings.

    Residual and forward-difference Jacobian from ONE batched model pass; Gaussian
    priors of the effects enter as extra residuals (:data:`PRIOR_WEIGHT_C` per sigma).
    """
    lo, hi = ext.bounds()
    mu, sd = ext.prior()
    idx = np.flatnonzero(free)
    has_prior = idx[np.isfinite(sd[idx])]
    p_full = np.clip(p0, lo + 1e-9, hi - 1e-9)
    cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def prior_res(p: np.ndarray) -> np.ndarray:
        return PRIOR_WEIGHT_C * (p[has_prior] - mu[has_prior]) / sd[has_prior]

    def evaluate(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = x.tobytes()
        if key not in cache:
            p = p_full.copy()
            p[idx] = x
            step = 1e-3 * np.maximum(1.0, np.abs(x))
            step = np.where(x + step > hi[idx], -step, step)
            P = np.tile(p, (idx.size + 1, 1))
            P[np.arange(1, idx.size + 1), idx] += step
            pred = ext.predict(P)
            res = (pred - y[None])[:, mask]
            pri = np.stack([prior_res(row) for row in P])
            full = np.concatenate([res, pri], axis=1)
            cache.clear()
            cache[key] = (full[0], ((full[1:] - full[0]) / step[:, None]).T)
        return cache[key]

    sol = least_squares(lambda x: evaluate(x)[0], p_full[idx], jac=lambda x: evaluate(x)[1],
                        bounds=(lo[idx], hi[idx]), x_scale="jac", loss="soft_l1",
                        f_scale=20.0, ftol=1e-4, xtol=1e-4, max_nfev=max_nfev)
    out = p_full.copy()
    out[idx] = sol.x
    return out


# ------------------------------------------------------------------ scoring
def _nanmean(a: np.ndarray, axis: int | None = None) -> Any:
    """``np.nanmean`` that returns NaN for an empty selection without a warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(a, axis=axis)


def _rmse(err: np.ndarray) -> float:
    e = err[np.isfinite(err)]
    return float(np.sqrt(np.mean(e**2))) if e.size else float("nan")


@dataclass(frozen=True)
class Layout:
    """Masks of the grid used for fitting, scoring and the phase splits."""

    train: np.ndarray  # (K,)
    held: np.ndarray  # (K,)
    braking: np.ndarray  # (K,)
    release: np.ndarray  # (K,) first seconds after a release
    cycles: np.ndarray  # (K,) id of the braking cycle (bootstrap unit), -1 outside


def zone_masks(zones: np.ndarray, K: int, settle: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per step from the ``[start, stop)`` braking zones: braking, release (the ``settle``
    steps after a release, off the brakes) and the braking cycle's id (-1 before the first).
    """
    braking = np.zeros(K, bool)
    release = np.zeros(K, bool)
    cycles = np.full(K, -1)
    for j, (a, b) in enumerate(zones):
        braking[a:b] = True
        release[b: b + settle] = True
        cycles[a:] = j
    return braking, release & ~braking, cycles


def _phase_masks(layout: Layout) -> dict[str, np.ndarray]:
    return {"braking": layout.braking, "cooling": ~layout.braking}


def score(pred: np.ndarray, y: np.ndarray, layout: Layout, spots: Sequence[int]
          ) -> dict[str, Any]:
    """Held-out RMSE per spot and phase, and overall on ``spots`` (1-based)."""
    err = pred - y
    cols = [s - 1 for s in spots]
    out: dict[str, Any] = {"overall": _rmse(err[layout.held][:, cols])}
    out["per_spot"] = {f"spot{i + 1}": _rmse(err[layout.held, i]) for i in range(4)}
    out["per_phase"] = {
        phase: _rmse(err[layout.held & m][:, cols]) for phase, m in _phase_masks(layout).items()
    }
    out["per_spot_phase"] = {
        f"spot{i + 1}": {phase: _rmse(err[layout.held & m, i])
                         for phase, m in _phase_masks(layout).items()}
        for i in range(4)
    }
    return out


def bootstrap_shrink(before: np.ndarray, after: np.ndarray, y: np.ndarray, layout: Layout,
                     spots: Sequence[int]) -> tuple[float, float, float]:
    """Held-out RMSE shrink (%) and its 95 % interval by bootstrap over braking cycles."""
    cols = [s - 1 for s in spots]
    units = np.where(layout.held, layout.cycles, -1)
    sb = unit_sse((before - y)[:, cols], units)[0]
    sa = unit_sse((after - y)[:, cols], units)[0]
    return shrink_interval(sb, sa, RULE)


def heldout_loglik(pred: np.ndarray, y: np.ndarray, layout: Layout, spots: Sequence[int]
                   ) -> float:
    """Gaussian log-likelihood per held-out reading, variance from the training residuals."""
    cols = [s - 1 for s in spots]
    total, count = 0.0, 0
    for c in cols:
        e_tr = (pred - y)[layout.train, c]
        e_tr = e_tr[np.isfinite(e_tr)]
        e_ho = (pred - y)[layout.held, c]
        e_ho = e_ho[np.isfinite(e_ho)]
        if e_tr.size < 2 or e_ho.size == 0:
            continue
        var = max(float(np.mean(e_tr**2)), 1e-6)
        total += float(np.sum(-0.5 * (np.log(2 * np.pi * var) + e_ho**2 / var)))
        count += e_ho.size
    return total / count if count else float("nan")


# ------------------------------------------------------------------ evidence
def _corr(a: np.ndarray, b: np.ndarray) -> float:
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 3 or np.std(a[ok]) == 0 or np.std(b[ok]) == 0:
        return float("nan")
    return float(np.corrcoef(a[ok], b[ok])[0, 1])


def signatures(res: np.ndarray, y: np.ndarray, inputs: DiscInputs, layout: Layout,
               segments: Segments, v_ref: float, dt: float) -> dict[str, dict[str, float]]:
    """Residual statistics behind each effect's signature (reference model, all laps).

    ``res`` is measurement minus model, degC (K, 4).
    """
    flying = layout.train | layout.held
    br, cool = layout.braking & flying, ~layout.braking & flying
    dTdt = np.gradient(y, dt, axis=0)
    fast = np.abs(inputs.speed) >= 0.8 * v_ref
    lapwise = []
    for s in range(segments.n_straights):
        m = (segments.straight == s) & cool
        if m.sum() > 20:
            lapwise.append(float(_nanmean(res[m])))
    contact = _nanmean(y[:, 1:4], axis=1)
    return {
        "sensor_lag": {"corr_residual_dTdt": _corr(res[flying].ravel(), dTdt[flying].ravel())},
        "emissivity_error": {
            "slope_braking_c_per_100c": 100.0 * _slope(y[br].ravel(), res[br].ravel()),
            "slope_cooling_c_per_100c": 100.0 * _slope(y[cool].ravel(), res[cool].ravel()),
        },
        "h_speed_knee": {
            "cooling_bias_fast_c": float(_nanmean(res[cool & fast])) if (cool & fast).any()
            else float("nan"),
            "cooling_bias_slow_c": float(_nanmean(res[cool & ~fast])),
        },
        "friction_temperature": {
            "corr_braking_residual_temperature": _corr(_nanmean(res[br], axis=1),
                                                       contact[br]),
        },
        "power_distribution": {
            "braking_bias_spot2_c": float(_nanmean(res[br, 1])),
            "braking_bias_spot4_c": float(_nanmean(res[br, 3])),
        },
        "slipstream": {"lap_to_lap_sd_straight_bias_c": float(np.std(lapwise))
                       if len(lapwise) > 2 else float("nan")},
        "thickness_gradient": {
            "braking_bias_c": float(_nanmean(res[br])),
            "release_bias_c": float(_nanmean(res[layout.release & flying])),
        },
    }


def _slope(x: np.ndarray, r: np.ndarray) -> float:
    ok = np.isfinite(x) & np.isfinite(r)
    if ok.sum() < 3 or np.std(x[ok]) == 0:
        return float("nan")
    return float(np.polyfit(x[ok], r[ok], 1)[0])


EVIDENCE: dict[str, Callable[[dict[str, float]], str]] = {
    "sensor_lag": lambda s: (
        f"residual vs dT/dt correlation {s['corr_residual_dTdt']:+.2f} (a lagging sensor"
        " reads low while heating, high while cooling: negative)"),
    "emissivity_error": lambda s: (
        f"bias slope {s['slope_braking_c_per_100c']:+.1f} °C per 100 °C braking,"
        f" {s['slope_cooling_c_per_100c']:+.1f} cooling (same sign in every phase for a"
        " wrong emissivity)"),
    "h_speed_knee": lambda s: (
        f"cooling bias {s['cooling_bias_fast_c']:+.1f} °C above 0.8 V_ref vs"
        f" {s['cooling_bias_slow_c']:+.1f} °C below (measured minus model)"),
    "friction_temperature": lambda s: (
        "braking residual vs contact temperature correlation"
        f" {s['corr_braking_residual_temperature']:+.2f}"),
    "power_distribution": lambda s: (
        f"braking bias spot 2 {s['braking_bias_spot2_c']:+.1f} °C, spot 4"
        f" {s['braking_bias_spot4_c']:+.1f} °C"
        + (" (opposite signs: the heat split over the radius is not the model's)"
           if s["braking_bias_spot2_c"] * s["braking_bias_spot4_c"] < 0 else
           " (same sign: the whole band, not its split, departs)")),
    "slipstream": lambda s: (
        f"lap-to-lap spread of the straights' cooling bias {s['lap_to_lap_sd_straight_bias_c']:.1f}"
        " °C"),
    "thickness_gradient": lambda s: (
        f"braking bias {s['braking_bias_c']:+.1f} °C, just after release"
        f" {s['release_bias_c']:+.1f} °C"),
}


def carry_command(session: Path, name: str) -> str:
    """The command that carries an effect into the law the race estimate uses."""
    return f"brakethermo identify-h {session} --with-effect {name} --out OUT"


def _spread(values: Sequence[float]) -> str:
    v = np.asarray(values, float)
    return f"median {np.median(v):.2f}, range {v.min():.2f}-{v.max():.2f}"


def effect_size(name: str, params: dict[str, Any], disc: DiscSpec, layers: int
                ) -> tuple[dict[str, Any], str]:
    """An effect's fitted size in physical units, and the sentence the page shows."""
    if name == "thickness_gradient":
        f = float(params["kz_factor"])
        k_z = f * disc.k_z if disc.k_z else float("nan")
        return ({"kz_over_nominal": f, "k_z_w_mk": k_z, "k_z_nominal_w_mk": disc.k_z},
                f"through-thickness conductivity k_z = {k_z:.1f} W/(m K), {f:.2f} x the"
                f" datasheet's {disc.k_z:g} W/(m K) ({layers} layers)")
    if name == "sensor_lag":
        tau = float(params["tau_s"])
        return {"tau_s": tau}, f"pyrometer time constant {tau:.2f} s"
    if name == "emissivity_error":
        r = float(params["ratio"])
        eps_set = disc.emissivity / r
        err600 = (600.0 + 273.15) * (r**0.25 - 1.0)
        return ({"eps_disc_over_set": r, "eps_set": eps_set, "eps_disc": disc.emissivity,
                 "reading_error_at_600c": err600},
                f"pyrometer set to emissivity {eps_set:.2f} on a {disc.emissivity:g} disc:"
                f" reads {err600:+.0f} °C at 600 °C")
    if name == "friction_temperature":
        points = {f"{t:.0f}": float(mu_ratio(np.array(t), params["beta"], params["t_mid"]))
                  for t in (200.0, 400.0, 600.0, 800.0)}
        return ({"mu_over_ref_at_c": points, "beta": params["beta"],
                 "t_mid_c": params["t_mid"]},
                "μ/μ_ref " + ", ".join(f"{v:.2f} at {t} °C" for t, v in points.items()))
    if name == "h_speed_knee":
        g = float(params["gain"])
        knee = 0.8 * disc.v_ref * 3.6
        return ({"knee_kmh": knee, "gain_at_v_ref": g},
                f"h {100 * g:+.0f} % at {disc.v_ref * 3.6:.0f} km/h, growing from the knee"
                f" at {knee:.0f} km/h")
    if name == "slipstream":
        f = np.asarray(params.get("straight_factor", [1.0]), float)
        off = int(np.sum(np.abs(f - 1.0) > 0.1))
        return ({"h_factor_per_straight": f.tolist(), "straights_off_10pct": off},
                f"h factor per straight {_spread(f)}; {off} of {f.size} straights more than"
                " 10 % off")
    if name == "power_distribution":
        b = np.asarray(params.get("zone_balance", []), float)
        m = np.asarray(params.get("zone_middle", []), float)
        zones = {zone_label(z): {"inner_vs_outer": float(np.exp(2 * b[z])),
                                 "middle_factor": float(np.exp(m[z]))} for z in range(b.size)}
        worst = int(np.argmax(np.abs(b))) if b.size else -1
        text = ("no zone" if worst < 0 else
                f"inner/outer crown power ratio per zone {_spread(np.exp(2 * b))}; most"
                f" uneven {zone_label(worst)}: {np.exp(2 * b[worst]):.2f}")
        return {"per_zone": zones}, text
    return dict(params), ""


# ------------------------------------------------------------------ where
def where_table(res: np.ndarray, layout: Layout, inputs: DiscInputs, segments: Segments,
                y: np.ndarray, top: int = 12) -> list[dict[str, Any]]:
    """Cells spot × phase × zone × speed band × temperature band, by share of squared error."""
    scored = layout.held | layout.train
    phase = np.where(layout.braking, "braking", np.where(layout.release, "release", "straight"))
    v_kmh = np.abs(inputs.speed) * 3.6
    speed_edges = _speed_edges(v_kmh[scored])
    speed_band = np.digitize(v_kmh, speed_edges[1:-1])
    rows = []
    total = float(np.nansum(res[scored] ** 2))
    for i in range(4):
        temp_band = np.digitize(np.nan_to_num(y[:, i], nan=-1.0), TEMP_BANDS_C[1:-1])
        ok = scored & np.isfinite(res[:, i])
        keys = np.stack([np.unique(phase, return_inverse=True)[1], segments.zone + 1,
                         speed_band, temp_band], axis=1)[ok]
        r = res[ok, i]
        uniq, inv = np.unique(keys, axis=0, return_inverse=True)
        phases = np.unique(phase)
        sse = np.bincount(inv, weights=r**2)
        bias = np.bincount(inv, weights=r) / np.bincount(inv)
        count = np.bincount(inv)
        for j, key in enumerate(uniq):
            if count[j] < 10:
                continue
            rows.append({
                "spot": f"spot{i + 1}",
                "phase": str(phases[key[0]]),
                "zone": zone_label(int(key[1]) - 1),
                "speed_band_kmh": _band(speed_edges, key[2]),
                "temp_band_c": _band(TEMP_BANDS_C, key[3]),
                "rmse_c": float(np.sqrt(sse[j] / count[j])),
                "bias_c": float(bias[j]),
                "share_pct": 100.0 * float(sse[j]) / total if total else 0.0,
                "samples": int(count[j]),
            })
    rows.sort(key=lambda r: -r["share_pct"])
    return rows[:top]


def _band(edges: Sequence[float], i: int) -> str:
    return f"{edges[i]:.0f}-{edges[i + 1]:.0f}"


def zone_label(z: int) -> str | None:
    """Braking zone ``z`` (0-based, in lap order) as the lap reports name it: B1, B2, …"""
    return f"B{z + 1}" if z >= 0 else None


def _speed_edges(v_kmh: np.ndarray) -> tuple[float, ...]:
    """Speed-band edges, km/h, within the session: the last band ends at its top speed."""
    top = float(np.ceil(np.nanmax(v_kmh))) if np.isfinite(v_kmh).any() else 1.0
    inner = tuple(e for e in SPEED_BANDS_KMH[1:] if e < top)
    return (SPEED_BANDS_KMH[0], *inner, top)


def _marginals(res: np.ndarray, layout: Layout, inputs: DiscInputs, segments: Segments,
               y: np.ndarray) -> dict[str, Any]:
    scored = layout.held | layout.train
    out: dict[str, Any] = {}
    phases = {"braking": layout.braking, "release": layout.release & ~layout.braking,
              "straight": ~layout.braking & ~layout.release}
    out["by_spot_phase"] = {
        f"spot{i + 1}": {p: {"rmse_c": _rmse(res[scored & m, i]),
                             "bias_c": float(_nanmean(res[scored & m, i]))
                             if (scored & m).any() else float("nan")}
                         for p, m in phases.items()}
        for i in range(4)
    }
    out["by_zone"] = [
        {"zone": zone_label(z), "rmse_c": _rmse(res[scored & (segments.zone == z)]),
         "bias_c": float(_nanmean(res[scored & (segments.zone == z)]))}
        for z in range(segments.n_zones) if (scored & (segments.zone == z)).any()
    ]
    v = np.abs(inputs.speed) * 3.6
    out["by_speed_band"] = [
        {"band_kmh": f"{lo:.0f}-{hi:.0f}", "rmse_c": _rmse(res[scored & (v >= lo) & (v <= hi)])}
        for lo, hi in itertools.pairwise(_speed_edges(v[scored]))
        if (scored & (v >= lo) & (v <= hi)).any()
    ]
    t = _nanmean(y, axis=1)
    out["by_temperature_band"] = [
        {"band_c": f"{lo:.0f}-{hi:.0f}", "rmse_c": _rmse(res[scored & (t >= lo) & (t < hi)])}
        for lo, hi in itertools.pairwise(TEMP_BANDS_C)
        if (scored & (t >= lo) & (t < hi)).any()
    ]
    return out


# ------------------------------------------------------------------ consistency
def consistency(model: DiscFEModel, inputs: DiscInputs, y: np.ndarray, law_h: np.ndarray,
                scale: float, T0: np.ndarray, spot_radii: np.ndarray, sigma_meas: np.ndarray,
                sigma_temp: float, init_sigma: float, scored: np.ndarray
                ) -> tuple[dict[str, Any], np.ndarray]:
    """Four-spot UKF on the reference model: NIS per spot vs its χ² band, autocorrelation."""
    ssm = DiscStateSpace(model, inputs.q_brk * scale, inputs.t_amb, law_h, (),
                         sigma_temp=sigma_temp, sigma_crown=0.0)
    x0, P0 = ssm.prior(T0, init_sigma)
    ukf = UnscentedKalmanFilter(ssm.f, ssm.Q, np.diag(sigma_meas**2), H=ssm.H(spot_radii))
    res = ukf.run(x0, P0, y, store="diag")
    nis_spot = res.innovation**2 / res.innovation_var
    out: dict[str, Any] = {"per_spot": {}, "sigma_meas_c": [float(s) for s in sigma_meas]}
    verdicts = []
    for i in range(4):
        v = nis_spot[scored, i]
        v = v[np.isfinite(v)]
        n = max(v.size, 1)
        lo, hi = chi2.ppf([0.025, 0.975], n) / n
        nu = res.innovation[scored, i]
        nu = nu[np.isfinite(nu)]
        ac = _corr(nu[:-1], nu[1:]) if nu.size > 3 else float("nan")
        mean = float(np.mean(v)) if v.size else float("nan")
        state = "over-confident" if mean > hi else "under-confident" if mean < lo else "consistent"
        verdicts.append(state)
        out["per_spot"][f"spot{i + 1}"] = {"mean_nis": mean, "chi2_band": [float(lo), float(hi)],
                                           "lag1_autocorrelation": ac, "state": state}
    over = verdicts.count("over-confident")
    out["summary"] = (
        f"the reference filter is over-confident at {over} of 4 spots: its model error is"
        " larger than its noise settings admit — the physics gap below is real, not a tuning"
        " artefact" if over else
        "the reference filter's innovations are consistent with its noise settings")
    return out, _nanmean(nis_spot, axis=1)


# ------------------------------------------------------------------ the pipeline
def _initial_nodes(model: DiscFEModel, spot_radii: np.ndarray, y: np.ndarray, t_amb: float
                   ) -> np.ndarray:
    first = y[:50]
    vals = np.array([col[np.isfinite(col)][0] if np.isfinite(col).any() else np.nan
                     for col in first.T])
    ok = np.isfinite(vals)
    prof = np.interp(model.radii, spot_radii[ok], vals[ok]) if ok.any() else \
        np.full(model.n_nodes, t_amb)
    return np.repeat(np.maximum(prof, t_amb), model.layers)


def _reference_start(disc: DiscSpec, h_law: str | Path | None
                     ) -> tuple[float, float, np.ndarray]:
    """Start of the reference fit: a, b and crown weights of the given or shipped law."""
    path = Path(h_law) if h_law else shipped_h_law(disc)
    if path is None:
        return 100.0, 0.8, np.ones(3)
    record = read_h_law(path)
    return record.law.a, record.law.b, np.asarray(record.weights, float)


def diagnose_session(
    session: Session,
    options: DiagnoseOptions | None = None,
    progress: Callable[[str, int, int], None] | None = None,
) -> DiagnoseResult:
    """Diagnose a four-spot session (module docstring). ``progress(label, done, total)``."""
    options = options or DiagnoseOptions()
    t_start = time.perf_counter()
    names = parse_effects(options.effects)
    est_tuning, _ = load_tuning(options.tuning)
    disc = disc_for(session, options.disc)
    inputs = disc_inputs(session, disc, options.ambient_c)
    if not inputs.is_multi_spot:
        if RACE_SPOT not in inputs.measured:
            raise DataError(
                "diagnose needs the four-spot sensor or the race sensor at the spot-3 radius;"
                f" this session logs spot(s) {', '.join(map(str, inputs.measured))}",
                path=session.path)
        return diagnose_single_spot(session, options, inputs, disc, progress)
    y = inputs.spots.copy()
    y[y <= SENSOR_FLOOR_C] = np.nan
    spot_radii = np.asarray(disc.spot_radii)
    zones, dist, segments = session_segments(session, inputs)
    train_laps, held_laps = split_laps(session, inputs, options.holdout_laps)
    braking, release, cycles = zone_masks(zones, inputs.time.size, round(SETTLE_S / session.dt))
    layout = Layout(train=np.isin(inputs.lap, train_laps), held=np.isin(inputs.lap, held_laps),
                    braking=braking, release=release, cycles=cycles)
    train_mask = layout.train[:, None] & np.isfinite(y)

    model = DiscFEModel(disc, est_tuning.nodes, est_tuning.layers,
                        layer_growth=est_tuning.layer_growth, k_z=disc.k_z)
    T0 = _initial_nodes(model, spot_radii, y, float(inputs.t_amb[0]))
    a0, b0, w0 = _reference_start(disc, options.h_law)

    def make(effects: tuple[str, ...]) -> ExtendedDisc:
        return ExtendedDisc(model, inputs.speed, inputs.q_brk, inputs.t_amb, T0, spot_radii,
                            disc.v_ref, effects, segments)

    total_steps = len(names) + 3
    done = 0

    def tick(label: str) -> None:
        nonlocal done
        done += 1
        if progress:
            progress(label, done, total_steps)

    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    ref = make(())
    p_ref = ref.neutral()
    p_ref[0], p_ref[1] = np.log(max(a0, 1.0)), b0
    w0 = np.maximum(w0, 1e-3)
    p_ref[3:5] = np.log(w0[:2] / w0[2])
    p_ref = _fit(ref, p_ref, y, train_mask, np.ones(ref.size, bool), options.max_nfev)
    ref_pred = ref.predict(p_ref)[0]
    timings["reference_s"] = time.perf_counter() - t0
    tick("reference model")

    def fit_candidate(effects: tuple[str, ...], start: Candidate | None = None) -> Candidate:
        t = time.perf_counter()
        ext = make(effects)
        p0 = ext.neutral()
        p0[:N_REFERENCE] = p_ref[:N_REFERENCE]
        if start is not None:
            start_ext = make(start.effects)
            for s in ext.slots:
                for s0 in start_ext.slots:
                    if (s0.effect, s0.param.name, s0.segment) == (s.effect, s.param.name,
                                                                  s.segment):
                        p0[s.index] = start.p[s0.index]
        # Latent per-straight values of held-out laps are not fitted on training laps, and
        # with per-straight values the reference stays as fitted: dozens of local factors
        # would otherwise bend the global law to absorb whatever else is wrong.
        free = np.ones(ext.size, bool)
        if any(EFFECTS[e].latent == "straight" for e in effects):
            free[:N_REFERENCE] = False
        held_latent = np.zeros(ext.size, bool)
        for s in ext.slots:
            if s.segment >= 0 and EFFECTS[s.effect].latent == "straight":
                if segments.straight_lap[s.segment] not in train_laps:
                    free[s.index] = False
                    held_latent[s.index] = segments.straight_lap[s.segment] in held_laps
        p = _fit(ext, p0, y, train_mask, free, options.max_nfev)
        spots: tuple[int, ...] = (1, 2, 3, 4)
        if held_latent.any():
            # Held-out straights: their latent values from the race sensor alone.
            race = np.zeros_like(train_mask)
            race[:, RACE_SPOT - 1] = layout.held & np.isfinite(y[:, RACE_SPOT - 1])
            p = _fit(ext, p, y, race, held_latent, options.max_nfev)
            spots = tuple(s for s in spots if s != RACE_SPOT)
        return Candidate(",".join(effects), effects, p, ext.predict(p)[0], spots,
                         time.perf_counter() - t)

    candidates: list[Candidate] = []
    for name in names:
        cand = fit_candidate((name,))
        candidates.append(cand)
        timings[f"{name}_s"] = cand.fit_s
        tick(name)

    def describe(c: Candidate, base_pred: np.ndarray) -> dict[str, Any]:
        before = score(base_pred, y, layout, c.scored_spots)
        after = score(c.pred, y, layout, c.scored_spots)
        shrink, lo, hi = bootstrap_shrink(base_pred, c.pred, y, layout, c.scored_spots)
        ll_before = heldout_loglik(base_pred, y, layout, c.scored_spots)
        ll_after = heldout_loglik(c.pred, y, layout, c.scored_spots)
        return {
            "rmse_before": before["overall"], "rmse_after": after["overall"],
            "shrink_pct": shrink, "shrink_ci95_pct": [lo, hi],
            "significant": bool(np.isfinite(lo) and lo > MIN_SHRINK_PCT),
            "heldout_loglik_gain": ll_after - ll_before,
            "scored_spots": [f"spot{s}" for s in c.scored_spots],
            "per_spot": {k: {"before": before["per_spot"][k], "after": after["per_spot"][k]}
                         for k in after["per_spot"]},
            "per_phase": {k: {"before": before["per_phase"][k], "after": after["per_phase"][k]}
                          for k in after["per_phase"]},
        }

    res_ref = y - ref_pred
    sig = signatures(res_ref, y, inputs, layout, segments, disc.v_ref, session.dt)
    units = np.where(layout.held, layout.cycles, -1)
    ref_sse = unit_sse(ref_pred - y, units, per_output=True)[0]
    evidence = [
        CandidateEvidence(c.name, unit_sse(c.pred - y, units, per_output=True)[0],
                          correction=(c.pred - ref_pred)[layout.held],
                          separate_by=EFFECTS[c.name].separate_by,
                          next_step=carry_command(session.path, c.name),
                          outputs=tuple(s_ - 1 for s_ in c.scored_spots))
        for c in candidates]
    blind = disc_data_power(inputs.speed, y, inputs.t_amb, layout.braking,
                            layout.train | layout.held, disc.v_ref, SENSOR_FLOOR_C)
    decision = decide(ref_sse, evidence, RULE, untestable=blind)
    effects_out = []
    for c in candidates:
        c.scores = describe(c, ref_pred)
        row = next(r for r in decision.rows if r["name"] == c.name)
        c.scores.update(shrink_pct=row["shrink_pct"], shrink_ci95_pct=row["shrink_ci95_pct"],
                        significant=row["significant"])
        params = make(c.effects).values(c.p, c.name)
        size, sentence = effect_size(c.name, params, disc, est_tuning.layers)
        if "kz_factor" in params:  # in h_law.toml kz_factor is relative to k(T), not k_z
            params = {"kz_over_nominal": params.pop("kz_factor"), **params}
        effects_out.append({
            "name": c.name,
            **c.scores,  # describe()'s keys, in its order
            "params": params,
            "size": size,
            "size_text": sentence,
            "evidence": EVIDENCE[c.name](sig[c.name]),
            "signature": EFFECTS[c.name].signature,
            "extension": EFFECTS[c.name].extension,
            "separate_by": EFFECTS[c.name].separate_by,
            "fit_s": c.fit_s,
            **({"vs_first_pp": row["vs_first_pp"]} if "vs_first_pp" in row else {}),
        })
    rank_of = {r["name"]: r["rank"] for r in decision.rows}
    effects_out.sort(key=lambda e: rank_of[e["name"]])
    ranked = sorted(candidates, key=lambda c: rank_of[c.name])
    for e in effects_out:
        e["rank"] = rank_of[e["name"]]

    significant = [c for c in ranked if c.scores["significant"]]
    verdict = decision.verdict

    # Correlated corrections: two significant effects moving the prediction alike.
    warnings: list[str] = []
    held = layout.held
    for i, a in enumerate(significant):
        for b in significant[i + 1:]:
            r = _corr((a.pred - ref_pred)[held].ravel(), (b.pred - ref_pred)[held].ravel())
            if np.isfinite(r) and r > CORRELATED:
                alone = decision.kind == "single" and verdict in (a.name, b.name)
                warnings.append(
                    f"{a.name} and {b.name} correct the held-out residual alike (correlation"
                    f" {r:.2f})" + ("; the first still beats the other clearly on held-out"
                                    " cycles" if alone else
                                    ": the data cannot tell them apart, the verdict names"
                                    " the set"))
    t0 = time.perf_counter()
    selection = _forward_selection(significant, fit_candidate, describe, y, layout)
    timings["forward_selection_s"] = time.perf_counter() - t0
    tick("forward selection")

    sigma_meas = np.array([max(scoring.reading_noise(y[:, i]), SIGMA_MEAS_FLOOR_C)
                           for i in range(4)])
    cons, nis = consistency(model, inputs, y, ref.law(p_ref)(inputs.speed),
                            float(np.exp(p_ref[2])), T0, spot_radii, sigma_meas,
                            est_tuning.sigma_temp, est_tuning.init_sigma_temp,
                            layout.train | layout.held)
    tick("consistency and where")
    ref_scores = score(ref_pred, y, layout, (1, 2, 3, 4))
    best = ranked[0] if ranked else None
    law = ref.law(p_ref)
    summary: dict[str, Any] = {
        "session": str(session.path),
        "metadata": session.metadata,
        "reference": {
            "contains": [
                f"datasheet structure of disc {disc.id}: {est_tuning.nodes} radial nodes x"
                f" {est_tuning.layers} graded layers, through-thickness conductivity"
                + (f" k_z = {disc.k_z:g} W/(m K) (nominal)" if disc.k_z else
                   " = radial k(T) (the datasheet gives no k_z)"),
                "one mean pad-crown weighting for every stop (w1..w3 fitted; the datasheet's"
                " uniform pressure misses the radial heat split of any real disc)",
                "constant friction: braking power = datasheet formula x one fitted scale",
                "power-law h(V) = a (V/V_ref)^b, no knee, no slipstream",
                "ideal pyrometer (no lag, correct emissivity)",
            ],
            "fitted": {"h_a": law.a, "h_b": law.b, "power_scale": float(np.exp(p_ref[2])),
                       "crown_weights": list(ref.weights(p_ref))},
        },
        "train_laps": list(train_laps),
        "heldout_laps": list(held_laps),
        "gap": {
            "rmse_c": ref_scores["overall"],
            "per_spot": ref_scores["per_spot"],
            "per_phase": ref_scores["per_phase"],
            "per_spot_phase": ref_scores["per_spot_phase"],
        },
        "where": {"ranked_cells": where_table(res_ref, layout, inputs, segments, y),
                  **_marginals(res_ref, layout, inputs, segments, y),
                  "braking_zones": segments.n_zones},
        "consistency": cons,
        "effects": effects_out,
        **decision.summary(),
        "combined": selection,
        "warnings": warnings,
        "run": {
            "brakethermo": __version__,
            "disc": disc.id,
            "effects_tried": list(names),
            "timings_s": timings,
            "wall_time_s": time.perf_counter() - t_start,
            "input_warnings": list(session.warnings) + list(inputs.warnings),
        },
    }
    return DiagnoseResult(session, summary, inputs.time, inputs.lap, y, ref_pred,
                          best.pred if best else None, dist, nis, timings, ref_sse, evidence)


# estimate.parquet's online columns are relative to the law's structure: their names here
ONLINE_KEY = {"kz_factor": "kz_over_test_session", "h_factor": "h_factor",
              "crown_balance": "crown_balance"}
# effect -> (estimate option that adapts it online, its state column, its test-session value)
SINGLE_SPOT_ONLINE = {"thickness_gradient": ("adapt_kz", "kz_factor", 1.0),
                      "slipstream": ("adapt_slipstream", "h_factor", 1.0),
                      "power_distribution": ("adapt_balance", "crown_balance", 0.0)}


def diagnose_single_spot(
    session: Session,
    options: DiagnoseOptions,
    inputs: DiscInputs,
    disc: DiscSpec,
    progress: Callable[[str, int, int], None] | None = None,
) -> DiagnoseResult:
    """What one race pyrometer can tell: innovation-based "where" and the online effects.

    The race filter (identified law, spot 3 measured) runs without online effects (the
    reference) and with each effect one spot can follow online; its one-step-ahead
    innovations are predictions from past readings only, so every flying lap is scored.
    The other effects need the four-spot test session and are listed as such.
    """
    from brakethermo.pipelines.estimate import EstimateOptions, estimate_from_session

    t_start = time.perf_counter()
    names = parse_effects(options.effects)
    flying = tuple(int(v) for v in np.unique(inputs.lap) if v >= 1)
    if not flying:
        raise DataError("diagnose needs at least one flying lap (lap_beacon >= 1)",
                        path=session.path, channel="lap_beacon")
    online = [n for n in names if n in SINGLE_SPOT_ONLINE]
    off = {flag: False for flag, _, _ in SINGLE_SPOT_ONLINE.values()}
    base = EstimateOptions(spot=RACE_SPOT, h_law=options.h_law, disc=options.disc,
                           tuning=options.tuning, aliases=options.aliases,
                           ambient_c=options.ambient_c, smoother=False, score=False)
    runs = {}
    for i, label in enumerate(["reference", *online], start=1):
        flags = dict(off)
        if label != "reference":
            flags[SINGLE_SPOT_ONLINE[label][0]] = True
        runs[label] = estimate_from_session(session, replace(base, **flags))
        if progress:
            progress(label, i, len(online) + 1)
    y = np.full((inputs.time.size, 4), np.nan)
    y[:, RACE_SPOT - 1] = inputs.spots[:, RACE_SPOT - 1]
    y[y <= SENSOR_FLOOR_C] = np.nan

    def prediction(label: str) -> np.ndarray:
        pred = np.full_like(y, np.nan)
        pred[:, RACE_SPOT - 1] = y[:, RACE_SPOT - 1] - runs[label].innovation
        return pred

    zones, dist, segments = session_segments(session, inputs)
    braking, release, cycles = zone_masks(zones, inputs.time.size, round(SETTLE_S / session.dt))
    scored = np.isin(inputs.lap, flying)
    layout = Layout(train=np.zeros_like(scored), held=scored, braking=braking,
                    release=release, cycles=cycles)
    ref_pred = prediction("reference")
    spots = (RACE_SPOT,)
    units = np.where(layout.held, layout.cycles, -1)
    ref_sse = unit_sse(ref_pred - y, units, per_output=True)[0]
    evidence = [
        CandidateEvidence(label, unit_sse(prediction(label) - y, units, per_output=True)[0],
                          correction=(prediction(label) - ref_pred)[layout.held],
                          separate_by=EFFECTS[label].separate_by,
                          next_step=(f"brakethermo estimate {session.path} --"
                                     f"{SINGLE_SPOT_ONLINE[label][0].replace('_', '-')}"),
                          outputs=(RACE_SPOT - 1,))
        for label in online]
    decision = decide(ref_sse, evidence, RULE)
    rows = {r["name"]: r for r in decision.rows}
    effects_out = []
    best_pred = None
    for label in online:
        pred = prediction(label)
        before, after = score(ref_pred, y, layout, spots), score(pred, y, layout, spots)
        row = rows[label]
        frame = runs[label].frame
        _, column, nominal = SINGLE_SPOT_ONLINE[label]
        track = frame[column].to_numpy()[scored]
        key = ONLINE_KEY[column]
        effects_out.append({
            "name": label, "rmse_before": before["overall"], "rmse_after": after["overall"],
            "shrink_pct": row["shrink_pct"], "shrink_ci95_pct": row["shrink_ci95_pct"],
            "significant": row["significant"], "rank": row["rank"],
            "heldout_loglik_gain": float(np.nanmean(_gauss_ll(runs[label]))
                                         - np.nanmean(_gauss_ll(runs["reference"]))),
            "scored_spots": [f"spot{RACE_SPOT}"],
            "per_spot": {f"spot{RACE_SPOT}": {"before": before["overall"],
                                              "after": after["overall"]}},
            "per_phase": {k: {"before": before["per_phase"][k], "after": after["per_phase"][k]}
                          for k in after["per_phase"]},
            "params": {f"{key}_median": float(np.median(track)),
                       f"{key}_p05": float(np.percentile(track, 5)),
                       f"{key}_p95": float(np.percentile(track, 95))},
            "evidence": (f"online {key} over the flying laps: median"
                         f" {np.median(track):.2f}, 5-95 % {np.percentile(track, 5):.2f}-"
                         f"{np.percentile(track, 95):.2f} ({nominal:g} = the test-session disc)"),
            "signature": EFFECTS[label].signature,
            "extension": EFFECTS[label].extension,
            "separate_by": EFFECTS[label].separate_by,
            "identifiable_from_one_spot": True,
        })
    effects_out.sort(key=lambda e: e["rank"])
    not_observable = [
        {"name": n, "identifiable_from_one_spot": False,
         "reason": ("one pyrometer cannot tell its own bias from the disc: only the test"
                    " session's four spots can") if n == "emissivity_error" else
                   "needs the four-spot test session (diagnose it there, then estimate with"
                   " its h_law.toml)"}
        for n in names if n not in SINGLE_SPOT_ONLINE]
    verdict = decision.verdict
    if verdict != "none":
        best_pred = prediction(verdict)
    ref_scores = score(ref_pred, y, layout, spots)
    nis = runs["reference"].innovation**2 / runs["reference"].innovation_var
    v = nis[scored & np.isfinite(nis)]
    lo_b, hi_b = chi2.ppf([0.025, 0.975], max(v.size, 1)) / max(v.size, 1)
    mean = float(np.mean(v)) if v.size else float("nan")
    state = "over-confident" if mean > hi_b else "under-confident" if mean < lo_b else \
        "consistent"
    nu = runs["reference"].innovation[scored]
    nu = nu[np.isfinite(nu)]
    res = y - ref_pred
    summary: dict[str, Any] = {
        "session": str(session.path),
        "metadata": session.metadata,
        "mode": "single-spot race session: innovation-based, spot 3 only",
        "reference": {
            "contains": [
                f"the race estimator of disc {disc.id} with the h law "
                f"{runs['reference'].summary['run']['h_law'] or 'shipped for the disc'}",
                "no online effects (k_z and slipstream factors fixed at 1)",
                "scored by its one-step-ahead innovations at spot 3: predictions from past"
                " readings only, so no lap needs to be held out",
            ],
            "fitted": {},
        },
        "train_laps": [],
        "heldout_laps": list(flying),
        "gap": {"rmse_c": ref_scores["overall"], "per_spot": ref_scores["per_spot"],
                "per_phase": ref_scores["per_phase"],
                "per_spot_phase": ref_scores["per_spot_phase"]},
        "where": {"ranked_cells": where_table(res, layout, inputs, segments, y),
                  **_marginals(res, layout, inputs, segments, y),
                  "braking_zones": segments.n_zones},
        "consistency": {
            "per_spot": {f"spot{RACE_SPOT}": {
                "mean_nis": mean, "chi2_band": [float(lo_b), float(hi_b)],
                "lag1_autocorrelation": _corr(nu[:-1], nu[1:]) if nu.size > 3 else
                float("nan"), "state": state}},
            "summary": f"the race filter is {state} at spot {RACE_SPOT} (mean NIS {mean:.2f})",
        },
        "effects": effects_out,
        "not_identifiable_from_one_spot": not_observable,
        **decision.summary(),
        "combined": {"effects": [verdict] if verdict != "none" else [], "steps": []},
        "warnings": [],
        "run": {"brakethermo": __version__, "disc": disc.id, "effects_tried": list(names),
                "timings_s": {}, "wall_time_s": time.perf_counter() - t_start,
                "input_warnings": list(session.warnings) + list(inputs.warnings)},
    }
    return DiagnoseResult(session, summary, inputs.time, inputs.lap, y, ref_pred, best_pred,
                          dist, nis, {}, ref_sse, evidence)


def _gauss_ll(result: Any) -> np.ndarray:
    """Per-step Gaussian log-likelihood of a filter's innovations."""
    nu, s2 = result.innovation, result.innovation_var
    return -0.5 * (np.log(2.0 * np.pi * s2) + nu**2 / s2)


def _forward_selection(
    significant: list[Candidate],
    fit_candidate: Callable[[tuple[str, ...], Candidate | None], Candidate],
    describe: Callable[[Candidate, np.ndarray], dict[str, Any]],
    y: np.ndarray,
    layout: Layout,
) -> dict[str, Any]:
    """Greedy forward selection over the significant effects, on held-out laps."""
    if not significant:
        return {"effects": [], "steps": []}
    current = significant[0]
    steps = [{"added": current.name, "rmse_after": current.scores["rmse_after"],
              "shrink_pct": current.scores["shrink_pct"]}]
    for cand in significant[1:]:
        trial = fit_candidate((*current.effects, *cand.effects), current)
        gain = describe(trial, current.pred)
        if gain["significant"]:
            trial.scores = gain
            steps.append({"added": cand.name, "rmse_after": gain["rmse_after"],
                          "shrink_pct": gain["shrink_pct"]})
            current = trial
    return {"effects": list(current.effects), "steps": steps}


def diagnose(path: str | Path, options: DiagnoseOptions | None = None,
             progress: Callable[[str, int, int], None] | None = None) -> DiagnoseResult:
    """Load a session file and diagnose it (:func:`diagnose_session`)."""
    options = options or DiagnoseOptions()
    session, read_s = load_timed(path, options.aliases)
    result = diagnose_session(session, options, progress)
    result.timings["read_s"] = read_s
    return result


def diagnose_many(paths: Sequence[str | Path], options: DiagnoseOptions | None = None,
                  progress: Callable[[str, int, int], None] | None = None
                  ) -> tuple[list[DiagnoseResult], dict[str, Any]]:
    """Diagnose several sessions of one bike and disc, then pool their evidence.

    Raises
    ------
    DataError
        Sessions of different discs, or a session without the four spots pooling needs.
    """
    options = options or DiagnoseOptions()
    sessions = [load_timed(p, options.aliases)[0] for p in paths]
    discs = {s.path.name: disc_for(s, options.disc).id for s in sessions}
    if len(set(discs.values())) > 1:
        listing = ", ".join(f"{n}: {d}" for n, d in discs.items())
        raise DataError(f"diagnose pools sessions of one disc; these run {listing}: diagnose"
                        " each disc's sessions in their own call")
    for s in sessions:
        have = [i for i in range(1, 5) if s.has(f"disc_temp_spot{i}")]
        if len(have) < 4:
            raise DataError(
                "pooling several sessions needs the four-spot sensor in each; this one logs"
                f" {len(have)} spot(s): diagnose it alone", path=s.path)
    results = []
    for i, s in enumerate(sessions):
        def tick(label: str, done: int, total: int, i: int = i, name: str = s.path.name
                 ) -> None:
            if progress:
                progress(f"{name} ({i + 1}/{len(sessions)}): {label}", done, total)
        results.append(diagnose_session(s, options, tick))
    return results, pool(results)


def pool(results: Sequence[DiagnoseResult]) -> dict[str, Any]:
    """One verdict from several sessions: their held-out braking cycles resampled together.

    Per-session verdicts stay beside the pooled one; an effect significant in one run only
    is said so (a one-off — a gusty session, one set of pads — is not the disc).
    """
    names = [e.name for e in results[0].evidence]
    by_session = [{e.name: e for e in r.evidence} for r in results]
    ref = np.concatenate([r.reference_sse for r in results if r.reference_sse is not None])
    evidence = [
        CandidateEvidence(n, np.concatenate([b[n].sse for b in by_session]),
                          correction=np.concatenate([np.ravel(b[n].correction)
                                                     for b in by_session]),
                          separate_by=by_session[0][n].separate_by,
                          next_step=by_session[0][n].next_step, outputs=by_session[0][n].outputs)
        for n in names if all(n in b for b in by_session)]
    blind_sets = [{u["name"]: u["why"] for u in r.summary.get("untestable", [])}
                  for r in results]
    blind = {n: f"in every session — {why}" for n, why in blind_sets[0].items()
             if all(n in b for b in blind_sets)}
    decision = decide(ref, evidence, RULE, untestable=blind)
    stems = [r.stem for r in results]
    seen_in = {n: [r.stem for r in results for e in r.summary["effects"]
                   if e["name"] == n and e["significant"]] for n in names}
    rows = []
    for row in decision.rows:
        per = {r.stem: next(e["shrink_pct"] for e in r.summary["effects"]
                            if e["name"] == row["name"]) for r in results}
        rows.append({**row, "per_session_shrink_pct": per, "significant_in": seen_in[row["name"]]})
    notes = [f"{n} is significant in {seen_in[n][0]} only: a one-off of that run, or an effect"
             " the other runs cannot show" for n in names if len(seen_in[n]) == 1]
    gaps = [r.summary["gap"]["rmse_c"] for r in results]
    first = results[0].summary
    return {
        "sessions": [str(r.session.path) for r in results],
        "reference": first["reference"],
        "train_laps": {r.stem: r.summary["train_laps"] for r in results},
        "heldout_laps": {r.stem: r.summary["heldout_laps"] for r in results},
        "gap": {"rmse_c": float(np.sqrt(np.mean(np.square(gaps)))),
                "per_session": dict(zip(stems, gaps, strict=True))},
        "where": {r.stem: r.summary["where"]["by_spot_phase"] for r in results},
        "consistency": {r.stem: r.summary["consistency"] for r in results},
        "effects": rows,
        **decision.summary(),
        "per_session": [{"session": r.stem, "verdict": r.summary["verdict"],
                         "verdict_set": r.summary["verdict_set"]} for r in results],
        "notes": notes,
        "run": {"brakethermo": __version__, "disc": first["run"]["disc"],
                "pooled_units": int(ref.shape[0])},
    }


def write_pooled(summary: dict[str, Any], out_dir: str | Path) -> Path:
    """``<out>/pooled/diagnosis.json``; returns its path."""
    from brakethermo.pipelines.outputs import write_json

    return write_json(Path(out_dir) / "pooled" / "diagnosis.json", summary)


def write_diagnosis(result: DiagnoseResult, out_dir: str | Path) -> Path:
    """Write ``<out>/<stem>/diagnosis.json``, ``diagnosis.parquet`` and the report page.

    The page and its PNGs go to ``<out>/<stem>/diagnosis/`` (staged and swapped in whole)
    so they never mix with the estimate's per-lap reports in the same session folder.
    """
    import pandas as pd

    from brakethermo.io.atomic import atomic_dir
    from brakethermo.pipelines.outputs import write_json, write_parquet
    from brakethermo.report.diagnose_report import diagnosis_page
    from brakethermo.report.page import write_page
    from brakethermo.report.session_links import refresh_page_links

    folder = Path(out_dir) / result.stem
    folder.mkdir(parents=True, exist_ok=True)
    cols: dict[str, np.ndarray] = {"time": result.time, "lap": result.lap.astype(np.int64),
                                   "lap_distance": result.lap_distance}
    for i in range(4):
        cols[f"spot{i + 1}"] = result.y[:, i]
        cols[f"reference_spot{i + 1}"] = result.reference_pred[:, i]
        if result.best_pred is not None:
            cols[f"best_spot{i + 1}"] = result.best_pred[:, i]
    cols["nis"] = result.nis
    units = {c: {"unit": "degC"} for c in cols if "spot" in c}
    units.update(time={"unit": "s"}, lap_distance={"unit": "m"})
    write_parquet(folder / "diagnosis.parquet", pd.DataFrame(cols), units,
                  {"brakethermo": __version__, "session": str(result.session.path)})
    write_json(folder / "diagnosis.json", result.summary)
    page = diagnosis_page(result.summary, result.time, result.lap, result.y,
                          result.reference_pred, result.best_pred, result.lap_distance,
                          result.nis, result.stem)
    with atomic_dir(folder / "diagnosis") as tmp:
        write_page(page, tmp)
    refresh_page_links(folder)  # the session index links the page (or a small one does)
    return folder
