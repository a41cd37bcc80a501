"""The crown-balance term of the reported band (pipelines/crown_band.py)."""

from __future__ import annotations

import numpy as np
import pytest

from brakethermo.pipelines.crown_band import crown_balance_std
from brakethermo.thermal.disc import load_disc
from brakethermo.thermal.model import DiscFEModel


def _braking(K: int = 400, dt: float = 0.1) -> tuple[np.ndarray, ...]:
    t = np.arange(K) * dt
    q = np.where((t % 10.0) < 2.5, 60e3, 0.0)  # a 2.5 s stop every 10 s
    return q, np.full(K, 150.0), np.full(K, 25.0)


def test_the_term_is_zero_at_the_measured_spot_and_grows_with_the_prior():
    disc = load_disc("cc-340-8")
    model = DiscFEModel(disc, 10, 2, weights=(1.2, 1.0, 0.8), dt=0.1)
    H_spots = model.spot_matrix(np.asarray(disc.spot_radii))
    H = np.vstack([H_spots, H_spots[1:4].mean(axis=0)])
    q, h, ta = _braking()
    T0 = model.initial_state(100.0)
    small, large = (crown_balance_std(model, T0, q, h, ta, H, 3, s) for s in (0.1, 0.3))
    assert small.shape == (q.size, 5)
    np.testing.assert_array_equal(small[:, 2], 0.0)
    assert np.all(np.isfinite(small)) and small[:, [0, 1, 3]].max() > 5.0
    # inner and outer move apart: the outer spots far more than the contact band's mean
    assert small[:, [0, 3]].mean() > 2.0 * small[:, 4].mean()
    grow = large.mean(axis=0)[[0, 1, 3, 4]] / small.mean(axis=0)[[0, 1, 3, 4]]
    assert np.all(grow > 2.5), grow  # about linear in the prior's sigma
    np.testing.assert_array_equal(crown_balance_std(model, T0, q, h, ta, H, 3, 0.0), 0.0)


def test_a_strongly_uneven_law_crown_widens_the_balance_it_admits() -> None:
    from brakethermo.pipelines.crown_band import crown_sd

    assert crown_sd(np.array([0.845, 1.025, 1.10]), 0.25) == 0.25  # a usual crown
    wide = crown_sd(np.array([0.40, 0.97, 1.52]), 0.25)  # a test session's tilted pads
    assert wide == pytest.approx(0.5 * np.log(1.52 / 0.40))
    assert crown_sd(np.array([0.40, 0.97, 1.52]), 0.0) == 0.0  # off stays off


def test_the_band_takes_the_crown_term_computed_apart_from_the_filter() -> None:
    """The race computes the crown term beside its filter (pipelines/race_run.py): the
    band adds it to the spots, the contact band and the face nodes' columns, and refuses
    a term of other readouts."""
    from brakethermo.pipelines.estimate_table import crown_term, reported_band
    from brakethermo.pipelines.tuning import EstimateTuning

    disc = load_disc("cc-340-8")
    model = DiscFEModel(disc, 10, 2, weights=(1.2, 1.0, 0.8), dt=0.1)
    q, h, ta = _braking()
    tuning = EstimateTuning()
    crown = crown_term(model, model.initial_state(100.0), q, h, ta,
                       np.asarray(disc.spot_radii), 3, tuning, True)
    assert crown.shape == (q.size, 5 + model.radii.size)
    out = np.full((q.size, 6 + model.radii.size), 300.0)  # 5 temperatures, a scale, nodes
    std = np.zeros_like(out)
    band = reported_band(out, std, tuning, crown, 6)
    assert np.all(band[:, 5] == 0.0)  # the power scale carries no crown term
    assert np.all(band[:, 6:] >= crown[:, 5:]) and np.all(band[:, :5] >= crown[:, :5])
    with pytest.raises(ValueError, match="crown term"):
        reported_band(out, std, tuning, crown, None)
