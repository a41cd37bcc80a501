"""The batch index page ``OUT/index.html``: one line per session, linking its report."""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from brakethermo import __version__
from brakethermo.io.atomic import write_text_atomic
from brakethermo.report.page import template_environment
from brakethermo.results.laps import temp_text

BATCH_MARK = '<meta name="generator" content="brakethermo batch index">'


def is_batch_index(path: Path) -> bool:
    """Whether ``path`` is an index a batch wrote (the sessions' pages may link up to it)."""
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            return BATCH_MARK in f.read(4096)
    except OSError:
        return False


def _diagnosis_cell(folder: Path) -> str | None:
    """The verdict of the diagnosis beside a session's results, in a few words (or None)."""
    try:
        d = json.loads((folder / "diagnosis.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not (folder / "diagnosis" / "index.html").is_file():
        return None
    if d.get("verdict_kind") == "set":
        return "one of " + " / ".join(d.get("verdict_set", []))
    return str(d.get("verdict", "none"))


# The pages another command writes into a folder of OUT, and how the index names them.
OTHER_PAGES = (("index.html", "page"), ("diagnosis/index.html", "diagnosis"),
               ("whatif/index.html", "what if"))


def other_pages(out: Path, names: Iterable[str]) -> list[dict[str, Any]]:
    """The folders of ``out`` that are no session of the batch's rows (``names``) but
    hold pages later commands wrote there (``diagnose A B --out OUT``'s ``pooled/`` and
    the folder of a session the batch never read): each with its pages' links, so the
    index reaches every page in ``out``."""
    rows = {str(n).casefold() for n in names}
    found = []
    try:
        folders = sorted(p for p in out.iterdir() if p.is_dir())
    except OSError:
        return found
    for folder in folders:
        if folder.name.startswith(".") or folder.name.casefold() in rows:
            continue  # a staging folder, or a session of the table
        links = [{"href": f"{folder.name}/{page}",
                  "label": "pooled diagnosis" if page == "index.html"
                  and folder.name == "pooled" and (folder / "diagnosis.json").is_file()
                  else label}
                 for page, label in OTHER_PAGES if (folder / page).is_file()]
        if links:
            found.append({"name": folder.name, "links": links})
    return found


def _owns_folder(folder: Path, row: dict[str, Any]) -> bool:
    """Whether the results in ``folder`` are the row's session's, to be linked.

    A failed session wrote nothing there: what a folder of its name holds is another
    run's (a failed ``batch2/rr.mcap`` linked an earlier ``rr.mcap``'s results and
    verdict). A rig log's folder holds what its rig command or diagnose wrote, of the
    file their ``summary.json`` or ``diagnosis.json`` names: linked when that is the
    row's file (or none is named).
    """
    if row.get("status") == "failed":
        return False
    if row.get("status") != "rig session" or not row.get("file"):
        return True
    mine = Path(str(row["file"]))
    for name in ("summary.json", "diagnosis.json"):
        try:
            said = json.loads((folder / name).read_text(encoding="utf-8")).get("session")
            # both files still there and not one: another file of the same stem (paths
            # written relative to another folder cannot tell, and keep the link)
            if said and not Path(str(said)).samefile(mine):
                return False
        except (OSError, ValueError, AttributeError):
            continue
    return True


def write_batch_index(
    out: str | Path, folder: str | Path, sessions: Iterable[dict[str, Any]]
) -> Path:
    """Write ``out/index.html`` listing the sessions of a batch.

    Parameters
    ----------
    out : path
        Batch output root.
    folder : path
        The folder the sessions came from (shown in the header).
    sessions : iterable of dict
        Records with ``name``, ``kind``, ``laps``, ``status``, ``peaks_c`` (degC per
        spot), ``reason`` and ``h_law`` (:meth:`SessionOutcome.to_json`).
    """
    out = Path(out)
    rows = []
    for s in sessions:
        page = out / str(s["name"]) / "index.html"
        owned = _owns_folder(out / str(s["name"]), s)
        diagnosis = _diagnosis_cell(out / str(s["name"])) if owned else None
        rows.append(
            {
                "name": s["name"],
                "kind": s.get("kind") or "–",
                "laps": s.get("laps") or "–",
                "status": s["status"],
                "peaks": s.get("peaks_c", {}),
                "reason": s.get("reason", ""),
                "replaced": bool(s.get("replaced")),
                "h_law": s.get("h_law") or "–",
                "h_law_reason": s.get("h_law_reason", ""),
                "href": f"{s['name']}/index.html" if owned and page.is_file() else None,
                "diagnosis": diagnosis,
                "diagnosis_href": f"{s['name']}/diagnosis/index.html" if diagnosis else None,
            }
        )
    env = template_environment()
    env.filters["temp"] = temp_text
    rig = sum(r["status"] == "rig session" for r in rows)
    # an index of rig logs only was titled "Disc temperature reports"
    title = ("Rig session reports" if rows and rig == len(rows) else
             "Disc temperature and rig session reports" if rig else "Disc temperature reports")
    html = env.get_template("batch.html.j2").render(
        sessions=rows, folder=str(folder), footer=f"brakethermo {__version__}", title=title,
        others=other_pages(out, [r["name"] for r in rows]),
    )
    index = out / "index.html"
    write_text_atomic(index, html)
    return index
