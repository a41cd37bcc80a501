"""Radial mesh and linear-element integrals of the axisymmetric disc model (eq. 10–14).

All integrals carry the axisymmetric weight ``2 pi r``. Pure functions of the mesh:
the model (:mod:`brakethermo.thermal.model`) multiplies them by the temperature-dependent
material properties of each step.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def radial_nodes(r_int: float, r_est: float, n_nodes: int) -> np.ndarray:
    """Equally spaced node radii.

    Parameters
    ----------
    r_int, r_est : float — m
        Inner and outer radius of the ring.
    n_nodes : int
        Number of nodes N (>= 2).

    Returns
    -------
    ndarray, shape (N,) — m
    """
    if n_nodes < 2:
        raise ValueError("the mesh needs at least two nodes")
    return np.linspace(r_int, r_est, n_nodes)


def nodal_areas(r: np.ndarray) -> np.ndarray:
    """Lumped face area of each node, ``a_i = int 2 pi r phi_i dr`` (one face), m^2.

    Row sums of the consistent axisymmetric mass matrix: they sum to
    ``pi (r_N^2 - r_1^2)`` exactly, so lumping conserves capacity and face area.
    """
    ra, rb = r[:-1], r[1:]
    le = rb - ra
    a = np.zeros_like(r)
    a[:-1] += 2.0 * np.pi * le * (2.0 * ra + rb) / 6.0
    a[1:] += 2.0 * np.pi * le * (ra + 2.0 * rb) / 6.0
    return a


def conduction_factors(r: np.ndarray) -> np.ndarray:
    """Element conduction factors ``g_e = 2 pi r_mid / l_e`` (m^0).

    The element conductance of a layer of thickness ``t`` with conductivity ``k`` is
    ``k t g_e`` (W/K); exact for ``k`` constant over the element since
    ``int 2 pi r phi_a' phi_b' dr = -2 pi r_mid / l_e``.
    """
    ra, rb = r[:-1], r[1:]
    return np.pi * (ra + rb) / (rb - ra)


def piecewise_flux_load(r: np.ndarray, edges: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Load vector of a piecewise-constant radial flux, integrated exactly.

    ``b_i = int f(r) 2 pi r phi_i(r) dr`` with ``f = values[j]`` on
    ``[edges[j], edges[j+1]]``; the pieces need not fall on nodes. Because the shape
    functions sum to one, ``sum(b) = sum_j values[j] pi (edges[j+1]^2 - edges[j]^2)``
    for the part of the flux inside the mesh.

    Parameters
    ----------
    r : ndarray, shape (N,) — m
        Node radii, increasing.
    edges : ndarray, shape (P + 1,) — m
        Increasing piece edges.
    values : ndarray, shape (P,) — W/m^2 (or per unit power: 1/m^2)
        Flux on each piece (both faces together).

    Returns
    -------
    ndarray, shape (N,) — W (or per unit power)
    """
    edges = np.asarray(edges, dtype=float)
    values = np.asarray(values, dtype=float)
    ra, rb = r[:-1, None], r[1:, None]
    le = rb - ra
    u0 = np.maximum(ra, edges[None, :-1])
    u1 = np.minimum(rb, edges[None, 1:])
    u1 = np.maximum(u1, u0)  # empty intersection -> zero-length interval
    um = 0.5 * (u0 + u1)
    # int 2 pi r phi dr over [u0, u1]: quadratic integrand, so Simpson's rule is exact;
    # its samples are >= 0, so no cancellation can make a load negative.
    w = 2.0 * np.pi * (u1 - u0) / (6.0 * le)

    def simpson(g: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        return w * (g(u0) + 4.0 * g(um) + g(u1))

    ia = simpson(lambda x: x * (rb - x))
    ib = simpson(lambda x: x * (x - ra))
    b = np.zeros_like(r)
    b[:-1] += ia @ values
    b[1:] += ib @ values
    return b


def interpolation_matrix(r: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Linear interpolation between the two nodes around each radius (eq. 53).

    Parameters
    ----------
    r : ndarray, shape (N,) — m
        Node radii, increasing.
    radii : array_like, shape (m,) — m
        Query radii inside ``[r[0], r[-1]]``.

    Returns
    -------
    ndarray, shape (m, N)
        Rows with two non-zero weights summing to one.
    """
    radii = np.atleast_1d(np.asarray(radii, dtype=float))
    if np.any(radii < r[0] - 1e-12) or np.any(radii > r[-1] + 1e-12):
        raise ValueError(f"radii must lie inside [{r[0]}, {r[-1]}] m, got {radii}")
    e = np.clip(np.searchsorted(r, radii, side="right") - 1, 0, r.size - 2)
    xi = np.clip((radii - r[e]) / (r[e + 1] - r[e]), 0.0, 1.0)
    H = np.zeros((radii.size, r.size))
    rows = np.arange(radii.size)
    H[rows, e] = 1.0 - xi
    H[rows, e + 1] += xi
    return H
