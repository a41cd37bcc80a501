"""Kalker's FASTSIM: the simplified theory of rolling contact on an elliptic patch.

Kalker, "A fast algorithm for the simplified theory of rolling contact", Vehicle
System Dynamics 11 (1982) 1-13; the roller-rig paper eq. 8-9. Each lateral strip of
the ellipse is marched from the leading edge x = a_j to the trailing edge: in
adhesion the traction grows with the rigid slip, d p_x/dx = -(xi/L1 - phi y/L3),
d p_y/dx = -(eta/L2 + phi x/L3); where it exceeds the traction bound mu p_z it slides
at the bound. Sign convention of :mod:`brakethermo.rigs.polach`: the returned forces
are those of the wheel on the roller, ``F_x = +G a b c11 xi`` at small creepage.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

PARABOLIC = 0  # Kalker's original traction bound, p_z = 2N/(pi a b) (1 - x^2/a^2 - y^2/b^2)
ELLIPTIC = 1  # Hertz's pressure, p_z = 3N/(2 pi a b) sqrt(1 - x^2/a^2 - y^2/b^2)
BOUNDS = {"parabolic": PARABOLIC, "elliptic": ELLIPTIC}


@njit(cache=True, nogil=True)
def fastsim_scalar(xi, eta, phi, mu, N, a, b, L1, L2, L3, nx, ny, bound):  # pragma: no cover
    """Total tangential force (F_x, F_y) of one contact, N; see :func:`fastsim`."""
    dy = 2.0 * b / ny
    fx = 0.0
    fy = 0.0
    if bound == PARABOLIC:
        pz0 = 2.0 * N / (math.pi * a * b)
    else:
        pz0 = 1.5 * N / (math.pi * a * b)
    rx = xi / L1
    for j in range(ny):
        y = -b + (j + 0.5) * dy
        aj = a * math.sqrt(1.0 - (y / b) ** 2)
        dx = 2.0 * aj / nx
        gx = rx - phi * y / L3
        px = 0.0
        py = 0.0
        for i in range(nx):
            x = aj - (i + 0.5) * dx  # element centre; the march starts at x = aj
            step = dx if i > 0 else 0.5 * dx
            px += gx * step
            py += (eta / L2 + phi * (x + 0.5 * step) / L3) * step
            rho = 1.0 - (x / a) ** 2 - (y / b) ** 2
            pz = pz0 * rho if bound == PARABOLIC else pz0 * math.sqrt(max(rho, 0.0))
            g = mu * pz
            p = math.sqrt(px * px + py * py)
            if p > g:
                px *= g / p
                py *= g / p
            fx += px * dx * dy
            fy += py * dx * dy
    return fx, fy


def fastsim(
    xi: float,
    eta: float,
    phi: float,
    mu: float,
    normal_force: float,
    a: float,
    b: float,
    flex: tuple[float, float, float],
    nx: int = 20,
    ny: int = 20,
    bound: str = "parabolic",
) -> tuple[float, float]:
    """Tangential contact force by FASTSIM.

    Parameters
    ----------
    xi, eta : float — longitudinal and lateral creepage, –.
    phi : float — spin creepage, 1/m.
    mu : float — friction coefficient.
    normal_force : float — N.
    a, b : float — semi-axes, rolling and lateral, m.
    flex : (L1, L2, L3) — flexibilities (:func:`brakethermo.rigs.kalker.flexibilities`).
    nx, ny : int — elements per strip and strips (the paper: 20 x 20).
    bound : {"parabolic", "elliptic"} — traction bound.

    Returns
    -------
    F_x, F_y : float — N, forces of the wheel on the roller.
    """
    L1, L2, L3 = flex
    fx, fy = fastsim_scalar(
        float(xi), float(eta), float(phi), float(mu), float(normal_force), float(a), float(b),
        L1, L2, L3, int(nx), int(ny), BOUNDS[bound],
    )  # fmt: skip
    return float(fx), float(fy)


TABLE_NU, TABLE_NV = 801, 7  # normalised creepage x normalised spin


@njit(cache=True, nogil=True)
def fastsim_table(a, b, L1, L2, L3, n_ref, u_max, v_lo, v_hi, nx, bound):  # pragma: no cover
    """FASTSIM's F_x/(mu N) on a grid, for fast lookup inside an integrator.

    With the semi-axes and flexibilities scaling as s = (N/N_ref)^(1/3) (Hertz),
    F_x/(mu N) depends on the creepage xi and the spin phi only through u = xi/(mu s)
    and v = phi/mu, so one table at N_ref serves every load and friction coefficient.
    Rows: v from ``v_lo`` to ``v_hi``; columns: u from 0 to ``u_max`` (beyond it the
    contact slides fully). Arguments as :func:`fastsim_scalar` at N_ref, m and m/Pa.
    """
    tab = np.empty((TABLE_NV, TABLE_NU))
    for iv in range(TABLE_NV):
        v = v_lo + (v_hi - v_lo) * iv / (TABLE_NV - 1)
        for iu in range(TABLE_NU):
            u = u_max * iu / (TABLE_NU - 1)
            fx, _ = fastsim_scalar(u, 0.0, v, 1.0, n_ref, a, b, L1, L2, L3, nx, nx, bound)
            tab[iv, iu] = fx / n_ref
    return tab


@njit(cache=True, nogil=True)
def fastsim_table_force(xi, phi, mu, N, n_ref, u_max, v_lo, v_hi, tab):  # pragma: no cover
    """F_x, N, from a :func:`fastsim_table` by bilinear interpolation (sign of xi)."""
    s = (N / n_ref) ** (1.0 / 3.0)
    u = abs(xi) / (mu * s) * (TABLE_NU - 1) / u_max
    v = (phi / mu - v_lo) / (v_hi - v_lo) * (TABLE_NV - 1) if v_hi > v_lo else 0.0
    v = min(max(v, 0.0), TABLE_NV - 1.000001)
    jv = int(v)
    fv = v - jv
    if u >= TABLE_NU - 1:
        g = (1.0 - fv) * tab[jv, TABLE_NU - 1] + fv * tab[jv + 1, TABLE_NU - 1]
    else:
        ju = int(u)
        fu = u - ju
        g = (1.0 - fv) * ((1.0 - fu) * tab[jv, ju] + fu * tab[jv, ju + 1]) + fv * (
            (1.0 - fu) * tab[jv + 1, ju] + fu * tab[jv + 1, ju + 1]
        )
    return math.copysign(g * mu * N, xi)
