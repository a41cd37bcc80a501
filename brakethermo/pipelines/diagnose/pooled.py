"""The figures of a pooled diagnosis (``DIR/pooled/diagnosis.json``) from the sessions'.

OUTPUTS.md gives the pooled file the keys of a session's: the gap per spot and phase, the
consistency per spot, and per effect ``rmse_before``, ``rmse_after``, ``params`` and
``evidence``. Each session's figure is measured on its own held-out laps; pooled, an RMSE
is the root of the sessions' mean square (every run weighs alike, as the pooled gap
does), a mean NIS is the mean over all the runs' innovations with the χ² band of their
total count, and a fitted parameter is the sessions' median (each run's own value beside
it: a parameter that differs between runs is a finding in itself).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from scipy.special import chdtri

from brakethermo.diagnosis.verdict import CandidateEvidence


def end_to_end(evidence: Sequence[CandidateEvidence], lead: int = 0, **fields: Any
               ) -> CandidateEvidence:
    """One candidate's evidence over several sessions: its SSE per unit and its
    corrections end to end, its next step session ``lead``'s (:func:`leading`: the
    command names that session), the rest the first session's unless ``fields`` says."""
    return replace(evidence[0], sse=np.concatenate([e.sse for e in evidence]),
                   correction=np.concatenate([np.ravel(e.correction) for e in evidence]),
                   next_step=evidence[lead].next_step, **fields)


def leading(rows: Sequence[dict[str, Any]]) -> int:
    """Which of the sessions' rows of one effect (their ``diagnosis.json`` ``effects``
    entries, in session order) shows it most: significant before not, then the higher
    lower end of the held-out shrink interval. A pooled verdict's next step carries the
    effect from that session: the first session named, whatever it showed, had a test
    session identified with an effect it did not have (new-user test)."""
    def strength(i: int) -> tuple[bool, float]:
        lo = (rows[i].get("shrink_ci95_pct") or [float("nan")])[0]
        return bool(rows[i].get("significant")), float(np.nan_to_num(lo, nan=-np.inf))

    return max(range(len(rows)), key=strength)


def rms(values: Sequence[float]) -> float:
    """Root of the mean square of per-session RMSEs; NaN if any is unknown (a session
    without a score leaves the pooled figure unknown, not smaller)."""
    return float(np.sqrt(np.mean(np.square(np.asarray(values, float)))))


def _rms_tree(trees: Sequence[Any]) -> Any:
    """:func:`rms` leaf by leaf over dicts of one shape (per spot, per phase, ...)."""
    if isinstance(trees[0], dict):
        return {k: _rms_tree([t[k] for t in trees]) for k in trees[0]
                if all(isinstance(t, dict) and k in t for t in trees)}
    return rms(trees)


def pooled_gap(summaries: Sequence[dict[str, Any]], stems: Sequence[str]) -> dict[str, Any]:
    """``gap``: the sessions' held-out RMSE per spot, phase and both, pooled."""
    gaps = [s["gap"] for s in summaries]
    out = _rms_tree([{k: g[k] for k in ("rmse_c", "per_spot", "per_phase", "per_spot_phase")
                      if k in g} for g in gaps])
    out["per_session"] = dict(zip(stems, (g["rmse_c"] for g in gaps), strict=True))
    return out


def pooled_consistency(summaries: Sequence[dict[str, Any]], stems: Sequence[str]
                       ) -> dict[str, Any]:
    """``consistency``: per spot, the mean NIS over every run's scored innovations and the
    95 % χ² band of their total count; each session's own beside it."""
    per_spot: dict[str, Any] = {}
    for spot in summaries[0]["consistency"]["per_spot"]:
        rows = [s["consistency"]["per_spot"][spot] for s in summaries]
        n = np.array([r.get("n", 0) for r in rows], float)
        if n.sum() <= 0:
            continue
        mean = float(np.dot(n, [r["mean_nis"] for r in rows]) / n.sum())
        lo, hi = (float(v) for v in chdtri(n.sum(), [0.975, 0.025]) / n.sum())
        ac = np.array([r["lag1_autocorrelation"] for r in rows], float)
        ok = np.isfinite(ac)
        per_spot[spot] = {
            "mean_nis": mean, "chi2_band": [lo, hi],
            "lag1_autocorrelation": float(np.dot(n[ok], ac[ok]) / n[ok].sum())
            if ok.any() else float("nan"),
            "state": "over-confident" if mean > hi else "under-confident" if mean < lo
            else "consistent",
            "n": int(n.sum()),
        }
    over = sum(v["state"] == "over-confident" for v in per_spot.values())
    return {
        "per_spot": per_spot,
        "summary": (f"pooled over {len(summaries)} sessions, the reference filter is"
                    f" over-confident at {over} of {len(per_spot)} spots" if over else
                    f"pooled over {len(summaries)} sessions, the reference filter's"
                    " innovations are consistent with its noise settings"),
        "per_session": {stem: s["consistency"] for stem, s in zip(stems, summaries,
                                                                   strict=True)},
    }


def _median_params(params: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The sessions' median of each parameter (element-wise for lists of one length)."""
    out: dict[str, Any] = {}
    for k in params[0]:
        arr = _stacked([p.get(k) for p in params])
        if arr is not None:
            med = np.median(arr, axis=0)
            out[k] = med.tolist() if arr.ndim > 1 else float(med)
    return out


def _stacked(vals: list[Any]) -> np.ndarray | None:
    """The runs' values of one parameter as one array, ``None`` when they do not stack
    (lists of different lengths, a run without the parameter)."""
    if any(v is None for v in vals):
        return None
    if any(isinstance(v, list) for v in vals) and len({len(v) for v in vals}) > 1:
        return None
    try:
        return np.asarray(vals, float)
    except (TypeError, ValueError):
        return None


def _unpooled_params(params: Sequence[dict[str, Any]]) -> dict[str, str]:
    """Why a parameter has no pooled median (``params_not_pooled``): per-segment values
    whose counts differ between the runs (9 braking zones against 10, 46 straights
    against 47) have no element-wise median; OUTPUTS.md promised one and ``params`` was
    silently ``{}``."""
    out: dict[str, str] = {}
    for k in params[0]:
        vals = [p.get(k) for p in params]
        if _stacked(vals) is not None:
            continue
        counts = [len(v) if isinstance(v, list) else (0 if v is None else 1) for v in vals]
        out[k] = (f"per-segment values of different counts in the runs"
                  f" ({', '.join(map(str, counts))}): no element-wise median; each run's"
                  " values are in params_per_session")
    return out


def pooled_effect(name: str, summaries: Sequence[dict[str, Any]], stems: Sequence[str],
                  shrink_pct: float) -> dict[str, Any]:
    """An effect row's session-level keys pooled: RMSE before (overall, per spot, per
    phase) and after, the median parameters with each session's, the evidence per run.

    ``rmse_after`` is the pooled ``rmse_before`` shrunk by the pooled verdict's
    ``shrink_pct`` (measured over every run's held-out braking cycles together), so the
    row keeps the relation a session's row has; per spot and phase both are the runs'.
    """
    rows = [next(e for e in s["effects"] if e["name"] == name) for s in summaries]
    tree = _rms_tree([{k: r[k] for k in ("rmse_before", "per_spot", "per_phase")}
                      for r in rows])
    return {
        "rmse_before": tree["rmse_before"],
        "rmse_after": tree["rmse_before"] * (1.0 - shrink_pct / 100.0),
        "per_spot": tree["per_spot"],
        "per_phase": tree["per_phase"],
        "params": _median_params([r["params"] for r in rows]),
        "params_per_session": {st: r["params"] for st, r in zip(stems, rows, strict=True)},
        **({"params_not_pooled": why} if (why := _unpooled_params([r["params"] for r in rows]))
           else {}),
        "evidence": "; ".join(f"{st}: {r['evidence']}" for st, r in zip(stems, rows,
                                                                          strict=True)),
    }
