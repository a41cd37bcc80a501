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
    μ(T), two): the set names the simpler first; without parameter counts, the order is
    by shrink alone."""
    before, a, b = _units(1)
    corr = np.linspace(-1, 1, 50)
    rule = VerdictRule(clear_margin_pct=0.0)
    counted = decide(before, [CandidateEvidence("mu_t", a, corr, n_params=2),
                              CandidateEvidence("emissivity", b, corr, n_params=1)], rule)
    assert counted.verdict_set == ["emissivity", "mu_t"]
    assert any("fewest parameters" in r for r in counted.reasons)
    plain = decide(before, [CandidateEvidence("mu_t", a, corr),
                            CandidateEvidence("emissivity", b, corr)], rule)
    assert plain.verdict_set == ["mu_t", "emissivity"]
