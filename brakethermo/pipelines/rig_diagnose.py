"""``diagnose`` on an E-Booster session: where the training p–V curve parts from this
session's pressures, which unmodelled effect causes it, and how far the gap shrinks — on
held-out apply cycles, with the same verdict engine as the disc.

1. **Reference model**: the p–V curve of the training session (``--train``, ``--fit`` or
   the shipped fit), as the observer uses it: p_m = f(s2). Nothing of it is refitted here:
   the question is whether this session's booster still follows the training day's.
2. **Split**: the session's apply cycles (the screw leaving rest and returning)
   alternate between fitting and held out; a session of fewer than
   :data:`MIN_CYCLES` cycles is cut into :data:`BLOCK_S` blocks instead.
3. **Which**: each candidate of :mod:`brakethermo.models.booster_effects` fitted on the
   fitting cycles, scored on the held-out ones (RMSE shrink, bootstrap over cycles).
4. **Verdict**: :func:`brakethermo.diagnosis.verdict.decide` — a single name only when it
   beats every other clearly and is no look-alike, else the set, or ``"none"``. A
   candidate whose correction is smaller than a pressure sensor's accuracy (or twice the
   training curve's own residual) is reported but never named: between two sessions the
   sensor's own offset could do as much.

Needs the master-cylinder pressure channel (a bench or validation session): a production
session without it cannot be compared with anything and is refused with one line.
"""

from __future__ import annotations

import itertools
import time
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
from brakethermo.models.booster_effects import BOOSTER_EFFECTS, BoosterContext
from brakethermo.models.ebooster import BoosterFit, load_fit
from brakethermo.pipelines.ebooster import (
    MM,
    MPA,
    S2,
    _series,
    default_fit_path,
    load_booster_session,
    train,
)
from brakethermo.results.ebooster import PRESSURES
from brakethermo.results.rig_diagnosis import RigDiagnosis
from brakethermo.rigs.booster import pv_pressure
from brakethermo.rigs.booster_datasheet import load_booster

MIN_CYCLES = 12  # apply cycles for a cycle-wise split (6 held out); fewer: time blocks
BLOCK_S = 1.0  # s, unit length when the session holds too few cycles
REST_MM = 0.5  # mm of screw travel below which the booster is at rest
SPEED_WINDOW_S = 0.02  # s, moving average of the screw speed (encoder quantisation)
RULE = VerdictRule(min_shrink_pct=10.0)
# MPa: a pressure transducer's accuracy (0.5 % of a 10 MPa range). A correction smaller
# than this, or than twice the training curve's own residual, could as well be the
# sensor's offset between two sessions: it is reported, never named.
SENSOR_ACCURACY_MPA = 0.05
RIG_FILES = ("diagnosis.json", "diagnosis.parquet", "diagnosis")


def _speed(s2: np.ndarray, dt: float) -> np.ndarray:
    width = max(1, round(SPEED_WINDOW_S / dt))
    smooth = np.convolve(np.pad(s2, (width // 2, width - 1 - width // 2), mode="edge"),
                         np.ones(width) / width, mode="valid")
    return np.gradient(smooth, dt)


def apply_units(s2: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, str]:
    """Unit id per sample (-1 at rest) and what a unit is."""
    active = s2 > REST_MM
    starts = np.flatnonzero(np.diff(active.astype(np.int8)) == 1) + 1
    if active[0]:
        starts = np.r_[0, starts]
    if starts.size >= MIN_CYCLES:
        ids = np.searchsorted(starts, np.arange(s2.size), side="right") - 1
        return np.where(active & (ids >= 0), ids, -1), "apply cycle"
    blocks = np.floor((t - t[0]) / BLOCK_S).astype(int)
    return np.where(active, blocks, -1), f"{BLOCK_S:g} s block"


def _fit_effect(name: str, ctx: BoosterContext, p: np.ndarray, mask: np.ndarray
                ) -> np.ndarray:
    e = BOOSTER_EFFECTS[name]
    sol = least_squares(lambda th: (e.predict(th, ctx) - p)[mask], np.array(e.start),
                        bounds=(np.array(e.lower), np.array(e.upper)), method="trf",
                        loss="soft_l1", f_scale=0.05)
    return sol.x


def diagnose_booster(
    path: str | Path,
    *,
    train_path: str | Path | None = None,
    fit_path: str | Path | None = None,
    bench: str | Path = "ebooster",
    aliases: str | Path | None = None,
    effects: str | None = "all",
) -> RigDiagnosis:
    """Diagnose an E-Booster session with a pressure sensor (module docstring)."""
    t_start = time.perf_counter()
    names = _effect_names(effects)
    spec = load_booster(bench)
    fit: BoosterFit = (train(train_path, spec, aliases) if train_path is not None
                       else load_fit(fit_path or default_fit_path()))
    session = load_booster_session(path, aliases)
    channel = PRESSURES["p_m"]
    if not session.has(channel):
        raise DataError(
            "has no master-cylinder pressure: diagnose compares the training p-V curve with"
            " this session's pressures, so it needs a bench or validation session that logs"
            " them (a production session can only be observed: brakethermo ebooster)",
            path=session.path, channel=channel)
    s2 = _series(session, S2, MM, gaps=False)
    p = _series(session, channel, MPA, gaps=True)
    t = session.time - session.time[0]
    coeffs = np.array(fit.pv_coeffs)
    ctx = BoosterContext(s2, _speed(s2, session.dt), t,
                         lambda s: pv_pressure(s, coeffs, fit.stroke_mm))
    units, unit_kind = apply_units(s2, t)
    units = np.where(np.isfinite(p), units, -1)
    ids = np.unique(units[units >= 0])
    if ids.size < 4:
        raise DataError(
            f"holds {ids.size} {unit_kind}(s) with the screw off rest and a pressure reading;"
            " the diagnosis fits on half of them and scores on the other half: record a"
            " session with at least 4", path=session.path, channel=S2)
    held_ids = ids[1::2]
    held = np.isin(units, held_ids)
    fitting = (units >= 0) & ~held
    ref = ctx.curve(s2)
    scored = np.where(held, units, -1)
    ref_sse = unit_sse(ref - p, scored)[0]
    preds: dict[str, np.ndarray] = {}
    params: dict[str, dict[str, float]] = {}
    for name in names:
        theta = _fit_effect(name, ctx, p, fitting)
        preds[name] = BOOSTER_EFFECTS[name].predict(theta, ctx)
        params[name] = {k: float(v) for k, v in
                        zip(BOOSTER_EFFECTS[name].params, theta, strict=True)}
    evidence = [CandidateEvidence(
        name, unit_sse(preds[name] - p, scored)[0], correction=(preds[name] - ref)[held],
        separate_by=BOOSTER_EFFECTS[name].separate_by, next_step=_next_step(name, path),
        n_params=len(BOOSTER_EFFECTS[name].params))
        for name in names]
    floor = max(SENSOR_ACCURACY_MPA, 2.0 * fit.pv_rmse_mpa)
    size = {name: _rmse((preds[name] - ref)[held]) for name in names}
    negligible = {n for n in names if not size[n] >= floor}
    decision = decide(ref_sse, [e for e in evidence if e.name not in negligible], RULE)
    rows = {r["name"]: r for r in decision.rows}
    for e in evidence:
        if e.name in negligible:
            point, lo, hi = shrink_interval(ref_sse, e.sse, RULE)
            rows[e.name] = {"name": e.name, "shrink_pct": point, "shrink_ci95_pct": [lo, hi],
                            "significant": False, "rank": len(rows) + 1}
    best = decision.verdict if decision.verdict != "none" else None
    effects_out = []
    for name in sorted(names, key=lambda n: rows[n]["rank"]):
        e, r = BOOSTER_EFFECTS[name], rows[name]
        effects_out.append({
            "name": name, "rank": r["rank"],
            "rmse_before": _rmse((ref - p)[held]), "rmse_after": _rmse((preds[name] - p)[held]),
            "shrink_pct": r["shrink_pct"], "shrink_ci95_pct": r["shrink_ci95_pct"],
            "significant": r["significant"], "params": params[name],
            "correction_rms_mpa": size[name],
            "negligible": name in negligible,
            "units": dict(zip(e.params, e.units, strict=True)),
            "extension": e.extension, "separate_by": e.separate_by,
            "evidence": _evidence(name, ref - p, held, ctx),
            **({"vs_first_pp": r["vs_first_pp"]} if "vs_first_pp" in r else {}),
        })
    summary: dict[str, Any] = {
        "session": str(session.path),
        "rig": "ebooster",
        "reference": {
            "contains": [f"the p-V curve of the training session {fit.train_session},"
                         " p_m = f(s2), as the observer uses it (not refitted here)"],
            "fitted": {"pv_coeffs_mpa": list(fit.pv_coeffs), "stroke_mm": fit.stroke_mm},
        },
        "units": unit_kind,
        "train_units": [int(v) for v in ids[0::2]],
        "heldout_units": [int(v) for v in held_ids],
        "gap": {"rmse_mpa": _rmse((ref - p)[held]), **_phases(ref - p, held, ctx)},
        "where": _where(ref - p, held, ctx),
        "consistency": {"summary": "no filter runs here: the training p-V curve is compared"
                        " with the pressure channel directly"},
        "effects": effects_out,
        **decision.summary(),
        "negligible_below_mpa": floor,
        "negligible": sorted(negligible),
        "combined": {"effects": [best] if best else []},
        "warnings": list(session.warnings),
        "run": {"brakethermo": __version__, "bench": spec.id, "effects_tried": list(names),
                "wall_time_s": time.perf_counter() - t_start},
    }
    return RigDiagnosis(session, summary, session.time, s2, p, ref,
                        preds[best] if best else None)


def _effect_names(text: str | None) -> tuple[str, ...]:
    if text is None or text.strip().lower() in ("", "all"):
        return tuple(BOOSTER_EFFECTS)
    names = tuple(dict.fromkeys(s.strip() for s in text.split(",") if s.strip()))
    unknown = [n for n in names if n not in BOOSTER_EFFECTS]
    if unknown or not names:
        raise ConfigError(f"unknown E-Booster effect(s) {', '.join(unknown) or '(none)'};"
                          f" use 'all' or some of: {', '.join(BOOSTER_EFFECTS)}")
    return names


def _next_step(name: str, path: str | Path) -> str:
    if name in ("pv_shift", "pv_scale", "pv_drift"):
        return (f"retrain the p-V curve on a session of this day: brakethermo ebooster"
                f" SESSION --train {path}  (the observer's band admits a shift of the"
                " datasheet's pv_shift_sd_mm, not more)")
    return ("the observer's p-V is static: this effect is in its band only through"
            " q_pm_speed; widen it in the bench file, or train on applies at the speeds of"
            " use")


def _rmse(e: np.ndarray) -> float:
    e = e[np.isfinite(e)]
    return float(np.sqrt(np.mean(e * e))) if e.size else float("nan")


def _phases(err: np.ndarray, held: np.ndarray, ctx: BoosterContext) -> dict[str, Any]:
    phase = {"applying": ctx.v > 0.5, "releasing": ctx.v < -0.5,
             "holding": np.abs(ctx.v) <= 0.5}
    return {"per_phase": {k: _rmse(err[held & m]) for k, m in phase.items()},
            "bias_mpa": float(np.nanmean(err[held]))}


def _where(err: np.ndarray, held: np.ndarray, ctx: BoosterContext) -> dict[str, Any]:
    top = float(np.nanmax(ctx.s2[held])) if held.any() else 0.0
    edges = np.linspace(REST_MM, max(top, REST_MM + 1e-6), 5)
    bands = []
    for a, b in itertools.pairwise(edges):
        m = held & (ctx.s2 >= a) & (ctx.s2 <= b)
        bands.append({"s2_mm": [float(a), float(b)], "rmse_mpa": _rmse(err[m]),
                      "bias_mpa": float(np.nanmean(err[m])) if m.any() else float("nan")})
    return {"by_travel": bands}


def _evidence(name: str, res: np.ndarray, held: np.ndarray, ctx: BoosterContext) -> str:
    """A sentence computed from the reference's held-out residual (model minus sensor)."""
    r, s2, v = res[held], ctx.s2[held], ctx.v[held]
    ok = np.isfinite(r)
    r, s2, v = r[ok], s2[ok], v[ok]
    if r.size < 3:
        return "too few held-out samples"
    if name in ("pv_shift", "pv_scale"):
        lo, hi = np.percentile(s2, [25, 75])
        return (f"model minus sensor {np.mean(r[s2 <= lo]):+.3f} MPa at low travel,"
                f" {np.mean(r[s2 >= hi]):+.3f} MPa at high travel")
    if name == "pv_drift":
        half = r.size // 2
        return (f"model minus sensor {np.mean(r[:half]):+.3f} MPa in the first half of the"
                f" held-out cycles, {np.mean(r[half:]):+.3f} MPa in the second")
    up, down = v > 0.5, v < -0.5
    return (f"model minus sensor {np.mean(r[up]) if up.any() else float('nan'):+.3f} MPa"
            f" applying, {np.mean(r[down]) if down.any() else float('nan'):+.3f} MPa"
            f" releasing; correlation with the screw speed"
            f" {np.corrcoef(r, v)[0, 1] if np.std(v) > 0 else float('nan'):+.2f}")


def write_rig_diagnosis(result: RigDiagnosis, out_dir: str | Path) -> Path:
    """``<out>/<stem>/diagnosis.json``, ``diagnosis.parquet`` and ``diagnosis/index.html``;
    the rig command's own files in the same folder are left as they are."""
    from brakethermo.pipelines.output_dir import replace_session_dir
    from brakethermo.pipelines.outputs import write_json, write_parquet
    from brakethermo.report.page import write_page
    from brakethermo.report.rig_diagnosis_page import rig_diagnosis_page

    folder = Path(out_dir) / result.stem
    cols = {"time": result.time, "s2": result.s2, "p_m": result.measured,
            "reference_p_m": result.reference}
    if result.best is not None:
        cols["best_p_m"] = result.best
    units = {"time": {"unit": "s"}, "s2": {"unit": "mm"},
             **{c: {"unit": "MPa"} for c in cols if "p_m" in c}}
    with replace_session_dir(folder, RIG_FILES) as stage:
        write_parquet(stage / "diagnosis.parquet", pd.DataFrame(cols), units,
                      {"brakethermo": __version__, "session": str(result.session.path)})
        write_json(stage / "diagnosis.json", result.summary)
        write_page(rig_diagnosis_page(result), stage / "diagnosis")
    return folder
