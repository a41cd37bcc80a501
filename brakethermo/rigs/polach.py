"""Polach's creep-force law with slip-velocity dependent friction.

Polach, "Creep forces in simulations of traction vehicles running on adhesion limit",
Wear 258 (2005) 992-1000; the roller-rig paper uses its friction law (paper eq. 7).
Sign convention of every function in :mod:`brakethermo.rigs`: the creepage is
``s_x = (v_w - v_r)/V`` (wheel surface faster than the roller under traction) and the
returned force is the force the wheel exerts on the roller, so ``F_x = +G a b c11 s_x``
at small creepage (Kalker's sign is the opposite).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]
_TINY = 1e-15  # creepage below which the law is its linear limit


def friction_coefficient(w: ArrayLike, mu0: float, A: float, B: float) -> Array:
    """Friction coefficient at slip velocity ``w`` (paper eq. 7).

    Parameters
    ----------
    w : array_like — magnitude of the slip velocity, m/s.
    mu0 : float — maximum (static) friction coefficient.
    A : float — ratio mu_inf / mu0 of the limit friction at infinite slip velocity.
    B : float — exponential decrease, s/m.

    Returns
    -------
    ndarray — mu.
    """
    w = np.abs(np.asarray(w, dtype=float))
    return mu0 * ((1.0 - A) * np.exp(-B * w) + A)  # eq. 7


def polach_force(
    s_x: ArrayLike,
    spin: ArrayLike,
    speed: ArrayLike,
    normal_force: ArrayLike,
    a: ArrayLike,
    b: ArrayLike,
    shear_modulus: float,
    c11: float,
    c22: float,
    mu0: float,
    A: float,
    B: float,
    k_a: float = 1.0,
    k_s: float = 1.0,
) -> tuple[Array, Array]:
    """Longitudinal creep force and friction coefficient by Polach's method, vectorised.

    Parameters
    ----------
    s_x : array_like — longitudinal creepage (v_w - v_r)/V, –.
    spin : array_like — spin creepage psi, 1/m (paper eq. 5b); no lateral creepage.
    speed : array_like — rolling speed V, m/s (slip velocity w = s_C V).
    normal_force : array_like — Q, N.
    a, b : array_like — contact semi-axes, rolling and lateral, m.
    shear_modulus : float — G, Pa.
    c11, c22 : float — Kalker's coefficients of the ellipse.
    mu0, A, B : float — friction law (eq. 7): -, -, s/m.
    k_a, k_s : float — Polach's reduction factors in the adhesion and slip areas,
        k_s <= k_a <= 1 (1 and 1: Kalker's theory).

    Returns
    -------
    F_x : ndarray — N, force of the wheel on the roller (sign of s_x).
    mu : ndarray — friction coefficient at the slip velocity.
    """
    s_x, spin, speed, Q, a, b = np.broadcast_arrays(
        *(np.asarray(v, dtype=float) for v in (s_x, spin, speed, normal_force, a, b))
    )
    # Polach (2005) eq. 12-13: spin adds psi a to the lateral creepage when it enlarges it
    s_yc = spin * a
    s_c = np.hypot(s_x, s_yc)
    mu = friction_coefficient(s_c * speed, mu0, A, B)
    safe = np.where(s_c > _TINY, s_c, 1.0)
    cx, cy = s_x / safe, s_yc / safe
    C = 0.375 * shear_modulus / a * np.hypot(c11 * cx, c22 * cy)  # Polach C = 3/8 G/a c_jj
    eps = (2.0 / 3.0) * C * np.pi * a * a * b / (Q * mu) * s_c  # Polach eq. 3
    F = 2.0 * Q * mu / np.pi * (k_a * eps / (1.0 + (k_a * eps) ** 2) + np.arctan(k_s * eps))
    linear = 0.5 * (k_a + k_s) * shear_modulus * a * b * c11 * s_x
    return np.where(s_c > _TINY, F * cx, linear), mu


@njit(cache=True, nogil=True)
def polach_force_scalar(
    s_x, spin, speed, Q, a, b, shear_modulus, c11, c22, mu0, A, B, k_a, k_s
):  # pragma: no cover - compiled; equal to polach_force (tested)
    """:func:`polach_force` for one contact, compiled for the models' integrators."""
    s_yc = spin * a
    s_c = math.sqrt(s_x * s_x + s_yc * s_yc)
    if s_c <= _TINY:
        return 0.5 * (k_a + k_s) * shear_modulus * a * b * c11 * s_x
    mu = mu0 * ((1.0 - A) * math.exp(-B * s_c * speed) + A)
    cx = s_x / s_c
    cy = s_yc / s_c
    C = 0.375 * shear_modulus / a * math.sqrt((c11 * cx) ** 2 + (c22 * cy) ** 2)
    eps = (2.0 / 3.0) * C * math.pi * a * a * b / (Q * mu) * s_c
    ke = k_a * eps
    F = 2.0 * Q * mu / math.pi * (ke / (1.0 + ke * ke) + math.atan(k_s * eps))
    return F * cx
