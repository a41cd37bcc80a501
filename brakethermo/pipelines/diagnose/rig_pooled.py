"""Several sessions of one rig diagnosed together (``diagnose S1 S2 …`` on rig sessions):
every session's held-out units resampled together under the rig diagnosis's rule, each
session's verdict beside the pooled one, and an effect significant in one run only said
so (one set of pads, one fluid temperature, is not the rig)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from brakethermo.diagnosis.verdict import decide
from brakethermo.pipelines.diagnose._common import filled
from brakethermo.pipelines.diagnose.pooled import end_to_end, leading, rms
from brakethermo.pipelines.diagnose.rig import RULE
from brakethermo.results.rig_diagnosis import RigDiagnosis


def pool_rig(results: Sequence[RigDiagnosis]) -> dict[str, Any]:
    """The pooled ``diagnosis.json`` of rig sessions diagnosed one by one (the keys of a
    session's, plus ``sessions``, ``per_session`` and ``notes``). A candidate negligible
    in every session (under its floor) stays out of the pooled verdict."""
    stems = [r.stem for r in results]
    by_session = [{e.name: e for e in r.evidence} for r in results]
    names = [n for n in by_session[0] if all(n in b for b in by_session)]
    ignored = set.intersection(*(set(r.negligible) for r in results))
    lead = {n: leading([next(e for e in r.summary["effects"] if e["name"] == n)
                        for r in results]) for n in names}
    evidence = [end_to_end([b[n] for b in by_session], lead[n], at_bound="; ".join(
        dict.fromkeys(b[n].at_bound for b in by_session if b[n].at_bound)))
        for n in names if n not in ignored]
    decision = decide(np.concatenate([r.reference_sse for r in results]), evidence, RULE)
    rows = []
    for row in decision.rows:
        rows.append({**row, **_pooled_row(row["name"], row["shrink_pct"], results)})
    nan = float("nan")
    rows += [{"name": n, "shrink_pct": nan, "shrink_ci95_pct": [nan, nan],
              "significant": False, "rank": len(rows) + i + 1, "negligible": True,
              **_pooled_row(n, nan, results)}
             for i, n in enumerate(n for n in names if n in ignored)]
    first = results[0].summary
    # a carried effect is read from a session's diagnosis: the run that shows it most
    shows = (results[lead[decision.verdict_set[0]]].stem if decision.verdict_set
             else results[0].stem)
    decision = replace(decision, next_steps=filled(
        decision.next_steps, {"DIR/<stem>/": f"DIR/{shows}/"}))
    return {
        "sessions": [str(r.session.path) for r in results],
        "rig": first["rig"], "unit": first["unit"], "input": first["input"],
        "reference": first["reference"],
        "gap": {"rmse": rms([r.summary["gap"]["rmse"] for r in results]),
                "per_session": {st: r.summary["gap"]["rmse"] for st, r in
                                zip(stems, results, strict=True)}},
        "effects": rows,
        **decision.summary(),
        "per_session": {st: {"verdict": r.summary["verdict"],
                             "verdict_set": r.summary["verdict_set"]}
                        for st, r in zip(stems, results, strict=True)},
        "notes": _notes(rows, results),
    }


def _pooled_row(name: str, shrink_pct: float, results: Sequence[RigDiagnosis]
                ) -> dict[str, Any]:
    """A candidate's session-level figures pooled: RMSE before (the runs' root mean
    square) and after (shrunk by the pooled shrink), its fit per session, the sessions
    where it was significant."""
    per = [next(e for e in r.summary["effects"] if e["name"] == name) for r in results]
    before = rms([e["rmse_before"] for e in per])
    return {
        "rmse_before": before,
        "rmse_after": before * (1.0 - shrink_pct / 100.0),
        "params_per_session": {r.stem: e["params"] for r, e in zip(results, per, strict=True)},
        "per_session_shrink_pct": {r.stem: e["shrink_pct"]
                                   for r, e in zip(results, per, strict=True)},
        "significant_in": [r.stem for r, e in zip(results, per, strict=True)
                           if e["significant"]],
        "evidence": "; ".join(f"{r.stem}: {e['evidence']}"
                              for r, e in zip(results, per, strict=True)),
    }


def _notes(rows: list[dict[str, Any]], results: Sequence[RigDiagnosis]) -> list[str]:
    """Effects significant in one run only, and sessions whose own verdicts differ."""
    notes = [f"{r['name']} is significant in {r['significant_in'][0]} only (held-out shrink"
             " per session: " + ", ".join(f"{k} {v:+.0f} %" for k, v in
                                         r["per_session_shrink_pct"].items())
             + "): a one-off of that run or a difference between the runs"
             for r in rows if len(r["significant_in"]) == 1 and len(results) > 1]
    own = {r.stem: r.summary["verdict"] for r in results if r.summary["verdict"] != "none"}
    if len(set(own.values())) > 1:
        notes.append("the sessions' own verdicts differ ("
                     + "; ".join(f"{k}: {v}" for k, v in own.items())
                     + "): the pooled verdict weighs every run's held-out units alike")
    return notes
