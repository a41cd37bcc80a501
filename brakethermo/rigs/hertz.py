"""Hertz's normal contact of two bodies with an elliptic contact patch.

Roller-rig paper (Onat, Voltr, Lata), "Normal problem"; the relations are Johnson,
*Contact Mechanics* (1985), eq. 4.37-4.40, with the curvature sums A (rolling
direction x) and B (lateral direction y).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq
from scipy.special import elliprd, elliprf

from brakethermo.errors import ConfigError


@dataclass(frozen=True)
class HertzContact:
    """The contact ellipse at one normal load.

    Attributes
    ----------
    a : float — semi-axis in the rolling direction x, m.
    b : float — semi-axis in the lateral direction y, m.
    delta : float — approach of the two bodies, m.
    p0 : float — peak pressure, Pa.
    normal_force : float — N.
    """

    a: float
    b: float
    delta: float
    p0: float
    normal_force: float

    def scaled(self, normal_force: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Semi-axes (a, b) at another load, m: the shape is load-independent, size ~ N^(1/3)."""
        s = np.cbrt(np.asarray(normal_force, dtype=float) / self.normal_force)
        return self.a * s, self.b * s


def curvature_sums(
    r_wheel: float, r_roller: float, k_wheel_lat: float, k_roller_lat: float
) -> tuple[float, float]:
    """Curvature sums A (rolling direction) and B (lateral) of a wheel on a roller.

    Parameters
    ----------
    r_wheel, r_roller : float — rolling radii, m (both convex in x).
    k_wheel_lat, k_roller_lat : float — lateral profile curvatures at the contact,
        1/m, positive when convex (the paper's signed curvature, eq. 3).

    Returns
    -------
    A, B : float — 1/m; A = (1/r_w + 1/r_r)/2, B = (k_w + k_r)/2.
    """
    A = 0.5 * (1.0 / r_wheel + 1.0 / r_roller)
    B = 0.5 * (k_wheel_lat + k_roller_lat)
    if not (A > 0.0 and B > 0.0):
        raise ConfigError(
            f"the contact curvature sums must be positive (A={A:g}, B={B:g} 1/m): "
            "check the radii and lateral curvatures"
        )
    return A, B


def _ratio_residual(m: float, target: float) -> float:
    # Johnson eq. 4.39: B/A = (E/(1 - m) - K)/(K - E) for a major axis along x (A < B),
    # e^2 = m; written with Carlson's K = R_F, (K - E)/m = R_D/3 (arguments 0, 1 - m, 1),
    # which stays exact as m -> 0 where K - E cancels (a near-round contact)
    rf, rd = elliprf(0.0, 1.0 - m, 1.0), elliprd(0.0, 1.0 - m, 1.0)
    return (3.0 * rf / rd - 1.0) / (1.0 - m) - target


def hertz_contact(
    normal_force: float, A: float, B: float, young: float, poisson: float
) -> HertzContact:
    """Solve Hertz's normal problem for two bodies of the same elastic material.

    Parameters
    ----------
    normal_force : float — N, > 0.
    A, B : float — curvature sums in x (rolling) and y (lateral), 1/m.
    young : float — Young's modulus E, Pa.
    poisson : float — Poisson's ratio nu.

    Returns
    -------
    HertzContact
    """
    if not (normal_force > 0 and A > 0 and B > 0 and young > 0 and 0 <= poisson < 0.5):
        raise ConfigError(
            f"Hertz contact needs N, A, B, E > 0 and 0 <= nu < 0.5 (N={normal_force:g},"
            f" A={A:g}, B={B:g}, E={young:g}, nu={poisson:g})"
        )
    e_star = young / (2.0 * (1.0 - poisson**2))  # 1/E* = 2 (1 - nu^2)/E, same material
    lo, hi = (A, B) if A <= B else (B, A)  # the major axis lies along the smaller curvature
    ratio = hi / lo
    if ratio - 1.0 < 1e-9:
        m, k_minus_e_over_m, K = 0.0, np.pi / 4.0, np.pi / 2.0
    else:
        m = brentq(_ratio_residual, 1e-14, 1.0 - 1e-14, args=(ratio,), xtol=1e-15, rtol=1e-14)
        K = float(elliprf(0.0, 1.0 - m, 1.0))
        k_minus_e_over_m = float(elliprd(0.0, 1.0 - m, 1.0)) / 3.0
    # eq. 4.38 with p0 = 3N/(2 pi a b): A_min = 3 N (K - E)/(2 pi E* a^3 e^2)
    major = (3.0 * normal_force * k_minus_e_over_m / (2.0 * np.pi * lo * e_star)) ** (1.0 / 3.0)
    minor = major * np.sqrt(1.0 - m)
    p0 = 3.0 * normal_force / (2.0 * np.pi * major * minor)
    delta = p0 * minor * K / e_star  # eq. 4.40
    a, b = (major, minor) if A <= B else (minor, major)
    return HertzContact(float(a), float(b), float(delta), float(p0), float(normal_force))
