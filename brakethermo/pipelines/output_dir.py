"""The output place of a command: checked before any work, replaced as a whole after it.

``--out`` that is a file, or a folder nobody can write to, used to end in a traceback
after all the computation; :func:`check_output_dir` says so first. A session's output
folder is written through :func:`replace_session_dir` (a staging folder renamed over
the old one), so a re-run never keeps stale ``lap_NN`` folders of an earlier, longer
session, and a run killed half-way leaves the old folder as it was.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from brakethermo.errors import ConfigError
from brakethermo.io.atomic import atomic_dir

# What identify-h writes into OUT/<stem>/: estimate replaces its own outputs, not these.
IDENTIFY_FILES = ("h_law.toml", "h_samples.parquet", "identify.json", "h_law.png")


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


def check_output_file(path: str | Path, option: str = "--out") -> Path:
    """Make sure ``path`` can be written as a file (not a folder, writable parent)."""
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"is a folder, but {option} needs a file name", path=path)
    check_output_dir(path.parent if str(path.parent) else Path("."), option)
    return path


@contextmanager
def replace_session_dir(
    target: str | Path, keep: tuple[str, ...] = IDENTIFY_FILES
) -> Iterator[Path]:
    """Yield a staging folder that replaces ``target`` as a whole on success.

    Files named in ``keep`` (another command's outputs in the same folder) are carried
    over from the old folder first; the caller may overwrite them.
    """
    target = Path(target)
    with atomic_dir(target) as stage:
        for name in keep:
            old = target / name
            if old.is_file():
                shutil.copy2(old, stage / name)
        yield stage
