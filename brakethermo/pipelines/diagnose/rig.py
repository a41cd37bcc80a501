"""``diagnose`` on a rig session: where the rig's trained relation parts from this
session's sensor, which unmodelled effect causes it, and how far the gap shrinks — on
held-out apply cycles, with the same verdict engine as the disc.

Rigs: the E-Booster (the training p–V curve against the master-cylinder pressure) and the
EMB caliper (the trained dynamic stiffness, eq. 6, against the clamp-force sensor).

1. **Reference model**: the rig's relation from its training session, as its estimator
   uses it. Nothing of it is refitted here: the question is whether this session's rig
   still follows the training day's.
2. **Split**: the session's apply cycles (the input leaving rest and returning)
   alternate between fitting and held out; a session of fewer than
   :data:`MIN_CYCLES` cycles is cut into :data:`BLOCK_S` blocks instead.
3. **Which**: each candidate of :mod:`brakethermo.models.rig_effects` fitted on the
   fitting cycles, scored on the held-out ones (RMSE shrink, bootstrap over cycles).
4. **Verdict**: :func:`brakethermo.diagnosis.verdict.decide` — a single name only when it
   beats every other clearly and is no look-alike, else the set, or ``"none"``. A
   candidate whose correction is smaller than the output sensor's accuracy (or the
   trained relation's own residual: twice the booster's p-V residual, once the caliper's
   stiffness residual, whose hysteresis makes it large on a real caliper — at twice it
   worn pads an independent caliper showed plainly, 28-33 % held-out shrink, were set
   aside) is reported but never named: between two sessions the sensor's own offset
   could do as much.

Needs the output's sensor (a bench or validation session): a production session without
it cannot be compared with anything and is refused with one line.
"""

from __future__ import annotations

import itertools
import shlex
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from brakethermo import __version__
from brakethermo.diagnosis.verdict import (
    CandidateEvidence,
    VerdictRule,
    decide,
    shrink_interval,
    unit_sse,
)
from brakethermo.errors import ConfigError, DataError
from brakethermo.io.session import Session
from brakethermo.io.units import unit_suffix
from brakethermo.models.ebooster import BoosterFit, load_fit
from brakethermo.models.rig_effects import BOOSTER_EFFECTS, EMB_EFFECTS, RigContext, RigEffect
from brakethermo.numeric import rmse
from brakethermo.pipelines.diagnose._common import filled
from brakethermo.pipelines.ebooster import (
    MM,
    MPA,
    S2,
    _series,
    booster_context,
    default_fit_path,
    fit_training,
    load_booster_session,
)
from brakethermo.results.ebooster import PRESSURES
from brakethermo.results.rig_diagnosis import RigDiagnosis
from brakethermo.rigs.booster_datasheet import load_booster
from brakethermo.rigs.signals import SPEED_WINDOW_S, smoothed_rate

MIN_CYCLES = 12  # apply cycles for a cycle-wise split (6 held out); fewer: time blocks
BLOCK_S = 1.0  # s, unit length when the session holds too few cycles
RULE = VerdictRule(min_shrink_pct=10.0)
UNEXPLAINED_FLOORS = 3.0  # a held-out gap this many floors wide is said unexplained
CHANGED_SHARE = 1.25  # ... or this many times the reference's training residual
TIE_SHARE = 0.8  # share of the floor a candidate passes when another passes it whole
RIG_FILES = ("diagnosis.json", "diagnosis.parquet", "diagnosis")


@dataclass(frozen=True)
class RigCase:
    """One rig's diagnosis problem, in the rig's own units."""

    rig: str
    session: Session
    effects: dict[str, RigEffect]
    ctx: RigContext
    measured: np.ndarray
    rest: float  # input below which the rig is at rest
    floor: float  # correction size below which a candidate is never named
    unit: str  # of the output
    input_name: str
    input_unit: str
    reference_text: str
    reference_fit: dict[str, Any]
    next_step: Any  # callable(name, fitted parameters) -> str
    block_s: float = BLOCK_S  # s, unit length when the session holds too few apply cycles
    notes: tuple[str, ...] = ()  # the training session's warnings (e.g. resampled)
    cycle: str = "apply cycle"  # what a stretch off rest is on this rig
    floor_text: str = "the sensor floor"  # what ``floor`` is, in words
    train_rmse: float | None = None  # the reference's held-out residual on its training
    phases: tuple[str, str, str] = ("applying", "releasing", "holding")  # input up/down/still


def apply_units(x: np.ndarray, t: np.ndarray, rest: float, block_s: float = BLOCK_S,
                cycle: str = "apply cycle") -> tuple[np.ndarray, str]:
    """Unit id per sample (-1 at rest) and what a unit is (``cycle``, a stretch off rest,
    or a time block)."""
    active = x > rest
    starts = np.flatnonzero(np.diff(active.astype(np.int8)) == 1) + 1
    if active[0]:
        starts = np.r_[0, starts]
    if starts.size >= MIN_CYCLES:
        ids = np.searchsorted(starts, np.arange(x.size), side="right") - 1
        return np.where(active & (ids >= 0), ids, -1), cycle
    blocks = np.floor((t - t[0]) / block_s).astype(int)
    return np.where(active, blocks, -1), f"{block_s:g} s block"


def _fit_effect(e: RigEffect, ctx: RigContext, y: np.ndarray, mask: np.ndarray,
                scale: float) -> np.ndarray:
    sol = least_squares(lambda th: (e.predict(th, ctx) - y)[mask], np.array(e.start),
                        bounds=(np.array(e.lower), np.array(e.upper)), method="trf",
                        loss="soft_l1", f_scale=scale)
    return sol.x


def diagnose_booster(
    path: str | Path,
    *,
    train_path: str | Path | None = None,
    fit_path: str | Path | None = None,
    bench: str | Path = "ebooster",
    aliases: str | Path | None = None,
    effects: str | None = "all",
    fit: BoosterFit | None = None,
) -> RigDiagnosis:
    """Diagnose an E-Booster session with a pressure sensor (module docstring); ``fit``, when
    given, is the training result already at hand (``train_path`` and ``fit_path`` unused)."""
    t_start = time.perf_counter()
    names = effect_names(effects, BOOSTER_EFFECTS, "E-Booster")
    spec = load_booster(bench)
    if fit is None:  # the p-V relation only: the observers' noise is not diagnosed
        fit = (fit_training(load_booster_session(train_path, aliases, training=True), spec)
               if train_path is not None else load_fit(fit_path or default_fit_path()))
    session = load_booster_session(path, aliases)
    channel = PRESSURES["p_m"]
    if not session.has(channel):
        raise DataError(
            "has no master-cylinder pressure: diagnose compares the training p-V curve with"
            " this session's pressures, so it needs a bench or validation session that logs"
            " them (a production session can only be observed: brakethermo ebooster)",
            path=session.path, channel=channel)
    s2 = _series(session, S2, MM, gaps=False)
    case = RigCase(
        "ebooster", session, {n: BOOSTER_EFFECTS[n] for n in names},
        booster_context(session, s2, fit),
        _series(session, channel, MPA, gaps=True), rest=0.5,
        # a pressure transducer's accuracy: 0.5 % of a 10 MPa range
        floor=max(0.05, 2.0 * fit.pv_rmse_mpa), unit="MPa", input_name="s2",
        floor_text="the floor (twice the training p-V curve's residual, the finest the"
                   " reference resolves, or a transducer's 0.05 MPa)",
        # held out on the training session's own blocks where the curve was chosen so
        train_rmse=min(fit.pv_heldout_mpa) if fit.pv_heldout_mpa else 2.0 * fit.pv_rmse_mpa,
        input_unit="mm",
        reference_text=f"the p-V curve of the training session {fit.train_session},"
                       f" p_m = f(s2) ({fit.pv_curve}), as the observer uses it (not refitted"
                       " here)",
        reference_fit={"pv_coeffs_mpa": list(fit.pv_coeffs), "stroke_mm": fit.stroke_mm,
                       "pv_knots_mm": list(fit.pv_knots_mm),
                       "pv_knot_mpa": list(fit.pv_knot_mpa)},
        next_step=lambda n, _: _booster_step(n, path))
    return run_case(case, t_start)


def diagnose_emb(
    path: str | Path,
    *,
    train_path: str | Path,
    aliases: str | Path | None = None,
    effects: str | None = "all",
) -> RigDiagnosis:
    """Diagnose an EMB caliper session with the clamp-force sensor (module docstring)."""
    from brakethermo.models.clamp_force import CV_BLOCK_S
    from brakethermo.models.clamp_force import train as train_emb
    from brakethermo.pipelines.clamp_force import (
        MIN_TRAIN_S,
        choose_sensor_lag,
        load_emb_at_one_rate,
    )
    from brakethermo.rigs.emb import sensor_delagged

    t_start = time.perf_counter()
    names = effect_names(effects, EMB_EFFECTS, "EMB")
    tr, data = load_emb_at_one_rate([(train_path, True, "training"),
                                     (path, False, "diagnosed")], aliases)
    if data.force is None:
        raise DataError(
            "has no clamp-force sensor: diagnose compares the trained stiffness model with"
            " this session's clamp force, so it needs a session that logs it (one without"
            " can only be estimated: brakethermo clamp-force)",
            path=data.session.path, channel="clamp_force")
    lag = choose_sensor_lag(tr.theta, tr.current, tr.force, tr.ts)
    own = choose_sensor_lag(data.theta, data.current, data.force, data.ts)
    if own is None:
        raise DataError(
            f"is {data.force.size * data.ts:.1f} s long; diagnose fits on some blocks of"
            f" {CV_BLOCK_S:g} s and checks on others, so it needs at least {MIN_TRAIN_S:g} s"
            " of the caliper working", path=data.session.path, channel="clamp_force")
    assert lag is not None  # the training session has the sensor and its length
    models = train_emb(tr.theta, tr.current, tr.force, tr.ts, sensor_lag_s=lag.lag_s,
                       eq7=lag.eq7)
    ds = models.stiffness
    # each sensor with its own lag taken out: the models were fitted so, and a leftover
    # lag would pass for a rate-dependent stiffness
    force = sensor_delagged(data.force, own.lag_s, data.ts)
    theta = data.theta
    rest = float(np.percentile(theta, 5) + 0.05 * np.ptp(theta))
    case = RigCase(
        "emb", data.session, {n: EMB_EFFECTS[n] for n in names},
        RigContext(theta, smoothed_rate(theta, data.ts, SPEED_WINDOW_S),
                   data.session.time - data.session.time[0], lambda x: ds.simulate(x) / 1e3),
        force / 1e3, rest=rest,
        # a load cell's accuracy (0.5 % of a 40 kN range), or the model's own residual
        floor=max(0.2, models.sigma_ds / 1e3), unit="kN", input_name="motor angle",
        floor_text="the floor (the stiffness model's residual on its training session, or"
                   " a load cell's 0.2 kN)",
        train_rmse=models.sigma_ds / 1e3,
        input_unit="rad",
        reference_text=f"the dynamic stiffness (eq. 6) of the training session"
                       f" {tr.session.path}, as the clamp-force filter uses it (not refitted"
                       " here)" + _lags_said(lag.lag_s, own.lag_s),
        reference_fit={"alpha0": ds.alpha0, "beta": list(ds.beta)},
        next_step=lambda n, _: (f"re-train on a session of these pads: brakethermo clamp-force"
                             f" SESSION --train {train_path} --retrain {path}  (the adaptive"
                             " filter follows a stiffness scale on its own)"),
        notes=tr.session.warnings)
    return run_case(case, t_start)


def _lags_said(train_lag_s: float, own_lag_s: float) -> str:
    """The force sensors' lags taken out, in words ('' when neither had one)."""
    if train_lag_s <= 0.0 and own_lag_s <= 0.0:
        return ""
    return (f"; force sensors de-lagged (F + τ dF/dt): the training session's by about"
            f" {train_lag_s * 1e3:g} ms, this session's by {own_lag_s * 1e3:g} ms")


@dataclass(frozen=True)
class _Split:
    """The session's units off rest, alternately fitting and held out."""

    kind: str  # what a unit is ("apply cycle", "1 s block")
    ids: np.ndarray  # every unit with a sensor reading, in increasing order
    held_ids: np.ndarray  # the held-out ones (every second)
    held: np.ndarray  # (K,) bool, samples of the held-out units
    fitting: np.ndarray  # (K,) bool, samples of the fitting units
    scored: np.ndarray  # (K,) held-out unit id per sample, -1 elsewhere


def _split(case: RigCase) -> _Split:
    """The session's apply cycles (or blocks) with a sensor reading, alternately fitting
    and held out (module docstring, step 2); DataError when fewer than 4."""
    ctx, y = case.ctx, case.measured
    units, unit_kind = apply_units(ctx.x, ctx.t, case.rest, case.block_s, case.cycle)
    units = np.where(np.isfinite(y), units, -1)
    ids = np.unique(units[units >= 0])
    if ids.size < 4:
        raise DataError(
            f"holds {ids.size} {unit_kind}(s) off rest with a sensor reading; the diagnosis"
            " fits on half of them and scores on the other half: record a session with at"
            " least 4", path=case.session.path)
    held_ids = ids[1::2]
    held = np.isin(units, held_ids)
    fitting = (units >= 0) & ~held
    return _Split(unit_kind, ids, held_ids, held, fitting, np.where(held, units, -1))


def _fit_effects(case: RigCase, fitting: np.ndarray
                 ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, float]]]:
    """Each candidate fitted on the ``fitting`` samples: its prediction over the whole
    session (the output's unit) and its parameters by name."""
    preds: dict[str, np.ndarray] = {}
    params: dict[str, dict[str, float]] = {}
    for name, e in case.effects.items():
        theta = _fit_effect(e, case.ctx, case.measured, fitting, case.floor)
        preds[name] = e.predict(theta, case.ctx)
        params[name] = {k: float(v) for k, v in zip(e.params, theta, strict=True)}
    return preds, params


def _negligible_reasons(case: RigCase, rows: dict[str, dict[str, Any]], size: dict[str, float],
                        negligible: set[str], cut: float) -> list[str]:
    """Why each negligible candidate that would have been significant is not named."""
    return [
        f"{n} shrinks the gap by {rows[n]['shrink_pct']:.0f} %"
        f" [{rows[n]['shrink_ci95_pct'][0]:.0f}, {rows[n]['shrink_ci95_pct'][1]:.0f}] but"
        f" corrects it by {size[n]:.3g} {case.unit} RMS, below {case.floor_text}"
        f" {case.floor:.3g} {case.unit}"
        + (f" (lowered to {TIE_SHARE:g}x, as another candidate passes it)" if cut < case.floor
           else "") + ": set aside as negligible"
        for n in sorted(negligible) if rows[n]["shrink_ci95_pct"][0] > RULE.min_shrink_pct]


def rig_consistency(case: RigCase, residual: np.ndarray, split: _Split) -> dict[str, Any]:
    """The reference's held-out residual as a mean NIS with its χ² band (OUTPUTS.md).

    No filter runs on a rig diagnosis: the trained relation is compared with the sensor.
    Its residual normalised by the spread the reference admits — its residual on the
    training session where the rig has one, else on this session's fitting units —
    is the normalised innovation a filter on that model would show, one component a
    sample.

    Parameters
    ----------
    case : RigCase
    residual : ndarray (K,)
        Reference minus sensor, the output's unit.
    split : _Split

    Returns
    -------
    dict
        ``per_channel`` (the output's name: ``mean_nis``, ``chi2_band``,
        ``lag1_autocorrelation``, ``state``, ``structured``, ``n``), ``sigma`` (the
        output's unit) and ``sigma_source``, ``summary`` (a sentence) and ``note`` (that
        no filter runs).
    """
    from brakethermo.estimation.consistency import nis_consistency

    own = rmse(residual[split.fitting], 0.0)
    sigma, source = ((case.train_rmse, "the reference's residual on its training session")
                     if case.train_rmse else
                     (own, "the reference's residual on this session's fitting units"))
    sigma = max(float(sigma), 1e-12)
    r = residual[split.held]
    c = nis_consistency((r / sigma) ** 2, 1, r)
    keys = ("mean_nis", "chi2_band", "lag1_autocorrelation", "state", "structured", "n")
    band = f"{c['chi2_band'][0]:.2f}-{c['chi2_band'][1]:.2f}"
    said = (f"held out, the reference's mean NIS is {c['mean_nis']:.3g} against its χ² band"
            f" {band} (σ {sigma:.3g}{unit_suffix(case.unit)}, {source}): {c['state']}"
            + (f"; its residual is structured (lag-1 autocorrelation"
               f" {c['lag1_autocorrelation']:.2f}), so the band says little" if c["structured"]
               else ""))
    return {"per_channel": {RIG_OUTPUT.get(case.rig, case.rig): {k: c[k] for k in keys}},
            "sigma": sigma, "sigma_unit": case.unit, "sigma_source": source,
            "summary": said,
            "note": "no filter runs here: the trained relation is compared with the sensor"
                    " directly; the NIS normalises its residual by sigma"}


# what each rig's diagnosis compares with its sensor (the consistency's channel)
RIG_OUTPUT = {"ebooster": "pressure", "emb": "clamp_force", "roller-rig": "creep_force",
              "tyre": "mu"}


def run_case(case: RigCase, t_start: float) -> RigDiagnosis:
    """The diagnosis proper, whatever the rig (module docstring, steps 2-4)."""
    ctx, y, session = case.ctx, case.measured, case.session
    split = _split(case)
    held, scored = split.held, split.scored
    ref = ctx.curve(ctx.x)
    ref_sse = unit_sse(ref - y, scored)[0]
    preds, params = _fit_effects(case, split.fitting)
    names = tuple(case.effects)
    edge = {name: at_bound_words(case.effects[name], params[name]) for name in names}
    evidence = [CandidateEvidence(
        name, unit_sse(preds[name] - y, scored)[0], correction=(preds[name] - ref)[held],
        separate_by=case.effects[name].separate_by, next_step=case.next_step(name, params[name]),
        n_params=len(case.effects[name].params), at_bound=edge[name])
        for name in names]
    size = {name: rmse((preds[name] - ref)[held], 0.0) for name in names}
    cut = negligible_cut(size, case.floor)
    negligible = {n for n in names if not size[n] >= cut}
    decision = decide(ref_sse, [e for e in evidence if e.name not in negligible], RULE)
    rows = {r["name"]: r for r in decision.rows}
    # the negligible ones after those the verdict weighed, by their shrink: they came in
    # the registry's order under a title saying "in the verdict's order"
    shrinks = {e.name: shrink_interval(ref_sse, e.sse, RULE) for e in evidence
               if e.name in negligible}
    for name in sorted(shrinks, key=lambda n: -shrinks[n][0]):
        point, lo, hi = shrinks[name]
        rows[name] = {"name": name, "shrink_pct": point, "shrink_ci95_pct": [lo, hi],
                      "significant": False, "rank": len(rows) + 1}
    best = decision.verdict if decision.verdict != "none" else None
    gap = rmse((ref - y)[held], 0.0)
    unexplained = ([] if best is not None or decision.undecided
                   else _unexplained(case, gap, split.kind))
    effects_out = []
    for name in sorted(names, key=lambda n: rows[n]["rank"]):
        e, r = case.effects[name], rows[name]
        effects_out.append({
            "name": name, "rank": r["rank"],
            "rmse_before": rmse((ref - y)[held], 0.0),
            "rmse_after": rmse((preds[name] - y)[held], 0.0),
            "shrink_pct": r["shrink_pct"], "shrink_ci95_pct": r["shrink_ci95_pct"],
            "significant": r["significant"], "params": params[name],
            "correction_rms": size[name],
            "negligible": name in negligible,
            "units": dict(zip(e.params, e.units, strict=True)),
            "extension": e.extension, "separate_by": e.separate_by,
            "evidence": _evidence(name, ref - y, held, ctx, case.unit, split.kind,
                                  case.phases, after=preds[name] - y),
            "at_bound": edge[name] or None,
            **({"vs_first_pp": r["vs_first_pp"]} if "vs_first_pp" in r else {}),
        })
    summary: dict[str, Any] = {
        "session": str(session.path),
        "rig": case.rig,
        "unit": case.unit,
        "input": {"name": case.input_name, "unit": case.input_unit},
        "reference": {"contains": [case.reference_text], "fitted": case.reference_fit},
        "units": split.kind,
        "train_units": [int(v) for v in split.ids[0::2]],
        "heldout_units": [int(v) for v in split.held_ids],
        # OUTPUTS.md's diagnose keys: a rig's laps are its units (``units`` says what)
        "train_laps": [int(v) for v in split.ids[0::2]],
        "heldout_laps": [int(v) for v in split.held_ids],
        "gap": {"rmse": gap, **_phases(ref - y, held, ctx, case.phases)},
        "where": _where(ref - y, held, ctx, case.rest),
        "consistency": rig_consistency(case, ref - y, split),
        "effects": effects_out,
        **decision.summary(),
        "next_steps": [*decision.next_steps, *unexplained],
        "negligible_below": cut,
        "verdict_reasons": [*decision.summary()["verdict_reasons"],
                            *_negligible_reasons(case, rows, size, negligible, cut)],
        "negligible": sorted(negligible),
        "combined": {"effects": [best] if best else []},
        "warnings": [*session.warnings, *case.notes],
        "run": {"brakethermo": __version__, "effects_tried": list(names),
                "wall_time_s": time.perf_counter() - t_start},
    }
    return RigDiagnosis(session, summary, session.time[0] + ctx.t, ctx.x, y, ref,
                        preds[best] if best else None, ref_sse, tuple(evidence),
                        frozenset(negligible))


def effect_names(text: str | None, registry: dict[str, RigEffect], rig: str
                  ) -> tuple[str, ...]:
    if text is None or text.strip().lower() in ("", "all"):
        return tuple(registry)
    names = tuple(dict.fromkeys(s.strip() for s in text.split(",") if s.strip()))
    unknown = [n for n in names if n not in registry]
    if unknown or not names:
        raise ConfigError(f"unknown {rig} effect(s) {', '.join(unknown) or '(none)'};"
                          f" use 'all' or some of: {', '.join(registry)}")
    return names


def _booster_step(name: str, path: str | Path) -> str:
    carry = (f"brakethermo ebooster {path} carries it by default (the session logs the"
             " pressure); carry it into sessions of this day without the pressure sensor:"
             " brakethermo ebooster SESSION --with-effect DIR/<stem>/diagnosis.json")
    if name in ("pv_shift", "pv_scale", "pv_drift"):
        return (f"{carry}; or retrain on this session: brakethermo ebooster SESSION --train"
                f" {path}  (constant-speed sweeps up and down train best; without the"
                " sensor the observer's band admits a shift of the datasheet's"
                " pv_shift_sd_mm, not more)")
    return (f"{carry}; or train on applies at the speeds of use (without the effect, the"
            " observer holds it in its band only through q_pm_speed)")


def negligible_cut(size: dict[str, float], floor: float) -> float:
    """The correction size (RMS, the output's unit) below which a candidate is negligible:
    ``floor``, lowered to :data:`TIE_SHARE` of it when some candidate passes it whole — a
    floor is no knife edge, and one within that share of it is as large as one just past
    it (0.3443 passed a 0.3441 MPa floor while 0.325, with more shrink, did not)."""
    return TIE_SHARE * floor if any(v >= floor for v in size.values()) else floor


def _unexplained(case: RigCase, gap: float, kind: str) -> list[str]:
    """A next step when no candidate explains a held-out gap (``gap``, the output's unit)
    over :data:`UNEXPLAINED_FLOORS` floors, or over the floor and :data:`CHANGED_SHARE`
    times the reference's residual on its training session; none otherwise (a clean
    booster session 0.042 MPa off, under a transducer's 0.05, was told to check its
    inputs)."""
    if case.train_rmse and gap > max(CHANGED_SHARE * case.train_rmse, case.floor):
        than = (f"{gap / case.train_rmse:.1f}x its residual on the training session"
                f" ({case.train_rmse:.3g} {case.unit})")
    elif gap > UNEXPLAINED_FLOORS * case.floor:
        than = f"{gap / case.floor:.0f}x {case.floor_text} {case.floor:.3g} {case.unit}"
    else:
        return []
    return [f"the reference misses this session by {gap:.3g} {case.unit} RMS on the"
            f" held-out {kind}s, {than}, and none of the candidates"
            f" ({', '.join(case.effects)}) explains it: an effect outside them (one that"
            f" differs from {case.cycle} to {case.cycle} cannot be fitted as one), a"
            " session run unlike the training one, or inputs off (check the channels'"
            " units and signs)"]


def at_bound_words(e: RigEffect, fit: dict[str, float]) -> str:
    """The fitted parameters that end on a bound of their range (not on a bound that is
    the effect's absence, 0), in words; "" when none does."""
    words = []
    for name, unit, lo, hi in zip(e.params, e.units, e.lower, e.upper, strict=True):
        v, tol = fit[name], 1e-3 * (hi - lo)
        for bound, side in ((lo, "lower"), (hi, "upper")):
            if bound != 0.0 and abs(v - bound) <= tol:
                u = "" if unit == "-" else f" {unit}"
                words.append(f"{name} = {v:.3g}{u}, at the {side} edge of its range"
                             f" {lo:g} to {hi:g}")
    return "; ".join(words)


def _phases(err: np.ndarray, held: np.ndarray, ctx: RigContext,
            names: tuple[str, str, str]) -> dict[str, Any]:
    moving = 0.05 * float(np.nanpercentile(np.abs(ctx.v), 95))
    up, down, still = names
    phase = {up: ctx.v > moving, down: ctx.v < -moving, still: np.abs(ctx.v) <= moving}
    return {"per_phase": {k: rmse(err[held & m], 0.0) for k, m in phase.items()},
            "bias": float(np.nanmean(err[held]))}


def _where(err: np.ndarray, held: np.ndarray, ctx: RigContext, rest: float
           ) -> dict[str, Any]:
    top = float(np.nanmax(ctx.x[held])) if held.any() else rest
    edges = np.linspace(rest, max(top, rest + 1e-6), 5)
    bands = []
    for a, b in itertools.pairwise(edges):
        m = held & (ctx.x >= a) & (ctx.x <= b)
        bands.append({"input": [float(a), float(b)], "rmse": rmse(err[m], 0.0),
                      "bias": float(np.nanmean(err[m])) if m.any() else float("nan")})
    return {"by_input": bands}


def _evidence(name: str, res: np.ndarray, held: np.ndarray, ctx: RigContext, unit: str,
              kind: str = "apply cycle",
              phases: tuple[str, str, str] = ("applying", "releasing", "holding"),
              after: np.ndarray | None = None) -> str:
    """A sentence computed from the reference's held-out residual (model minus sensor)
    and, given ``after`` (the effect's own residual), the same figures with the effect:
    the reference's alone read the same for every candidate of one form (the roller
    rig's three: "+172.867 N at low input, +416.021 N at high input" each)."""
    said = _residual_text(name, res, held, ctx, unit, kind, phases)
    if after is None or said == "too few held-out samples":
        return said
    return f"{said}; with {name}: {_residual_text(name, after, held, ctx, unit, kind, phases)}"


def _residual_text(name: str, res: np.ndarray, held: np.ndarray, ctx: RigContext, unit: str,
                   kind: str, phases: tuple[str, str, str]) -> str:
    """The held-out residual ``res`` (model minus sensor) in the figures the candidate
    ``name`` is told by (halves, phases, low and high input)."""
    u = unit_suffix(unit)  # "+0.012 -" read as text for the tyre's μ
    r, x, v = res[held], ctx.x[held], ctx.v[held]
    ok = np.isfinite(r)
    r, x, v = r[ok], x[ok], v[ok]
    if r.size < 3:
        return "too few held-out samples"
    if "drift" in name:
        half = r.size // 2
        return (f"model minus sensor {np.mean(r[:half]):+.3f}{u} in the first half of the"
                f" held-out {kind}s, {np.mean(r[half:]):+.3f}{u} in the second")
    if name in ("rate_dependent", "hysteresis"):
        moving = 0.05 * float(np.percentile(np.abs(v), 95))
        up, down = v > moving, v < -moving
        corr = np.corrcoef(r, v)[0, 1] if np.std(v) > 0 else float("nan")
        return (f"model minus sensor {np.mean(r[up]) if up.any() else float('nan'):+.3f}"
                f"{u} {phases[0]}, {np.mean(r[down]) if down.any() else float('nan'):+.3f}"
                f"{u} {phases[1]}; correlation with the input's speed {corr:+.2f}")
    lo, hi = np.percentile(x, [25, 75])
    return (f"model minus sensor {np.mean(r[x <= lo]):+.3f}{u} at low input,"
            f" {np.mean(r[x >= hi]):+.3f}{u} at high input")


def write_rig_diagnosis(result: RigDiagnosis, out_dir: str | Path) -> Path:
    """``<out>/<stem>/diagnosis.json``, ``diagnosis.parquet`` and ``diagnosis/index.html``;
    the rig command's own files in the same folder are left as they are, its page (or a
    small index, the page's back link) links the diagnosis."""
    from brakethermo.pipelines.output_dir import refresh_indexes, replace_session_dir
    from brakethermo.pipelines.outputs import write_json, write_parquet
    from brakethermo.report.page import write_page
    from brakethermo.report.rig_diagnosis_page import rig_diagnosis_page

    folder = Path(out_dir) / result.stem
    result.summary = filled(result.summary, {
        "DIR/<stem>/diagnosis.json": shlex.quote(str(folder / "diagnosis.json"))})
    s = result.summary
    cols = {"time": result.time, "input": result.x, "measured": result.measured,
            "reference": result.reference}
    if result.best is not None:
        cols["best"] = result.best
    units = {"time": {"unit": "s"}, "input": {"unit": s["input"]["unit"]},
             **{c: {"unit": s["unit"]} for c in ("measured", "reference", "best")}}
    with replace_session_dir(folder, RIG_FILES) as stage:
        write_parquet(stage / "diagnosis.parquet", pd.DataFrame(cols), units,
                      {"brakethermo": __version__, "session": str(result.session.path)})
        write_json(stage / "diagnosis.json", result.summary)
        write_page(rig_diagnosis_page(result), stage / "diagnosis")
    refresh_indexes(folder)  # the rig command's page links it (or a small index does), and
    # a batch's index over OUT shows its verdict
    return folder
