"""Errors a user can act on, and the exit codes of OUTPUTS.md."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

EXIT_OK = 0
EXIT_BAD_INPUT = 1
EXIT_USAGE = 2
EXIT_BATCH_PARTIAL = 3
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report it
# every output is staged and swapped in whole: an interrupted run leaves nothing half-written
INTERRUPTED_TEXT = "nothing of this run was written; earlier outputs are as they were"


# Outputs this process has committed (renamed into place, by io.atomic) since the last
# forget_committed(): an interrupt after them can say what is complete.
_committed: list[Path] = []


def record_output(path: str | Path) -> None:
    """Note an output committed whole (a file renamed into place, a staged folder)."""
    _committed.append(Path(path))


def committed_outputs() -> list[Path]:
    """The outputs recorded since :func:`forget_committed` still in place, in order; one
    inside another recorded (a page in a session folder) is counted with it."""
    kept = list(dict.fromkeys(p for p in _committed if p.exists()))
    return [p for p in kept if not any(q != p and q in p.parents for q in kept)]


def forget_committed() -> None:
    """Start a new record of committed outputs (each command does, on entry)."""
    _committed.clear()


def interrupted_text(written: Sequence[object]) -> str:
    """What an interrupt leaves, given the outputs the run had committed (paths)."""
    if not written:
        return INTERRUPTED_TEXT
    names = ", ".join(str(p) for p in written[:3]) + (", …" if len(written) > 3 else "")
    return (f"this run had written {len(written)} output(s) complete before it ({names});"
            " nothing after them was done; other outputs are as they were")


class BrakethermoError(Exception):
    """A problem with the user's input data or configuration.

    The CLI prints the message on one line and exits with code 1; it never shows a
    traceback for these. Messages name the file, the channel (where there is one),
    the problem and the fix.
    """

    exit_code = EXIT_BAD_INPUT

    def __init__(self, message: str, *, path: object | None = None, channel: str | None = None):
        self.path = path
        self.channel = channel
        prefix = []
        if path is not None:
            prefix.append(str(path))
        if channel is not None:
            prefix.append(f"channel '{channel}'")
        self.detail = message
        super().__init__(": ".join([*prefix, message]) if prefix else message)


class DataError(BrakethermoError):
    """The session file cannot be read or does not hold what the command needs."""


class ConfigError(BrakethermoError):
    """A TOML configuration (datasheet, aliases, tuning, track, h law) is invalid."""


class Interrupted(BrakethermoError):
    """The user stopped the run (Ctrl-C): what finished is complete, the rest untouched."""

    exit_code = EXIT_INTERRUPTED
