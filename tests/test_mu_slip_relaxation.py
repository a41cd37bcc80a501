"""mu-slip aligns a ramp's slip with its lagging force (models/mu_slip.choose_relaxation)."""

from __future__ import annotations

import numpy as np

from brakethermo.models.mu_slip import RELAXATION_M, choose_relaxation, fit_families
from brakethermo.rigs.tyre import magic_formula_mu, relaxation_lag


def _ramp(length_m: float, seed: int = 0):
    """A ramp to lock at 20 m/s whose force follows the Magic Formula over ``length_m``."""
    t = np.arange(0.0, 2.0, 2e-3)
    s = np.clip((t / 2.0) ** 3, 1e-4, 0.95)  # the slip runs away towards lock
    speed = np.full(t.size, 20.0)
    steady = magic_formula_mu(s, 10.0, 1.6, 1.0)
    mu = relaxation_lag(steady, t, speed, length_m)
    mu = mu + np.random.default_rng(seed).normal(0.0, 0.005, t.size)
    return t, s, mu, speed


def test_a_lagging_force_is_aligned_and_its_length_found():
    t, s, mu, speed = _ramp(0.5)
    choice, aligned = choose_relaxation(t, s, mu, speed)
    assert 0.25 <= choice.length_m <= 1.0, choice
    logged = min(fit_families(s, mu), key=lambda f: f.heldout_rmse)
    best = min(fit_families(aligned, mu), key=lambda f: f.heldout_rmse)
    true_slip = s[np.argmax(magic_formula_mu(s, 10.0, 1.6, 1.0))]
    # the logged points trace the curve late; aligned, the peak slip moves back to it
    assert abs(best.slip_peak - true_slip) < 0.5 * abs(logged.slip_peak - true_slip)
    assert min(choice.heldout_rmse) < 0.85 * choice.heldout_rmse[0]  # over 0.005 noise
    assert len(choice.heldout_rmse) == len(RELAXATION_M) and choice.as_logged


def test_a_force_that_keeps_up_keeps_the_slip_as_logged():
    t, s, mu, speed = _ramp(0.0)
    choice, aligned = choose_relaxation(t, s, mu, speed)
    assert choice.length_m <= 0.03
    assert np.allclose(aligned, relaxation_lag(s, t, speed, choice.length_m))
