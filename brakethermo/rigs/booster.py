"""E-Booster observer physics (paper 004): hydraulics, reaction disk, leverage.

Pure functions on arrays, units MPa, mm, N, s (1 MPa x 1 mm^2 = 1 N, so forces need no
conversion factor). These are the observer's simplified physics; the bench simulator
(:mod:`brakethermo.sim.ebooster`) has its own, richer ones.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import expm

Array = NDArray[np.float64]
PV_POWERS = (2, 4, 6, 8)


def pv_pressure(s2_mm: Array | float, coeffs: Array, stroke_mm: float,
                s_max_mm: float = np.inf) -> Array:
    """Hydraulic p-V characteristic: even polynomial through the origin (eq. 12, 13),
    continued along its tangent beyond the travel it was fitted on.

    An 8th-order polynomial past its data turns wherever its last terms take over (a
    session braking harder than its training read 28 MPa for 15); the tangent keeps the
    curve's last known stiffness.

    Parameters
    ----------
    s2_mm : ndarray — mm, screw displacement (stands in for the piston travel s_1).
    coeffs : ndarray (4,) — MPa, weights of (s/stroke)^2, ^4, ^6, ^8.
    stroke_mm : float — mm, regressor scale.
    s_max_mm : float — mm, the furthest travel of the fit's data (inf: the polynomial
        everywhere).

    Returns
    -------
    ndarray — MPa, static pressure.
    """
    s = np.asarray(s2_mm, dtype=np.float64)
    c = np.asarray(coeffs, dtype=np.float64)
    u = np.minimum(s, s_max_mm) / stroke_mm
    u2 = u * u
    p = u2 * (c[0] + u2 * (c[1] + u2 * (c[2] + u2 * c[3])))
    if not np.isfinite(s_max_mm):
        return p
    # dp/ds of the polynomial at the end of the data, never negative
    slope = u * (2 * c[0] + u2 * (4 * c[1] + u2 * (6 * c[2] + u2 * 8 * c[3]))) / stroke_mm
    return p + np.maximum(slope, 0.0) * np.maximum(s - s_max_mm, 0.0)


def orifice_coefficient(
    stiffness_mpa_per_cm3: float, discharge_coeff: float, area_mm2: float, density: float
) -> float:
    """k of dp/dt = k sqrt(|dp|) for a circuit behind a port (eq. 3-4, 13).

    dp/dt = (E_w/V) C_q A sqrt(2 |dp| / rho) in SI, rewritten with pressures in MPa.

    Parameters
    ----------
    stiffness_mpa_per_cm3 : float — MPa/cm^3, E_w / V of the circuit.
    discharge_coeff : float — C_q.
    area_mm2 : float — mm^2, port area A.
    density : float — kg/m^3.

    Returns
    -------
    float — MPa^0.5 / s.
    """
    e_over_v = stiffness_mpa_per_cm3 * 1e6 / 1e-6  # Pa/m^3
    k_si = e_over_v * discharge_coeff * area_mm2 * 1e-6 * np.sqrt(2.0 / density)  # Pa^.5/s
    return float(k_si * np.sqrt(1e6) / 1e6)


def orifice_step(p_up: Array, p_down: Array, k: float, dt: float) -> Array:
    """Circuit pressure after dt behind a sqrt-law port, upstream pressure held.

    d(p_up - p)/dt = -k sqrt(p_up - p) integrates exactly to
    sqrt(e(dt)) = max(sqrt(e0) - k dt / 2, 0): no overshoot, no chatter at e = 0,
    whatever the step (eq. 13 over one sample).

    Parameters
    ----------
    p_up, p_down : ndarray — MPa.
    k : float — MPa^0.5 / s (:func:`orifice_coefficient`).
    dt : float — s.

    Returns
    -------
    ndarray — MPa, downstream pressure at the end of the step.
    """
    e = p_up - p_down
    root = np.maximum(np.sqrt(np.abs(e)) - 0.5 * k * dt, 0.0)
    return p_up - np.sign(e) * root * root


def leverage_force(
    p_m: Array, s2_mm: Array, f_in: Array, area_mm2: float, k_r: float, area_ratio: float
) -> Array:
    """Net force compressing the reaction disk, quasi-static leverage (eq. 10).

    The output rod carries F_out = p_m A_mc + k_r s; at delta = 0 the input rod would
    carry the share A_1/(A_1 + A_2) of it; the rubber takes the difference.

    Returns
    -------
    ndarray — N, F_in - A_1/(A_1+A_2) F_out.
    """
    return f_in - area_ratio * (p_m * area_mm2 + k_r * s2_mm)


def three_slope(x: Array, p: Array) -> Array:
    """Piecewise-linear quasi-static fit through the origin (eq. 14).

    min(p3 x, p4 x + (p3 - p4) p1, p5 x + (p4 - p5) p2 + (p3 - p4) p1).

    Parameters
    ----------
    x : ndarray — abscissa (N here).
    p : ndarray (5,) — breakpoints p1 < p2 and slopes p3, p4, p5.
    """
    p1, p2, p3, p4, p5 = (float(v) for v in p)
    a = p3 * x
    b = p4 * x + (p3 - p4) * p1
    c = p5 * x + (p4 - p5) * p2 + (p3 - p4) * p1
    return np.minimum(np.minimum(a, b), c)


def disk_quasi_static(force_n: Array, p: Array) -> Array:
    """Quasi-static disk compression, mm: eq. 14 on |F|, odd in F.

    The rubber is loaded both ways (F < 0 when the output force exceeds the driver's
    share); eq. 14 is the curve of one direction, mirrored for the other.
    """
    f = np.asarray(force_n, dtype=np.float64)
    return np.sign(f) * three_slope(np.abs(f), p)


def disk_transfer(omega_n: float, damping: float, tau_z: float) -> tuple[Array, Array]:
    """Second-order dynamic fit of the disk, unit DC gain, two poles and one zero.

    G(s) = w^2 (tau_z s + 1) / (s^2 + 2 d w s + w^2) in observable canonical form:
    zeta1' = -a1 zeta1 + zeta2 + b1 u, zeta2' = -a0 zeta1 + b0 u, delta = zeta1.

    Returns
    -------
    A : ndarray (2, 2) — 1/s.
    B : ndarray (2,) — input column (u in mm).
    """
    a1, a0 = 2.0 * damping * omega_n, omega_n * omega_n
    b1, b0 = a0 * tau_z, a0
    return np.array([[-a1, 1.0], [-a0, 0.0]]), np.array([b1, b0])


def discretise(A: Array, B: Array, dt: float) -> tuple[Array, Array]:
    """Zero-order-hold discretisation (exact for an input held over the step)."""
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = A * dt
    M[:n, n] = B * dt
    E = expm(M)
    return E[:n, :n], E[:n, n]
