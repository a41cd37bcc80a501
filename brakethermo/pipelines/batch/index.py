"""The batch's root page ``OUT/index.html`` and the rows it was drawn from.

The batch writes the page from its sessions' outcomes, and the rows beside it
(``OUT/batch_index.json``). Other commands may write into a session's folder later
(``estimate … --out OUT``, ``identify-h``, ``diagnose``); they redraw the page from those
rows, so that it never shows the batch's peaks for results that are no longer the
batch's (the session's manifest fingerprints what the batch wrote) and lists the
diagnosis now beside a session.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from brakethermo.io.atomic import write_text_atomic
from brakethermo.pipelines.batch.discovery import REPLACED, outputs_replaced, read_manifest
from brakethermo.pipelines.batch.tasks import DEFAULT_LAW, file_sha256

INDEX_ROWS = "batch_index.json"


def write_index(out: Path, folder: Path, rows: list[dict[str, Any]]) -> Path:
    """``out/index.html`` from ``rows`` (:meth:`SessionOutcome.to_json` records) and the
    rows themselves beside it."""
    from brakethermo.report.index import write_batch_index

    write_text_atomic(out / INDEX_ROWS, json.dumps(
        {"folder": str(folder), "sessions": rows}, indent=1, default=str) + "\n")
    return write_batch_index(out, folder, rows)


def earlier_rows(out: Path, listed: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The rows of the index an earlier batch left in ``out`` that ``listed`` lacks.

    A session folder with a manifest is listed by
    :func:`~brakethermo.pipelines.batch.discovery.earlier_sessions`; a rig log (no
    folder of the batch's) has only its row, and a second batch of
    another input folder into the same ``--out`` dropped them from the index.

    Parameters
    ----------
    out : Path
        The batch's output folder.
    listed : list of dict
        The rows this batch lists (its sessions and the earlier ones found by manifest).

    Returns
    -------
    list of dict
        The earlier index's other rows, each with its reason saying which batch it is from.
    """
    try:
        saved = json.loads((out / INDEX_ROWS).read_text(encoding="utf-8"))
        rows, folder = [dict(r) for r in saved["sessions"]], str(saved["folder"])
    except (OSError, ValueError, KeyError, TypeError):
        return []
    have = {str(r.get("name", "")).casefold() for r in listed}
    kept = []
    for row in rows:
        name = str(row.get("name", ""))
        # a disc session's row without its folder's manifest lost its results: not kept
        if name.casefold() in have or row.get("status") != "rig session":
            continue
        if not str(row.get("reason", "")).startswith("from an earlier batch"):
            row["reason"] = f"from an earlier batch of {folder}: {row.get('reason', '')}"
        kept.append(row)
    return kept


def refresh_batch_index(out: str | Path) -> Path | None:
    """Redraw a batch's ``out/index.html`` after another command wrote into ``out``: a
    session whose results were replaced since loses the batch's peaks and says so.
    Nothing happens where no batch index is."""
    from brakethermo.report.index import is_batch_index, write_batch_index

    out = Path(out)
    if not is_batch_index(out / "index.html"):
        return None
    try:
        saved = json.loads((out / INDEX_ROWS).read_text(encoding="utf-8"))
        rows = [dict(r) for r in saved["sessions"]]
        folder = Path(saved["folder"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    for row in rows:
        if row.get("status") not in ("ok", "skipped", "earlier batch"):
            continue
        if outputs_replaced(out / str(row["name"])):
            # "up to date" beside "replaced since" contradicted itself: say which
            row.update(status=REPLACED_STATUS, reason=REPLACED, peaks_c={}, replaced=True,
                       h_law=None, h_law_reason="")
            continue
        changed = law_changed(out, read_manifest(out / str(row["name"])))
        if changed is not None:
            row.update(status=STALE_STATUS, replaced=True,
                       reason=f"the h law it was estimated with ({changed}) was rewritten"
                              " since (identify-h or another batch): its peaks are of the"
                              " old law; batch this folder again for the new one")
    return write_batch_index(out, folder, rows)


REPLACED_STATUS = "replaced"  # another command's results now in the session's folder
STALE_STATUS = "stale"  # the batch's results, of a law rewritten since


def law_changed(out: Path, manifest: dict[str, Any] | None) -> str | None:
    """The law file a session was estimated with, when it holds other bytes now than the
    manifest recorded (else None: the same, the shipped law, or a file no longer found).
    The manifest names it as the batch was given it, perhaps relative to the folder the
    batch ran in; a law identified in the batch is also found under ``out``."""
    if not isinstance(manifest, dict):
        return None
    used, sha = manifest.get("h_law_used"), manifest.get("h_law_sha256")
    if not isinstance(used, str) or not used or not isinstance(sha, str) or sha == DEFAULT_LAW:
        return None
    path = Path(used)
    for candidate in (path, out / path.parent.name / path.name):
        if candidate.is_file():
            try:
                return None if file_sha256(candidate) == sha else str(candidate)
            except OSError:
                return None
    return None
