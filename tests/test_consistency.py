"""The NIS consistency check against its chi-square band (estimation/consistency.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from brakethermo.estimation import UnscentedKalmanFilter
from brakethermo.estimation.consistency import nis_consistency, variance_scale


def _random_walk_run(q_true: float, q_filter: float, seed: int = 3) -> dict:
    """A scalar random walk seen in noise, filtered with the right or a wrong Q."""
    rng = np.random.default_rng(seed)
    K, r = 4000, 0.5
    x = np.cumsum(rng.normal(0.0, np.sqrt(q_true), K))
    y = (x + rng.normal(0.0, np.sqrt(r), K))[:, None]
    y[::7] = np.nan  # gaps: no NIS there
    ukf = UnscentedKalmanFilter(lambda X, k: X, np.array([[q_filter]]), np.array([[r]]),
                                H=np.array([[1.0]]))
    res = ukf.run(np.array([0.0]), np.array([[1.0]]), y, store="diag")
    return nis_consistency(res.nis, res.n_obs, res.innovation)


def test_a_filter_with_the_true_noise_is_consistent():
    c = _random_walk_run(0.1, 0.1)
    assert c["state"] == "consistent" and abs(c["mean_nis"] - 1.0) < 0.06
    assert c["n"] == 4000 - len(range(0, 4000, 7)) and c["dof_per_step"] == 1.0
    assert abs(c["lag1_autocorrelation"]) < 0.06


def test_too_little_process_noise_is_over_confident_and_too_much_under():
    assert _random_walk_run(0.1, 0.005)["state"] == "over-confident"
    assert _random_walk_run(0.1, 5.0)["state"] == "under-confident"


def test_the_band_counts_every_measurement_component():
    nis = np.array([2.0, np.nan, 1.5, 2.5])
    c = nis_consistency(nis, np.array([2, 0, 2, 2]))
    lo, hi = chi2.ppf([0.025, 0.975], 6) / 3
    assert c["chi2_band"] == pytest.approx([lo, hi], rel=1e-12)  # scipy.stats' chi2, here
    assert c["mean_nis"] == 2.0 and c["n"] == 3
    assert nis_consistency(np.full(3, np.nan))["state"] == "no measurements"


def test_variance_scale_widens_only_an_over_confident_filter():
    over = nis_consistency(np.full(400, 3.0), 2)  # mean NIS 3 for 2 components a step
    assert over["state"] == "over-confident" and variance_scale(over) == pytest.approx(1.5)
    assert variance_scale(nis_consistency(np.full(400, 1.0))) == 1.0
    assert variance_scale(nis_consistency(np.full(400, 0.2))) == 1.0  # never narrowed


def test_strongly_autocorrelated_innovations_are_not_called_under_confident():
    """The μ-slip EKF's innovations were +0.86 autocorrelated and its peak 21σ off, yet
    its page said "under-confident" from a mean NIS below 1 (new-user test): a model
    whose shape misses the truth leaves a structured error the filter follows step by
    step, and the words say that, not that the band is too wide."""
    from brakethermo.report.page import consistency_text

    rng = np.random.default_rng(4)
    K = 4000
    x = 2.0 * np.sin(np.arange(K) / 300.0)  # a slow swing the constant model lacks
    y = (x + rng.normal(0.0, 0.1, K))[:, None]
    ukf = UnscentedKalmanFilter(lambda X, k: X, np.array([[1e-4]]), np.array([[4.0]]),
                                H=np.array([[1.0]]))
    res = ukf.run(np.array([0.0]), np.array([[1.0]]), y, store="diag")
    c = nis_consistency(res.nis, res.n_obs, res.innovation)
    assert c["state"] == "under-confident" and c["lag1_autocorrelation"] > 0.9
    assert c["structured"]
    text = consistency_text(c)
    assert "strongly autocorrelated" in text and "band does not hold" in text, text
    assert not text.startswith(f"mean NIS {c['mean_nis']:.2f} per step, under-confident")
    fine = _random_walk_run(0.1, 0.1)
    assert not fine["structured"]
    assert consistency_text(fine).startswith(f"mean NIS {fine['mean_nis']:.2f} per step,"
                                             " consistent")
