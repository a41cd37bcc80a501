"""Kalker's creep coefficients c11, c22, c23 from the paper's polynomial fit (Appendix A).

The fit takes the contact-ellipse ratio g = b/a (a in the rolling direction) and
Poisson's ratio nu, so wheel and roller steels need not share nu = 0.27 as older fits
assumed. Kalker's linear theory then gives Fx = -G a b c11 xi, Fy = -G a b (c22 eta +
sqrt(ab) c23 phi).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Rows k1..k4, columns the coefficients of 1, nu, nu^2 (eq. 17a-17d).
_C11 = np.array(
    [
        [2.3464, 1.5443, 7.9577],
        [0.961669, -0.043513, 2.402357],
        [-0.0160185, 0.0055475, -0.0741104],
        [0.10563, 0.61285, -7.26904],
    ]
)
_C22 = np.array(
    [
        [2.34641, -0.27993, 0.19763],
        [0.96167, 0.52684, 1.22642],
        [-0.0160185, -0.0126292, -0.0011272],
        [0.10563, 0.78197, -1.12348],
    ]
)
_C23 = np.array(
    [
        [0.29677, 0.22524, 0.71899],
        [1.01321, 0.20407, -0.72375],
        [0.0092415, 0.0854262, 0.319940],
        [8.4835e-4, -3.211e-3, -1.7484e-2],
    ]
)
_C33 = np.array(
    [
        [0.72795, -1.00202, -0.32695],
        [0.461755, 1.002340, 0.081441],
        [0.023739, -0.110640, 0.249008],
        [-0.0012999, 0.0063653, -0.0129114],
    ]
)


@dataclass(frozen=True)
class KalkerCoefficients:
    """Kalker's dimensionless creep coefficients for one ellipse shape and nu."""

    c11: float
    c22: float
    c23: float
    c33: float


def _k(table: np.ndarray, nu: float) -> np.ndarray:
    return table @ np.array([1.0, nu, nu * nu])


def kalker_coefficients(b_over_a: float, poisson: float) -> KalkerCoefficients:
    """c11, c22, c23, c33 (eq. 17a-17d).

    Parameters
    ----------
    b_over_a : float — ellipse ratio b/a, a the semi-axis in the rolling direction.
    poisson : float — Poisson's ratio nu.

    Returns
    -------
    KalkerCoefficients
    """
    g = float(b_over_a)
    k = _k(_C11, poisson)
    c11 = k[0] + k[1] / g + k[2] / g**2 + k[3] / np.sqrt(g)  # eq. 17a
    k = _k(_C22, poisson)
    c22 = k[0] + k[1] / g + k[2] / g**2 + k[3] / np.sqrt(g)  # eq. 17b
    k = _k(_C23, poisson)
    c23 = k[0] + k[1] / g + k[2] / g**2 + k[3] / g**3  # eq. 17c
    k = _k(_C33, poisson)
    c33 = k[0] + k[1] / g + k[2] / g**2 + k[3] / g**3  # eq. 17d
    return KalkerCoefficients(float(c11), float(c22), float(c23), float(c33))


def flexibilities(
    a: float, b: float, shear_modulus: float, coeffs: KalkerCoefficients
) -> tuple[float, float, float]:
    """FASTSIM flexibilities L1, L2, L3 (paper eq. 9, Kalker 1982), m/Pa (L3: m^2/Pa... per unit).

    Parameters
    ----------
    a, b : float — semi-axes, rolling and lateral, m.
    shear_modulus : float — G, Pa.
    coeffs : KalkerCoefficients

    Returns
    -------
    L1, L2 : float — longitudinal and lateral flexibility, m/Pa.
    L3 : float — spin flexibility, m^2/Pa.
    """
    L1 = 8.0 * a / (3.0 * shear_modulus * coeffs.c11)  # eq. 9
    L2 = 8.0 * a / (3.0 * shear_modulus * coeffs.c22)
    L3 = np.pi * a * a / (4.0 * shear_modulus * coeffs.c23 * np.sqrt(a * b))  # eq. 9
    return float(L1), float(L2), float(L3)
