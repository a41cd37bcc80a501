"""Friction-heat distribution over the pad crowns (eq. 6–8).

``f(r) = w_i Q / (pi (r_4^2 - r_1^2))`` on crown ``i`` and zero elsewhere. The paper's
eq. 5 counts both faces with a factor 2 on a per-face flux; here ``f`` is the flux of
both faces together, so that ``int f 2 pi r dr = Q``: ``Q`` is the power entering this
disc (``DiscSpec.braking_power``), and the weights conserve it whenever eq. 8 holds.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from brakethermo.thermal.fe import piecewise_flux_load


def crown_areas(edges: np.ndarray) -> np.ndarray:
    """Area of each crown, ``pi (r_{i+1}^2 - r_i^2)``, m^2."""
    edges = np.asarray(edges, dtype=float)
    return np.pi * np.diff(edges**2)


def normalise_weights(weights: Sequence[float] | np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Scale crown weights so that eq. 8 holds.

    Parameters
    ----------
    weights : sequence of float — dimensionless
        Non-negative crown weights w_1..w_P (not all zero), any scale.
    edges : ndarray, shape (P + 1,) — m
        Crown edges r_1..r_{P+1}.

    Returns
    -------
    ndarray, shape (P,)
        ``w`` with ``sum(area_i w_i) = pi (r_{P+1}^2 - r_1^2)``.
    """
    w = np.asarray(weights, dtype=float)
    edges = np.asarray(edges, dtype=float)
    if w.shape != (edges.size - 1,):
        raise ValueError(f"need {edges.size - 1} crown weights, got {w.size}")
    if np.any(~np.isfinite(w)) or np.any(w < 0) or not np.any(w > 0):
        raise ValueError(f"crown weights must be finite, >= 0 and not all zero, got {w}")
    area = crown_areas(edges)
    return w * area.sum() / np.dot(area, w)


def crown_flux(weights: Sequence[float] | np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Flux per unit braking power on each crown (eq. 6), 1/m^2.

    Weights are normalised by :func:`normalise_weights` first.
    """
    edges = np.asarray(edges, dtype=float)
    w = normalise_weights(weights, edges)
    return w / (np.pi * (edges[-1] ** 2 - edges[0] ** 2))


def crown_load(
    r: np.ndarray, edges: np.ndarray, weights: Sequence[float] | np.ndarray = (1.0, 1.0, 1.0)
) -> np.ndarray:
    """Nodal load per unit braking power of the crown distribution (eq. 6–8).

    Parameters
    ----------
    r : ndarray, shape (N,) — m
        Node radii; the crowns must lie inside ``[r[0], r[-1]]``.
    edges : ndarray, shape (P + 1,) — m
        Crown edges (``DiscSpec.crown_edges``).
    weights : sequence of float
        Crown weights, normalised to eq. 8 here.

    Returns
    -------
    ndarray, shape (N,) — dimensionless
        Shares of ``Q`` per node; they sum to one.
    """
    edges = np.asarray(edges, dtype=float)
    if edges[0] < r[0] - 1e-12 or edges[-1] > r[-1] + 1e-12:
        raise ValueError("pad crowns must lie inside the meshed ring")
    return piecewise_flux_load(r, edges, crown_flux(weights, edges))


def shape_load(
    r: np.ndarray, flux: Callable[[np.ndarray], np.ndarray], n_gauss: int = 8
) -> np.ndarray:
    """Nodal load per unit braking power of an arbitrary radial flux shape.

    Parameters
    ----------
    r : ndarray, shape (N,) — m
        Node radii.
    flux : callable
        ``flux(radius_m) -> relative flux`` (>= 0, any scale); it is normalised so the
        load sums to one. Integrated by ``n_gauss``-point Gauss–Legendre per element,
        so a discontinuous shape should rather go through :func:`piecewise_flux_load`.

    Returns
    -------
    ndarray, shape (N,) — dimensionless, sums to one
    """
    xg, wg = np.polynomial.legendre.leggauss(n_gauss)
    ra, rb = r[:-1, None], r[1:, None]
    le = rb - ra
    rq = ra + (xg[None, :] + 1.0) * le / 2.0
    f = np.asarray(flux(rq), dtype=float) * 2.0 * np.pi * rq * wg[None, :] * le / 2.0
    if np.any(f < 0) or not np.isfinite(f).all() or f.sum() <= 0:
        raise ValueError("the flux shape must be finite, >= 0 and not identically zero")
    b = np.zeros_like(r)
    b[:-1] += (f * (rb - rq) / le).sum(axis=1)
    b[1:] += (f * (rq - ra) / le).sum(axis=1)
    return b / b.sum()
