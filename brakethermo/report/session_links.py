"""The links of a session folder's index to the pages other commands wrote beside it.

Several commands write into ``OUT/<stem>/``: estimate (the lap reports and the session
index) or a rig command (its page), identify-h (the h(V) plot), diagnose
(``diagnosis/``), whatif (``whatif/``).
Whichever runs last refreshes the index's list of pages from what is on disk, so the
index links every page that exists and nothing that is gone; when no lap report was
written, a small index holds the links (the pages' back links land there).
"""

from __future__ import annotations

import html
import json
from pathlib import Path

from brakethermo.io.atomic import write_text_atomic
from brakethermo.io.kinds import rig_kind

PAGES = (
    ("diagnosis/index.html", "diagnosis: where the model parts from the disc"),
    ("whatif/index.html", "what if: the laps replayed with a change"),
    ("h_law.png", "h(V) law identified here"),
)
START, END = "<!--pages-->", "<!--/pages-->"


def _rig_of(folder: Path) -> str | None:
    """The command of the rig a diagnosis beside the page was made for (None: a disc
    session)."""
    try:
        rig = json.loads((folder / "diagnosis.json").read_text(encoding="utf-8")).get("rig")
    except (OSError, ValueError, AttributeError):
        return None
    kind = rig_kind(rig) if isinstance(rig, str) else None
    return None if kind is None else kind.command


def _law_of(path: Path) -> tuple[str, str | None] | None:
    """The h law a run recorded in its summary: its path as given, and the SHA-256 of
    the file it read (None in a summary written before that was recorded)."""
    try:
        run = json.loads(path.read_text(encoding="utf-8"))["run"]
        law, sha = run["h_law"], run.get("h_law_sha256")
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not isinstance(law, str):
        return None
    return law, sha if isinstance(sha, str) else None


def _same_law(made: tuple[str, str | None], now: tuple[str, str | None]) -> bool:
    """Whether two runs read the same h law: by the bytes they read when both recorded
    them, else by the file the paths name (a batch records a law relative to its working
    folder, ``whatif --h-law`` as typed, perhaps absolute: two spellings of one file)."""
    if made[1] is not None and now[1] is not None:
        return made[1] == now[1]
    if made[0] == now[0]:
        return True
    a, b = Path(made[0]), Path(now[0])
    try:
        return a.resolve() == b.resolve() or (a.is_file() and b.is_file() and a.samefile(b))
    except OSError:
        return False


def _one_file(a: str, b: str) -> bool:
    try:
        return Path(a).resolve() == Path(b).resolve()
    except OSError:
        return False


def _told_apart(made: str, now: str) -> tuple[str, str]:
    """The two laws' paths cut to what tells them apart: the file names when they differ,
    else as many trailing folders as it takes."""
    a, b = Path(made).parts, Path(now).parts
    for n in range(1, max(len(a), len(b)) + 1):
        if a[-n:] != b[-n:]:
            return str(Path(*a[-n:])), str(Path(*b[-n:]))
    return made, now


def _note(folder: Path, href: str) -> str:
    """What a reader must know before following a link: a what-if replayed on another h
    law than the estimate now beside it (a later estimate replaced the one it anchored to,
    or the law file was rewritten between the two runs).
    """
    if href != "whatif/index.html":
        return ""
    made, now = _law_of(folder / "whatif" / "summary.json"), _law_of(folder / "summary.json")
    if made is None or now is None or _same_law(made, now):
        return ""
    if _one_file(made[0], now[0]):  # one file, other bytes: rewritten between the runs
        shas = (f" (sha256 {made[1][:12]}… and {now[1][:12]}…)"
                if made[1] is not None and now[1] is not None else "")
        return (f" (the what-if and the estimate here read the h law {made[0]} with other"
                f" contents{shas}: it was rewritten between them; run the older again to"
                " compare them)")
    old, new = _told_apart(made[0], now[0])
    return (f" (made with the h law {old}; the estimate here now uses {new}: run whatif"
            " again to compare with it)")


def page_links(folder: Path) -> str:
    """The HTML list of the sibling pages present in ``folder``."""
    rig = _rig_of(folder)
    items = [f'<a href="{href}">'
             f'{html.escape(label.replace("the disc", "the rig") if rig else label)}</a>'
             f'{html.escape(_note(folder, href))}'
             for href, label in PAGES if (folder / href).exists()]
    return " · ".join(items)


def refresh_page_links(folder: str | Path) -> Path | None:
    """Rewrite the page links of ``folder/index.html`` (or write a small index)."""
    folder = Path(folder)
    if not folder.is_dir():
        return None
    index = folder / "index.html"
    links = page_links(folder)
    if index.is_file():
        text = index.read_text(encoding="utf-8")
        a, b = text.find(START), text.find(END)
        if a < 0 or b < a:
            return index
        write_text_atomic(index, text[: a + len(START)] + links + text[b:])
        return index
    if not links:
        return None
    name = html.escape(folder.name)
    rig = _rig_of(folder)
    own = (f"No page of the rig's own run here (run <code>{rig}</code> for it)." if rig
           else "No per-lap reports here (run <code>brakethermo estimate</code> without"
           " --no-reports for them).")
    write_text_atomic(index, (
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        f"<title>{name}</title><link rel=\"icon\" href=\"data:,\"></head><body>"
        f"<h1>{name}</h1><p>{own}</p>"
        f"<nav class=\"pages\">{START}{links}{END}</nav></body></html>\n"))
    return index
