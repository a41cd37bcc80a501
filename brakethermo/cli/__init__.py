"""Command-line interface: thin Typer commands that parse, call a pipeline, render.

Each command lives in its own module and registers itself on :data:`app`.
"""

from __future__ import annotations

from brakethermo.cli._app import app

# Command modules register on import; keep one line per module, sorted.
from brakethermo.cli import batch_cmd  # noqa: F401  isort: skip
from brakethermo.cli import clamp_force_cmd  # noqa: F401  isort: skip
from brakethermo.cli import diagnose_cmd  # noqa: F401  isort: skip
from brakethermo.cli import ebooster_cmd  # noqa: F401  isort: skip
from brakethermo.cli import estimate_cmd  # noqa: F401  isort: skip
from brakethermo.cli import identify_cmd  # noqa: F401  isort: skip
from brakethermo.cli import inspect_cmd  # noqa: F401  isort: skip
from brakethermo.cli import mu_slip_cmd  # noqa: F401  isort: skip
from brakethermo.cli import roller_rig_cmd  # noqa: F401  isort: skip
from brakethermo.cli import simulate_cmd  # noqa: F401  isort: skip
from brakethermo.cli import timing_cmd  # noqa: F401  isort: skip
from brakethermo.cli import whatif_cmd  # noqa: F401  isort: skip


def main() -> None:
    """Console-script entry point."""
    app()


__all__ = ["app", "main"]
