"""``brakethermo`` console script and ``python -m brakethermo``.

A Ctrl-C while the command modules are still importing (numpy, scipy, numba: a few
tenths of a second, longer on a loaded machine) comes before the CLI's own interrupt
handling: it gets the same one line and exit code here instead of a traceback. One in
the interpreter's teardown after the command is ignored (the work is done).
"""

from __future__ import annotations

import signal
import sys

from brakethermo.errors import EXIT_INTERRUPTED, INTERRUPTED_TEXT


def main() -> None:
    """Import the CLI and run it; an interrupt during the import is one line, exit 130,
    and one during the shutdown after the command is ignored (the command's code)."""
    try:
        from brakethermo.cli import app
    except KeyboardInterrupt:
        print(f"interrupted: {INTERRUPTED_TEXT}", file=sys.stderr)
        raise SystemExit(EXIT_INTERRUPTED) from None
    try:
        app()
    finally:
        # The command is done (its outputs written, or its error said); what follows is
        # the interpreter's teardown. An interrupt there raised in the middle of it or,
        # once Python had reset its handlers, killed the process (exit -2; once in tens
        # of tries an abort): ignored instead — every pool and thread is closed by now.
        signal.signal(signal.SIGINT, signal.SIG_IGN)


if __name__ == "__main__":
    main()
