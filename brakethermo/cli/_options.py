"""Command-line options shared by several commands (one help text, one spelling)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

OutDir = Annotated[Path, typer.Option("--out", "-o", help="Output folder.")]
DiscOpt = Annotated[str | None, typer.Option(help="Disc datasheet id or TOML file.")]
TuningOpt = Annotated[Path | None, typer.Option(help="Filter tuning TOML.")]
AliasesOpt = Annotated[Path | None, typer.Option(help="Channel alias TOML.")]
AmbientOpt = Annotated[
    float | None, typer.Option(help="Ambient temperature, degC (else from the session).")
]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print a JSON summary.")]
