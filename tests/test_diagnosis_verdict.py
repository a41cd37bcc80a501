"""The model-agnostic verdict: single names only when clear, sets for look-alikes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brakethermo.diagnosis.verdict import (
    CandidateEvidence,
    Signature,
    VerdictRule,
    decide,
    gain_interval,
    shrink_interval,
    unit_sse,
)

RULE = VerdictRule(n_boot=500)


def _units(n: int, rng: np.random.Generator, scale: float) -> np.ndarray:
    return scale * rng.uniform(0.5, 1.5, n)


def test_unit_sse_sums_per_unit_and_skips_nan_and_negative_ids() -> None:
    err = np.array([[1.0, np.nan], [2.0, 1.0], [3.0, 0.0], [5.0, 5.0]])
    units = np.array([0, 0, 1, -1])
    sse, n, ids = unit_sse(err, units)
    np.testing.assert_allclose(sse, [1 + 4 + 1, 9])
    np.testing.assert_allclose(n, [3, 2])
    np.testing.assert_array_equal(ids, [0, 1])


def test_clear_winner_stands_alone() -> None:
    rng = np.random.default_rng(1)
    before = _units(40, rng, 100.0)
    good = CandidateEvidence("a", before * 0.25, next_step="carry a")
    weak = CandidateEvidence("b", before * 0.7)
    d = decide(before, [weak, good], RULE)
    assert d.verdict == "a" and d.verdict_set == ["a"] and d.kind == "single"
    assert d.next_steps == ["carry a"]
    assert [r["name"] for r in d.rows] == ["a", "b"]


def test_near_tie_gives_a_ranked_set_with_what_separates_them() -> None:
    rng = np.random.default_rng(2)
    before = _units(40, rng, 100.0)
    a = CandidateEvidence("a", before * 0.30 * rng.uniform(0.95, 1.05, 40),
                          separate_by="a cool-down run")
    b = CandidateEvidence("b", before * 0.31 * rng.uniform(0.95, 1.05, 40),
                          separate_by="a second pyrometer")
    d = decide(before, [a, b], RULE)
    assert d.kind == "set" and set(d.verdict_set) == {"a", "b"}
    assert d.verdict == d.verdict_set[0]
    assert any("cool-down" in s for s in d.next_steps)
    assert any("second pyrometer" in s for s in d.next_steps)


def test_an_effect_fitted_at_a_bound_of_its_range_is_never_named() -> None:
    """An independent generator's baseline session: a wrong emissivity closed 33 % of the
    gap only at the end of its range (a setting of 1.42) and was named alone, then
    carried, putting a race 100 °C off. Such a candidate is neither named nor undecided;
    the next steps say why."""
    rng = np.random.default_rng(5)
    before = _units(40, rng, 100.0)
    edge = CandidateEvidence("a", before * 0.45, at_bound="ratio = 0.6, at the end of its"
                             " range 0.6-1.5")
    weak = CandidateEvidence("b", before * 0.95)
    d = decide(before, [edge, weak], RULE)
    assert d.verdict == "none" and d.verdict_set == [] and d.undecided == []
    row = next(r for r in d.rows if r["name"] == "a")
    assert row["significant"] is False and "0.6" in row["at_bound"]
    assert any(s.startswith("a closes") and "not named" in s for s in d.next_steps)
    # without the bound the same evidence is a clear single name
    free = CandidateEvidence("a", before * 0.45)
    assert decide(before, [free, weak], RULE).verdict == "a"


def test_a_weaker_effect_is_not_named_alone_beside_a_larger_one_at_its_bound() -> None:
    """A μ(T) steeper than its ramp allows closed 33 % of the gap at its bound, a knee 9 %
    (significant where its signature lives): the knee was named alone, a confident wrong
    name. The one at the bound is still not named for itself, but the first does not
    beat it: the verdict is the set, the bound said; beaten clearly, it stays aside."""
    rng = np.random.default_rng(11)
    before = _units(40, rng, 100.0)
    knee = CandidateEvidence("knee", before * 0.80)
    mu = CandidateEvidence("mu", before * 0.45 * rng.uniform(0.8, 1.2, 40),
                           at_bound="beta = 0.596, at the edge of its range -0.6 to 0.6")
    d = decide(before, [knee, mu], RULE)
    assert d.verdict == "knee" and d.verdict_set == ["knee", "mu"] and d.kind == "set"
    assert any(s.startswith("mu closes") and "in the set only because knee" in s
               for s in d.next_steps)
    assert not any(r.startswith("mu set aside") for r in d.reasons)
    small = CandidateEvidence("mu", before * 0.97 * rng.uniform(0.7, 1.3, 40),
                              at_bound="beta = 0.596, at the edge of its range -0.6 to 0.6")
    d = decide(before, [CandidateEvidence("knee", before * 0.5), small], RULE)
    assert d.verdict_set == ["knee"]


def test_an_undecided_candidate_past_a_full_set_is_not_called_significant() -> None:
    """An independent caliper with three times the trained hysteresis: three look-alike
    stiffness effects filled the set, and hysteresis (5 to 12 %, the rule 10 %) was
    listed after them as "also significant" while the next steps called it undecided."""
    rng = np.random.default_rng(7)
    before = _units(40, rng, 100.0)
    common = rng.uniform(0.4, 1.6, 40)
    alike = [CandidateEvidence(n, before * 0.68 * common * rng.uniform(0.97, 1.03, 40))
             for n in "abcd"]
    maybe = CandidateEvidence("u", before * 0.82 * np.random.default_rng(8).uniform(0.4, 1.6, 40))
    d = decide(before, [*alike[:3], maybe], RULE)
    assert d.undecided == ["u"] and len(d.verdict_set) == 3 and "u" not in d.verdict_set
    assert [r for r in d.reasons if r.startswith("also ")] == [
        "also possible (undecided), not separated: u"]
    d = decide(before, [*alike, maybe], RULE)
    fourth = next(n for n in "abcd" if n not in d.verdict_set)
    assert [r for r in d.reasons if r.startswith("also ")] == [
        f"also significant, not separated: {fourth}",
        "also possible (undecided), not separated: u"]


def test_nothing_significant_is_none_and_straddlers_are_undecided() -> None:
    rng = np.random.default_rng(3)
    before = _units(6, rng, 100.0)
    noisy = CandidateEvidence("c", before * rng.uniform(0.3, 1.3, 6), separate_by="more laps")
    d = decide(before, [noisy], RULE)
    lo, hi = d.rows[0]["shrink_ci95_pct"]
    if lo <= RULE.min_shrink_pct:
        assert d.verdict == "none" and d.verdict_set == []
        if hi > RULE.min_shrink_pct and d.rows[0]["shrink_pct"] > 0:
            assert d.undecided == ["c"] and "more laps" in d.next_steps[-1]


def test_a_fit_that_widens_the_held_out_gap_is_not_undecided() -> None:
    # four times worse on half the units, far better on the others: an interval reaching
    # past the threshold around a negative best estimate (a roller rig's creep slope:
    # -272 % [-281, 75])
    before = np.full(6, 100.0)
    after = np.array([400.0, 1.0, 420.0, 2.0, 410.0, 1.0])
    d = decide(before, [CandidateEvidence("c", after, separate_by="more laps")], RULE)
    row = d.rows[0]
    assert row["shrink_pct"] < 0 and row["shrink_ci95_pct"][1] > RULE.min_shrink_pct
    assert d.undecided == [] and d.verdict == "none"
    assert not any("more laps" in s for s in d.next_steps)
    edge = decide(before, [CandidateEvidence("c", after, at_bound="a = 2, at its edge")], RULE)
    assert not any("closes" in s for s in edge.next_steps)


def test_shrink_interval_contains_point_and_is_exact_for_uniform_scaling() -> None:
    before = np.full(10, 4.0)
    point, lo, hi = shrink_interval(before, before * 0.25, RULE)
    assert point == lo == hi == 50.0


@settings(max_examples=25, deadline=None)
@given(st.permutations(range(4)), st.integers(0, 10_000))
def test_verdict_does_not_depend_on_candidate_order(order: list[int], seed: int) -> None:
    rng = np.random.default_rng(seed)
    before = _units(20, rng, 50.0)
    cands = [CandidateEvidence(f"e{i}", before * rng.uniform(0.2, 1.1) * rng.uniform(0.9, 1.1, 20))
             for i in range(4)]
    d1 = decide(before, cands, RULE)
    d2 = decide(before, [cands[i] for i in order], RULE)
    assert d1.verdict_set == d2.verdict_set and d1.verdict == d2.verdict


def test_per_output_sse_compares_candidates_on_common_outputs() -> None:
    rng = np.random.default_rng(5)
    before = rng.uniform(50, 150, (30, 4))
    # 'a' is scored on every output, 'b' (latent values fitted on output 2) on 0, 1, 3
    a = CandidateEvidence("a", before * 0.3)
    b = CandidateEvidence("b", before * 0.31, outputs=(0, 1, 3))
    d = decide(before, [a, b], RULE)
    assert set(d.verdict_set) == {"a", "b"}
    row_b = next(r for r in d.rows if r["name"] == "b")
    assert row_b["shrink_pct"] == pytest.approx(100 * (1 - np.sqrt(0.31)), rel=1e-9)
    sse, n, _ids = unit_sse(np.ones((6, 3)), np.array([0, 0, 1, 1, 2, -1]), per_output=True)
    assert sse.shape == (3, 3) and np.all(sse[0] == 2) and np.all(n[2] == 1)


def test_signature_names_an_effect_the_whole_data_dilutes_but_never_one_that_harms() -> None:
    """An effect that lives on a few units (a knee on the fastest straights) is
    significant by its signature when it clearly shrinks those units and does not harm
    the whole; a candidate that shrinks its signature units but whose whole-data
    interval reaches below zero stays unnamed."""
    rng = np.random.default_rng(11)
    before = _units(40, rng, 100.0)
    diluted = before * rng.uniform(0.84, 0.96, 40)  # ~10 % whole shrink, interval below 10
    sig_before = _units(12, rng, 50.0)
    where = "held-out straights above the knee speed"
    knee = CandidateEvidence("knee", diluted,
                             signature=Signature(where, sig_before, sig_before * 0.5))
    d = decide(before, [knee], RULE)
    row = d.rows[0]
    assert row["shrink_ci95_pct"][0] < RULE.min_shrink_pct  # not by the whole data
    assert row["significant"] and row["significant_by"] == "signature"
    assert d.verdict == "knee" and row["signature_where"] == where
    harmful = before * rng.uniform(0.6, 1.5, 40)  # helps some cycles, harms others
    other = CandidateEvidence("other", harmful,
                              signature=Signature(where, sig_before, sig_before * 0.5))
    d = decide(before, [other], RULE)
    assert d.rows[0]["shrink_ci95_pct"][0] <= 0.0
    assert not d.rows[0]["significant"] and d.verdict == "none"
    # without the signature the diluted effect is not named
    assert decide(before, [CandidateEvidence("knee", diluted)], RULE).verdict == "none"


def test_gain_interval_is_the_mean_gain_per_sample_over_units() -> None:
    rng = np.random.default_rng(3)
    count = rng.integers(50, 150, 40).astype(float)
    before = rng.normal(-2.0, 0.3, 40) * count
    point, lo, hi = gain_interval(before, before + 0.1 * count, count, VerdictRule())
    assert point == pytest.approx(0.1) and lo == pytest.approx(0.1) and hi == pytest.approx(0.1)
    noisy = before + rng.normal(0.0, 0.2, 40) * count  # no gain, only noise
    point, lo, hi = gain_interval(before, noisy, count, VerdictRule())
    assert lo < 0.0 < hi and lo <= point <= hi
    assert all(np.isnan(gain_interval(np.zeros(0), np.zeros(0), np.zeros(0), VerdictRule())))


def test_one_unit_is_no_interval_and_names_nothing() -> None:
    """A signature on a single unit (one fast straight in the session's one held-out lap)
    halving its error is one observation: no interval, not significant; the whole-data
    shrink of one unit is no interval either, while two units give one."""
    rng = np.random.default_rng(5)
    before = _units(40, rng, 100.0)
    slight = before * rng.uniform(0.95, 0.99, 40)  # a few % whole shrink, interval above 0
    where = "held-out straights above the knee speed"
    knee = CandidateEvidence("knee", slight, signature=Signature(where, np.array([50.0]),
                                                                 np.array([20.0])))
    d = decide(before, [knee], RULE)
    row = d.rows[0]
    assert row["shrink_ci95_pct"][0] > 0.0
    assert np.isnan(row["signature_shrink_ci95_pct"][0]) and row["signature_shrink_pct"] > 10
    assert not row["significant"] and d.verdict == "none"
    point, lo, hi = shrink_interval(np.array([50.0]), np.array([20.0]), RULE)
    assert point > 30.0 and np.isnan(lo) and np.isnan(hi)
    point, lo, hi = shrink_interval(np.array([50.0, 40.0]), np.array([20.0, 16.0]), RULE)
    assert np.isfinite(lo) and lo <= point <= hi


@pytest.mark.parametrize(("point", "ci", "said"), [
    (12.6, [None, None], "[no interval: one unit]"),
    (float("nan"), [float("nan"), float("nan")], "[none in the held-out laps]"),
    (20.0, [12.0, 28.0], "[12 … 28]"),
])
def test_the_page_says_why_a_signature_has_no_interval(point, ci, said) -> None:
    from brakethermo.report.diagnose_report import _significant_text

    text = _significant_text({"significant": False, "signature_where": "fast straights",
                              "signature_shrink_pct": point, "signature_shrink_ci95_pct": ci})
    assert said in text


def test_a_name_an_untestable_effect_reads_like_is_a_set() -> None:
    """A wrong emissivity with no reading near the air cannot be tested and reads like a
    friction rising with temperature: μ(T) is then the first of a set with it, not a
    single name; where the emissivity can be tested, μ(T) stands alone."""
    rng = np.random.default_rng(12)
    before = _units(40, rng, 100.0)
    mu = CandidateEvidence("mu", before * 0.5)
    eps = CandidateEvidence("eps", before * 0.99 * rng.uniform(0.9, 1.1, 40))
    why = {"eps": "no reading near the air"}
    d = decide(before, [mu, eps], RULE, untestable=why, reads_like={"eps": ("mu",)})
    assert d.verdict == "mu" and d.verdict_set == ["mu", "eps"] and d.kind == "set"
    assert any("mu is not named alone: eps reads like it" in r for r in d.reasons)
    assert decide(before, [mu, eps], RULE, reads_like={"eps": ("mu",)}).verdict_set == ["mu"]


def test_a_set_made_by_an_untestable_look_alike_says_so() -> None:
    """μ(T) significant alone, a wrong emissivity joined it as untestable: the rule text,
    the console's verdict line and the page's verdict line gave only "the data cannot
    tell them apart", the clause that set the verdict only in verdict_reasons."""
    from brakethermo.cli.diagnose_cmd import _verdict_text
    from brakethermo.report.diagnose_report import _which_section

    rng = np.random.default_rng(12)
    before = _units(40, rng, 100.0)
    mu = CandidateEvidence("mu", before * 0.5)
    eps = CandidateEvidence("eps", before * 0.99 * rng.uniform(0.9, 1.1, 40))
    joined = decide(before, [mu, eps], RULE, untestable={"eps": "no reading near the air"},
                    reads_like={"eps": ("mu",)}).summary()
    said = "eps cannot be tested on this data and reads like mu"
    assert joined["verdict_why"] == said
    assert "cannot test that the single named one reads like joins it" in joined[
        "verdict_rule"]
    assert _verdict_text(joined) == f"one of mu / eps ({said})"
    page = _which_section({**joined, "effects": [], "combined": {"effects": []}},
                          joined["verdict_set"], "mu or eps")
    assert page.paragraphs[0].startswith(f"Verdict: mu or eps ({said}). Rule:")
    # a set of candidates the first does not beat clearly says that instead
    alike = decide(before, [mu, CandidateEvidence("nu", before * 0.5)], RULE).summary()
    assert alike["verdict_set"] == ["mu", "nu"]
    assert alike["verdict_why"] == "the data cannot tell them apart"
    alone = decide(before, [mu, eps], RULE).summary()
    assert alone["verdict_why"] == "" and _verdict_text(alone) == "mu"


def test_the_pages_ranked_cells_say_they_span_every_flying_lap() -> None:
    """where_table scores the training and the held-out laps (layout.train | held): the
    page said "(all flying laps; …)" and the README "held-out residuals"; both now say
    the cells span the training laps and the held-out ones."""
    from brakethermo.report.diagnose_report import _where_section

    summary = {"gap": {"per_spot_phase": {}}, "where": {"ranked_cells": []}}
    n = 200
    section = _where_section(summary, np.linspace(0.0, 4000.0, n), np.ones(n, int),
                             np.zeros((n, 4)))
    caption = section.tables[1].caption
    assert "all flying laps, the training laps and the held-out ones" in caption
