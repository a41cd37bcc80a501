"""Command-line options shared by several commands (one help text, one spelling, one check)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated

import typer

from brakethermo.errors import ConfigError
from brakethermo.pipelines.tuning import BOUNDS

NODES_MIN, NODES_MAX = (int(v) for v in BOUNDS["nodes"])
LAYERS_MIN, LAYERS_MAX = (int(v) for v in BOUNDS["layers"])
AMBIENT_RANGE_C = (-60.0, 80.0)


def _finite_ambient(value: float | None) -> float | None:
    lo, hi = AMBIENT_RANGE_C
    if value is not None and not lo <= value <= hi:  # also false for nan
        raise typer.BadParameter(
            f"{value} is not an air temperature; give degC in [{lo:g}, {hi:g}]"
        )
    return value


def positive_finite(value: float) -> float:
    """Option callback: a finite number > 0 (budgets, durations)."""
    if not (math.isfinite(value) and value > 0):
        raise typer.BadParameter(f"{value} must be a finite number > 0")
    return value


@contextmanager
def option_values() -> Iterator[None]:
    """An option value the command checks itself (a range, a combination) is a usage
    error, exit 2 as Typer's own checks, not a data problem (exit 1).

    Wrap only the building of a command's options from its arguments: a session or
    file read inside stays a data problem.
    """
    try:
        yield
    except ConfigError as exc:
        raise typer.BadParameter(str(exc)) from None


# what the readers take (io.formats.SUFFIXES; a test keeps the two in step without
# importing every reader at start-up)
SESSION_FORMATS = ".mcap, .parquet, .csv, .mf4/.mdf/.mf3 (MDF), .xrk/.xrz (AiM)"

OutDir = Annotated[Path, typer.Option("--out", "-o", help="Output folder.")]
DiscOpt = Annotated[str | None, typer.Option(help="Disc datasheet id or TOML file.")]
TuningOpt = Annotated[Path | None, typer.Option(help="Filter tuning TOML.")]
AliasesOpt = Annotated[Path | None, typer.Option(help="Channel alias TOML.")]
NodesOpt = Annotated[
    int | None,
    typer.Option(min=NODES_MIN, max=NODES_MAX, help="Radial nodes (as the tuning file caps them)."),
]
LayersOpt = Annotated[
    int | None,
    typer.Option(min=LAYERS_MIN, max=LAYERS_MAX, help="Layers over the half thickness."),
]
AmbientOpt = Annotated[
    float | None,
    typer.Option(
        callback=_finite_ambient, help="Ambient temperature, degC (else from the session)."
    ),
]
JsonOpt = Annotated[
    bool, typer.Option("--json", metavar="", help="Print a JSON summary instead of tables.")
]

NoReportsOpt = Annotated[
    bool, typer.Option("--no-reports", metavar="", help="Skip the per-lap HTML/PNG reports.")
]
# The old spelling of estimate, kept working but out of the help.
LegacyReportOpt = Annotated[bool | None, typer.Option("--report/--no-report", hidden=True)]
