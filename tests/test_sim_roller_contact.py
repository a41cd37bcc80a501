"""The roller-rig truth's own contact (sim/roller_contact.py), checked against closed
forms and, for Hertz, against the estimator's independent solution."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brakethermo.rigs.hertz import hertz_contact
from brakethermo.sim.roller_contact import (
    contact_strips,
    hertz_ellipse,
    load_machine,
    strip_force,
)

E_STAR = 2.1e11 / (2.0 * (1.0 - 0.28**2))


def test_hertz_sphere_closed_form() -> None:
    R, N = 0.02, 5000.0  # two spheres of radius 2R: relative radius R, A = B = 1/(2R)
    a, b, p0 = hertz_ellipse(N, 1.0 / (2.0 * R), 1.0 / (2.0 * R), E_STAR)
    radius = (3.0 * N * R / (4.0 * E_STAR)) ** (1.0 / 3.0)
    assert a == pytest.approx(radius, rel=1e-10) and b == pytest.approx(radius, rel=1e-10)
    assert p0 == pytest.approx(3.0 * N / (2.0 * math.pi * radius**2), rel=1e-10)


@settings(max_examples=25, deadline=None)
@given(st.floats(0.5, 10.0), st.floats(0.5, 10.0), st.floats(1e3, 5e4))
def test_hertz_carlson_agrees_with_elliptic_ratio(A: float, B: float, N: float) -> None:
    a, b, p0 = hertz_ellipse(N, A, B, E_STAR)
    ref = hertz_contact(N, A, B, 2.1e11, 0.28)  # the estimator's, another formulation
    assert (a, b, p0) == pytest.approx((ref.a, ref.b, ref.p0), rel=1e-8)


def test_strip_theory_slope_saturation_and_spin() -> None:
    machine = load_machine()
    strips = contact_strips(machine, 0.3482)
    assert strips[1].sum() == pytest.approx(1.0)
    N, mu = machine.nominal_load, 0.4
    A = 0.5 * (1.0 / 0.3482 + 1.0 / machine.roller_radius)
    B = 0.5 * (machine.wheel_lateral_curvature + machine.roller_lateral_curvature)
    a, b, _ = hertz_ellipse(N, A, B, E_STAR)
    xi = 1e-7
    slope = strip_force(xi, mu, N, N, 0.0, strips) / xi
    assert slope == pytest.approx(math.pi**2 / 4.0 * a * b * E_STAR, rel=2e-3)  # Carter, summed
    assert strip_force(0.05, mu, N, N, 0.0, strips) == pytest.approx(mu * N)
    xs = np.linspace(-0.02, 0.02, 81)
    f = np.array([strip_force(x, mu, N, N, 0.0, strips) for x in xs])
    assert np.all(np.diff(f) >= -1e-9) and np.allclose(f, -f[::-1])
    # spin spreads the strips' creepages: less force below saturation, none lost beyond
    spun = strip_force(0.002, mu, N, N, 0.5, strips)
    assert 0.0 < spun < strip_force(0.002, mu, N, N, 0.0, strips)
    # Hertz scaling: twice the load needs 2^(1/3) the creepage for the same force share
    s = 2.0 ** (1.0 / 3.0)
    assert strip_force(0.002 * s, mu, 2 * N, N, 0.0, strips) == pytest.approx(
        2.0 * strip_force(0.002, mu, N, N, 0.0, strips)
    )
