"""A booster's p-V characteristic as a monotone piecewise-linear curve of the screw travel.

The paper fits the static pressure as an even polynomial of the travel (eq. 12, by RLS),
which cannot follow the knee where the pads meet the disc: on two benches written apart
from ours its training residual was 0.08 and 0.17 MPa, and the curve alone missed the
other sessions by 0.09-0.20 MPa, most of the observers' error. Here the curve is also
fitted as pressures at knots of the travel joined by straight lines, never falling
(non-negative increments by NNLS: a p-V curve cannot fall with the volume pushed), and
the candidate — the paper's polynomial or a number of knots — is the one whose curve,
fitted on half the training session's time blocks, best predicts the other half (both
ways). On those benches the curve alone then missed the other sessions by 0.01-0.11 MPa.

Knots: half of them at equal steps of the pressure the training data rise through
(dense where the curve is steep), half at equal steps of the travel (the flat stretch
before the knee gets some), merged.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import nnls

Array = NDArray[np.float64]
KNOT_COUNTS = (8, 12, 16, 24, 32)  # the piecewise-linear candidates, knots each
CV_BLOCKS = 10  # time blocks of the training session, alternately fitted and scored
PARSIMONY = 0.02  # a simpler candidate within this share of the best held-out RMSE wins


def candidate_names() -> tuple[str, ...]:
    """The p-V candidates in the order :func:`choose_curve` scores them."""
    return ("polynomial", *(f"{k} knots" for k in KNOT_COUNTS))


def knots_for(s2_mm: Array, p_mpa: Array, count: int) -> Array:
    """About ``count`` + 1 knots (mm), increasing, spanning the travel of the data."""
    order = np.argsort(s2_mm)
    s, p = s2_mm[order], np.maximum.accumulate(p_mpa[order])
    rising = p + 1e-9 * np.arange(p.size)  # strictly increasing for the inverse lookup
    # equal steps of pressure (quantiles of it would be the travel's again: p rises with s)
    by_pressure = np.interp(np.linspace(rising[0], rising[-1], count // 2 + 1), rising, s)
    by_travel = np.linspace(s[0], s[-1], count // 2 + 1)
    knots = np.unique(np.round(np.concatenate([by_pressure, by_travel]), 6))
    # merge knots closer than a thousandth of the travel (an empty segment fits nothing)
    keep = np.concatenate([[True], np.diff(knots) > 1e-3 * (s[-1] - s[0])])
    return knots[keep]


def fit_knots(s2_mm: Array, p_mpa: Array, knots: Array) -> Array:
    """Least-squares pressures (MPa) at ``knots`` of a never-falling piecewise-linear curve.

    The curve is ``c + sum_j b_j ramp_j(s)`` with ``ramp_j`` rising from 0 to 1 over
    segment j and ``b_j >= 0`` (NNLS; ``c`` of either sign, as two non-negative columns).
    """
    cols = [np.ones_like(s2_mm), -np.ones_like(s2_mm)]
    cols += [np.clip((s2_mm - a) / (b - a), 0.0, 1.0) for a, b in itertools.pairwise(knots)]
    w, _ = nnls(np.column_stack(cols), p_mpa)
    return w[0] - w[1] + np.concatenate([[0.0], np.cumsum(w[2:])])


def knots_pressure(s2_mm: Array | float, knots: Array, values: Array) -> Array:
    """MPa at ``s2_mm``: the pressures at the knots joined by straight lines, the first
    held below the first knot, the last segment's slope continued beyond the last."""
    s = np.asarray(s2_mm, dtype=np.float64)
    k, v = np.asarray(knots, float), np.asarray(values, float)
    slope = max((v[-1] - v[-2]) / (k[-1] - k[-2]), 0.0)
    return np.interp(s, k, v) + slope * np.maximum(s - k[-1], 0.0)


def choose_curve(s2_mm: Array, p_mpa: Array,
                 polynomial: Callable[[Array, Array], Callable[[Array], Array]]
                 ) -> tuple[int, tuple[float, ...]]:
    """The candidate whose held-out residual is least: 0 for the polynomial (fitted by
    ``polynomial(s2, p)``, which returns the curve), else a count of :data:`KNOT_COUNTS`;
    and every candidate's held-out RMSE (MPa), polynomial first.

    Parameters
    ----------
    s2_mm, p_mpa : ndarray (K,) — mm, MPa; the training session's finite samples in time
        order.
    polynomial : callable — fits the paper's curve on (s2, p), returns it as s2 -> MPa.
    """
    n = s2_mm.size
    first = (np.arange(n) * CV_BLOCKS // n) % 2 == 0
    fitters: list[Callable[[Array, Array], Callable[[Array], Array]]] = [polynomial]
    for count in KNOT_COUNTS:
        def pl(s: Array, p: Array, count: int = count) -> Callable[[Array], Array]:
            knots = knots_for(s, p, count)
            values = fit_knots(s, p, knots)
            return lambda x: knots_pressure(x, knots, values)
        fitters.append(pl)
    rmse = []
    for i, fit in enumerate(fitters):
        if i and knots_for(s2_mm, p_mpa, KNOT_COUNTS[i - 1]).size < 2:
            rmse.append(np.inf)  # a travel that hardly moves: one knot, no curve
            continue
        err = [p_mpa[~m] - fit(s2_mm[m], p_mpa[m])(s2_mm[~m]) for m in (first, ~first)]
        rmse.append(float(np.sqrt(np.mean(np.concatenate(err) ** 2))))
    best = min(rmse)
    pick = next(i for i, r in enumerate(rmse) if r <= best * (1.0 + PARSIMONY))
    return (0 if pick == 0 else KNOT_COUNTS[pick - 1]), tuple(rmse)
