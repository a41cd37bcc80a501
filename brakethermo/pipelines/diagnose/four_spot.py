"""The diagnosis of a four-spot session: reference model, candidates fitted on training
laps and scored on held-out laps, the verdict and the forward selection."""

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
    Signature,
    decide,
    unit_sse,
)
from brakethermo.errors import DataError
from brakethermo.io.session import Session
from brakethermo.models.disc_effects import N_REFERENCE, ExtendedDisc
from brakethermo.models.effects import EFFECTS, parse_effects
from brakethermo.pipelines import scoring
from brakethermo.pipelines.diagnose._common import (
    CORRELATED,
    MIN_SHRINK_PCT,
    RACE_SPOT,
    REFERENCE_WARNING,
    RULE,
    SETTLE_S,
    Candidate,
    DiagnoseOptions,
    DiagnoseResult,
)
from brakethermo.pipelines.diagnose.data_power import READS_LIKE, disc_data_power, top_speed_kmh
from brakethermo.pipelines.diagnose.evidence import (
    EVIDENCE,
    _corr,
    carry_command,
    effect_size,
    signatures,
    straight_places,
)
from brakethermo.pipelines.diagnose.fit import _fit, _initial_nodes, _reference_start
from brakethermo.pipelines.diagnose.layout import (
    Layout,
    session_segments,
    signature_units,
    split_laps,
    zone_masks,
)
from brakethermo.pipelines.diagnose.scores import (
    bootstrap_shrink,
    consistency,
    heldout_loglik,
    score,
)
from brakethermo.pipelines.diagnose.single_spot import diagnose_single_spot
from brakethermo.pipelines.diagnose.where import _marginals, where_table
from brakethermo.pipelines.estimate import SENSOR_FLOOR_C
from brakethermo.pipelines.inputs import DiscInputs, disc_inputs
from brakethermo.pipelines.models import assumed_disc, disc_for
from brakethermo.pipelines.race_run import SIGMA_MEAS_FLOOR_C
from brakethermo.pipelines.tuning import EstimateTuning, read_tuning
from brakethermo.results.laps import slow_laps
from brakethermo.thermal.disc import DiscSpec
from brakethermo.thermal.hlaw_check import B_LAW_CHECKED, law_speed_check
from brakethermo.thermal.model import DiscFEModel


def diagnose_session(
    session: Session,
    options: DiagnoseOptions | None = None,
    progress: Callable[[str, int, int], None] | None = None,
) -> DiagnoseResult:
    """Diagnose a four-spot session (module docstring). ``progress(label, done, total)``."""
    options = options or DiagnoseOptions()
    t_start = time.perf_counter()
    names = parse_effects(options.effects)
    files = read_tuning(options.tuning)
    options = replace(options, tuning=files)  # read once for every fit and estimate
    est_tuning = files.estimate
    disc = disc_for(session, options.disc)
    inputs = disc_inputs(session, disc, options.ambient_c)
    if not inputs.is_multi_spot:
        if RACE_SPOT not in inputs.measured:
            raise DataError(
                "diagnose needs the four-spot sensor or the race sensor at the spot-3 radius;"
                f" this session logs spot(s) {', '.join(map(str, inputs.measured))}",
                path=session.path)
        return diagnose_single_spot(session, options, inputs, disc, progress)
    d = _FourSpot(session, options, inputs, disc, est_tuning, names, progress)
    d.fit_reference()
    candidates = [d.fit_one(name) for name in names]
    decision, evidence, ranked = d.decide(candidates)
    significant = [c for c in ranked if c.scores["significant"]]
    t0 = time.perf_counter()
    selection = _forward_selection(significant, d.fit_candidate, d.describe,
                                   lambda c: d.make(c.effects).at_bounds_words(c.p))
    d.timings["forward_selection_s"] = time.perf_counter() - t0
    d.tick("forward selection")
    summary = d.summary(decision, ranked, significant, selection, t_start)
    best = ranked[0] if ranked else None
    return DiagnoseResult(session, summary, inputs.time, inputs.lap, d.y, d.ref_pred,
                          best.pred if best else None, d.dist, d.nis, d.timings, d.ref_sse,
                          evidence)


class _FourSpot:
    """One four-spot diagnosis: the session's layout, the reference fit and the candidates.

    Each method is one step of the module docstring; the state they share (the readings,
    the lap split, the model, the reference parameters) lives here.
    """

    def __init__(self, session: Session, options: DiagnoseOptions, inputs: DiscInputs,
                 disc: DiscSpec, est_tuning: EstimateTuning, names: tuple[str, ...],
                 progress: Callable[[str, int, int], None] | None) -> None:
        self.session, self.options, self.inputs, self.disc = session, options, inputs, disc
        self.est_tuning, self.names, self.progress = est_tuning, names, progress
        y = inputs.spots.copy()
        y[y <= SENSOR_FLOOR_C] = np.nan
        self.y = y
        self.spot_radii = np.asarray(disc.spot_radii)
        zones, self.dist, self.segments = session_segments(session, inputs)
        self.train_laps, self.held_laps = split_laps(session, inputs, options.holdout_laps)
        braking, release, cycles = zone_masks(zones, inputs.time.size,
                                              round(SETTLE_S / session.dt))
        self.layout = Layout(train=np.isin(inputs.lap, self.train_laps),
                             held=np.isin(inputs.lap, self.held_laps),
                             braking=braking, release=release, cycles=cycles)
        self.train_mask = self.layout.train[:, None] & np.isfinite(y)
        self.model = DiscFEModel(disc, est_tuning.nodes, est_tuning.layers,
                                 layer_growth=est_tuning.layer_growth, k_z=disc.k_z)
        self.T0 = _initial_nodes(self.model, self.spot_radii, y, float(inputs.t_amb[0]))
        self.timings: dict[str, float] = {}
        self.done = 0
        self.total_steps = len(names) + 3

    def tick(self, label: str) -> None:
        self.done += 1
        if self.progress:
            self.progress(label, self.done, self.total_steps)

    def make(self, effects: tuple[str, ...]) -> ExtendedDisc:
        i = self.inputs
        # a slipstream's factors depart from the training straights' level: the held-out
        # ones, fitted later from spot 3, must not move h on the laps before them
        level = np.isin(self.segments.straight_lap, self.train_laps)
        return ExtendedDisc(self.model, i.speed, i.q_brk, i.t_amb, self.T0, self.spot_radii,
                            self.disc.v_ref, effects, self.segments, level)

    def fit_reference(self) -> None:
        """Step 1: the reference model fitted on the training laps (all four spots)."""
        t0 = time.perf_counter()
        a0, b0, w0 = _reference_start(self.disc, self.options.h_law)
        self.ref = ref = self.make(())
        p_ref = ref.neutral()
        p_ref[0], p_ref[1] = np.log(max(a0, 1.0)), b0
        w0 = np.maximum(w0, 1e-3)
        p_ref[3:5] = np.log(w0[:2] / w0[2])
        self.p_ref = _fit(ref, p_ref, self.y, self.train_mask, np.ones(ref.size, bool),
                          self.options.max_nfev)
        self.ref_pred = ref.predict(self.p_ref)[0]
        self.timings["reference_s"] = time.perf_counter() - t0
        self.tick("reference model")

    def fit_one(self, name: str) -> Candidate:
        cand = self.fit_candidate((name,))
        self.timings[f"{name}_s"] = cand.fit_s
        self.tick(name)
        return cand

    def fit_candidate(self, effects: tuple[str, ...], start: Candidate | None = None
                      ) -> Candidate:
        """Step 4: an extension fitted on the training laps (from ``start``'s values)."""
        t = time.perf_counter()
        ext = self.make(effects)
        p0 = ext.neutral()
        p0[:N_REFERENCE] = self.p_ref[:N_REFERENCE]
        if start is not None:
            start_ext = self.make(start.effects)
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
        straight_lap = self.segments.straight_lap
        for s in ext.slots:
            if s.segment >= 0 and EFFECTS[s.effect].latent == "straight":
                if straight_lap[s.segment] not in self.train_laps:
                    free[s.index] = False
                    held_latent[s.index] = straight_lap[s.segment] in self.held_laps
        p = _fit(ext, p0, self.y, self.train_mask, free, self.options.max_nfev)
        spots: tuple[int, ...] = (1, 2, 3, 4)
        if held_latent.any():
            # Held-out straights: their latent values from the race sensor alone.
            race = np.zeros_like(self.train_mask)
            race[:, RACE_SPOT - 1] = self.layout.held & np.isfinite(self.y[:, RACE_SPOT - 1])
            p = _fit(ext, p, self.y, race, held_latent, self.options.max_nfev)
            spots = tuple(s for s in spots if s != RACE_SPOT)
        return Candidate(",".join(effects), effects, p, ext.predict(p)[0], spots,
                         time.perf_counter() - t)

    def describe(self, c: Candidate, base_pred: np.ndarray) -> dict[str, Any]:
        """A candidate's held-out scores against ``base_pred``."""
        y, layout = self.y, self.layout
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

    def signature(self, c: Candidate) -> Signature | None:
        """The held-out units where ``c``'s signature lives, scored (layout.signature_units)."""
        found = signature_units(c.name, self.layout, self.inputs.speed, self.segments,
                                self.disc.v_ref)
        if found is None:
            return None
        where, units = found
        cols = [s - 1 for s in c.scored_spots]
        before = unit_sse(self.ref_pred - self.y, units, per_output=True)[0][:, cols]
        after = unit_sse(c.pred - self.y, units, per_output=True)[0][:, cols]
        return Signature(where, before.sum(axis=1), after.sum(axis=1))

    def decide(self, candidates: list[Candidate]
               ) -> tuple[Decision, list[CandidateEvidence], list[Candidate]]:
        """Step 5: the engine's verdict over held-out braking cycles; ranked candidates."""
        y, layout = self.y, self.layout
        units = np.where(layout.held, layout.cycles, -1)
        self.ref_sse = unit_sse(self.ref_pred - y, units, per_output=True)[0]
        evidence = [
            CandidateEvidence(c.name, unit_sse(c.pred - y, units, per_output=True)[0],
                              correction=(c.pred - self.ref_pred)[layout.held],
                              separate_by=EFFECTS[c.name].separate_by,
                              next_step=carry_command(self.session.path, c.name),
                              outputs=tuple(s_ - 1 for s_ in c.scored_spots),
                              n_params=sum(s.effect != "reference"
                                           for s in self.make(c.effects).slots),
                              signature=self.signature(c),
                              at_bound=self.make(c.effects).at_bounds_words(c.p))
            for c in candidates]
        blind = disc_data_power(self.inputs.speed, y, self.inputs.t_amb, layout.braking,
                                layout.train | layout.held, self.disc.v_ref, SENSOR_FLOOR_C)
        decision = decide(self.ref_sse, evidence, RULE, untestable=blind, reads_like=READS_LIKE)
        for c in candidates:
            c.scores = self.describe(c, self.ref_pred)
            row = next(r for r in decision.rows if r["name"] == c.name)
            c.scores.update(shrink_pct=row["shrink_pct"], shrink_ci95_pct=row["shrink_ci95_pct"],
                            significant=row["significant"],
                            **{k: v for k, v in row.items() if k.startswith("signature")
                               or k == "significant_by"})
        self.candidates = candidates
        rank_of = {r["name"]: r["rank"] for r in decision.rows}
        return decision, evidence, sorted(candidates, key=lambda c: rank_of[c.name])

    def effects_out(self, decision: Decision) -> list[dict[str, Any]]:
        """``effects`` of diagnosis.json: scores, size, evidence, ranked."""
        sig = signatures(self.y - self.ref_pred, self.y, self.inputs, self.layout,
                         self.segments, self.disc.v_ref, self.session.dt)
        rows = {r["name"]: r for r in decision.rows}
        top = top_speed_kmh(self.inputs.speed, self.layout.train | self.layout.held)
        places = straight_places(self.segments)
        fitted = np.isin(self.segments.straight_lap, (*self.train_laps, *self.held_laps))
        out = []
        for c in self.candidates:
            row = rows[c.name]
            ext = self.make(c.effects)
            params = ext.values(c.p, c.name)
            shown = params
            if "straight_factor" in params:  # the straights fitted, not the out-lap's
                shown = {**params, "straight_factor": list(np.compress(
                    fitted, params["straight_factor"]))}
            size, sentence = effect_size(c.name, shown, self.disc, self.est_tuning.layers,
                                         self.segments.zone_names, top,
                                         [p for p, f in zip(places, fitted, strict=True) if f],
                                         crown=ext.weights(c.p),
                                         reference_crown=self.ref.weights(self.p_ref))
            if "kz_factor" in params:  # in h_law.toml kz_factor is relative to k(T), not k_z
                params = {"kz_over_nominal": params.pop("kz_factor"), **params}
            out.append({
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
                **({"at_bound": row["at_bound"]} if "at_bound" in row else {}),
                # reported, deciding nothing: a straight's or zone's value, or the
                # effect's absent value, at the edge of its range
                **({"edges": edges} if (edges := ext.at_bounds_words(c.p, every=True))
                   and "at_bound" not in row else {}),
                "rank": row["rank"],
            })
        return sorted(out, key=lambda e: e["rank"])

    def reference_warnings(self) -> list[str]:
        """Warnings on the reference fit: its h law implausible, a parameter at a bound."""
        check = self.law_check()
        out = [] if check is None else [f"{REFERENCE_WARNING}{check['text']}"]
        # h's exponent at its lower bound is the law check's, said once with what it
        # means; at its upper bound (3) it is said here
        words = self.ref.bound_words({k: v for k, v in self.ref.reference_at_bounds(
            self.p_ref).items() if k[1] != "b" or v > B_LAW_CHECKED})
        if words:
            out.append(f"{REFERENCE_WARNING}{words} (the data push it past the reference's"
                       " range: read its 'before' figures with care)")
        return out

    def alike(self, decision: Decision, significant: list[Candidate]) -> list[str]:
        """Warnings for two significant effects whose corrections move the prediction alike."""
        warnings: list[str] = []
        held = self.layout.held
        for i, a in enumerate(significant):
            for b in significant[i + 1:]:
                r = _corr((a.pred - self.ref_pred)[held].ravel(),
                          (b.pred - self.ref_pred)[held].ravel())
                if np.isfinite(r) and r > CORRELATED:
                    alone = decision.kind == "single" and decision.verdict in (a.name, b.name)
                    warnings.append(
                        f"{a.name} and {b.name} correct the held-out residual alike"
                        f" (correlation {r:.2f})"
                        + ("; the first still beats the other clearly on held-out cycles"
                           if alone else ": the data cannot tell them apart, the verdict"
                           " names the set"))
        return warnings

    def reference_facts(self) -> dict[str, Any]:
        """``reference`` of diagnosis.json: what the model contains and what was fitted."""
        disc, tun, ref, p_ref = self.disc, self.est_tuning, self.ref, self.p_ref
        law = ref.law(p_ref)
        return {
            "contains": [
                f"datasheet structure of disc {disc.id}: {tun.nodes} radial nodes x"
                f" {tun.layers} graded layers, through-thickness conductivity"
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
            "at_bounds": {f"{e}.{p}": v for (e, p), v in ref.reference_at_bounds(p_ref).items()},
            "law_check": self.law_check(),
        }

    def law_check(self) -> dict[str, Any] | None:
        """The reference h law's plausibility (``thermal.hlaw_check``) over the fitted and
        held-out laps' speeds: a law flat with speed has absorbed what a candidate may
        explain, and every 'before' figure rests on it."""
        used = self.layout.train | self.layout.held
        return law_speed_check(self.ref.law(self.p_ref), self.inputs.speed[used])

    def summary(self, decision: Decision, ranked: list[Candidate],
                significant: list[Candidate], selection: dict[str, Any], t_start: float
                ) -> dict[str, Any]:
        """diagnosis.json (with the consistency header and the 'where' tables)."""
        y, layout, inputs = self.y, self.layout, self.inputs
        m = np.asarray(inputs.per_reading, float)  # each reading weighs once (race_run)
        sigma_meas = np.sqrt(m) * np.array([
            max(scoring.reading_noise(y[:, i], inputs.per_reading[i], inputs.steady),
                SIGMA_MEAS_FLOOR_C)
            for i in range(4)])
        cons, self.nis = consistency(
            self.model, inputs, y, self.ref.law(self.p_ref)(inputs.speed),
            float(np.exp(self.p_ref[2])), self.T0, self.spot_radii, sigma_meas,
            self.est_tuning.sigma_temp, self.est_tuning.init_sigma_temp,
            layout.train | layout.held)
        self.tick("consistency and where")
        ref_scores = score(self.ref_pred, y, layout, (1, 2, 3, 4))
        res_ref = y - self.ref_pred
        return {
            "session": str(self.session.path),
            "metadata": self.session.metadata,
            "reference": self.reference_facts(),
            "train_laps": list(self.train_laps),
            "heldout_laps": list(self.held_laps),
            "slow_laps": {str(n): share for n, share in slow_laps(self.session.laps).items()
                          if n in self.train_laps or n in self.held_laps},
            "gap": {
                "rmse_c": ref_scores["overall"],
                "per_spot": ref_scores["per_spot"],
                "per_phase": ref_scores["per_phase"],
                "per_spot_phase": ref_scores["per_spot_phase"],
            },
            "where": {"ranked_cells": where_table(res_ref, layout, inputs, self.segments, y),
                      **_marginals(res_ref, layout, inputs, self.segments, y),
                      "braking_zones": self.segments.n_zones},
            "consistency": cons,
            "effects": self.effects_out(decision),
            **decision.summary(),
            "combined": selection,
            "warnings": self.reference_warnings() + self.alike(decision, significant),
            "run": {
                "brakethermo": __version__,
                "disc": self.disc.id,
                "effects_tried": list(self.names),
                "timings_s": self.timings,
                "wall_time_s": time.perf_counter() - t_start,
                "input_warnings": [*self.session.warnings, *inputs.warnings,
                                   *filter(None, [assumed_disc(self.session,
                                                               self.options.disc)])],
            },
        }


def _forward_selection(
    significant: list[Candidate],
    fit_candidate: Callable[[tuple[str, ...], Candidate | None], Candidate],
    describe: Callable[[Candidate, np.ndarray], dict[str, Any]],
    at_bound: Callable[[Candidate], str],
) -> dict[str, Any]:
    """Greedy forward selection over the significant effects, on held-out laps; an
    effect is not added where the combined fit leaves a parameter at a bound of its range
    (it then stands in for something else: a look-alike came in through the combined
    model and identify-h carried it)."""
    if not significant:
        return {"effects": [], "steps": []}
    current = significant[0]
    steps = [{"added": current.name, "rmse_after": current.scores["rmse_after"],
              "shrink_pct": current.scores["shrink_pct"]}]
    for cand in significant[1:]:
        trial = fit_candidate((*current.effects, *cand.effects), current)
        gain = describe(trial, current.pred)
        if gain["significant"] and not at_bound(trial):
            trial.scores = gain
            steps.append({"added": cand.name, "rmse_after": gain["rmse_after"],
                          "shrink_pct": gain["shrink_pct"]})
            current = trial
    return {"effects": list(current.effects), "steps": steps}

