"""``brakethermo`` console script and ``python -m brakethermo``.

A Ctrl-C while the command modules are still importing (numpy, scipy, numba: a few
tenths of a second, longer on a loaded machine) comes before the CLI's own interrupt
handling: it gets the same one line and exit code here instead of a traceback.
"""

from __future__ import annotations

import sys

from brakethermo.errors import EXIT_INTERRUPTED, INTERRUPTED_TEXT


def main() -> None:
    """Import the CLI and run it; an interrupt during the import is one line, exit 130."""
    try:
        from brakethermo.cli import app
    except KeyboardInterrupt:
        print(f"interrupted: {INTERRUPTED_TEXT}", file=sys.stderr)
        raise SystemExit(EXIT_INTERRUPTED) from None
    app()


if __name__ == "__main__":
    main()
