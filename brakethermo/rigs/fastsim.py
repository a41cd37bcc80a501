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
