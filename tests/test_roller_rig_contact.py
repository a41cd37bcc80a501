"""Contact mechanics of the roller rig against CONTACT's outputs (Vollebregt & Co).

Oracles: ``../shared/reference/contact/`` (Apache-2.0): Kalker's FASTSIM case
(``fastsim``) and Polach's 2005 traction-curve case (``tractcurv``: Eurosprinter,
R = 625 mm, Q = 106.7 kN, V = 10 m/s, four series).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brakethermo.rigs.fastsim import PARABOLIC, fastsim, fastsim_table, fastsim_table_force
from brakethermo.rigs.hertz import hertz_contact
from brakethermo.rigs.kalker import flexibilities, kalker_coefficients
from brakethermo.rigs.motor import InductionMotor, motor_torque, motor_torque_scalar
from brakethermo.rigs.polach import friction_coefficient, polach_force, polach_force_scalar
from tests._contact_reference import contact_cases, contact_value, needs_contact

G = 82.0e9  # Pa, CONTACT's GG = 82000 N/mm^2
NU = 0.28
E = 2.0 * G * (1.0 + NU)
# tractcurv: Hertz with A1 = 0.8e-3 /mm and a/b = 0.5 -> CONTACT's semi-axes 6.304 x 12.61 mm
TC_N, TC_V = 106.7e3, 10.0


@needs_contact
def test_hertz_matches_contact_normal_solution() -> None:
    """Semi-axes and approach of both CONTACT Hertz cases to 4 digits, peak pressure to
    0.1 % (CONTACT's is the largest element pressure of its grid)."""
    c = hertz_contact(TC_N, 0.8e-3 * 1e3, 0.2814e-3 * 1e3, E, NU)  # A1, B1 printed in 1/mm
    # "BASIC SEMIAXES AA,BB, RATIO  6.304  12.61  0.5000" in the output
    np.testing.assert_allclose([c.a * 1e3, c.b * 1e3], [6.304, 12.61], rtol=2e-4)
    _, _, _, approach, pmax = contact_value("tractcurv.ref_out", "FN/G      FX/FSTAT/FN", 1)
    assert c.delta * 1e3 == pytest.approx(approach, rel=2e-4)
    assert c.p0 / 1e6 == pytest.approx(pmax, rel=1e-3)
    d = hertz_contact(82e3, 0.8464, 2.406, E, NU)  # fastsim.inp: AA = 8, BB = 4 mm
    _, _, _, approach, pmax = contact_value("fastsim.ref_out", "FN/G      FX/FSTAT/FN", 1)
    np.testing.assert_allclose([d.a * 1e3, d.b * 1e3], [8.0, 4.0], rtol=2e-4)
    assert d.delta * 1e3 == pytest.approx(approach, rel=2e-4)
    assert d.p0 / 1e6 == pytest.approx(pmax, rel=1e-3)


def test_hertz_circular_limit_is_analytic() -> None:
    """Equal curvatures: a = (3 N R / 4 E*)^(1/3) with 1/R = 2A (Hertz, circular)."""
    A = 2.541
    c = hertz_contact(13e3, A, A, 2.1e11, 0.28)
    e_star = 2.1e11 / (2 * (1 - 0.28**2))
    a = (3 * 13e3 * (1 / (2 * A)) / (4 * e_star)) ** (1 / 3)
    assert c.a == pytest.approx(a, rel=1e-9) and c.b == pytest.approx(a, rel=1e-9)


@needs_contact
def test_kalker_polynomials_match_contact_flexibilities() -> None:
    """The paper's c11, c22, c23 fit gives CONTACT's FASTSIM flexibilities within 2.5 %
    (CONTACT interpolates Kalker's table)."""
    for name, a, b in (("fastsim.ref_out", 8e-3, 4e-3), ("tractcurv.ref_out", 6.304e-3, 12.61e-3)):
        case = 2 if name == "fastsim.ref_out" else 61
        ref = np.array(contact_value(name, "FLX1        FLX2        FLX3", case)) * 1e-9  # mm^3/N
        ours = np.array(flexibilities(a, b, G, kalker_coefficients(b / a, NU)))
        np.testing.assert_allclose(ours, ref, rtol=0.025)


def test_kalker_table_value() -> None:
    """Kalker's tabulated c11 = 4.12, c22 = 3.67, c23 = 1.47 at a = b, nu = 0.25."""
    c = kalker_coefficients(1.0, 0.25)
    np.testing.assert_allclose([c.c11, c.c22, c.c23], [4.12, 3.67, 1.47], atol=0.01)


@needs_contact
@pytest.mark.parametrize(
    ("bound", "contact_fastsim_fine"), [("elliptic", -0.5956), ("parabolic", -0.6359)]
)
def test_fastsim_lateral_spin_case(bound: str, contact_fastsim_fine: float) -> None:
    """fastsim.inp: FY/(mu FN) with lateral creepage and spin, 200 x 200 elements.

    Against CONTACT's FASTSIM on its fine grid (cases 5-6) and its exact solution
    (case 1, -0.6074): Kalker's elliptic-bound FASTSIM within 2 % of the exact one.
    """
    cases = contact_cases("fastsim.ref_out")
    eta, phi = cases[0, 1], cases[0, 2] * 1e3  # -, 1/m
    exact = cases[0, 5] / (0.3 * cases[0, 3])
    assert exact == pytest.approx(-0.6074, abs=1e-4)
    flex = flexibilities(8e-3, 4e-3, G, kalker_coefficients(0.5, NU))
    # our sign is Kalker's negated: the force of the wheel on the roller follows the creepage
    _, fy = fastsim(0.0, eta, phi, 0.3, 82e3, 8e-3, 4e-3, flex, 200, 200, bound)
    ratio = -fy / (0.3 * 82e3)
    assert ratio == pytest.approx(contact_fastsim_fine, rel=0.025)
    if bound == "elliptic":
        assert ratio == pytest.approx(exact, rel=0.02)


@needs_contact
def test_fastsim_traction_curve_matches_contact_fastsim() -> None:
    """tractcurv series 3 (FASTSIM, parabolic bound, Coulomb mu = 0.33) on CONTACT's grid."""
    cases = contact_cases("tractcurv.ref_out")[60:90]
    a, b = 6.304e-3, 12.61e-3
    flex = flexibilities(a, b, G, kalker_coefficients(b / a, NU))
    ours = np.array([fastsim(x, 0, 0, 0.33, TC_N, a, b, flex, 48, 44, "parabolic")[0]
                     for x in cases[:, 0]])  # fmt: skip
    np.testing.assert_allclose(ours / (0.33 * TC_N), -cases[:, 4] / (0.33 * TC_N), atol=0.012)


@needs_contact
def test_polach_traction_curve_against_contact_exact() -> None:
    """tractcurv series 1 (CONTACT's exact theory, Coulomb mu = 0.33) vs Polach, kA = kS = 1.

    Polach's law is an approximation of Kalker's theory: the initial slope matches
    (within the 2 % of the coefficient fit), the whole curve within 6.5 % of mu N,
    saturating to mu N at large creepage.
    """
    cases = contact_cases("tractcurv.ref_out")[:30]
    a, b = 6.304e-3, 12.61e-3
    c = kalker_coefficients(b / a, NU)
    F, mu = polach_force(cases[:, 0], 0.0, TC_V, TC_N, a, b, G, c.c11, c.c22, 0.33, 1.0, 0.0)
    ref = -cases[:, 4] / (0.33 * TC_N)
    ours = F / (0.33 * TC_N)
    np.testing.assert_allclose(mu, 0.33)
    assert ours[0] == pytest.approx(ref[0], rel=0.02)  # linear range, 1e-5 creepage
    assert np.max(np.abs(ours - ref)) < 0.065
    assert ours[-1] == pytest.approx(1.0, abs=1e-3)


@needs_contact
def test_polach_falling_friction_against_contact_modified_fastsim() -> None:
    """tractcurv series 4 (falling friction, slope reduction) vs Polach's recommended dry
    reduction factors (kA = 1, kS = 0.4) with CONTACT's friction law (mu0 = 0.36,
    A = 0.1368/0.36, B = 1/0.99 s/m): the adhesion optimum within 5 % and at a creepage
    within a factor 1.5, the falling branch beyond it, the curve within 0.05 N/N."""
    cases = contact_cases("tractcurv.ref_out")[90:120]
    a, b = 6.304e-3, 12.61e-3
    c = kalker_coefficients(b / a, NU)
    F, _ = polach_force(cases[:, 0], 0.0, TC_V, TC_N, a, b, G, c.c11, c.c22, 0.36,
                        0.1368 / 0.36, 1 / 0.99, 1.0, 0.4)  # fmt: skip
    ours, ref = F / TC_N, -cases[:, 4] / TC_N
    i_o, i_r = int(np.argmax(ours)), int(np.argmax(ref))
    assert ours[i_o] == pytest.approx(ref[i_r], rel=0.05)
    assert 1 / 1.5 < cases[i_o, 0] / cases[i_r, 0] < 1.5
    assert np.all(np.diff(ours[i_o:]) < 0) and np.all(np.diff(ref[i_r:]) < 0)
    assert np.max(np.abs(ours - ref)) < 0.05


def test_friction_law_limits() -> None:
    """mu(0) = mu0, mu(inf) = A mu0 (paper eq. 7)."""
    assert friction_coefficient(0.0, 0.4, 0.4, 0.6) == pytest.approx(0.4)
    assert friction_coefficient(1e3, 0.4, 0.4, 0.6) == pytest.approx(0.16)


@settings(max_examples=60, deadline=None)
@given(
    s=st.floats(-0.3, 0.3), spin=st.floats(0.0, 2.0), v=st.floats(0.5, 30.0),
    n=st.floats(2e3, 5e4), ka=st.floats(0.2, 1.0),
)  # fmt: skip
def test_polach_compiled_equals_vectorised_and_is_odd(s, spin, v, n, ka) -> None:
    """The compiled scalar law equals the vectorised one; F(-s) = -F(s); |F| <= mu N."""
    args = (v, n, 2.5e-3, 2.9e-3, 8e10, 4.08, 3.5, 0.4, 0.4, 0.6, ka, 0.5 * ka)
    F, mu = polach_force(s, spin, *args)
    assert polach_force_scalar(s, spin, *args) == pytest.approx(float(F), rel=1e-12, abs=1e-9)
    assert float(polach_force(-s, spin, *args)[0]) == pytest.approx(-float(F), abs=1e-9)
    assert abs(float(F)) <= float(mu) * n * (1 + 1e-12)


MOTOR = InductionMotor(220.0, 0.04, 0.25, 0.0467, 0.25, 50.0, 5)


def test_motor_zero_at_synchronous_speed_and_signs() -> None:
    """No torque at synchronous speed, motoring below it, braking above it."""
    for f in (7.5, 15.0, 50.0):
        w = float(MOTOR.synchronous_speed(f))
        assert float(motor_torque(MOTOR, w, f)) == pytest.approx(0.0, abs=1e-9)
        assert float(motor_torque(MOTOR, 0.99 * w, f)) > 0 > float(motor_torque(MOTOR, 1.01 * w, f))


def test_motor_breakdown_torque_is_analytic() -> None:
    """Peak over slip = 3 V^2 / (2 w_syn (R_th + sqrt(R_th^2 + X^2))) (Sen 2007)."""
    w_syn = float(MOTOR.synchronous_speed(50.0))
    s = np.linspace(1e-4, 1.0, 200001)
    peak = float(np.max(motor_torque(MOTOR, w_syn * (1 - s), 50.0)))
    x = MOTOR.x_th + MOTOR.x2
    analytic = 3 * 220.0**2 / (2 * w_syn * (0.04 + math.sqrt(0.04**2 + x**2)))
    assert peak == pytest.approx(analytic, rel=1e-6)


def test_motor_vf_keeps_torque_per_slip_speed_without_stator_resistance() -> None:
    """Under V/f with R_th = 0 the torque depends on the slip speed only, not on f."""
    m = InductionMotor(220.0, 0.0, 0.25, 0.0467, 0.25, 50.0, 5)
    for f in (7.5, 15.0, 30.0):
        w = float(m.synchronous_speed(f))
        assert float(motor_torque(m, w - 0.5, f)) == pytest.approx(
            float(motor_torque(m, float(m.synchronous_speed(50.0)) - 0.5, 50.0)), rel=1e-12
        )
    p = MOTOR.params()
    assert motor_torque_scalar(9.0, 7.5, *p) == pytest.approx(float(motor_torque(MOTOR, 9.0, 7.5)))


def test_fastsim_table_reproduces_fastsim_at_other_loads_and_friction() -> None:
    """One table at N_ref serves any load and mu (Hertz scaling): within 0.1 % of FASTSIM."""
    a, b, n_ref, phi = 2.46e-3, 2.9e-3, 13e3, 0.2555
    flex = flexibilities(a, b, 8e10, kalker_coefficients(b / a, NU))
    u_max = 9.0 * n_ref / (8e10 * a * b * 4.08)
    tab = fastsim_table(a, b, *flex, n_ref, u_max, phi / 0.4, phi / 0.16, 20, PARABOLIC)
    for xi, mu, n in [(3e-4, 0.3, 14e3), (1e-3, 0.2, 12e3), (-5e-4, 0.35, 13e3), (0.05, 0.2, 13e3)]:
        s = (n / n_ref) ** (1 / 3)
        direct = fastsim(xi, 0.0, phi, mu, n, a * s, b * s, tuple(f * s for f in flex))[0]
        looked = fastsim_table_force(xi, phi, mu, n, n_ref, u_max, phi / 0.4, phi / 0.16, tab)
        assert looked == pytest.approx(direct, rel=1e-3)
