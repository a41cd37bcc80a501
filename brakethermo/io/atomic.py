"""Atomic file and directory writes: a temp file next to the target, then rename."""

from __future__ import annotations

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


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def atomic_path(target: str | Path, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``target``; rename it onto ``target`` on success.

    On any exception the temporary file is removed and ``target`` is left as it was.
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


def write_bytes_atomic(target: str | Path, data: bytes) -> None:
    """Write ``data`` to ``target`` atomically."""
    with atomic_path(target) as tmp:
        tmp.write_bytes(data)


def write_text_atomic(target: str | Path, text: str) -> None:
    """Write UTF-8 ``text`` to ``target`` atomically."""
    write_bytes_atomic(target, text.encode("utf-8"))


_STAGE = ".stage."
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
    for prefix in (_STAGE, _ASIDE):
        short = _short(target.name)
        for path in target.parent.glob(f".{glob.escape(short)}{prefix}*"):
            parts = path.name[len(short) + 1 + len(prefix):].split(".")
            stage_host, pid = (parts[0], parts[1]) if len(parts) >= 2 else ("", "")
            if not pid.isdigit():
                continue
            try:
                age = time.time() - path.stat().st_mtime
            except OSError:
                continue
            mine = stage_host == host
            if (mine and not _alive(int(pid))) or (not mine and age > STALE_FOREIGN_S):
                shutil.rmtree(path, ignore_errors=True)
                removed.append(path)
    return removed


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
    clean_stale_stages(target)
    tag = f"{_host()}.{os.getpid()}."
    stage = f".{_short(target.name)}{_STAGE}{tag}"
    tmp = Path(tempfile.mkdtemp(prefix=stage, dir=target.parent))
    os.chmod(tmp, 0o777 & ~_umask())
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if target.exists():
        old = target.with_name(f".{_short(target.name)}{_ASIDE}{tag}{os.urandom(4).hex()}")
        os.replace(target, old)
    os.replace(tmp, target)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def write_atomic_with(target: str | Path, writer: Callable[[Path], None]) -> None:
    """Call ``writer(tmp_path)`` and move the result onto ``target`` atomically."""
    with atomic_path(target) as tmp:
        writer(tmp)
