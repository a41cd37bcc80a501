"""Verdicts from held-out evidence, for any model: which candidate effect explains the
gap, which few the data cannot tell apart, and what would separate them.

The engine knows nothing of discs or rigs. A caller scores the reference model and each
candidate extension on held-out data, cuts the held-out errors into independent
*units* (braking cycles of a lap, apply cycles of a rig, sessions of a test day) and
hands over the sum of squared errors per unit. Everything here resamples those units:

- **shrink** of a candidate: ``100 (1 - sqrt(SSE_after / SSE_before))`` over all units,
  with a 95 % interval from a paired bootstrap over units;
- **significant**: the lower end of that interval above ``min_shrink_pct`` (no interval,
  so never significant, over fewer than two units: one unit resampled is one observation
  presented as certain); or, for a
  candidate that registers where its signature lives (a subset of the held-out data cut
  into its own units, e.g. the fastest straights for a cooling law's knee), the lower end
  of the shrink interval on those units above ``min_shrink_pct`` while the whole-data
  interval stays above zero (it helps where it should and harms nowhere on the whole);
- **set verdict**: the best significant candidate, joined by every other significant one
  it does not beat clearly — the lower end of the bootstrap interval of the shrink
  *difference* (percentage points, same resamples) not above ``clear_margin_pct``, or
  whose correction correlates with the best's above ``correlated`` while the two shrink
  intervals overlap (look-alikes). Undecided candidates (below) are held to the same test
  and join the set after the significant ones: a single name is given only when it beats
  every other candidate that may be the cause clearly;
- **undecided**: candidates that shrink the held-out gap at their best estimate and
  whose interval straddles the threshold (the data can neither confirm nor rule them
  out) are listed with what would decide them;
- **at a bound**: a candidate whose fitted parameters sit at a bound of the range the
  caller allows them (not the effect's absent value) closes the gap only with a form
  past what it physically allows: it is neither significant nor undecided (the gap is
  more likely another effect's that looks like it) and is listed with that in the next
  steps — but the gap it closes is there: the first significant candidate stands alone
  only when it beats it clearly too, else it joins the set behind the others (a μ(T)
  steeper than its ramp allows, 33 % at its bound, beside a knee of 9 %, named the knee
  alone);
- **untestable**: candidates the caller knows the data hardly contain the signature of
  (a model-specific check) are, when not significant, listed with why rather than left
  to read as absent; one the caller says reads like the single name (``reads_like``)
  joins it: the data cannot rule it out.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True)
class VerdictRule:
    """The thresholds of a verdict.

    Parameters
    ----------
    min_shrink_pct : float — % ; lower bootstrap bound a named effect needs.
    clear_margin_pct : float — percentage points; lower bound of the shrink difference by
        which the first effect must beat another to stand alone.
    correlated : float — correlation of two held-out corrections reported as alike.
    n_boot : int — bootstrap resamples.
    max_set : int — most effects in a set verdict (the rest are listed as also significant).
    seed : int — resampling seed (verdicts are reproducible).
    """

    min_shrink_pct: float = 10.0
    clear_margin_pct: float = 3.0
    correlated: float = 0.8
    n_boot: int = 2000
    max_set: int = 3
    seed: int = 0


@dataclass(frozen=True)
class Signature:
    """Where a candidate's signature lives: held-out SSE per signature unit.

    Parameters
    ----------
    where : str — the units in words ("held-out straights above 0.8 V_ref").
    sse_before, sse_after : numpy.ndarray — (V,) SSE per unit, reference and candidate.
    """

    where: str
    sse_before: np.ndarray
    sse_after: np.ndarray


@dataclass(frozen=True)
class CandidateEvidence:
    """One candidate's held-out errors per unit and what to say about it.

    Parameters
    ----------
    name : str — effect name as registered by the model.
    sse : numpy.ndarray — (U,) or (U, m) held-out sum of squared errors per unit (and per
        output) with the effect, in the same unit order as the reference's.
    correction : numpy.ndarray — held-out change of the prediction against the reference
        (any shape; flattened), used to tell look-alike effects.
    separate_by : str — the data that would tell this effect from look-alikes.
    next_step : str — how to carry it forward (a command), shown when it is named.
    outputs : tuple of int, optional — the output columns of ``sse`` this candidate is
        scored on (e.g. not the spot its latent values were fitted to); ``None`` = all.
        Two candidates are compared on the outputs both are scored on.
    n_params : int, optional — parameters the candidate adds; of the effects a set
        verdict cannot tell apart the one with fewer comes first (a drift whose rate
        comes out nil is the plain shift). 0: not known, no reordering.
    signature : Signature, optional — the held-out units where the effect's signature
        lives, scored before and after; a second way to significance (module docstring).
    at_bound : str, optional — which fitted parameters sit at a bound of their range, in
        words (``"ratio = 0.6, at the edge of its range 0.6 to 1.5"``); such a candidate
        is never named.
    """

    name: str
    sse: np.ndarray
    correction: np.ndarray = field(default_factory=lambda: np.zeros(0))
    separate_by: str = ""
    next_step: str = ""
    outputs: tuple[int, ...] | None = None
    n_params: int = 0
    signature: Signature | None = None
    at_bound: str = ""

    def total(self, cols: tuple[int, ...] | None = None) -> np.ndarray:
        """(U,) SSE per unit over ``cols`` (default: its own outputs)."""
        return _total(self.sse, self.outputs if cols is None else cols)


def _total(sse: np.ndarray, cols: tuple[int, ...] | None) -> np.ndarray:
    a = np.asarray(sse, float)
    if a.ndim == 1:
        return a
    return a.sum(axis=1) if cols is None else a[:, list(cols)].sum(axis=1)


def _common(a: tuple[int, ...] | None, b: tuple[int, ...] | None) -> tuple[int, ...] | None:
    if a is None:
        return b
    if b is None:
        return a
    return tuple(sorted(set(a) & set(b)))


def unit_sse(err: np.ndarray, units: np.ndarray, mask: np.ndarray | None = None,
             per_output: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sum of squared finite errors and sample count per unit.

    Parameters
    ----------
    err : numpy.ndarray — (K,) or (K, m) errors, any unit of measure.
    units : numpy.ndarray — (K,) integer unit id per step; negative ids are not scored.
    mask : numpy.ndarray, optional — (K,) bool, steps to score (e.g. held-out laps).
    per_output : bool — keep the outputs apart: ``sse`` and ``count`` are then (U, m).

    Returns
    -------
    sse, count, ids : numpy.ndarray — (U,) (or (U, m)), units in increasing id order.
    """
    e = np.asarray(err, float).reshape(len(units), -1)
    keep = np.asarray(units) >= 0
    if mask is not None:
        keep &= np.asarray(mask, bool)
    ids, inv = np.unique(np.asarray(units)[keep], return_inverse=True)
    sq = np.where(np.isfinite(e[keep]), e[keep], 0.0) ** 2
    n = np.isfinite(e[keep]).astype(float)
    if not per_output:
        sq, n = sq.sum(axis=1, keepdims=True), n.sum(axis=1, keepdims=True)
    sse = np.stack([np.bincount(inv, weights=c, minlength=ids.size) for c in sq.T], axis=1)
    count = np.stack([np.bincount(inv, weights=c, minlength=ids.size) for c in n.T], axis=1)
    if not per_output:
        sse, count = sse[:, 0], count[:, 0]
    return sse, count, ids


# The fewest units a bootstrap interval is drawn over: resampling one unit gives an
# interval of zero width around it, one observation presented as certain (a knee named
# on the single fast straight of a session's one held-out lap, at 12.6 % [12.6, 12.6]).
MIN_UNITS = 2


def _bootstrap(n_units: int, rule: VerdictRule, stat: Callable[[np.ndarray], np.ndarray]
               ) -> tuple[float, float]:
    """95 % interval of ``stat`` over paired bootstrap draws of the units (``stat`` maps
    the (n_boot, n_units) unit indices to one value per draw); NaN over fewer than
    :data:`MIN_UNITS`."""
    if n_units < MIN_UNITS:
        return float("nan"), float("nan")
    draw = np.random.default_rng(rule.seed).integers(0, n_units, size=(rule.n_boot, n_units))
    lo, hi = np.percentile(stat(draw), [2.5, 97.5])
    return float(lo), float(hi)


def _shrink(sse_before: np.ndarray, sse_after: np.ndarray) -> np.ndarray:
    return 100.0 * (1.0 - np.sqrt(sse_after / np.maximum(sse_before, 1e-300)))


def shrink_interval(sse_before: np.ndarray, sse_after: np.ndarray, rule: VerdictRule
                    ) -> tuple[float, float, float]:
    """Held-out RMSE shrink (%) and its 95 % paired-bootstrap interval over units (no
    interval, NaN, over fewer than :data:`MIN_UNITS`)."""
    sb, sa = np.asarray(sse_before, float), np.asarray(sse_after, float)
    if sb.size == 0 or sb.sum() <= 0:
        return float("nan"), float("nan"), float("nan")
    lo, hi = _bootstrap(sb.size, rule,
                        lambda draw: _shrink(sb[draw].sum(axis=1), sa[draw].sum(axis=1)))
    return float(_shrink(sb.sum(), sa.sum())), lo, hi


def gain_interval(before: np.ndarray, after: np.ndarray, count: np.ndarray, rule: VerdictRule
                  ) -> tuple[float, float, float]:
    """Mean gain per sample of ``after`` over ``before`` (sums per unit, e.g. predictive
    log-likelihoods) and its 95 % paired-bootstrap interval over units (none over fewer
    than :data:`MIN_UNITS`)."""
    d, n = np.asarray(after, float) - np.asarray(before, float), np.asarray(count, float)
    if d.size == 0 or n.sum() <= 0:
        return float("nan"), float("nan"), float("nan")
    lo, hi = _bootstrap(d.size, rule, lambda draw: d[draw].sum(axis=1)
                        / np.maximum(n[draw].sum(axis=1), 1.0))
    return float(d.sum() / n.sum()), lo, hi


def difference_interval(sse_before: np.ndarray, sse_a: np.ndarray, sse_b: np.ndarray,
                        rule: VerdictRule) -> tuple[float, float, float]:
    """Shrink of ``a`` minus shrink of ``b`` (percentage points), 95 % interval, paired
    (none over fewer than :data:`MIN_UNITS`)."""
    sb, a, b = (np.asarray(v, float) for v in (sse_before, sse_a, sse_b))
    if sb.size == 0 or sb.sum() <= 0:
        return float("nan"), float("nan"), float("nan")

    def diff(draw: np.ndarray) -> np.ndarray:
        base = sb[draw].sum(axis=1)
        return _shrink(base, a[draw].sum(axis=1)) - _shrink(base, b[draw].sum(axis=1))

    lo, hi = _bootstrap(sb.size, rule, diff)
    return float(_shrink(sb.sum(), a.sum()) - _shrink(sb.sum(), b.sum())), lo, hi


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of two corrections over their common finite entries."""
    a, b = np.ravel(a), np.ravel(b)
    if a.size != b.size:
        return float("nan")
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 3 or np.std(a[ok]) == 0 or np.std(b[ok]) == 0:
        return float("nan")
    return float(np.corrcoef(a[ok], b[ok])[0, 1])


@dataclass(frozen=True)
class Decision:
    """A verdict and how it was reached; :meth:`summary` gives the OUTPUTS.md keys."""

    verdict: str
    verdict_set: list[str]
    rows: list[dict[str, Any]]
    undecided: list[str]
    next_steps: list[str]
    reasons: list[str]
    rule: VerdictRule
    untestable: dict[str, str] = field(default_factory=dict)
    joined_untested: dict[str, str] = field(default_factory=dict)

    @property
    def kind(self) -> str:
        """``"none"``, ``"single"`` or ``"set"``."""
        return "none" if not self.verdict_set else (
            "single" if len(self.verdict_set) == 1 else "set")

    @property
    def why(self) -> str:
        """Which clause made the verdict a set, in a few words (``""`` for a single name or
        none): an untestable look-alike that joined the named one, or candidates the first
        does not beat clearly."""
        if self.kind != "set":
            return ""
        if self.joined_untested:
            return "; ".join(f"{name} cannot be tested on this data and reads like {alike}"
                             for name, alike in self.joined_untested.items())
        return "the data cannot tell them apart"

    def summary(self) -> dict[str, Any]:
        r = self.rule
        return {
            "verdict": self.verdict,
            "verdict_set": list(self.verdict_set),
            "verdict_kind": self.kind,
            "undecided": list(self.undecided),
            "next_steps": list(self.next_steps),
            "verdict_reasons": list(self.reasons),
            "verdict_why": self.why,
            "untestable": [{"name": n, "why": why} for n, why in self.untestable.items()],
            "verdict_rule": (
                f"an effect is significant when the lower end of its 95 % bootstrap interval"
                f" of held-out shrink exceeds {r.min_shrink_pct:g} % (on all held-out data, or"
                f" on the units where its signature lives while its whole-data interval stays"
                f" above 0 %; no interval over fewer than {MIN_UNITS} units); the best"
                f" significant"
                f" effect stands alone only when it beats each other significant or undecided"
                f" one (interval straddling {r.min_shrink_pct:g} %) by more"
                f" than {r.clear_margin_pct:g} percentage points (lower end of the paired"
                f" interval) and is no look-alike (corrections correlated above"
                f" {r.correlated:g} with overlapping shrink intervals), else the verdict is"
                f" the set of those it does not beat, significant ones first"
                f" (at most {r.max_set}); none when no effect is significant; an effect"
                f" whose fitted parameters end at a bound of their range is not named for"
                f" itself, but joins the set when the first does not beat it clearly; an"
                f" effect this data cannot test that the single named one reads like joins"
                f" it (the data cannot rule it out), the set of both"),
        }


def _signature_test(sig: Signature, whole_lo: float, significant: bool, rule: VerdictRule
                    ) -> dict[str, Any]:
    """The signature's shrink and whether it makes a candidate significant."""
    s_point, s_lo, s_hi = shrink_interval(sig.sse_before, sig.sse_after, rule)
    out: dict[str, Any] = {"signature_where": sig.where, "signature_shrink_pct": s_point,
                           "signature_shrink_ci95_pct": [s_lo, s_hi]}
    by_signature = (not significant and np.isfinite(s_lo) and s_lo > rule.min_shrink_pct
                    and np.isfinite(whole_lo) and whole_lo > 0.0)
    if by_signature:
        out["significant"] = True
        out["significant_by"] = "signature"
    return out


def decide(sse_before: np.ndarray, candidates: Sequence[CandidateEvidence],
           rule: VerdictRule | None = None,
           untestable: Mapping[str, str] | None = None,
           reads_like: Mapping[str, Sequence[str]] | None = None) -> Decision:
    """Rank the candidates and give the verdict (module docstring).

    Parameters
    ----------
    sse_before : numpy.ndarray — (U,) or (U, m) held-out SSE per unit of the reference.
    candidates : sequence of CandidateEvidence — each with the same units.
    rule : VerdictRule, optional.
    untestable : mapping, optional — candidate name -> why the data hardly hold its
        signature (and what would); kept for the candidates that are not significant.
    reads_like : mapping, optional — candidate name -> the candidates its effect reads
        like where it cannot be tested (a model's knowledge): one of those is not named
        alone while it is untestable, it is the set of both.
    """
    rule = rule or VerdictRule()
    by_name = {c.name: c for c in candidates}
    rows = _ranked_rows(sse_before, candidates, rule)
    significant = [r["name"] for r in rows if r["significant"]]
    # a fit that widens the held-out gap at its best estimate is no candidate for the
    # cause, however wide its interval (a roller-rig creep slope: -272 % [-281, 75])
    undecided = [r["name"] for r in rows if not r["significant"] and not r.get("at_bound")
                 and _may_matter(r, rule) and r["shrink_pct"] > 0.0]
    reasons: list[str] = []
    verdict_set: list[str] = []
    edge = [r for r in rows if r.get("at_bound") and _may_matter(r, rule)
            and r["shrink_pct"] > 0.0]
    if significant:
        # one at a bound is not named for itself, but the first stands alone only when it
        # beats that one clearly too: the gap it closes is there, whatever its cause
        verdict_set, reasons = _verdict_set(sse_before, rows, significant,
                                            undecided + [r["name"] for r in edge], by_name,
                                            rule)
    verdict_set, reasons, joined = _untestable_alike(verdict_set, reasons, by_name,
                                                     untestable, reads_like)
    next_steps = _next_steps(verdict_set, undecided, rows, by_name, untestable)
    next_steps += [f"{r['name']} closes {r['shrink_pct']:.0f} % of the held-out gap only with"
                   f" {r['at_bound']}, past what its form allows: "
                   + (f"in the set only because {verdict_set[0]} does not beat it clearly (its"
                      " form is stretched: the cause may be it, beyond its form, or another"
                      " effect like it)" if r["name"] in verdict_set else
                      "not named (another unmodelled effect that looks like it is more"
                      " likely)") for r in edge]
    reasons += [f"{r['name']} set aside: its fit ends at a bound ({r['at_bound']})"
                for r in edge if r["name"] not in verdict_set]
    # an undecided one is listed once, with what would decide it
    unseen = {n: why for n, why in (untestable or {}).items()
              if n in by_name and n not in significant and n not in undecided}
    next_steps += [f"{n} cannot be told on this data: {why}" for n, why in unseen.items()]
    return Decision(verdict_set[0] if verdict_set else "none", verdict_set, rows, undecided,
                    next_steps, reasons, rule, unseen, joined)


def _untestable_alike(verdict_set: list[str], reasons: list[str],
                      by_name: Mapping[str, CandidateEvidence],
                      untestable: Mapping[str, str] | None,
                      reads_like: Mapping[str, Sequence[str]] | None
                      ) -> tuple[list[str], list[str], dict[str, str]]:
    """A single name that an untestable candidate reads like becomes the set of both: the
    data cannot rule that one out (a wrong emissivity with no reading near the air was
    named μ(T), twice, by an independent generator). Also returns the candidate that
    joined, mapped to the name it reads like (empty when none did)."""
    if len(verdict_set) != 1:
        return verdict_set, reasons, {}
    for name, alikes in (reads_like or {}).items():
        if (verdict_set[0] in alikes and name in (untestable or {}) and name in by_name):
            return [*verdict_set, name], [
                *reasons, f"{verdict_set[0]} is not named alone: {name} reads like it and"
                f" cannot be tested on this data ({(untestable or {})[name]})"], {
                name: verdict_set[0]}
    return verdict_set, reasons, {}


def _may_matter(row: dict[str, Any], rule: VerdictRule) -> bool:
    """Whether a candidate's shrink interval reaches above the rule's threshold."""
    hi = row["shrink_ci95_pct"][1]
    return bool(np.isfinite(hi) and hi > rule.min_shrink_pct)


def _ranked_rows(sse_before: np.ndarray, candidates: Sequence[CandidateEvidence],
                 rule: VerdictRule) -> list[dict[str, Any]]:
    """Each candidate's shrink, interval and significance (its signature's too), ranked
    by shrink, largest first.

    Parameters
    ----------
    sse_before : numpy.ndarray — (U,) or (U, m) held-out SSE per unit of the reference.
    candidates : sequence of CandidateEvidence — each with the same units.
    rule : VerdictRule
    """
    rows = []
    for c in candidates:
        point, lo, hi = shrink_interval(_total(sse_before, c.outputs), c.total(), rule)
        row = {"name": c.name, "shrink_pct": point, "shrink_ci95_pct": [lo, hi],
               "significant": bool(np.isfinite(lo) and lo > rule.min_shrink_pct)}
        if c.signature is not None:
            row.update(_signature_test(c.signature, lo, row["significant"], rule))
        if c.at_bound:
            row.update(at_bound=c.at_bound, significant=False)
            row.pop("significant_by", None)
        rows.append(row)
    rows.sort(key=lambda r: -np.nan_to_num(r["shrink_pct"], nan=-1e9))
    for rank, row in enumerate(rows, start=1):
        row["rank"] = rank
    return rows


def _verdict_set(sse_before: np.ndarray, rows: list[dict[str, Any]], significant: list[str],
                 undecided: list[str], by_name: Mapping[str, CandidateEvidence],
                 rule: VerdictRule) -> tuple[list[str], list[str]]:
    """The best significant candidate and those it does not beat clearly (module
    docstring), the simplest of them first, at most ``rule.max_set``; and the reasons.

    Records each comparison with the first in its row (``vs_first_pp``); ``significant``
    is not empty.
    """
    reasons: list[str] = []
    top = significant[0]
    verdict_set = [top]
    outscored: set[str] = set()  # joined as look-alikes though the first beats them clearly
    # An undecided candidate may be the cause as well: the first stands alone only
    # when it beats those clearly too.
    for name in significant[1:] + undecided:
        cols = _common(by_name[top].outputs, by_name[name].outputs)
        d, lo, hi = difference_interval(_total(sse_before, cols), by_name[top].total(cols),
                                        by_name[name].total(cols), rule)
        r = correlation(by_name[top].correction, by_name[name].correction)
        alike = f", corrections correlated {r:.2f}" if np.isfinite(r) else ""
        row = next(x for x in rows if x["name"] == name)
        row["vs_first_pp"] = {"point": d, "ci95": [lo, hi], "correlation": r}
        top_ci = next(x for x in rows if x["name"] == top)["shrink_ci95_pct"]
        look_alike = (np.isfinite(r) and r > rule.correlated
                      and row["shrink_ci95_pct"][1] >= top_ci[0])
        if lo > rule.clear_margin_pct and not look_alike:
            reasons.append(f"{top} beats {name} by {d:.1f} points (95 % interval"
                           f" {lo:.1f} to {hi:.1f}{alike})")
        else:
            verdict_set.append(name)
            if lo > rule.clear_margin_pct:
                outscored.add(name)
            if name in outscored:
                reasons.append(f"{top} shrinks more than {name} by {d:.1f} points (95 %"
                               f" interval {lo:.1f} to {hi:.1f}) but is not named alone:"
                               f" their corrections are alike ({r:.3f} >"
                               f" {rule.correlated:g}) and their shrink intervals overlap")
            else:
                reasons.append(f"{top} does not beat {name} clearly: {d:.1f} points (95 %"
                               f" interval {lo:.1f} to {hi:.1f}{alike})")
    # the fewest parameters first only among those the data cannot rank: a look-alike
    # the first beats clearly stays behind it (hot pads: a stiffness drift at 72 %, beating
    # a constant scale at 51 % by 4.6 to 42.2 points, corrections correlated 0.80, was
    # listed behind the scale)
    named = [n for n in verdict_set if n in significant and n not in outscored]
    if len(named) > 1 and all(by_name[n].n_params for n in named):
        simplest = min(named, key=lambda n: by_name[n].n_params)
        if by_name[simplest].n_params < by_name[verdict_set[0]].n_params:
            reasons.append(f"{simplest} first: of those the data cannot tell apart, it"
                           f" adds the fewest parameters ({by_name[simplest].n_params})")
            verdict_set.remove(simplest)
            verdict_set.insert(0, simplest)
    if len(verdict_set) > rule.max_set:
        rest = verdict_set[rule.max_set:]
        bound = {r["name"] for r in rows if r.get("at_bound")}
        also = [n for n in rest if n in significant]
        maybe = [n for n in rest if n not in significant and n not in bound]
        edge = [n for n in rest if n in bound]
        if also:
            reasons.append("also significant, not separated: " + ", ".join(also))
        if maybe:
            reasons.append("also possible (undecided), not separated: " + ", ".join(maybe))
        if edge:
            reasons.append("also possible (at a bound of its range), not separated: "
                           + ", ".join(edge))
        verdict_set = verdict_set[: rule.max_set]
    return verdict_set, reasons


def _next_steps(verdict_set: list[str], undecided: list[str], rows: list[dict[str, Any]],
                by_name: Mapping[str, CandidateEvidence],
                untestable: Mapping[str, str] | None) -> list[str]:
    """How to carry the verdict forward, or what would separate its set, then what would
    decide each undecided candidate."""
    next_steps: list[str] = []
    if len(verdict_set) == 1:
        if by_name[verdict_set[0]].next_step:
            next_steps.append(by_name[verdict_set[0]].next_step)
    elif verdict_set:
        next_steps.append("the data cannot tell " + " from ".join(verdict_set)
                          + "; to separate them:")
        next_steps += [f"{n}: {by_name[n].separate_by}" for n in verdict_set
                       if by_name[n].separate_by]
        steps = [by_name[n].next_step for n in verdict_set if by_name[n].next_step]
        if steps:
            next_steps.append(f"meanwhile, carry the first: {steps[0]}")
    for name in undecided:
        row = next(x for x in rows if x["name"] == name)
        lo, hi = row["shrink_ci95_pct"]
        hint = (untestable or {}).get(name) or by_name[name].separate_by or "more held-out laps"
        next_steps.append(f"{name} undecided (held-out shrink {lo:.0f} to {hi:.0f} %): "
                          f"{hint}")
    return next_steps
