"""The page of a pooled diagnosis (``diagnose S1 S2 …``: ``OUT/pooled/index.html``, beside
its ``diagnosis.json``): the pooled verdict and why, what to do next, each candidate's
pooled held-out shrink beside every session's, and each session's own verdict with a link
to its page. Disc and rig pools alike: it reads only the keys their ``diagnosis.json``
share."""

from __future__ import annotations

import math
from typing import Any

from brakethermo.report.page import (
    Card,
    Page,
    Section,
    TableBlock,
    number_text,
    verdict_text,
)


def _per_session(summary: dict[str, Any]) -> list[tuple[str, str, list[str]]]:
    """(stem, verdict, verdict set) per session, in order: a disc pool lists them, a rig
    pool maps stem to verdict."""
    per = summary["per_session"]
    if isinstance(per, dict):
        return [(stem, v["verdict"], list(v["verdict_set"])) for stem, v in per.items()]
    return [(v["session"], v["verdict"], list(v["verdict_set"])) for v in per]


def _interval(row: dict[str, Any]) -> str:
    lo, hi = row.get("shrink_ci95_pct") or (math.nan, math.nan)
    return f"[{number_text(lo, '.0f')}, {number_text(hi, '.0f')}]"


def pooled_page(summary: dict[str, Any]) -> Page:
    """The page of a pooled ``diagnosis.json`` (its keys as OUTPUTS.md gives them)."""
    sessions = _per_session(summary)
    stems = [stem for stem, _, _ in sessions]
    verdict = summary["verdict"]
    kind = summary.get("verdict_kind", "")
    shown = verdict_text(summary)
    effects = [[e["name"], f"{number_text(e.get('shrink_pct'), '+.1f')} %", _interval(e),
                "yes" if e.get("significant") else "no",
                ", ".join(e.get("significant_in") or []) or "–",
                *(f"{number_text((e.get('per_session_shrink_pct') or {}).get(s), '+.0f')} %"
                  for s in stems)]
               for e in summary["effects"]]
    return Page(
        title=f"diagnosis — {len(stems)} sessions pooled",
        subtitle=", ".join(stems),
        cards=[Card("pooled verdict", verdict if kind != "set" else "set"),
               Card("sessions", str(len(stems))),
               Card("named in a session", str(sum(v != "none" for _, v, _ in sessions)))],
        sections=[
            Section("Verdict", paragraphs=[
                f"Pooled verdict: {shown}.",
                *summary.get("verdict_reasons", []),
                *(f"Note: {n}" for n in summary.get("notes", [])),
                *(f"WARNING: {w}" for w in summary.get("warnings", [])),
                f"Rule: {summary.get('verdict_rule', '')}"]),
            Section("Next steps", paragraphs=list(summary.get("next_steps", [])) or ["none"]),
            Section("Candidates", tables=[TableBlock(
                ["effect", "pooled held-out shrink", "95 % interval", "significant",
                 "significant in", *(f"{s}: shrink" for s in stems)], effects,
                caption="every session's held-out braking cycles (or units) resampled"
                        " together; each session's own shrink beside the pooled one")]),
            Section("Sessions",
                    tables=[TableBlock(["session", "own verdict", "verdict set"],
                                       [[s, v, " / ".join(vs) or "–"]
                                        for s, v, vs in sessions])],
                    links=[(f"{s}: its diagnosis page", f"../{s}/diagnosis/index.html")
                           for s in stems]),
        ],
    )
