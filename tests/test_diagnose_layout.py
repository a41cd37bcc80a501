"""Where an effect's signature lives: the held-out units the verdict also tests it on."""

import numpy as np

from brakethermo.models.disc_effects import KNEE, Segments
from brakethermo.pipelines.diagnose.layout import Layout, signature_units

V_REF = 350 / 3.6


def _setup():
    # two laps of 10 steps: braking at steps 0-2 of each lap, a straight after it that
    # passes the knee speed at its steps 6-8; the second lap held out
    K = 20
    braking = np.zeros(K, bool)
    braking[[0, 1, 2, 10, 11, 12]] = True
    straight = np.where(braking, -1, np.arange(K) // 10)
    speed = np.full(K, 0.5 * V_REF)
    speed[[6, 7, 8, 16, 17, 18]] = 0.95 * V_REF
    held = np.arange(K) >= 10
    layout = Layout(train=~held, held=held, braking=braking, release=np.zeros(K, bool),
                    cycles=np.arange(K) // 10)
    segments = Segments(zone=np.arange(K) // 10, n_zones=1, straight=straight,
                        n_straights=2, straight_lap=np.array([1, 2]))
    return layout, speed, segments


def test_the_knee_is_tested_from_the_first_pass_of_the_knee_speed():
    layout, speed, segments = _setup()
    _, units = signature_units("h_speed_knee", layout, speed, segments, V_REF)
    assert np.array_equal(np.flatnonzero(units >= 0), np.arange(16, 20))
    assert speed[16] >= KNEE * V_REF > speed[15]


def test_an_effect_without_a_signature_is_tested_on_whole_cycles_only():
    layout, speed, segments = _setup()
    assert signature_units("thickness_gradient", layout, speed, segments, V_REF) is None
    # off-brake straights are no slipstream's own: a k_z change shrinks them as much
    assert signature_units("slipstream", layout, speed, segments, V_REF) is None
