"""decide(): look-alike corrections with overlapping shrink intervals make a set even when
the point difference exceeds the clear margin; different corrections do not."""

from __future__ import annotations

import numpy as np

from brakethermo.diagnosis.verdict import CandidateEvidence, VerdictRule, decide


def _units(seed: int, n: int = 10):
    rng = np.random.default_rng(seed)
    before = rng.uniform(50, 150, n)
    a = before * rng.uniform(0.2, 0.5, n)
    b = a * rng.uniform(1.05, 1.35, n)  # ~5 points less shrink on average, noisy
    return before, a, b


def test_correlated_corrections_with_overlapping_intervals_are_a_set() -> None:
    before, a, b = _units(1)
    corr = np.linspace(-1, 1, 50)
    rule = VerdictRule(clear_margin_pct=0.0)
    alike = decide(before, [CandidateEvidence("x", a, corr), CandidateEvidence("y", b, corr)],
                   rule)
    apart = decide(before, [CandidateEvidence("x", a, corr),
                            CandidateEvidence("y", b, corr[::-1] ** 2)], rule)
    assert alike.verdict_set == ["x", "y"]
    assert "alike" in alike.reasons[0]
    assert apart.verdict_set == ["x"]


def test_of_look_alikes_the_one_with_fewer_parameters_comes_first() -> None:
    """Two effects the data cannot tell apart (a wrong emissivity, one parameter, against a
    μ(T), two; ~5 points apart, not clearly): the set names the simpler first; without
    parameter counts, the order is by shrink alone."""
    before, a, b = _units(1)
    corr = np.linspace(-1, 1, 50)
    rule = VerdictRule(clear_margin_pct=10.0)
    counted = decide(before, [CandidateEvidence("mu_t", a, corr, n_params=2),
                              CandidateEvidence("emissivity", b, corr, n_params=1)], rule)
    assert counted.verdict_set == ["emissivity", "mu_t"]
    assert any("fewest parameters" in r for r in counted.reasons)
    plain = decide(before, [CandidateEvidence("mu_t", a, corr),
                            CandidateEvidence("emissivity", b, corr)], rule)
    assert plain.verdict_set == ["mu_t", "emissivity"]


def test_an_undecided_look_alike_stops_a_single_name_but_does_not_lead() -> None:
    """The dev-seed case of a strong wrong emissivity: μ(T) significant (13.8 % [10.6,
    17.3]), emissivity undecided (10.3 % [7.0, 13.7]), corrections alike. The verdict is the
    set, μ(T) first (only a significant effect leads, whatever its parameter count); a μ(T)
    that beats it clearly, with a different correction, stands alone."""
    rng = np.random.default_rng(3)
    before = rng.uniform(50, 150, 40)
    a = before * rng.uniform(0.70, 0.79, 40)  # ~14 % shrink, lower end above 10 %
    b = before * rng.uniform(0.74, 0.88, 40)  # ~10 % shrink, interval straddles 10 %
    corr = np.linspace(-1, 1, 50)
    rule = VerdictRule()
    alike = decide(before, [CandidateEvidence("mu_t", a, corr, n_params=2),
                            CandidateEvidence("emissivity", b, corr, n_params=1)], rule)
    rows = {r["name"]: r for r in alike.rows}
    assert rows["mu_t"]["significant"] and not rows["emissivity"]["significant"]
    assert rows["emissivity"]["shrink_ci95_pct"][1] > rule.min_shrink_pct
    assert alike.verdict_set == ["mu_t", "emissivity"]
    assert alike.kind == "set"
    strong = before * rng.uniform(0.55, 0.65, 40)
    apart = decide(before, [CandidateEvidence("mu_t", strong, corr, n_params=2),
                            CandidateEvidence("emissivity", b, corr[::-1] ** 2, n_params=1)],
                   rule)
    assert apart.verdict_set == ["mu_t"]


def test_a_look_alike_the_first_beats_clearly_stays_behind_it() -> None:
    """Hot pads on an independent caliper: a stiffness drift (two parameters) at 72 %
    beat a constant stiffness scale (one) at 51 % by 4.6 to 42.2 points, their corrections
    correlated 0.80: a set (look-alikes), but the drift stays first — fewer parameters
    order only what the data cannot rank."""
    before, a, b = _units(1)
    corr = np.linspace(-1, 1, 50)
    rule = VerdictRule(clear_margin_pct=0.0)
    d = decide(before, [CandidateEvidence("drift", a, corr, n_params=2),
                        CandidateEvidence("scale", b, corr, n_params=1)], rule)
    row = next(r for r in d.rows if r["name"] == "scale")
    assert row["vs_first_pp"]["ci95"][0] > rule.clear_margin_pct
    assert d.verdict_set == ["drift", "scale"] and d.verdict == "drift"
    assert not any("fewest parameters" in r for r in d.reasons)
    assert "shrinks more than scale" in d.reasons[0] and "alike" in d.reasons[0]
