"""``whatif``: the session's own laps replayed with a change — a bigger duct, another disc,
a hotter day — anchored to the estimate.

The estimate (UKF + RTS smoother on the identified model) gives the disc state ``x_k`` at
every step. Against the model's own one-step prediction ``f(x_k)`` it leaves a correction
``w_k = x_{k+1} − f(x_k)``: what the measured laps say the model gets wrong (a pad that
bit harder, a gust, a model error). The scenario replays the same laps with the changed
model ``f'`` and the same corrections::

    x'_{k+1} = f'(x'_k) + w_k,        x'_0 = x_0

so the model predicts the change, the measurement fixes the rest, and a scenario that
changes nothing reproduces the estimate exactly. The rider is assumed to brake for the
same corners at the same speeds: the speed trace and the braking power of every stop are
the session's (a cooler disc does not make the rider brake differently), the identified
effects of the law (μ(T), the online k_z and h factors) ride along.

Changes: ``cooling`` scales the convection coefficient (a bigger duct; the rims' small
share scales with it); ``ambient_c`` sets the air temperature, and h with the air density
(``h ∝ ρ^0.8``, turbulent forced convection, ``ρ ∝ 1/T``); ``disc`` swaps the datasheet
(geometry, c(T), k(T), k_z, heat share; the identified through-thickness ratio, crown
weights and h law are kept: the same duct, wheel and pads); ``heat_share`` (other pads)
sets the share of the friction heat that enters the disc — the braking power is the
rider's, whatever the pad's friction level. Node ``i`` of the new disc
takes the correction of node ``i`` of the old (the same relative place on the ring).

Band: the estimate's own band, plus the spread of the replay over draws of the h law
(log-normal, ``h_rel_sigma``: the change's size scales with h), plus a model-structure
allowance of ``model_error_pct`` of the change itself, all in quadrature.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from brakethermo import __version__
from brakethermo.errors import ConfigError, DataError
from brakethermo.models.disc import DiscStateSpace
from brakethermo.models.effects import mu_ratio
from brakethermo.pipelines.estimate import (
    EstimateOptions,
    EstimateResult,
    estimate_from_session,
)
from brakethermo.pipelines.inputs import load_timed
from brakethermo.pipelines.models import DiscCalibration, calibration_for, disc_for, other_disc
from brakethermo.pipelines.outputs import write_json, write_parquet
from brakethermo.report.braking_zones import detect_zones, lap_distance, zone_names
from brakethermo.thermal.disc import DiscSpec, load_disc
from brakethermo.thermal.model import DiscFEModel
from brakethermo.thermal.tyre_radiation import TyreView, tyre_heat

DENSITY_EXPONENT = 0.8  # h ∝ Re^0.8 ∝ ρ^0.8 (turbulent forced convection)
H_REL_SIGMA = 0.08  # 1-sigma of the identified law's level, when the law does not say
MODEL_ERROR_PCT = 10.0  # % of the change: the model's structure is not the disc's
REPLAY_CHUNK = 512  # steps of the base predictions computed in one batched call


@dataclass(frozen=True)
class Scenario:
    """One change to replay.

    Parameters
    ----------
    cooling : float — dimensionless
        Factor on the convection coefficient (1.2 = a duct with 20 % more cooling).
    disc : str, optional
        Datasheet id or TOML file of another disc.
    ambient_c : float, optional — degC
        Air temperature.
    heat_share : float, optional — dimensionless
        Share of the friction heat entering the disc with other pads (the datasheet's is
        0.9): a pad compound of lower thermal effusivity sends more heat into the disc.
    """

    cooling: float = 1.0
    disc: str | None = None
    ambient_c: float | None = None
    heat_share: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.cooling) and 0.0 < self.cooling <= 10.0):
            raise ConfigError(f"--cooling {self.cooling}: the factor on the disc's convection"
                              " must be finite, above 0 and at most 10 (1.2 = 20 % more)")
        if self.ambient_c is not None and not (math.isfinite(self.ambient_c)
                                               and -40.0 <= self.ambient_c <= 60.0):
            raise ConfigError(f"--ambient {self.ambient_c}: give the air temperature in degC,"
                              " between -40 and 60")
        if self.heat_share is not None and not (math.isfinite(self.heat_share)
                                                and 0.3 <= self.heat_share <= 1.0):
            raise ConfigError(f"--pads {self.heat_share}: give the share of the friction heat"
                              " that enters the disc with those pads, 0.3 to 1 (datasheet 0.9)")

    @property
    def label(self) -> str:
        parts = []
        if self.cooling != 1.0:
            parts.append(f"cooling x{self.cooling:g}")
        if self.disc:
            parts.append(f"disc {Path(self.disc).stem}")
        if self.ambient_c is not None:
            parts.append(f"ambient {self.ambient_c:g} degC")
        if self.heat_share is not None:
            parts.append(f"pads heat share {self.heat_share:g}")
        return ", ".join(parts) or "no change"

    def describe(self) -> dict[str, Any]:
        return {"label": self.label, "cooling": self.cooling, "disc": self.disc,
                "ambient_c": self.ambient_c, "heat_share": self.heat_share}


@dataclass(frozen=True)
class WhatifOptions:
    """What ``whatif`` replays and how.

    Parameters
    ----------
    scenarios : tuple of Scenario
    h_law : path, optional — the law of the session's disc (default: the shipped one).
    h_law_reason : str — why that law, as ``estimate`` says it (``run.h_law_choice``).
    spot : int — the measured spot of the estimate.
    disc, tuning, aliases : optional — as for ``estimate``.
    ambient_c : float, optional — degC, the session's air when it logs none.
    draws : int — replays over the h law's uncertainty (besides the nominal one).
    h_rel_sigma : float, optional — relative 1-sigma of the law's level; default the
        law's ``[extra] h_rel_sigma``, else :data:`H_REL_SIGMA`.
    model_error_pct : float — % of the change added to the band.
    tyre : TyreView — geometry of the disc–tyre radiation.
    seed : int
    """

    scenarios: tuple[Scenario, ...] = (Scenario(),)
    h_law: str | Path | None = None
    h_law_reason: str = "given with --h-law"
    spot: int = 3
    disc: str | Path | None = None
    tuning: str | Path | None = None
    aliases: str | Path | None = None
    ambient_c: float | None = None
    draws: int = 12
    h_rel_sigma: float | None = None
    model_error_pct: float = MODEL_ERROR_PCT
    tyre: TyreView = field(default_factory=TyreView)
    seed: int = 0

    def __post_init__(self) -> None:
        if not self.scenarios:
            raise ConfigError("whatif needs at least one change: --cooling, --disc, --ambient,"
                              " --pads or --scenario")
        labels = [sc.label for sc in self.scenarios]
        twice = sorted({lab for lab in labels if labels.count(lab) > 1})
        if twice:
            raise ConfigError(f"scenario {', '.join(repr(t) for t in twice)} given twice: give"
                              " each change once")
        if self.draws < 0 or self.draws > 200:
            raise ConfigError(f"--draws {self.draws}: give 0 to 200 replays")
        if self.h_rel_sigma is not None and not (0.0 <= self.h_rel_sigma <= 1.0):
            raise ConfigError(f"h_rel_sigma {self.h_rel_sigma} must be in [0, 1]")


@dataclass
class Replay:
    """One scenario replayed: readouts per step and their band."""

    scenario: Scenario
    disc: DiscSpec
    spots: np.ndarray  # (K, 4) degC
    contact: np.ndarray  # (K,) degC
    contact_std: np.ndarray  # (K,) degC
    hottest: np.ndarray  # (K,) degC, hottest face node
    tyre_w: np.ndarray  # (K,) W
    mu_rel: np.ndarray  # (K,)
    time_s: float


@dataclass
class WhatifResult:
    """The estimate, the base as replayed and each scenario; :attr:`summary` is summary.json."""

    estimate: EstimateResult
    base: Replay
    replays: list[Replay]
    frame: pd.DataFrame
    summary: dict[str, Any]

    @property
    def stem(self) -> str:
        return self.estimate.stem


def _mu_assumption(est: EstimateResult) -> str:
    """Where μ/μ_nom comes from, in words: the law's μ(T), a μ(T) the race dropped (its own
    evidence), or none identified."""
    if est.state_space.effects.mu_beta:
        return "μ/μ_nom from the identified μ(T) of the law"
    dropped = est.summary["run"].get("online_choice", {}).get("law_effects_dropped", [])
    if "friction_temperature" in dropped:
        return ("μ/μ_nom constant: the law carries an identified μ(T), but this race's own"
                " held-out innovations did not support it and the estimate dropped it (its"
                " evidence: run.online_choice in this what-if's whatif/summary.json)")
    return "μ/μ_nom constant: the law carries no identified μ(T)"


def _checked_law(h_law: str | Path | None, disc: DiscSpec) -> DiscCalibration:
    """The law, read and checked; a law of another disc cannot predict this one."""
    cal = calibration_for(disc, h_law)
    mismatch = other_disc(cal, disc, "--disc-of-session")
    if mismatch:
        raise ConfigError(mismatch)
    return cal


def _law_choice(options: WhatifOptions, est: EstimateResult) -> tuple[str, list[str]]:
    """Which h law the replay ran on, in words, and the run's warnings: without ``--h-law``
    the law shipped for the disc, said as ``estimate`` says it (it was used silently).

    Returns
    -------
    choice : str
        ``run.h_law_choice`` of the summary.
    warnings : list of str
        The estimate's warnings, after the shipped-law one where it applies.
    """
    from brakethermo.pipelines.models import SHIPPED_DEFAULT, SHIPPED_LAW_NOTE

    warnings = list(est.summary["run"]["warnings"])
    if options.h_law is not None:
        return options.h_law_reason, warnings
    return (f"{SHIPPED_DEFAULT} for disc {est.disc.id}",
            [f"no h law of this bike (no --h-law): {SHIPPED_LAW_NOTE}", *warnings])


def _scenario_disc(scenario: Scenario, disc: DiscSpec) -> DiscSpec:
    if not scenario.disc:
        return disc
    try:
        return load_disc(scenario.disc)
    except ConfigError:
        raise
    except (OSError, ValueError) as exc:
        raise ConfigError(f"--disc {scenario.disc}: {exc}") from None


def _space_for(base: DiscStateSpace, model: Any, q: np.ndarray, t_amb: np.ndarray,
               h: np.ndarray, spot_radius: float) -> DiscStateSpace:
    """A state space like ``base`` with other inputs (2-D inputs: one column per member)."""
    return DiscStateSpace(model, q, t_amb, h, base.params, sigma_temp=0.0, sigma_crown=0.0,
                          effects=base.effects, spot_radius=spot_radius)


def _spot_rows(model: DiscFEModel, disc: DiscSpec) -> np.ndarray:
    """Read-out rows (5, n_state): spot1..4 at the datasheet radii, then the contact band."""
    H = model.spot_matrix(np.asarray(disc.spot_radii))
    return np.vstack([H, H[1:4].mean(axis=0, keepdims=True)])


def replay(est: EstimateResult, scenario: Scenario, options: WhatifOptions,
           h_rel_sigma: float) -> Replay:
    """Replay the estimate's laps with ``scenario`` (module docstring)."""
    t0 = time.perf_counter()
    ssm = est.state_space
    X = est.states
    if ssm is None or X is None:
        raise DataError("the estimate kept no state trajectory to replay",
                        path=est.session.path)
    disc0 = est.disc
    disc1 = _scenario_disc(scenario, disc0)
    model0 = ssm.model
    model1 = model0
    if disc1 is not disc0:
        kz = model0.kz_ratio
        if disc0.k_z and disc1.k_z:
            kz *= disc1.k_z / disc0.k_z  # the identified ratio to nominal carries over
        model1 = DiscFEModel(disc1, model0.n_nodes, model0.layers, weights=model0.weights,
                             kz_ratio=kz, layer_growth=model0.layer_growth)

    K = X.shape[0]
    rng = np.random.default_rng(options.seed)
    g = np.concatenate([[1.0], np.exp(h_rel_sigma * rng.standard_normal(options.draws))])
    S = g.size
    h0 = np.asarray(ssm.h, float)
    ta0 = np.asarray(ssm.t_amb, float)
    q0 = np.asarray(ssm.q_brk, float)
    h1, ta1, q1 = h0 * scenario.cooling, ta0.copy(), q0
    if scenario.ambient_c is not None:
        ta1 = np.full(K, scenario.ambient_c)
        h1 = h1 * ((ta0 + 273.15) / (ta1 + 273.15)) ** DENSITY_EXPONENT
    share = disc1.heat_share if scenario.heat_share is None else scenario.heat_share
    q1 = q0 * share / disc0.heat_share
    spot_r = float(disc0.spot_radii[options.spot - 1])
    # the base model's one-step predictions from the estimate are independent of each
    # other: one batched call per chunk of steps, member k S + s at step k with draw s
    base = _space_for(ssm, model0, np.repeat(q0, S), np.repeat(ta0, S),
                      (h0[:, None] * g).ravel(), spot_r)
    scen = _space_for(ssm, model1, q1, np.repeat(ta1[:, None], S, 1), h1[:, None] * g,
                      float(disc1.spot_radii[options.spot - 1]))
    n = X.shape[1]
    Xs = np.empty((K, S, n))
    Xs[0] = X[0]
    for a in range(0, K - 1, REPLAY_CHUNK):
        b = min(K - 1, a + REPLAY_CHUNK)
        pred = base.f(np.repeat(X[a:b], S, axis=0), np.arange(a * S, b * S))
        w = X[a + 1:b + 1, None, :] - pred.reshape(b - a, S, n)
        Xs[a:b + 1] = scen.replay(Xs[a], w, a)
    T = Xs[:, :, : model1.n_state]
    # the change (K, S, 5) at spot1..4 and the contact band, anchored to the published
    # estimate: a scenario that changes nothing is the estimate itself
    delta = (np.einsum("ksn,in->ksi", T, _spot_rows(model1, disc1))
             - (X[:, : model0.n_state] @ _spot_rows(model0, disc0).T)[:, None, :])
    # the replayed state itself, read out on the scenario disc: it follows the estimate's
    # corrections, so it is the estimate plus the change; a disc is never colder than the
    # air (the estimate's own projection, Simon & Chia 2002)
    out = np.fmax(T[:, 0] @ _spot_rows(model1, disc1).T, ta1[:, None])
    est_std = est.frame["contact_avg_std"].to_numpy()
    spread = delta[:, 1:, 4].std(axis=1) if S > 1 else np.zeros(K)
    std = np.sqrt(est_std**2 + spread**2
                  + (0.01 * options.model_error_pct * delta[:, 0, 4]) ** 2)
    face = T[:, 0, model1.face_index]
    return Replay(scenario, disc1, out[:, :4], out[:, 4], std, face.max(axis=1),
                  tyre_heat(face, model1.radii, disc1.r_int, disc1.r_est, disc1.emissivity,
                            options.tyre),
                  _mu_rel(ssm, out[:, 4]), time.perf_counter() - t0)


def _mu_rel(ssm: DiscStateSpace, contact_c: np.ndarray) -> np.ndarray:
    """μ/μ_nom at the contact-band temperature: the identified μ(T), else constant."""
    fx = ssm.effects
    if fx.mu_beta:
        return mu_ratio(contact_c, fx.mu_beta, fx.mu_t_mid_c)
    return np.ones_like(contact_c)


def _base_replay(est: EstimateResult, options: WhatifOptions) -> Replay:
    """The session as estimated, with the same derived columns as a scenario."""
    model = est.state_space.model
    X = est.states[:, : model.n_state]
    face = X[:, model.face_index]
    disc = est.disc
    contact = est.frame["contact_avg"].to_numpy()
    spots = est.frame[[f"spot{i}" for i in range(1, 5)]].to_numpy()
    return Replay(Scenario(), disc, spots, contact, est.frame["contact_avg_std"].to_numpy(),
                  face.max(axis=1),
                  tyre_heat(face, model.radii, disc.r_int, disc.r_est, disc.emissivity,
                            options.tyre),
                  _mu_rel(est.state_space, contact), 0.0)


def lap_figures(r: Replay, lap: np.ndarray, braking: np.ndarray, dt: float
                ) -> dict[int, dict[str, float]]:
    """Per lap: time in / above the window, peaks, heat to the tyre, least μ when braking."""
    lo, hi = r.disc.window_c
    out = {}
    for n in np.unique(lap):
        m = lap == n
        c = r.contact[m]
        b = m & braking
        out[int(n)] = {
            "time_in_window_pct": float(100.0 * np.mean((c >= lo) & (c <= hi))),
            "time_above_s": float(np.sum(c > hi) * dt),
            "peak_contact_c": float(np.max(c)),
            "peak_contact_std_c": float(r.contact_std[m][np.argmax(c)]),
            "peak_contact_band95_c": float(1.96 * r.contact_std[m][np.argmax(c)]),
            "hottest_radius_c": float(np.max(r.hottest[m])),
            "tyre_heat_kj": float(np.sum(r.tyre_w[m]) * dt / 1000.0),
            "tyre_heat_peak_w": float(np.max(r.tyre_w[m])),
            "mu_rel_min": float(np.min(r.mu_rel[b])) if b.any() else float("nan"),
        }
    return out


def zone_figures(r: Replay, zones: np.ndarray, lap: np.ndarray, names: list[str]
                 ) -> list[dict[str, Any]]:
    """Per braking zone (named by track position, as the lap reports): peak contact and μ."""
    return [{"lap": int(lap[a]), "zone": name, "peak_contact_c": float(np.max(r.contact[a:b])),
             "mu_rel_min": float(np.min(r.mu_rel[a:b]))}
            for (a, b), name in zip(zones, names, strict=True)]


def _frame(est: EstimateResult, base: Replay, replays: list[Replay]) -> pd.DataFrame:
    cols: dict[str, np.ndarray] = {"time": est.frame["time"].to_numpy(),
                                   "lap": est.frame["lap"].to_numpy()}
    cols["base_contact_avg"] = base.contact
    for i in range(4):
        cols[f"base_spot{i + 1}"] = base.spots[:, i]
    cols["base_tyre_heat_w"] = base.tyre_w
    cols["base_mu_rel"] = base.mu_rel
    for j, r in enumerate(replays, start=1):
        sfx = "" if j == 1 else f"_{j}"
        cols[f"contact_avg{sfx}"] = r.contact
        cols[f"contact_avg_std{sfx}"] = r.contact_std
        for i in range(4):
            cols[f"spot{i + 1}{sfx}"] = r.spots[:, i]
        cols[f"hottest_radius{sfx}"] = r.hottest
        cols[f"tyre_heat_w{sfx}"] = r.tyre_w
        cols[f"mu_rel{sfx}"] = r.mu_rel
    return pd.DataFrame(cols)


def _assumptions(est: EstimateResult) -> list[str]:
    """The replay's assumptions, in words (``assumptions`` of the summary)."""
    return [
        "same speed trace and the same braking power at every stop (the rider brakes"
        " for the same corners)",
        "the laps' own model corrections replayed on the changed model, so the model"
        " predicts the change and the measured laps fix the rest",
        "cooling scales the convection coefficient of faces and rims; ambient changes"
        f" the air and h with its density (h ∝ ρ^{DENSITY_EXPONENT:g})",
        "another disc keeps the identified h law, crown weights and k_z ratio to its"
        " nominal",
        "heat to the tyre: one disc's inner face to the sidewall annulus, exact view"
        " factor of coaxial parallel annuli, grey bodies, shading ignored (an upper"
        " bound of the direct exchange); two discs on the wheel give twice this",
        _mu_assumption(est),
    ]


def whatif_session(path: str | Path, options: WhatifOptions) -> WhatifResult:
    """Estimate the session, then replay its laps under each scenario."""
    t0 = time.perf_counter()
    session, read_s = load_timed(path, options.aliases)
    cal = _checked_law(options.h_law, disc_for(session, options.disc))
    for s in options.scenarios:  # an unknown disc before any work
        if s.disc:
            _scenario_disc(s, disc_for(session, options.disc))
    est = estimate_from_session(session, EstimateOptions(
        spot=options.spot, h_law=cal, disc=options.disc, tuning=options.tuning,
        aliases=options.aliases, ambient_c=options.ambient_c, score=False))
    law_choice, warnings = _law_choice(options, est)
    h_sig = options.h_rel_sigma
    if h_sig is None:
        h_sig = H_REL_SIGMA if cal.h_rel_sigma is None else cal.h_rel_sigma
    base = _base_replay(est, options)
    replays = [replay(est, s, options, h_sig) for s in options.scenarios]
    lap = est.frame["lap"].to_numpy()
    q = est.frame["braking_power"].to_numpy()
    braking = q > 0.01 * max(float(np.max(q, initial=0.0)), 1.0)
    dt = session.dt
    zones = detect_zones(est.frame["time"].to_numpy(), session.values("brake_pressure_front"))
    names = zone_names(zones, lap, lap_distance(
        lap, session.values("speed"), dt,
        session.values("distance") if session.has("distance") else None))
    base_laps = lap_figures(base, lap, braking, dt)
    scen_laps = [lap_figures(r, lap, braking, dt) for r in replays]
    laps = []
    durations = {lp.lap: lp.duration_s for lp in session.laps}  # as the estimate reports them
    for n, b in base_laps.items():
        t_lap = round(float(durations.get(n, np.sum(lap == n) * dt)), 3)
        row: dict[str, Any] = {"lap": n, "lap_time_s": t_lap, "base": b}
        for r, figs in zip(replays, scen_laps, strict=True):
            row[r.scenario.label] = figs[n]
        laps.append(row)
    summary = {
        "session": str(session.path),
        "metadata": session.metadata,
        "scenarios": [r.scenario.describe() for r in replays],
        "laps": laps,
        "zones": {"base": zone_figures(base, zones, lap, names),
                  **{r.scenario.label: zone_figures(r, zones, lap, names) for r in replays}},
        "assumptions": _assumptions(est),
        "run": {
            "brakethermo": __version__,
            "h_law": est.summary["run"]["h_law"],
            "h_law_sha256": est.summary["run"].get("h_law_sha256"),
            "disc": est.disc.id,
            "window_c": list(est.disc.window_c),
            "measured_spot": options.spot,
            "draws": options.draws,
            "h_rel_sigma": h_sig,
            "model_error_pct": options.model_error_pct,
            "tyre_view": {"rim_radius_m": options.tyre.rim_radius,
                          "tyre_radius_m": options.tyre.tyre_radius,
                          "gap_m": options.tyre.gap, "emissivity": options.tyre.emissivity,
                          "carcass_c": options.tyre.carcass_c},
            "estimate_s": est.timings.get("total_s", float("nan")),
            "replay_s": [r.time_s for r in replays],
            "read_s": read_s,
            "wall_time_s": time.perf_counter() - t0,
            "h_law_choice": law_choice,
            # the race's own decision on the law's effects, which the μ assumption cites:
            # whatif writes no estimate summary.json of its own, so the evidence is here
            "online_choice": est.summary["run"].get("online_choice", {}),
            "warnings": warnings,
        },
    }
    return WhatifResult(est, base, replays, _frame(est, base, replays), summary)


def write_whatif(result: WhatifResult, out: str | Path) -> Path:
    """``DIR/<stem>/whatif.parquet`` and ``DIR/<stem>/whatif/summary.json``; the folder.

    The summary sits in the ``whatif/`` folder with the page, so it never replaces the
    ``summary.json`` of ``estimate`` in the same session folder.
    """
    folder = Path(out) / result.stem
    meta = {c: {"unit": "degC"} for c in result.frame.columns
            if c.startswith(("base_contact", "base_spot", "contact_avg", "spot", "hottest"))}
    meta.update({c: {"unit": "W"} for c in result.frame.columns if "tyre_heat_w" in c})
    meta["time"] = {"unit": "s"}
    write_parquet(folder / "whatif.parquet", result.frame, meta,
                  {"brakethermo": __version__, "session": str(result.estimate.session.path)})
    write_json(folder / "whatif" / "summary.json", result.summary)
    return folder
