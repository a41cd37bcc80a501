"""Atomic file and directory writes: a temp file next to the target, then rename."""

from __future__ import annotations

import fnmatch
import glob
import hashlib
import os
import shutil
import socket
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from brakethermo.errors import record_output


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def atomic_path(target: str | Path, suffix: str | None = None, output: bool = True
                ) -> Iterator[Path]:
    """Yield a temporary path beside ``target``; rename it onto ``target`` on success.

    On any exception the temporary file is removed and ``target`` is left as it was.
    ``output=False`` for a file that is no result of the command (a cache): it is not
    listed among the outputs an interrupt reports (:func:`brakethermo.errors.committed_outputs`).
    Use it with writers that take a path (``pyarrow.parquet.write_table``,
    ``Figure.savefig``)::

        with atomic_path(out / "estimate.parquet") as tmp:
            pq.write_table(table, tmp)
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(
        prefix=f".{_short(target.name)}.", suffix=suffix or target.suffix or ".tmp",
        dir=target.parent,
    )
    os.close(fd)
    tmp = Path(name)
    os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the file the usual mode
    try:
        yield tmp
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    if output:
        _record(target)


def write_bytes_atomic(target: str | Path, data: bytes, output: bool = True) -> None:
    """Write ``data`` to ``target`` atomically (``output`` as in :func:`atomic_path`)."""
    with atomic_path(target, output=output) as tmp:
        tmp.write_bytes(data)


def write_text_atomic(target: str | Path, text: str, output: bool = True) -> None:
    """Write UTF-8 ``text`` to ``target`` atomically (``output`` as in :func:`atomic_path`)."""
    write_bytes_atomic(target, text.encode("utf-8"), output=output)


_STAGE = ".stage."


def _record(target: Path) -> None:
    """Record ``target`` as committed unless it sits in a staging folder (it is then part
    of an output committed later, when the stage is swapped in)."""
    if not any(part.startswith(".") and _STAGE in part for part in target.parts):
        record_output(target)


_NAME_KEEP = 100  # a temp name adds ~40 characters; file names stop at 255


def _short(name: str) -> str:
    """``name`` itself, or (when too long to carry a temp suffix) its head and a hash."""
    if len(name.encode()) <= _NAME_KEEP:
        return name
    digest = hashlib.sha1(name.encode()).hexdigest()[:12]
    return f"{name.encode()[:60].decode(errors='ignore')}~{digest}"


_ASIDE = ".old."
STALE_FOREIGN_S = 24 * 3600.0  # a stage of another host this old is from a dead run


def _host() -> str:
    return socket.gethostname().replace(".", "-") or "host"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists, owned by someone else
        return True
    return True


def _stages(folder: Path, name_glob: str) -> Iterator[tuple[Path, str, str]]:
    """Staging and set-aside folders in ``folder`` whose names match ``.<name_glob>``
    followed by the stage or aside marker: each with the host and pid its name carries."""
    for prefix in (_STAGE, _ASIDE):
        for path in folder.glob(f".{name_glob}{prefix}*"):
            # the marker's last occurrence: a session name may hold ".old." itself
            parts = path.name[path.name.rindex(prefix) + len(prefix):].split(".")
            if len(parts) >= 2 and parts[1].isdigit():
                yield path, parts[0], parts[1]


def _remove(path: Path) -> None:
    """Remove a stage whole, even when an interrupt lands while it is being removed (the
    removal is finished, then the interrupt goes on)."""
    try:
        shutil.rmtree(path, ignore_errors=True)
    except KeyboardInterrupt:
        shutil.rmtree(path, ignore_errors=True)
        raise


def clean_stale_stages(target: str | Path) -> list[Path]:
    """Remove what killed runs left beside ``target`` (staging and set-aside folders).

    A stage is named ``.<name>.stage.<host>.<pid>.<random>``: it is stale when its
    process no longer runs on this host (or, from another host, when it is older than
    :data:`STALE_FOREIGN_S`). Stages of live runs are left alone.

    Returns
    -------
    list of Path
        The folders removed.
    """
    target = Path(target)
    host = _host()
    removed = []
    for path, stage_host, pid in _stages(target.parent, glob.escape(_short(target.name))):
        try:
            age = time.time() - path.stat().st_mtime
        except OSError:
            continue
        mine = stage_host == host
        if (mine and not _alive(int(pid))) or (not mine and age > STALE_FOREIGN_S):
            shutil.rmtree(path, ignore_errors=True)
            removed.append(path)
    return removed


def remove_own_stages(folder: str | Path) -> list[Path]:
    """Remove the staging and set-aside folders this process left in ``folder``.

    An interrupt that lands while a stage is being removed (or while a thread still
    writes into it) can leave one behind; nothing in it is a result. Called once the
    interrupted work has stopped.

    Returns
    -------
    list of Path
        The folders removed.
    """
    host, pid = _host(), str(os.getpid())
    removed = []
    for path, stage_host, stage_pid in _stages(Path(folder), "*"):
        if (stage_host, stage_pid) == (host, pid):
            _remove(path)
            removed.append(path)
    return removed


def _new_stage(target: Path) -> tuple[Path, str]:
    """A staging folder beside ``target`` (stale ones of killed runs removed first) and the
    run's tag; the usual permissions (``mkdtemp`` alone would make it private)."""
    clean_stale_stages(target)
    tag = f"{_host()}.{os.getpid()}."
    stage = Path(tempfile.mkdtemp(prefix=f".{_short(target.name)}{_STAGE}{tag}",
                                  dir=target.parent))
    os.chmod(stage, 0o777 & ~_umask())
    return stage, tag


@contextmanager
def atomic_dir(target: str | Path) -> Iterator[Path]:
    """Yield a temporary directory; on success it replaces ``target`` as a whole.

    A reader never sees a half-written directory: the old one stays until the new
    one is complete, then the swap is two renames (old aside, new in place). Stages
    left by a killed run are removed first (:func:`clean_stale_stages`); the new
    directory gets the usual permissions (``mkdtemp`` alone would make it private).
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp, tag = _new_stage(target)
    try:
        yield tmp
    except BaseException:
        _remove(tmp)
        raise
    old = None
    if target.exists():
        old = target.with_name(f".{_short(target.name)}{_ASIDE}{tag}{os.urandom(4).hex()}")
        os.replace(target, old)
    os.replace(tmp, target)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    _record(target)


def write_atomic_with(target: str | Path, writer: Callable[[Path], None]) -> None:
    """Call ``writer(tmp_path)`` and move the result onto ``target`` atomically."""
    with atomic_path(target) as tmp:
        writer(tmp)


def _swap_in(src: Path, dest: Path, tag: str) -> None:
    """Move ``src`` onto ``dest`` (a file or a folder), the old one set aside first."""
    if src.is_dir() and dest.exists():
        aside = dest.with_name(f".{_short(dest.name)}{_ASIDE}{tag}{os.urandom(4).hex()}")
        os.replace(dest, aside)
        os.replace(src, dest)
        if aside.is_dir():
            shutil.rmtree(aside, ignore_errors=True)
        else:
            aside.unlink()
    else:
        if dest.is_dir():
            shutil.rmtree(dest)
        os.replace(src, dest)


def owns(name: str, patterns: tuple[str, ...]) -> bool:
    """Whether entry ``name`` of a session folder matches one of a command's patterns."""
    return any(fnmatch.fnmatchcase(name, p) for p in patterns)


@contextmanager
def atomic_entries(target: str | Path, owned: tuple[str, ...]) -> Iterator[Path]:
    """Yield a staging folder whose entries replace their namesakes in ``target``.

    For folders several commands write into: every entry of the stage (a file or a
    folder) is swapped in atomically on its own, entries of ``target`` matching the
    ``owned`` patterns that the stage did not produce (an earlier, longer session's
    ``lap_12``) are removed, and everything else — another command's results — is left
    as it was. A failure or an interrupt inside the ``with`` leaves ``target`` untouched.
    """
    target = Path(target)
    created = not target.exists()
    target.mkdir(parents=True, exist_ok=True)
    stage, tag = _new_stage(target)
    try:
        try:
            yield stage
        except BaseException:
            # a folder made for this write and never filled is not left behind (an
            # interrupted batch left one per session it had not finished)
            _remove(stage)
            if created and not any(target.iterdir()):
                target.rmdir()
            raise
        produced = {e.name for e in stage.iterdir()}
        for entry in list(target.iterdir()):
            if entry.name in produced or not owns(entry.name, owned):
                continue
            if entry.is_dir():
                shutil.rmtree(entry)
            else:
                entry.unlink()
        # the index after what it links; a manifest (a command's record that the folder is
        # complete) after everything, so an interrupt never leaves one beside half the rest
        for entry in sorted(stage.iterdir(), key=lambda e: (e.name.endswith("manifest.json"),
                                                            e.name == "index.html")):
            _swap_in(entry, target / entry.name, tag)
        _record(target)
    finally:
        _remove(stage)
