"""The h law each single-spot session is estimated with, chosen deliberately: same disc,
then same track and vehicle, then the newest; never silently another disc's law."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from brakethermo.io.session import Session
from brakethermo.pipelines.batch.discovery import skipped_outcome
from brakethermo.pipelines.batch.tasks import (
    DEFAULT_LAW,
    BatchOptions,
    Event,
    SessionOutcome,
    SessionTask,
    file_sha256,
)

MULTI_SPOT = tuple(f"disc_temp_spot{i}" for i in range(1, 5))
DISC_ASSUMED_FACT = "disc_assumed"  # a session fact of the batch's own: no disc was named


def _disc_words(facts: dict[str, str]) -> str:
    """``disc <id>``, said to be assumed where the file's facts named none."""
    disc = facts.get("disc", "")
    return (f"disc {disc} (assumed: the file's facts name no disc)"
            if facts.get(DISC_ASSUMED_FACT) else f"disc {disc}")


def is_multi_spot(session: Session) -> bool:
    """Whether a session carries the four-spot sensor (a test session)."""
    return all(session.has(c) for c in MULTI_SPOT)


def session_facts(session: Session) -> dict[str, str]:
    """What the h-law choice matches on: disc id as processed, track, vehicle, date (and
    ``disc_assumed`` where no fact named the disc)."""
    from brakethermo.pipelines.models import DEFAULT_DISC

    meta = session.metadata
    facts = {"disc": str(meta.get("disc") or DEFAULT_DISC)}
    if not meta.get("disc"):  # no fact names it: the default was assumed, and is said so
        facts[DISC_ASSUMED_FACT] = "yes"
    for key in ("track", "vehicle", "date"):
        if meta.get(key):
            facts[key] = str(meta[key])
    return facts


@dataclass(frozen=True)
class LawChoice:
    """The h law a single-spot session is estimated with, and why.

    Attributes
    ----------
    path : Path or None
        The law file; None is the law shipped for the session's disc.
    source : str
        Short tag for tables: ``given``, ``identified: <session>``, ``default (shipped)``.
    reason : str
        One sentence for the console, the batch JSON, the manifest and summary.json.
    """

    path: Path | None
    source: str
    reason: str


def choose_law(facts: dict[str, str], outcomes: Iterable[SessionOutcome]) -> LawChoice:
    """Choose the identified law for a single-spot session with ``facts``.

    Only laws identified for the same disc qualify (a law of another disc is never
    used); among them the one from the same track and vehicle wins, then the newest
    (session date, then file time). Without a qualifying law, the law shipped for the
    disc — and the reason says which other laws were passed over.
    """
    laws = [o for o in outcomes if o.kind == "multi" and o.h_law_file and o.status != "failed"]
    disc = facts.get("disc", "")
    same_disc = [o for o in laws if o.facts.get("disc") == disc]
    if not same_disc:
        others = sorted(f"{o.name} ({o.facts.get('disc', '?')})" for o in laws)
        passed = f"; laws of other discs not used: {', '.join(others)}" if others else ""
        return LawChoice(
            None, DEFAULT_LAW,
            f"no law identified in this batch for {_disc_words(facts)}: shipped"
            f" default{passed}",
        )  # fmt: skip

    def matches(o: SessionOutcome, key: str) -> bool:
        return bool(facts.get(key)) and o.facts.get(key) == facts.get(key)

    def rank(o: SessionOutcome) -> tuple[bool, bool, str, float]:
        try:
            mtime = o.path.stat().st_mtime
        except OSError:
            mtime = 0.0
        return matches(o, "track"), matches(o, "vehicle"), o.session_date, mtime

    best = max(same_disc, key=rank)
    why = [f"same {_disc_words(facts)}"]
    why += [f"same {k} {facts[k]}" for k in ("track", "vehicle") if matches(best, k)]
    if len(same_disc) > 1:
        why.append(f"newest of {len(same_disc)} for this disc")
    return LawChoice(
        Path(str(best.h_law_file)), f"identified: {best.name}",
        f"identified from {best.name} ({', '.join(why)})",
    )  # fmt: skip


def second_pass(
    known_single: list[tuple[Path, str, str, dict[str, Any]]], first: list[SessionTask],
    done: dict[Path, SessionOutcome], options: BatchOptions, out: Path,
    on_event: Event | None,
) -> list[SessionTask]:
    """The single-spot sessions, once the test sessions of this batch have their laws: the
    ones deferred in the first pass, and the ones up to date unless their law changed
    (those are skipped here, into ``done``)."""
    identified = [o for o in done.values() if o.kind == "multi"]
    second: list[SessionTask] = []
    for path, name, sha, manifest in known_single:
        facts = {str(k): str(v) for k, v in dict(manifest["facts"]).items()}
        choice = choose_law(facts, identified)
        law_sha = file_sha256(choice.path) if choice.path is not None else DEFAULT_LAW
        if manifest.get("h_law_sha256") == law_sha:
            done[path] = skipped_outcome(path, name, manifest, out)
            if on_event is not None:
                on_event("done", done[path])
            continue
        second.append(SessionTask(path, name, options, sha, choice.path, choice.source,
                                  h_law_reason=choice.reason))
    for o in [o for o in done.values() if o.status == "deferred"]:
        task = next(t for t in first if t.path == o.path)
        choice = choose_law(o.facts, identified)
        second.append(replace(task, h_law=choice.path, h_law_source=choice.source,
                              h_law_reason=choice.reason, defer_single=False,
                              session=o.session))
    return second
