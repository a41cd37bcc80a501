"""Which online effects a race supports: decided by the race's own innovations.

A race disc may have another through-thickness conductivity than the test session's, a
rider may follow others down the straights, the pads may bite off-centre; each is an
online state of the estimate (``adapt_kz``, ``adapt_slipstream``, ``adapt_balance``). A
state the race does not need only adds variance — on a disc like the test session's an
online k_z lets the one measured spot pull the whole profile — so none is switched on
by default. Instead the race decides:

1. the filter runs (no smoother) on the first :data:`DECISION_LAPS` flying laps with no
   online effect (the reference) and with each candidate alone;
2. **a disc property** (k_z, the crown balance) is learned on the odd flying laps — the
   median of its online state there — and tested on the even ones: from the filtered
   state at the start of each held-out lap, the model runs open loop through the lap
   once with the property at its test-session value and once at the learned value;
   whichever predicts the measured spot better over the lap's braking cycles wins. A
   whole lap ahead, a structural error shows (one-step innovations hardly see it). A k_z
   learned within :data:`KZ_LIKE_LAW` of the law's stays off whatever it wins: a disc
   like the test session's, where adapting to it sharpened the measured spot and, more
   often than not, moved the unmeasured ones the wrong way;
3. **slipstream** changes straight by straight, so nothing learned on one lap holds on
   the next: it is judged by the one-step-ahead innovations, predictions from past
   readings only (a prequential score), with the predictive log-likelihood improving;
4. in both, the shrink must exceed :data:`MIN_SHRINK_PCT` at the lower end of a 95 %
   bootstrap interval over braking cycles (the diagnosis engine's rule). Of two effects
   one spot cannot tell apart (k_z and the crown balance) only the better is kept. A
   one-step candidate left off alone is judged again on top of what was chosen
   (:func:`_on_top`): alone, an online h factor stands in for a k_z change and loses.

5. **an effect the h law carries** and whose value a race may not share (the test
   session's μ(T): pads bed, a compound changes) must earn its place: the filter runs
   with the law as written and without that effect; from each run's own filtered state
   at the start of every flying lap after the first, its model predicts the lap open
   loop, and the effect is kept only when the lap-ahead error with it shrinks by the same
   rule (:data:`EARNED`: when it was dropped only on evidence it was kept in most
   development races and cost their contact band, races with the test session's own
   μ(T) too). When k_z is
   a candidate too, the two are judged together as a 2 x 2 (:func:`_joint_test`): with
   or without the effect, k_z off or online, each a whole lap ahead from its own
   filtered state. The best combination that beats the law without the effect says
   which factors to test (judged one after the other, the first change explains what the
   second causes: a μ(T) the race's pads lack made a normal disc's k_z look low); each
   must then beat its own counterpart at the other's final level. A k_z like the law's
   (item 2) stays off, and the effect is then judged with k_z off, as the race runs.
6. **the law's pyrometer lag** is the test session's sensor: a race logged by another
   (or a cleaned) pyrometer has its own. It is judged by the one-step predictive
   likelihood (a lag is the measurement's own model and shapes every braking's reading
   within seconds; dropped when the gain's lower 95 % bound over braking cycles exceeds
   :data:`MIN_LOGLIK_GAIN`) and, like the crown below, before the online states: a lag
   the race's sensor does not have smears the readings and hides a k_z change from the
   structural test.
7. **the law's pad-crown weights** (eq. 6-8) are the test session's pads: a race on
   other pads (or the same pads bedded otherwise) may not share a strongly uneven crown.
   They are tested the same way — uniform weights against the law's, a lap ahead — but
   *before* the online states: a crown the race does not have makes the measured spot
   run hotter or cooler than the model, which an online k_z (or the power scale) would
   otherwise "explain", moving the unmeasured spots the wrong way. When the uniform
   crown wins, the online candidates are judged again on it. Where it loses with the
   law's k_z and k_z is a candidate, it is judged again with k_z online in both
   (:func:`_crown_with_kz`): a race disc of lower k_z on other pads needs both changes.

8. **the crown-split noise of a thinner skin**: a race that switches k_z on below the
   law's chooses the law's crown-split noise or a lower one by its one-step predictive
   likelihood on these laps (:mod:`brakethermo.pipelines.crown_noise`), beside its own
   filter.

The crown balance is not a candidate: on the measured spot it does what a k_z change
does, and on races where neither the test session's split nor its k_z held, letting the
race pick it moved the unmeasured spots the wrong way (README, accuracy); it stays off
unless forced. The user's ``--adapt-*`` flags (or the tuning file's keys) force either
way.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from brakethermo.diagnosis.verdict import (
    CandidateEvidence,
    VerdictRule,
    decide,
    gain_interval,
    unit_sse,
)
from brakethermo.io.session import Session
from brakethermo.pipelines.law_drops import said
from brakethermo.pipelines.speculative import core
from brakethermo.report.braking_zones import detect_zones

if TYPE_CHECKING:
    from brakethermo.pipelines.estimate import EstimateOptions
    from brakethermo.pipelines.models import DiscCalibration

DECISION_LAPS = 8  # flying laps the decision runs on (a disc's k_z shows in a few)
MIN_SHRINK_PCT = 5.0  # % — lower bootstrap bound of the innovation shrink
# effect -> estimate option the race may switch on
ONLINE_FLAGS = {"thickness_gradient": "adapt_kz", "slipstream": "adapt_slipstream"}
CONFOUNDED = ("thickness_gradient", "power_distribution")  # one spot cannot tell them apart
# disc properties (a constant of the race disc) and their state columns and neutral value
STRUCTURAL = {"thickness_gradient": "kz_factor", "power_distribution": "crown_balance"}
NEUTRAL = {"kz_factor": 1.0, "crown_balance": 0.0}
# learned k_z / the law's within which a race disc counts as like the test session's. In
# the 22 development races this changed, the race disc's k_z was 0.82-1.22x the test
# disc's and identify-h had found 0.92-0.95x its own disc's; the race learns about the
# right factor there, yet switching it on sharpened the measured spot and moved the
# unmeasured ones the wrong way more often than not: one spot does not tell a moderate
# k_z change from what the law's h, crown and power scale, fitted with its own k_z,
# already hold (dev seeds 57010-13 and 58010-13: contact band 0.20-0.81x -> 0.12-0.49x
# the single-spot baseline, mean 0.50 -> 0.34x, 17 better, 5 worse; a whatif seed,
# 52010, lost 4.3 -> 8.3 degC). Wider above: a better-conducting disc flattens the
# through-thickness profile, so the contact band gains little from it.
KZ_LIKE_LAW = (0.67, 2.0)


# effects of the h law the race may drop (the rest are the disc's or the sensor's)
DROPPABLE = ("friction_temperature", "sensor_lag")  # the first: EARNED, below
CROWN = "crown_weights"  # the law's pad-crown weights, tested before the online states
# what shapes the measured spot itself: judged before the online states, which it hides
FIRST = (CROWN, "sensor_lag")
# a lag is the measurement's own model: judged by the one-step predictive likelihood (a
# proper score: a wrong lag shows in the innovations' size and in their variance)
BY_LIKELIHOOD = ("sensor_lag",)
MIN_LOGLIK_GAIN = 0.02  # nats per reading — lower bootstrap bound the drop must clear
JOINT = "thickness_gradient"  # judged together with the law's later parts (_joint_test)
# The law's later part (its μ(T)) must earn its place in the race: it is kept only where
# the law as written predicts the race's laps a lap ahead better than without it by the
# rule. Until then it was dropped only on evidence, kept in most races, and it cost the
# contact band:
# on 28 development races (seeds 58300-58340 and 57330-57340, μ(T) test laws of 2- and
# 5-lap sessions, races none / slipstream / pad split / μ(T)), the law without its μ(T)
# was never worse, mean 0.45 -> 0.33x the single-spot baseline, 0.26-0.86x -> 0.22-0.57x
# where it had been kept — on races with the test session's own μ(T) too. One spot's
# estimate feeds the power a temperature it does not measure, and the online power scale
# already follows what friction does over a race.
EARNED = "friction_temperature"
UNIFORM_CROWN = (1.0, 1.0, 1.0)
CROWN_KZ = f"without {CROWN} + {JOINT}"  # uniform weights with k_z online (_crown_with_kz)
# weights all within this of uniform: nothing worth a filter pass (the test sessions
# without a pad split give 0.8-1.25: the crown's usual unevenness and the model's own)
CROWN_TOLERANCE = 0.3


def law_without(cal: DiscCalibration, name: str) -> DiscCalibration:
    """The h law's calibration without one of its race-droppable parts (module docstring)."""
    if name == CROWN:
        return replace(cal, weights=UNIFORM_CROWN)
    return replace(cal, effects={k: v for k, v in cal.effects.items() if k != name})


def droppable(cal: DiscCalibration) -> tuple[str, ...]:
    """The parts of ``cal`` a race may drop: its uneven crown first, then its effects."""
    crown = (CROWN,) if max(abs(w - 1.0) for w in cal.weights) > CROWN_TOLERANCE else ()
    return crown + tuple(name for name in DROPPABLE if name in cal.effects)


@dataclass(frozen=True)
class OnlineChoice:
    """The flags the race chose, the law's effects it dropped, and why
    (the ``run.online_choice`` facts)."""

    flags: dict[str, bool]
    facts: dict[str, Any]
    dropped: tuple[str, ...] = ()


def head(session: Session, laps: int) -> Session:
    """The session up to the end of flying lap ``laps`` (out-lap included)."""
    ends = [lap.start_s + lap.duration_s for lap in session.laps if 1 <= lap.lap <= laps]
    if not ends:
        return session
    keep = session.frame["time"].to_numpy() <= max(ends) + 1e-9
    return replace(session, frame=session.frame.loc[keep].reset_index(drop=True),
                   laps=tuple(lap for lap in session.laps if lap.lap <= laps))


UNDECIDED = "not decided: fewer than two flying laps"  # the rule's opening words


def choose_online(session: Session, base: EstimateOptions, candidates: tuple[str, ...],
                  cal: DiscCalibration, parts: tuple[str, ...] = (),
                  on_learned: Callable[[float], None] | None = None) -> OnlineChoice:
    """Run the decision (module docstring) for ``candidates`` (effect names).

    ``base`` is the estimate's options with every candidate's flag unset; the decision
    runs filter-only passes with each flag forced, on the calibration ``cal``. ``parts``
    are the parts of the h law the race may drop (:func:`droppable`). ``on_learned``
    gets the k_z factor (of the law's) the race learned, as soon as a pass's k_z variant
    ends (that variant runs first), on the thread and core that ran it: what it does
    there holds that core from the decision's next variant.
    """
    flying = sorted({lap.lap for lap in session.laps if lap.lap >= 1})
    if not (candidates or parts) or len(flying) < 2:
        unearned = (EARNED,) if EARNED in parts else ()
        untested = [_earned_row({"shrink_pct": float("nan"),
                                 "shrink_ci95_pct": [float("nan")] * 2,
                                 "test": "not tested: fewer than two flying laps"}, p, True)
                    for p in unearned]
        return OnlineChoice({ONLINE_FLAGS[c]: False for c in candidates}, {
            "rule": f"{UNDECIDED}; online effects left off, the h law's effects kept"
                    + (f" but its {EARNED}, which a race must earn" if unearned else ""),
            "candidates": list(candidates),
            "law_effects_tested": [_read_out(r, unearned, base.spot) for r in untested],
            "law_effects_dropped": list(unearned)}, unearned)
    t = _trial(session, base, candidates, parts, flying)
    runs = _one_pass(t, cal, True, on_learned)
    tested = _first_tests(t, runs, cal)
    dropped_first = tuple(r["name"].removeprefix("without ") for r in tested
                          if r["significant"])
    for name in dropped_first:
        cal = law_without(cal, name)
    if dropped_first:
        runs = _one_pass(t, cal, False, on_learned)
    rows = _online_rows(runs, candidates, t.lap, t.cycles, t.rule)
    # a crown dropped for uniform weights *with k_z online*: k_z goes on with it, and the
    # law's μ(T) is judged at that k_z level
    kz_forced = any((r.get("with_kz") or {}).get("significant") for r in tested)
    if t.joint is not None:
        _judge_jointly(t, t.joint, runs, rows, tested, kz_forced)
    if kz_forced:
        _on_with_uniform_crown(rows)
    chosen = [r["name"] for r in rows if r["significant"]]
    alike = [c for c in chosen if c in CONFOUNDED]
    chosen = [c for c in chosen if c not in alike[1:]]
    chosen += _on_top(t, runs, rows, cal, chosen, tested)
    flags = {ONLINE_FLAGS[c]: c in chosen for c in candidates}
    tested.extend(_later_tests(t, runs, cal, chosen))
    dropped = tuple(r["name"].removeprefix("without ") for r in tested if r["significant"])
    return OnlineChoice(flags, {
        "rule": (f"switched on when the measured spot's one-step-ahead innovation RMSE"
                 f" shrinks by more than {MIN_SHRINK_PCT:g} % (lower end of a 95 % bootstrap"
                 " interval over braking cycles) and the predictive log-likelihood improves,"
                 f" on flying laps 1-{min(DECISION_LAPS, flying[-1])}; of k_z and the crown"
                 " balance (one spot cannot tell them apart) only the better; the law's"
                 " pyrometer lag and uneven pad crown are judged first (the crown again"
                 " with k_z online where it lost with the law's k_z); its μ(T) is kept"
                 " only where the race earns it"
                 + (", judged together with k_z" if t.joint is not None else "")),
        "laps": [int(v) for v in np.unique(t.lap[t.lap >= 1])],
        "chosen": chosen,
        "scores": rows,
        "law_effects_tested": [_read_out(r, dropped, base.spot) for r in tested],
        "law_effects_dropped": list(dropped),
        **_law_kz(runs["reference"], cal, t.lap),
    }, dropped)


def _law_kz(run: Any, cal: DiscCalibration, lap: np.ndarray) -> dict[str, float]:
    """``law_kz_learned``: where the h law carries a k_z (identify-h found the test disc's),
    the race's k_z is online from the start, not a candidate; what it learned (a factor of
    the law's, :func:`_learned`) says whether the race disc has a thinner skin still
    (:func:`thin_skin_learned`)."""
    if JOINT not in cal.effects or STRUCTURAL[JOINT] not in run.state_space.index:
        return {}
    return {"law_kz_learned": _learned(run, STRUCTURAL[JOINT], lap)}


def _read_out(row: dict[str, Any], dropped: tuple[str, ...], spot: int = 3
              ) -> dict[str, Any]:
    """A ``law_effects_tested`` row with what it decided (``outcome``), what the sign of
    its figure means (``meaning``) and, for a part dropped (or kept against the measured
    spot's lean), the sentence said on the console and the page (``said``,
    :func:`~brakethermo.pipelines.law_drops.said`; ``spot``: the measured one): the rows
    compare in different directions (the crown and the lag: the law without the part
    against with it; an earned effect: with it against without), so "without
    friction_temperature" at -9 % read as "removing μ(T) makes the error 9 % worse" where
    the law's μ(T) had raised it by 9 % and was dropped."""
    name = row["name"].removeprefix("without ")
    if row.get("must_earn") and not np.isfinite(row["shrink_pct"]):
        meaning = (f"not tested (fewer than two flying laps): the law's {name} must be"
                   " earned by the race, so it is dropped")
    elif row.get("must_earn"):
        meaning = (f"shrink_pct: how much the lap-ahead error shrinks with the law's {name}"
                   " kept against dropped (negative: it made the error worse); kept only"
                   " where that shrink clears the rule (significant: true here means"
                   " dropped, not earned)")
    elif name in BY_LIKELIHOOD:
        meaning = (f"loglik_gain_per_reading: how much the one-step predictive likelihood"
                   f" rises with the law's {name} dropped (positive favours dropping it;"
                   f" dropped, significant: true, when its lower 95 % bound exceeds"
                   f" {MIN_LOGLIK_GAIN:g}); shrink_pct: the one-step innovations' shrink"
                   " with it dropped")
    else:
        meaning = ("shrink_pct: how much the lap-ahead error shrinks with uniform pad-crown"
                   " weights instead of the law's (positive favours dropping the law's;"
                   " dropped, significant: true, where it clears the rule)")
    out = {**row, "outcome": "dropped" if name in dropped else "kept", "meaning": meaning}
    line = said(out, name in dropped, spot)
    return {**out, "said": line} if line else out


@dataclass(frozen=True)
class _Trial:
    """What every pass of the decision shares: the decision laps, the options and flags
    the variants start from, the law's parts under test and the tests' units."""

    part: Session  # the session up to the last decision lap
    quick: EstimateOptions  # filter-only options, every candidate's flag unset
    off: dict[str, bool]  # every candidate's flag, off
    candidates: tuple[str, ...]
    first: tuple[str, ...]  # the law's parts judged before the online states
    later: tuple[str, ...]  # the others
    joint: str | None  # the candidate judged together with ``later`` (:func:`_joint_test`)
    lap: np.ndarray  # (K,) lap number per step of ``part``
    cycles: np.ndarray  # (K,) braking cycle per step, -1 before the first
    rule: VerdictRule


def decision_units(part: Session) -> tuple[np.ndarray, np.ndarray, VerdictRule]:
    """The lap of each grid point of the decision's laps ``part``, its braking cycle (-1
    before the first: the unit the bootstrap resamples) and the rule the tests apply."""
    lap = part.frame["lap"].to_numpy()
    zones = detect_zones(part.time, part.values("brake_pressure_front"))
    cycles = np.full(lap.size, -1)
    for j, (a, _) in enumerate(zones):
        cycles[a:] = j
    return lap, cycles, VerdictRule(min_shrink_pct=MIN_SHRINK_PCT)


def thin_skin_learned(choice: OnlineChoice) -> float | None:
    """The k_z factor (of the law's) a race switched on below the law's — a thinner
    thermal skin than the law's disc — or None. Where the law carries a k_z (online in
    every race), the factor the race learned on it, when below :data:`KZ_LIKE_LAW`: a
    development race on a disc 0.42x its baseline test disc's k_z learned 0.47 on the law's
    coarser layering and ran 1.25x the single-spot baseline."""
    row = next((r for r in choice.facts.get("scores", []) if r.get("name") == JOINT), None)
    if row is not None and JOINT in choice.facts.get("chosen", []):
        learned = row.get("learned", 1.0)
        return float(learned) if learned < 1.0 else None
    carried = choice.facts.get("law_kz_learned")
    if carried is not None and np.isfinite(carried) and carried < KZ_LIKE_LAW[0]:
        return float(carried)
    return None


def _trial(session: Session, base: EstimateOptions, candidates: tuple[str, ...],
           parts: tuple[str, ...], flying: list[int]) -> _Trial:
    """The decision's shared setup on the first :data:`DECISION_LAPS` flying laps."""
    part = head(session, min(DECISION_LAPS, flying[-1]))
    off = {ONLINE_FLAGS[c]: False for c in candidates}
    quick = replace(base, smoother=False, score=False, online_auto=False)
    lap, cycles, rule = decision_units(part)
    first = tuple(p for p in parts if p in FIRST)
    later = tuple(p for p in parts if p == EARNED)
    joint = JOINT if JOINT in candidates and later else None
    return _Trial(part, quick, off, candidates, first, later, joint, lap, cycles, rule)


def _one_pass(t: _Trial, law: DiscCalibration, with_first: bool,
              on_learned: Callable[[float], None] | None = None) -> dict[str, Any]:
    """The reference, each candidate alone, the law without each of its parts under test
    (``with_first``: the first ones too) and, with a joint candidate, without each later
    part plus it; all filter-only runs on the calibration ``law``. The k_z variant runs
    first and hands what it learned to ``on_learned`` (:func:`choose_online`)."""
    kz = "thickness_gradient"
    variants = {c: (replace(t.quick, **{**t.off, ONLINE_FLAGS[c]: True}), law)
                for c in sorted(t.candidates, key=lambda c: c != kz)}
    variants["reference"] = (replace(t.quick, **t.off), law)
    variants.update({f"without {p}": (replace(t.quick, **t.off), law_without(law, p))
                     for p in (*t.first, *t.later) if with_first or p in t.later})
    if with_first and CROWN in t.first and kz in t.candidates:
        variants[CROWN_KZ] = (replace(t.quick, **{**t.off, ONLINE_FLAGS[kz]: True}),
                              law_without(law, CROWN))
    if t.joint is not None:
        variants.update({f"without {p} + {t.joint}": (
            replace(t.quick, **{**t.off, ONLINE_FLAGS[t.joint]: True}), law_without(law, p))
            for p in t.later})

    def done(name: str, run: Any) -> None:
        if name == kz and on_learned is not None:
            on_learned(_learned(run, STRUCTURAL[kz], t.lap))

    return _run_variants(t.part, variants, done)


def _first_tests(t: _Trial, runs: dict[str, Any], cal: DiscCalibration
                 ) -> list[dict[str, Any]]:
    """The law's parts that shape the measured spot itself (its crown, its lag), each
    dropped against the law as written (``cal``) before the online states are judged."""
    tested = []
    for name in t.first:
        if name in BY_LIKELIHOOD:
            row = likelihood_test(runs["reference"], runs[f"without {name}"], t.lap, t.cycles,
                                  t.rule)
        else:
            row = _lap_ahead_test(runs["reference"], runs[f"without {name}"], t.lap, t.cycles,
                                  t.rule)
        if name == CROWN:
            row = {**row, "law": list(cal.weights),
                   "test": f"uniform weights against the law's, {row['test']}"}
            if not row["significant"] and CROWN_KZ in runs:
                row = _crown_with_kz(t, runs, row)
        # what dropping it does to the unmeasured spots, in the configuration it was
        # dropped in
        law, other = ((JOINT, CROWN_KZ) if (row.get("with_kz") or {}).get("significant")
                      else ("reference", f"without {name}"))
        tested.append({**row, "name": f"without {name}",
                       "peaks_apart_c": _peaks_apart(runs[law], runs[other], t.lap)})
    return tested


def _on_with_uniform_crown(rows: list[dict[str, Any]]) -> None:
    """k_z on, whatever its own test on the uniform crown said: the crown was dropped
    because uniform weights *with k_z online* beat the law's (:func:`_crown_with_kz`)."""
    row = next(r for r in rows if r["name"] == JOINT)
    row.pop("like_law", None)
    if not row["significant"]:
        row["significant"] = True
        row["with_uniform_crown"] = ("switched on with the uniform crown: the law's crown was"
                                     " dropped for uniform weights with k_z online")


def _crown_with_kz(t: _Trial, runs: dict[str, Any], row: dict[str, Any]) -> dict[str, Any]:
    """The law's uneven crown against uniform weights with k_z online in both, where it won
    with k_z off: a race disc of lower k_z on other pads (or pads bedded otherwise) needs
    both changes, and with the law's k_z the uniform crown predicts the measured spot
    worse (a development race: -106 % with k_z off; 2.71x the single-spot baseline with the
    law's crown kept, 0.49x with uniform weights and k_z on). Dropped (``with_kz``) only
    where uniform + k_z beats the law's crown + k_z *and* the law as written by the rule,
    at a k_z the race may switch on (:func:`kz_allowed`): that configuration is then the
    race's (:func:`choose_online` switches k_z on with it)."""
    learned = _learned(runs[CROWN_KZ], STRUCTURAL[JOINT], t.lap)
    kz_on = _lap_ahead_test(runs[JOINT], runs[CROWN_KZ], t.lap, t.cycles, t.rule)
    law = _lap_ahead_test(runs["reference"], runs[CROWN_KZ], t.lap, t.cycles, t.rule)
    won = kz_on["significant"] and law["significant"] and kz_allowed(learned)
    joint = {"shrink_pct": kz_on["shrink_pct"], "shrink_ci95_pct": kz_on["shrink_ci95_pct"],
             "against_law_as_written": {k: law[k] for k in ("shrink_pct", "shrink_ci95_pct",
                                                            "significant")},
             "kz_learned": learned, "significant": won}
    out = {**row, "with_kz": joint}
    if won:
        out.update(shrink_pct=kz_on["shrink_pct"], shrink_ci95_pct=kz_on["shrink_ci95_pct"],
                   significant=True,
                   test=(f"uniform weights against the law's with k_z online in both (with k_z"
                         f" off: {row['shrink_pct']:.0f} %), {kz_on['test']}; k_z goes on with"
                         f" it (learned {learned:.2f} of the law's)"))
    return out


def _judge_jointly(t: _Trial, joint: str, runs: dict[str, Any], rows: list[dict[str, Any]],
                   tested: list[dict[str, Any]], kz_forced: bool = False) -> None:
    """``joint`` and the law's :data:`EARNED` effect judged together (:func:`_joint_test`;
    ``kz_forced``: k_z goes on whatever, :func:`_crown_with_kz`): the joint verdict
    replaces ``joint``'s own test in ``rows``, the effect's row joins ``tested``."""
    own = next(r for r in rows if r["name"] == joint)
    allowed = kz_allowed(own["learned"])
    (p,) = t.later
    j = _joint_test(runs, joint, p, t.lap, t.cycles, t.rule, allowed, kz_forced)
    # the joint verdict replaces the structural test's
    own.update({k: j.kz_row[k] for k in ("shrink_pct", "shrink_ci95_pct", "test")},
               significant=j.kz_on, joint_test=j.combos)
    own.pop("like_law", None)
    if j.gated:
        own["like_law"] = _LIKE_LAW_SAID.format(own["learned"])
    with_kz = j.kz_on and f"without {p} + {joint}" in runs
    apart = (_peaks_apart(runs[joint], runs[f"without {p} + {joint}"], t.lap) if with_kz
             else _peaks_apart(runs["reference"], runs[f"without {p}"], t.lap))
    tested.append({**_earned_row(j.effect_row, p, not j.kept), "peaks_apart_c": apart})


def _on_top(t: _Trial, runs: dict[str, Any], rows: list[dict[str, Any]],
            cal: DiscCalibration, chosen: list[str], tested: list[dict[str, Any]]
            ) -> list[str]:
    """The one-step candidates left off, judged again on top of the states the race
    chose, on the law as the race will run it (without a law effect the joint test
    dropped): alone, an online h factor tries to stand in for a k_z change and loses,
    while on a low-k_z disc with k_z online it still corrects the law (an independent
    generator's low-k_z races: left off at -35 %, they ran 0.78x the single-spot
    baseline; with it 0.24x). Each such row gets its test on top (``on_top``); its own
    figures stay the test alone."""
    rest = [r for r in rows if not r["significant"] and r["name"] not in STRUCTURAL]
    if not chosen or not rest:
        return []
    dropped = [r["name"].removeprefix("without ") for r in tested
               if r.get("must_earn") and r["significant"]]
    law = cal
    for name in dropped:
        law = law_without(law, name)
    on = {**t.off, **{ONLINE_FLAGS[c]: True for c in chosen}}
    # the run of what was chosen, when the decision has it already
    have = {(): chosen[0]} if len(chosen) == 1 else {}
    if t.joint is not None and chosen == [t.joint]:
        have[tuple(t.later)] = f"without {t.later[0]} + {t.joint}"
    base_key = have.get(tuple(dropped), "chosen")
    variants = {} if base_key in runs else {"chosen": (replace(t.quick, **on), law)}
    variants.update({f"chosen + {r['name']}": (
        replace(t.quick, **{**on, ONLINE_FLAGS[r["name"]]: True}), law) for r in rest})
    runs.update(_run_variants(t.part, variants))
    added = []
    for r in rest:
        top = _one_step_test(runs[base_key], runs[f"chosen + {r['name']}"], t.lap, t.cycles,
                             t.rule)
        r["on_top"] = {"of": list(chosen), **{k: top[k] for k in (
            "shrink_pct", "shrink_ci95_pct", "significant", "test", "loglik_gain_per_reading")}}
        if top["significant"]:
            added.append(r["name"])
    return added


def _later_tests(t: _Trial, runs: dict[str, Any], cal: DiscCalibration, chosen: list[str]
                 ) -> list[dict[str, Any]]:
    """The law's later parts each dropped a lap ahead, under the online states the race
    chose (re-run into ``runs`` when it chose any); none when they were judged jointly."""
    if t.joint is not None:
        return []
    ref = runs["reference"]
    if t.later and chosen:
        # the law's effects are judged under the online states the race chose
        on = {**t.off, **{ONLINE_FLAGS[c]: True for c in chosen}}
        again = {"reference": (replace(t.quick, **on), cal)}
        again.update({f"without {p}": (replace(t.quick, **on), law_without(cal, p))
                      for p in t.later})
        runs.update(_run_variants(t.part, again))
        ref = runs["reference"]
    tested = []
    for p in t.later:
        row = _lap_ahead_test(runs[f"without {p}"], ref, t.lap, t.cycles, t.rule)
        row["test"] = f"against the law without its {p}, {row['test']}"
        tested.append({**_earned_row(row, p, not row["significant"]),
                       "peaks_apart_c": _peaks_apart(ref, runs[f"without {p}"], t.lap)})
    return tested


def _earned_row(row: dict[str, Any], name: str, dropped: bool) -> dict[str, Any]:
    """The :data:`EARNED` effect's row in ``law_effects_tested``: ``row`` is the law with
    the effect against the law without it (k_z as the race runs it), so its shrink is
    what keeping the effect gains (the page says "with it"); ``must_earn`` marks such a
    row and ``significant`` that the race did not earn it (dropped)."""
    return {**row, "name": f"without {name}", "significant": dropped, "must_earn": True,
            "test": f"kept only where the race earns it ({row['test']})"}


def _online_rows(runs: dict[str, Any], candidates: tuple[str, ...], lap: np.ndarray,
                 cycles: np.ndarray, rule: VerdictRule) -> list[dict[str, Any]]:
    """Each online candidate's test against the reference run, best first."""
    ref = runs["reference"]
    loglik = {name: float(np.nanmean(_loglik(r))) for name, r in runs.items()}
    rows = []
    for c in candidates:
        if c in STRUCTURAL:
            row = _structural_test(runs[c], STRUCTURAL[c], lap, cycles, rule)
        else:
            row = _one_step_test(ref, runs[c], lap, cycles, rule, loglik[c] - loglik["reference"])
            row.update(_by_lap(runs[c]))
        row["name"] = c
        rows.append(row)
    rows.sort(key=lambda r: -np.nan_to_num(r["shrink_pct"], nan=-1e9))
    return rows


@dataclass(frozen=True)
class _Joint:
    """The joint judgement of k_z and the law's effect (:func:`_joint_test`)."""

    combos: list[dict[str, Any]]  # each combination against the law without the effect
    kept: bool  # the law's effect earned its place
    kz_on: bool  # k_z goes on
    gated: bool  # k_z won its test but is like the law's (KZ_LIKE_LAW): left off
    effect_row: dict[str, Any]  # the effect kept against dropped, at k_z's final state
    kz_row: dict[str, Any]  # k_z on against off, on the law as the race uses it


def _joint_test(runs: dict[str, Any], joint: str, p: str, lap: np.ndarray,
                cycles: np.ndarray, rule: VerdictRule, allowed: bool = True,
                forced: bool = False) -> _Joint:
    """k_z and the law's :data:`EARNED` effect ``p``, judged together: a 2 x 2 of the law
    with or without ``p`` and k_z off or online, each a whole lap ahead from its own
    filtered state (online states frozen at the lap's start) on the flying laps after
    the first.

    The best combination that beats the law without ``p`` by the rule says which factors
    are worth testing (judged one after the other, the first change explains what the
    second causes: a μ(T) the race's pads lack made a normal disc's k_z look low); each
    factor then has to beat its own counterpart at the other's final level — ``p`` is
    kept only where the law with it beats the law without it, with k_z as it will run,
    and k_z goes on (only when ``allowed``: learned outside :data:`KZ_LIKE_LAW`) only
    where it beats k_z off on the law as the race will use it. ``forced``: k_z goes on
    whatever (the law's crown was dropped for uniform weights with k_z online), and
    ``p`` is judged at that level.
    """
    laps = np.unique(lap[lap >= 2])
    units = np.where(np.isin(lap, laps), cycles, -1)
    y = runs["reference"].y_measured
    base = f"without {p}"
    law_kz, base_kz = joint, f"{base} + {joint}"
    sse = {n: unit_sse(_lap_ahead(runs[n], lap, laps) - y, units)[0]
           for n in (base, "reference", law_kz, base_kz)}
    where = "each a whole lap ahead from its own filtered state, flying laps " + ", ".join(
        str(int(v)) for v in laps)
    d = decide(sse[base], [CandidateEvidence(n, sse[n])
                           for n in ("reference", law_kz, base_kz)], rule)
    # "reference" is the law as written, μ(T) included: each combination says what it is
    variant = {"reference": f"the law as written, with its {p}; k_z off",
               law_kz: f"the law as written, with its {p}; k_z online",
               base_kz: f"the law without its {p}; k_z online"}
    combos = [{**r, "variant": variant[r["name"]],
               "test": f"against the law without its {p} (k_z off), {where}"} for r in d.rows]
    winner = next((r["name"] for r in combos if r["significant"]), base)
    won_kz = winner in (law_kz, base_kz)

    def pair(before: str, after: str, test: str) -> dict[str, Any]:
        row = decide(sse[before], [CandidateEvidence(after, sse[after])], rule).rows[0]
        return {**row, "test": f"{test}, {where}"}

    def effect(kz: bool) -> dict[str, Any]:
        if kz:
            return pair(base_kz, law_kz, f"the law with its {p} against without it, k_z"
                        " online in both (a k_z difference otherwise masks it)")
        return pair(base, "reference", f"the law with its {p} against without it")

    def kz(kept: bool) -> dict[str, Any]:
        if kept:
            return pair("reference", law_kz, "k_z online against off, on the law as written")
        return pair(base, base_kz, f"k_z online against off, on the law without its {p}")

    kz_try = forced or (allowed and won_kz)
    effect_row = effect(kz_try)
    kz_row = kz(effect_row["significant"])
    kz_on = forced or (kz_try and kz_row["significant"])
    if kz_try and not kz_on:
        # no configuration where each factor beats its counterpart at the other's level
        # (k_z helps at one μ(T) level only): k_z stays off, the effect judged as the
        # race then runs
        effect_row = effect(False)
        kz_row = kz(effect_row["significant"])
        if kz_row["significant"]:
            kz_row = {**kz_row, "test": f"{kz_row['test']}; left off: with the law's {p}"
                      " judged beside it, it did not clear the rule"}
    gated = won_kz and not allowed and kz_row["significant"]
    return _Joint(combos, effect_row["significant"], kz_on, gated, effect_row, kz_row)


def likelihood_test(ref: Any, other: Any, lap: np.ndarray, cycles: np.ndarray,
                    rule: VerdictRule) -> dict[str, Any]:
    """Does ``other`` predict the flying laps' readings one step ahead with a higher
    likelihood, per braking cycle, by more than :data:`MIN_LOGLIK_GAIN` at the lower end
    of the 95 % bootstrap interval?"""
    units = np.where(lap >= 1, cycles, -1)
    a, b = _loglik(ref), _loglik(other)
    keep = (units >= 0) & np.isfinite(a) & np.isfinite(b)
    _, inv = np.unique(units[keep], return_inverse=True)
    count = np.bincount(inv)
    gain, lo, hi = gain_interval(np.bincount(inv, a[keep]), np.bincount(inv, b[keep]), count,
                                 rule)
    d = decide(unit_sse(ref.innovation, units)[0],
               [CandidateEvidence("other", unit_sse(other.innovation, units)[0])], rule)
    return {**d.rows[0], "test": "one-step predictive likelihood, every flying lap",
            "loglik_gain_per_reading": gain, "loglik_gain_ci95": [lo, hi],
            "significant": bool(np.isfinite(lo) and lo > MIN_LOGLIK_GAIN)}


def _by_lap(run: Any) -> dict[str, str]:
    """What a slipstream variant's (filtered) h factor read lap by lap, when some laps
    were lower than the others (:mod:`~brakethermo.pipelines.h_factor_found`): one spot's
    innovations gain little from following it (the filter corrects that spot anyway), but
    the engineer should know where the cooling dropped — the third independent generator's
    race behind another bike on three laps gained 1 % and was left off, while the state
    read 0.88-0.90 on exactly those laps."""
    found = ((run.summary["run"].get("effects") or {}).get("slipstream") or {}).get("found")
    return {"by_lap": found["said"]} if found and found.get("kind") == "by lap" else {}


def _one_step_test(ref: Any, other: Any, lap: np.ndarray, cycles: np.ndarray,
                   rule: VerdictRule, loglik_gain: float | None = None) -> dict[str, Any]:
    """Do ``other``'s one-step-ahead innovations (predictions from past readings only)
    shrink over the flying laps' braking cycles, with the predictive likelihood up?"""
    if loglik_gain is None:
        loglik_gain = float(np.nanmean(_loglik(other)) - np.nanmean(_loglik(ref)))
    units = np.where(lap >= 1, cycles, -1)
    d = decide(unit_sse(ref.innovation, units)[0],
               [CandidateEvidence("other", unit_sse(other.innovation, units)[0])], rule)
    row = {**d.rows[0], "test": "one-step-ahead innovations, every flying lap",
           "loglik_gain_per_reading": loglik_gain}
    row["significant"] &= loglik_gain > 0
    return row


def _structural_test(run: Any, param: str, lap: np.ndarray, cycles: np.ndarray,
                     rule: VerdictRule) -> dict[str, Any]:
    """Learn a disc property on odd laps, test it a whole lap ahead on even ones."""
    ssm, X = run.state_space, run.states
    j = ssm.index[param]
    neutral = NEUTRAL[param]
    learned = _learned(run, param, lap)
    y = run.y_measured
    starts = np.repeat(X[:, None, :], 2, axis=1)
    starts[:, :, j] = (neutral, learned)
    pred = np.full((lap.size, 2), np.nan)
    for rows, p in _open_loop(run, lap, np.unique(lap[(lap >= 2) & (lap % 2 == 0)]),
                              starts):
        pred[rows] = p
    held = (lap >= 2) & (lap % 2 == 0)
    units = np.where(held, cycles, -1)
    err = pred - y[:, None]
    d = decide(unit_sse(err[:, 0], units)[0],
               [CandidateEvidence(param, unit_sse(err[:, 1], units)[0])], rule)
    row = {**d.rows[0], "test": "learned on odd flying laps, a whole lap ahead on even ones",
           "learned": learned, "neutral": neutral}
    if param == "kz_factor" and not kz_allowed(learned):
        if row["significant"]:  # the gate, not the test, leaves it off: say so
            row["like_law"] = _LIKE_LAW_SAID.format(learned)
        row["significant"] = False
    return row


def _learned(run: Any, param: str, lap: np.ndarray) -> float:
    """What the race learned of a disc property: the median of its online state in
    ``run`` over the odd flying laps (its neutral value without one)."""
    train = (lap >= 1) & (lap % 2 == 1)
    if not train.any():
        return NEUTRAL[param]
    return float(np.median(run.states[train, run.state_space.index[param]]))


def kz_allowed(learned: float) -> bool:
    """May a race switch k_z on at this learned factor of the law's? Only a finite one
    outside the band of discs like the test session's (:data:`KZ_LIKE_LAW`)."""
    return bool(np.isfinite(learned)
                and not KZ_LIKE_LAW[0] <= learned <= KZ_LIKE_LAW[1])


_LIKE_LAW_SAID = (f"but the race's k_z came out {{:.2f}} of the law's, within"
                  f" {KZ_LIKE_LAW[0]:g}-{KZ_LIKE_LAW[1]:g}: a disc like the test session's,"
                  " where switching k_z on did more harm than good on development races, so it"
                  " stays off (--adapt-kz forces it)")


def _run_variants(part: Session, variants: dict[str, tuple[Any, Any]],
                  done: Callable[[str, Any], None] | None = None) -> dict[str, Any]:
    """Filter-only estimates of ``part``, one per (options, calibration) variant, started
    in their order; ``done(name, result)`` after each, on its core still. The filter's
    kernels release the GIL: the variants run side by side on the cores a speculative
    run of the estimate leaves (:mod:`brakethermo.pipelines.speculative`)."""
    from brakethermo.pipelines.estimate import estimate_from_session

    def run(name: str, opts: EstimateOptions, cal: DiscCalibration) -> Any:
        with core():
            result = estimate_from_session(part, opts, cal)
            if done is not None:
                done(name, result)
            return result

    with ThreadPoolExecutor(len(variants)) as pool:
        futures = {name: pool.submit(run, name, opts, cal)
                   for name, (opts, cal) in variants.items()}
        return {name: f.result() for name, f in futures.items()}


def _lap_ahead(run: Any, lap: np.ndarray, laps: np.ndarray) -> np.ndarray:
    """The measured spot predicted open loop through each of ``laps`` from the run's own
    filtered state at the lap's start (its model, its online states frozen)."""
    pred = np.full(lap.size, np.nan)
    for rows, p in _open_loop(run, lap, laps, run.states[:, None, :]):
        pred[rows] = p[:, 0]
    return pred


def _open_loop(run: Any, lap: np.ndarray, laps: np.ndarray, starts: np.ndarray
               ) -> list[tuple[np.ndarray, np.ndarray]]:
    """Open-loop predictions of the measured spot through each of ``laps``, all laps and
    all variants in one batch (each row at its own step: the model's inputs are indexed
    per row), from ``starts[k]`` (V, n): the V variant states at step k.

    Returns ``(the lap's step indices, (len, V) predictions)`` per lap."""
    ssm = run.state_space
    H = ssm.H_measured(run.spot_radius)[0]
    idx = [np.flatnonzero(lap == n) for n in laps]
    idx = [i for i in idx if i.size]
    if not idx:
        return []
    V = starts.shape[1]
    first = np.array([i[0] for i in idx])
    length = np.repeat([i.size for i in idx], V)
    x = starts[first].reshape(-1, starts.shape[2]).copy()
    k0 = np.repeat(first, V)
    pred = np.full((x.shape[0], int(length.max())), np.nan)
    for j in range(pred.shape[1]):
        live = j < length
        pred[live, j] = x[live] @ H
        step = live & (k0 + j + 1 < lap.size)
        if step.any():
            x[step] = ssm.f(x[step], k0[step] + j)
    return [(i, pred[m * V:(m + 1) * V, :i.size].T) for m, i in enumerate(idx)]


def _lap_ahead_test(ref: Any, other: Any, lap: np.ndarray, cycles: np.ndarray,
                    rule: VerdictRule) -> dict[str, Any]:
    """Does ``other``'s model predict the flying laps after the first better, a lap ahead?"""
    laps = np.unique(lap[lap >= 2])
    held = np.isin(lap, laps)
    units = np.where(held, cycles, -1)
    y = ref.y_measured
    before = unit_sse(_lap_ahead(ref, lap, laps) - y, units)[0]
    after = unit_sse(_lap_ahead(other, lap, laps) - y, units)[0]
    d = decide(before, [CandidateEvidence("other", after)], rule)
    return {**d.rows[0], "test": "each model a whole lap ahead from its own filtered state,"
            f" flying laps {', '.join(str(int(v)) for v in laps)}"}


def _peaks_apart(law: Any, other: Any, lap: np.ndarray) -> dict[str, float]:
    """How far each spot's lap peak reads with the law's part (run ``law``) from without
    it (``other``), °C, the mean over the decision's flying laps: what dropping a part
    judged on one spot does to the spots the race does not measure."""
    flying = np.unique(lap[lap >= 1])
    out = {}
    for s in ("spot1", "spot2", "spot3", "spot4"):
        a, b = law.frame[s].to_numpy(dtype=float), other.frame[s].to_numpy(dtype=float)
        diff = [np.nanmax(a[lap == n]) - np.nanmax(b[lap == n]) for n in flying
                if np.isfinite(a[lap == n]).any() and np.isfinite(b[lap == n]).any()]
        out[s] = float(np.mean(diff)) if diff else float("nan")
    return out


def _loglik(result: Any) -> np.ndarray:
    nu, s2 = result.innovation, result.innovation_var
    return -0.5 * (np.log(2.0 * np.pi * s2) + nu**2 / s2)
