"""Accuracy tables of the paper (Tables 3 and 4), peak errors and band coverage.

Scores compare estimated spot temperatures with a reference: the measured spots of a
multi-spot session (what the paper does), or simulator truth in benchmarks. The spot
used as the filter's measurement is scored too, as in the paper.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brakethermo.numeric import rmse, true_runs

CONTACT_SPOTS = (2, 3, 4)  # spot numbers inside the pad contact band
Z95 = 1.959963984540054


def contact_average(spots: np.ndarray) -> np.ndarray:
    """Mean of spots 2..4, degC; ``spots`` has shape (K, 4)."""
    return spots[:, 1:4].mean(axis=1)


def reading_noise(y: np.ndarray, per_reading: int = 1, steady: np.ndarray | None = None
                  ) -> float:
    """White noise of a reading, degC, from robust second differences.

    ``y[k+1] - 2 y[k] + y[k-1]`` cancels the temperature's slope and has variance
    ``6 sigma²`` for white noise; the median keeps braking transients out.

    A pyrometer slower than the grid (``per_reading`` grid points per reading) is taken
    at its own rate: between its readings the grid holds interpolations, whose second
    differences shrink. Every phase of the grid is tried and the largest estimate kept
    (the phase that lands on the readings), over the differences that lie wholly in
    ``steady`` (off the brakes: at the reading's spacing, a difference across a brake
    application is no longer small).
    """
    if per_reading <= 1:
        return _d2_noise(y, None)
    return max(_d2_noise(y[o::per_reading],
                         None if steady is None else steady[o::per_reading])
               for o in range(per_reading))


def _d2_noise(y: np.ndarray, steady: np.ndarray | None) -> float:
    if steady is None:
        d2 = np.diff(y[np.isfinite(y)], 2)
    else:
        d2 = y[2:] - 2.0 * y[1:-1] + y[:-2]
        d2 = d2[np.isfinite(d2) & steady[2:] & steady[1:-1] & steady[:-2]]
    if d2.size < 10:
        return 0.0
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0))


def ratio(a: float, b: float) -> float:
    """``a / b``, NaN when ``b`` is zero or not finite (a score against nothing)."""
    return a / b if np.isfinite(b) and b > 0 else float("nan")


def segments(flag: np.ndarray, min_len: int = 1) -> list[tuple[int, int]]:
    """Contiguous runs of True in ``flag`` as half-open index ranges ``(start, stop)``."""
    return [(int(a), int(b)) for a, b in true_runs(flag) if b - a >= min_len]


@dataclass(frozen=True)
class MethodScore:
    """RMSE (degC) of one method per spot (1..4) and of the contact-band average."""

    method: str
    spot_rmse: tuple[float, float, float, float]
    contact_rmse: float

    def as_dict(self) -> dict[str, float | str]:
        row: dict[str, float | str] = {"method": self.method}
        row.update({f"spot{i + 1}": v for i, v in enumerate(self.spot_rmse)})
        row["contact_avg"] = self.contact_rmse
        return row


def score_method(
    method: str, spots_est: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None
) -> MethodScore:
    """Score a method's (K, 4) spot estimates against a (K, 4) reference."""
    per_spot = tuple(rmse(spots_est[:, i], reference[:, i], mask) for i in range(4))
    contact = rmse(contact_average(spots_est), contact_average(reference), mask)
    return MethodScore(method, per_spot, contact)  # type: ignore[arg-type]


def single_spot_baseline(measured_spot: np.ndarray) -> np.ndarray:
    """The pre-paper practice: the one spot reading copied to every spot, shape (K, 4)."""
    return np.repeat(measured_spot[:, None], 4, axis=1)


def peak_errors(
    estimate: np.ndarray, reference: np.ndarray, braking: np.ndarray, dt: float = 0.1,
    settle_s: float = 3.0, zones: np.ndarray | None = None,
) -> dict[str, float]:
    """Relative peak error per braking zone at one spot.

    Each zone runs from the brake application to ``settle_s`` after release, where the
    face peak occurs. Returns the mean absolute and the worst relative error (%) and the
    signed error of the session's highest peak, the zones scored and ``zones_total``.
    ``zones`` (``[start, stop)`` rows, e.g. the report's
    :func:`~brakethermo.report.braking_zones.detect_zones`) replaces the runs of
    ``braking``, so that scores and reports count the same braking zones.
    """
    pad = round(settle_s / dt)
    errors = []
    runs = segments(braking, min_len=5) if zones is None else [(int(a), int(b)) for a, b in zones]
    for a, b in runs:
        stop = min(b + pad, len(reference))
        ok = np.isfinite(reference[a:stop]) & np.isfinite(estimate[a:stop])
        if not ok.any():
            continue
        ref = reference[a:stop][ok]
        est = estimate[a:stop][ok]
        errors.append((np.nanmax(est) - np.nanmax(ref)) / np.nanmax(ref) * 100.0)
    if not errors:
        return {"zones": 0, "zones_total": len(runs), "mean_abs_pct": float("nan"),
                "worst_pct": float("nan"), "max_peak_pct": float("nan")}
    arr = np.asarray(errors)
    ref_peak = np.nanmax(reference)
    est_peak = np.nanmax(estimate[np.isfinite(reference)])
    return {
        "zones": len(errors),
        "zones_total": len(runs),
        "mean_abs_pct": float(np.mean(np.abs(arr))),
        "worst_pct": float(arr[np.argmax(np.abs(arr))]),
        "max_peak_pct": float((est_peak - ref_peak) / ref_peak * 100.0),
    }


def coverage(
    estimate: np.ndarray, std: np.ndarray, reference: np.ndarray, extra_var: float = 0.0,
    level_z: float = Z95,
) -> float:
    """Fraction of finite reference points inside ``estimate ± z·sqrt(std² + extra_var)``.

    ``extra_var`` (degC²) adds the sensor noise when the reference is a measurement
    rather than the true temperature.
    """
    ok = np.isfinite(estimate) & np.isfinite(reference) & np.isfinite(std)
    if not ok.any():
        return float("nan")
    half = level_z * np.sqrt(std[ok] ** 2 + extra_var)
    return float(np.mean(np.abs(estimate[ok] - reference[ok]) <= half))
