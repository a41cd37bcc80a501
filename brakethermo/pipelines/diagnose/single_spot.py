"""The diagnosis of a single-spot race: the innovations' "where" and the online effects
one spot can follow."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from brakethermo import __version__
from brakethermo.diagnosis.verdict import (
    CandidateEvidence,
    Decision,
    decide,
    unit_sse,
)
from brakethermo.errors import DataError
from brakethermo.estimation.consistency import nis_consistency
from brakethermo.io.session import Session
from brakethermo.models.disc_effects import Segments
from brakethermo.models.effects import EFFECTS, parse_effects
from brakethermo.pipelines.diagnose._common import (
    RACE_SPOT,
    RULE,
    SETTLE_S,
    DiagnoseOptions,
    DiagnoseResult,
)
from brakethermo.pipelines.diagnose.fit import _gauss_ll
from brakethermo.pipelines.diagnose.layout import Layout, session_segments, zone_masks
from brakethermo.pipelines.diagnose.scores import score
from brakethermo.pipelines.diagnose.where import _marginals, where_table
from brakethermo.pipelines.estimate import SENSOR_FLOOR_C
from brakethermo.pipelines.h_factor_found import h_factor_found
from brakethermo.pipelines.inputs import DiscInputs
from brakethermo.pipelines.models import SHIPPED_LAW_NOTE, assumed_disc
from brakethermo.results.laps import whole_flying_laps
from brakethermo.thermal.disc import DiscSpec

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
    t_start = time.perf_counter()
    names = parse_effects(options.effects)
    flying = tuple(int(v) for v in np.unique(inputs.lap) if v >= 1)
    if not flying:
        raise DataError("diagnose needs at least one flying lap (lap_beacon >= 1)",
                        path=session.path, channel="lap_beacon")
    online = [n for n in names if n in SINGLE_SPOT_ONLINE]
    runs = _race_runs(session, options, online, progress)
    y = _race_readings(inputs)
    layout, dist, segments = _flying_layout(session, inputs, flying)
    scored = layout.held
    ref_pred = _prediction(y, runs, "reference")
    spots = (RACE_SPOT,)
    units = np.where(layout.held, layout.cycles, -1)
    ref_sse = unit_sse(ref_pred - y, units, per_output=True)[0]
    law_opt = f" --h-law {options.h_law}" if options.h_law is not None else ""
    evidence = [_online_evidence(label, session, y, runs, ref_pred, units, layout.held,
                                 law_opt) for label in online]
    decision = _h_factor_read(decide(ref_sse, evidence, RULE), session, inputs, runs)
    rows = {r["name"]: r for r in decision.rows}
    best_pred = None
    effects_out = sorted(
        (_online_record(label, rows[label], runs, score(ref_pred, y, layout, spots),
                        score(_prediction(y, runs, label), y, layout, spots), scored)
         for label in online), key=lambda e: e["rank"])
    verdict = decision.verdict
    if verdict != "none":
        best_pred = _prediction(y, runs, verdict)
    ref_scores = score(ref_pred, y, layout, spots)
    nis = runs["reference"].innovation**2 / runs["reference"].innovation_var
    res = y - ref_pred
    summary: dict[str, Any] = {
        "session": str(session.path),
        "metadata": session.metadata,
        "mode": "single-spot race session: innovation-based, spot 3 only",
        "reference": _reference_facts(disc, runs["reference"]),
        "train_laps": [],
        "heldout_laps": list(flying),
        "gap": {"rmse_c": ref_scores["overall"], "per_spot": ref_scores["per_spot"],
                "per_phase": ref_scores["per_phase"],
                "per_spot_phase": ref_scores["per_spot_phase"]},
        "where": {"ranked_cells": where_table(res, layout, inputs, segments, y),
                  **_marginals(res, layout, inputs, segments, y),
                  "braking_zones": segments.n_zones},
        "consistency": _race_consistency(nis, runs["reference"].innovation, scored),
        "effects": effects_out,
        "not_identifiable_from_one_spot": [
            {"name": n, "identifiable_from_one_spot": False, "reason": _why_not(n)}
            for n in names if n not in SINGLE_SPOT_ONLINE],
        **decision.summary(),
        "combined": {"effects": [verdict] if verdict != "none" else [], "steps": []},
        "warnings": [] if options.h_law is not None else [
            "no --h-law: the race is judged against the law shipped for the disc, and a gap"
            " it shows may be that law's (an online effect then stands in for it); "
            + SHIPPED_LAW_NOTE],
        "run": {"brakethermo": __version__, "disc": disc.id, "effects_tried": list(names),
                "timings_s": {}, "wall_time_s": time.perf_counter() - t_start,
                "input_warnings": [*session.warnings, *inputs.warnings,
                                   *filter(None, [assumed_disc(session, options.disc)])]},
    }
    return DiagnoseResult(session, summary, inputs.time, inputs.lap, y, ref_pred, best_pred,
                          dist, nis, {}, ref_sse, evidence)


def _h_factor_read(decision: Decision, session: Session, inputs: DiscInputs,
                   runs: dict[str, Any]) -> Decision:
    """``decision`` with the slipstream run's h factor read as estimate reads it, where
    slipstream is in the verdict and its factor is no slipstream's."""
    if "slipstream" not in decision.verdict_set:
        return decision
    form = _not_slipstream(session, inputs, runs["slipstream"].frame)
    if not form:
        return decision
    said = (f"slipstream's online h factor reads as no slipstream: {form}; carried online"
            " it still corrects the law for this race")
    return replace(decision, next_steps=[said, *decision.next_steps],
                   reasons=[*decision.reasons, said])


def _not_slipstream(session: Session, inputs: DiscInputs, frame: Any) -> str:
    """Why the online h factor is no slipstream's ("" when it may be one): a slipstream
    lowers h on some laps only, so a factor off the law on every lap alike, or off it
    unevenly without laps below the others, is the law's departure or a heat path the
    model lacks (a race diagnosed with a set [slipstream, ...] while estimate said the
    factor sat at 0.87 on every lap; another named slipstream on a median of 1.45)."""
    if "h_factor" not in frame:
        return ""
    found = h_factor_found(frame["h_factor"].to_numpy(), inputs.braking,
                           frame["lap"].to_numpy(), whole_flying_laps(session.laps),
                           float(session.dt))
    if found is None or found.kind in ("by lap", "near the law"):
        return ""
    if found.kind == "steady":
        return (f"{found.median:.2f} on every lap alike, where a slipstream comes and goes:"
                " the law is off for this race, or the disc has a heat path the model lacks")
    return (f"off the law's unevenly (median {found.median:.2f}) with no laps below the"
            " others, as a slipstream would give")


def _race_readings(inputs: DiscInputs) -> np.ndarray:
    """(K, 4) readings, degC: the race spot's, NaN below the sensor's floor and elsewhere."""
    y = np.full((inputs.time.size, 4), np.nan)
    y[:, RACE_SPOT - 1] = inputs.spots[:, RACE_SPOT - 1]
    y[y <= SENSOR_FLOOR_C] = np.nan
    return y


def _prediction(y: np.ndarray, runs: dict[str, Any], label: str) -> np.ndarray:
    """(K, 4) one-step-ahead prediction of run ``label`` at the race spot, degC: the
    reading ``y`` minus the innovation (NaN elsewhere)."""
    pred = np.full_like(y, np.nan)
    pred[:, RACE_SPOT - 1] = y[:, RACE_SPOT - 1] - runs[label].innovation
    return pred


def _flying_layout(session: Session, inputs: DiscInputs, flying: tuple[int, ...]
                   ) -> tuple[Layout, np.ndarray, Segments]:
    """Every flying lap scored (none trained: the innovations need no held-out lap), with
    the braking cycles; the lap distance (m) and the segments."""
    zones, dist, segments = session_segments(session, inputs)
    braking, release, cycles = zone_masks(zones, inputs.time.size, round(SETTLE_S / session.dt))
    scored = np.isin(inputs.lap, flying)
    layout = Layout(train=np.zeros_like(scored), held=scored, braking=braking,
                    release=release, cycles=cycles)
    return layout, dist, segments


def _online_evidence(label: str, session: Session, y: np.ndarray, runs: dict[str, Any],
                     ref_pred: np.ndarray, units: np.ndarray, held: np.ndarray,
                     law_opt: str) -> CandidateEvidence:
    """One online effect's held-out errors per braking cycle at the race spot; its next
    step carries the h law the race was judged with (``law_opt``, the option or "")."""
    pred = _prediction(y, runs, label)
    return CandidateEvidence(label, unit_sse(pred - y, units, per_output=True)[0],
                             correction=(pred - ref_pred)[held],
                             separate_by=EFFECTS[label].separate_by,
                             next_step=(f"brakethermo estimate {session.path}{law_opt} --"
                                        f"{SINGLE_SPOT_ONLINE[label][0].replace('_', '-')}"),
                             outputs=(RACE_SPOT - 1,))


def _reference_facts(disc: DiscSpec, reference: Any) -> dict[str, Any]:
    """The summary's ``reference``: what the reference run contains."""
    return {
        "contains": [
            f"the race estimator of disc {disc.id} with the h law "
            f"{reference.summary['run']['h_law'] or 'shipped for the disc'}",
            "no online effects (k_z and slipstream factors fixed at 1)",
            "scored by its one-step-ahead innovations at spot 3: predictions from past"
            " readings only, so no lap needs to be held out",
        ],
        "fitted": {},
    }


def _online_record(label: str, row: dict[str, Any], runs: dict[str, Any],
                   before: dict[str, Any], after: dict[str, Any], scored: np.ndarray
                   ) -> dict[str, Any]:
    """One online effect's entry of ``effects``: scores, and its online state's range."""
    _, column, nominal = SINGLE_SPOT_ONLINE[label]
    track = runs[label].frame[column].to_numpy()[scored]
    key = ONLINE_KEY[column]
    return {
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
    }


def _race_consistency(nis: np.ndarray, innovation: np.ndarray, scored: np.ndarray
                      ) -> dict[str, Any]:
    """The race filter's mean NIS at spot 3 against its χ² band, and its innovations'
    lag-1 autocorrelation."""
    c = nis_consistency(nis[scored], 1, innovation[scored])
    return {
        "per_spot": {f"spot{RACE_SPOT}": {k: c[k] for k in (
            "mean_nis", "chi2_band", "lag1_autocorrelation", "state")}},
        "summary": f"the race filter is {c['state']} at spot {RACE_SPOT} (mean NIS"
                   f" {c['mean_nis']:.2f})",
    }


def _race_runs(session: Session, options: DiagnoseOptions, online: list[str],
               progress: Callable[[str, int, int], None] | None) -> dict[str, Any]:
    """The race filter without online effects (the reference) and with each one alone."""
    from brakethermo.pipelines.estimate import EstimateOptions, estimate_from_session

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
    return runs


def _why_not(name: str) -> str:
    """Why one race pyrometer cannot diagnose ``name``."""
    if name == "emissivity_error":
        return ("one pyrometer cannot tell its own bias from the disc: only the test"
                " session's four spots can")
    return ("needs the four-spot test session (diagnose it there, then estimate with its"
            " h_law.toml)")
