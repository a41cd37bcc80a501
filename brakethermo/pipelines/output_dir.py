"""The output place of a command: checked before any work, replaced as a whole after it.

``--out`` that is a file, or a folder nobody can write to, used to end in a traceback
after all the computation; :func:`check_output_dir` says so first. A session's output
folder is shared by the commands (estimate, identify-h, diagnose, whatif, batch): each
writes through a staging folder whose entries replace only their namesakes and the
stale entries the command owns (:func:`replace_session_dir`), so a re-run never keeps
stale ``lap_NN`` folders of an earlier, longer session, never deletes another
command's results, and a run killed half-way leaves the old folder as it was.
"""

from __future__ import annotations

import filecmp
import json
import os
import tempfile
from contextlib import AbstractContextManager
from pathlib import Path

from brakethermo.errors import ConfigError
from brakethermo.io.atomic import atomic_entries

# What each command owns in OUT/<stem>/ (fnmatch patterns); nothing else is its to delete.
IDENTIFY_FILES = ("h_law.toml", "h_samples.parquet", "identify.json", "h_law.png")
ESTIMATE_FILES = ("estimate.parquet", "estimate.mf4", "estimate.mcap", "summary.json",
                  "index.html", "lap_[0-9]*", "trend.png")
BATCH_FILES = (*ESTIMATE_FILES, *IDENTIFY_FILES, "batch_manifest.json")


def _nearest_existing(path: Path) -> Path:
    probe = path.absolute()
    while not probe.exists() and probe.parent != probe:
        probe = probe.parent
    return probe


def _writable(folder: Path) -> bool:
    return os.access(folder, os.W_OK | os.X_OK)


def check_output_dir(out: str | Path, option: str = "--out") -> Path:
    """Make sure ``out`` is (or can become) a writable folder, before any computation.

    Raises
    ------
    ConfigError
        ``out`` (or a folder above it) is a file, is not writable, or cannot be created.
    """
    out = Path(out)
    base = _nearest_existing(out)
    if not base.is_dir():
        where = "" if base == out.absolute() else f" (inside {out})"
        raise ConfigError(
            f"is a file{where}, but {option} needs a folder; give a folder path", path=base
        )
    if not _writable(base):
        raise ConfigError(
            f"is not writable; give a {option} folder you can write to", path=base
        )
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        raise ConfigError(
            f"cannot write there ({exc.strerror}); give another {option} folder", path=out
        ) from None
    return out


# The table each command writes into OUT/<stem>/ beside a summary.json and index.html of
# its own: two of them in one folder are two sessions of one name (a roller-rig day1.mcap
# and a tyre day1.mcap), whose pages would replace each other's.
SESSION_TABLES = ("estimate", "roller_rig", "ebooster", "clamp_force", "mu_slip")
# What the commands record of the session they ran on, in OUT/<stem>/: file, key of the
# session file's path (batch's manifest records it as "input").
SESSION_RECORDS = (("summary.json", "session"), ("identify.json", "session"),
                   ("diagnosis.json", "session"), ("whatif/summary.json", "session"),
                   ("batch_manifest.json", "input"))


def _recorded(folder: Path) -> list[str]:
    out = []
    for name, key in SESSION_RECORDS:
        try:
            source = json.loads((folder / name).read_text(encoding="utf-8"))[key]
        except (OSError, ValueError, KeyError, TypeError):
            continue
        if isinstance(source, str):
            out.append(source)
    return out


def _other_file(recorded: str, session: Path) -> bool:
    """Whether ``recorded`` is, for sure, another file than ``session``: it still exists
    and holds other bytes (a file since moved, or named relative to another folder,
    cannot be told: no refusal)."""
    other = Path(recorded)
    try:
        if not other.is_file() or other.samefile(session):
            return False
        return other.stat().st_size != session.stat().st_size or not filecmp.cmp(
            other, session, shallow=False)
    except OSError:
        return False


def check_session_folder(out: str | Path, session: str | Path, table: str | None) -> None:
    """Refuse, before any work, to write a run of ``session`` into ``OUT/<stem>/`` when
    that folder holds another session of that name: another command's table
    (:data:`SESSION_TABLES`, ``table`` being this command's own, or None), or a record of
    a session file that is another one (estimate, whatif, identify-h and diagnose
    results of two sessions would sit on one page).

    Raises
    ------
    ConfigError
        ``OUT/<stem>/`` holds another session's results.
    """
    session = Path(session)
    folder = Path(out) / session.stem
    other = next((t for t in SESSION_TABLES
                  if t != table and (folder / f"{t}.parquet").is_file()), None)
    if other is None:
        check_same_session(folder, session)
        return
    sources = _recorded(folder)
    whose = f" of {sources[0]}" if sources else ""
    raise ConfigError(
        f"holds the {other.replace('_', '-')} results{whose}, another session named"
        f" '{session.stem}': this run would replace its summary and page; give another"
        " --out (or rename one of the files)", path=folder)


def check_same_session(folder: str | Path, session: str | Path,
                       fix: str = "give another --out (or rename one of the files)") -> None:
    """Refuse to write ``session``'s results into ``folder`` when the results there record
    another session file (one that still exists and holds other bytes).

    Raises
    ------
    ConfigError
        ``folder`` holds another session's results; ``fix`` says what to do.
    """
    folder, session = Path(folder), Path(session)
    elsewhere = next((s for s in _recorded(folder) if _other_file(s, session)), None)
    if elsewhere is not None:
        raise ConfigError(
            f"holds the results of {elsewhere}, another session named '{session.stem}':"
            f" this run would mix them on one page; {fix}", path=folder)


def check_session_output(out: str | Path, session: str | Path, table: str) -> None:
    """Before any work: ``out`` can be written (:func:`check_output_dir`) and its folder for
    ``session`` holds no other session's run (:func:`check_session_folder`)."""
    check_output_dir(out)
    check_session_folder(out, session, table)


def check_output_file(path: str | Path, option: str = "--out") -> Path:
    """Make sure ``path`` can be written as a file (not a folder, writable parent)."""
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"is a folder, but {option} needs a file name", path=path)
    check_output_dir(path.parent if str(path.parent) else Path("."), option)
    return path


def replace_session_dir(target: str | Path, owned: tuple[str, ...] = ESTIMATE_FILES
                        ) -> AbstractContextManager[Path]:
    """A staging folder whose entries replace their namesakes in ``target`` on success.

    Entries of ``target`` matching ``owned`` that the run did not produce are removed;
    every other entry (another command's results) is left as it was.
    """
    return atomic_entries(target, owned)


def refresh_indexes(folder: str | Path) -> None:
    """After a command wrote into a session's folder: the folder's links to the pages
    beside it (``report.session_links``) and, where a batch wrote ``OUT/index.html``,
    that page (``pipelines.batch.index``)."""
    from brakethermo.report.session_links import refresh_page_links

    refresh_page_links(folder)
    refresh_out_index(Path(folder).parent)


def refresh_out_index(out: str | Path) -> None:
    """Redraw the batch's ``out/index.html`` (if a batch wrote one) after a command wrote
    into ``out``: its rows, and the pages of folders that are none of its sessions."""
    out = Path(out)
    # only where a page is: the batch package brings the report stack (matplotlib), 0.3-
    # 0.6 s of the wall of an estimate that writes no page
    if (out / "index.html").is_file():
        from brakethermo.pipelines.batch.index import refresh_batch_index

        refresh_batch_index(out)
