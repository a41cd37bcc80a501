"""Output-error fitting of the reference model and of each candidate effect."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from brakethermo.models.disc_effects import ExtendedDisc
from brakethermo.pipelines.diagnose._common import PRIOR_WEIGHT_C
from brakethermo.pipelines.models import read_calibration, shipped_h_law
from brakethermo.thermal.disc import DiscSpec
from brakethermo.thermal.model import DiscFEModel


def _fit(
    ext: ExtendedDisc,
    p0: np.ndarray,
    y: np.ndarray,
    mask: np.ndarray,
    free: np.ndarray,
    max_nfev: int,
) -> np.ndarray:
    """Output-error least squares of the free parameters on ``mask`` (K, 4) readings.

    Residual and forward-difference Jacobian from ONE batched model pass; Gaussian
    priors of the effects enter as extra residuals (:data:`PRIOR_WEIGHT_C` per sigma).
    """
    lo, hi = ext.bounds()
    mu, sd = ext.prior()
    idx = np.flatnonzero(free)
    has_prior = idx[np.isfinite(sd[idx])]
    p_full = np.clip(p0, lo + 1e-9, hi - 1e-9)
    cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def prior_res(p: np.ndarray) -> np.ndarray:
        return PRIOR_WEIGHT_C * (p[has_prior] - mu[has_prior]) / sd[has_prior]

    def evaluate(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = x.tobytes()
        if key not in cache:
            p = p_full.copy()
            p[idx] = x
            step = 1e-3 * np.maximum(1.0, np.abs(x))
            step = np.where(x + step > hi[idx], -step, step)
            P = np.tile(p, (idx.size + 1, 1))
            P[np.arange(1, idx.size + 1), idx] += step
            pred = ext.predict(P)
            res = (pred - y[None])[:, mask]
            pri = np.stack([prior_res(row) for row in P])
            full = np.concatenate([res, pri], axis=1)
            cache.clear()
            cache[key] = (full[0], ((full[1:] - full[0]) / step[:, None]).T)
        return cache[key]

    sol = least_squares(lambda x: evaluate(x)[0], p_full[idx], jac=lambda x: evaluate(x)[1],
                        bounds=(lo[idx], hi[idx]), x_scale="jac", loss="soft_l1",
                        f_scale=20.0, ftol=1e-4, xtol=1e-4, max_nfev=max_nfev)
    out = p_full.copy()
    out[idx] = sol.x
    return out


def _nanmean(a: np.ndarray, axis: int | None = None) -> Any:
    """``np.nanmean`` that returns NaN for an empty selection without a warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(a, axis=axis)


def _initial_nodes(model: DiscFEModel, spot_radii: np.ndarray, y: np.ndarray, t_amb: float
                   ) -> np.ndarray:
    first = y[:50]
    vals = np.array([col[np.isfinite(col)][0] if np.isfinite(col).any() else np.nan
                     for col in first.T])
    ok = np.isfinite(vals)
    prof = np.interp(model.radii, spot_radii[ok], vals[ok]) if ok.any() else \
        np.full(model.n_nodes, t_amb)
    return np.repeat(np.maximum(prof, t_amb), model.layers)


def _reference_start(disc: DiscSpec, h_law: str | Path | None
                     ) -> tuple[float, float, np.ndarray]:
    """Start of the reference fit: a, b and crown weights of the given or shipped law."""
    path = Path(h_law) if h_law else shipped_h_law(disc)
    if path is None:
        return 100.0, 0.8, np.ones(3)
    cal = read_calibration(path)  # checked as estimate checks it: a bad law is no start
    return cal.law.a, cal.law.b, np.asarray(cal.weights, float)


def _gauss_ll(result: Any) -> np.ndarray:
    """Per-step Gaussian log-likelihood of a filter's innovations."""
    nu, s2 = result.innovation, result.innovation_var
    return -0.5 * (np.log(2.0 * np.pi * s2) + nu**2 / s2)

