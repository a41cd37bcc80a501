"""The Typer application object and the user-error boundary shared by all commands."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterable
from typing import Any, TypeVar

import click
import numpy as np
import typer
from rich.console import Console
from rich.markup import escape
from typer.core import TyperGroup

from brakethermo import __version__
from brakethermo.errors import (
    EXIT_INTERRUPTED,
    BrakethermoError,
    committed_outputs,
    forget_committed,
    interrupted_text,
)

console = Console()
err_console = Console(stderr=True)


class _UserErrorGroup(TyperGroup):
    """Turn :class:`BrakethermoError` into one red line and its exit code, no traceback.

    The message quotes file names, channel names and units from the user's files, so it
    is printed as text, never as rich markup (a ``[km/h]`` or ``[/b]`` must show as
    written). numpy's floating-point RuntimeWarnings (an all-NaN lap's mean...) are
    internal: the commands report what matters in their own words.
    """

    def invoke(self, ctx: click.Context) -> Any:
        forget_committed()
        try:
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore", RuntimeWarning)
                return super().invoke(ctx)
        except BrakethermoError as exc:
            # The message quotes file names, keys and values: text, never markup.
            err_console.print(f"[bold red]error:[/] {escape(str(exc))}", highlight=False,
                              soft_wrap=True)
            ctx.exit(exc.exit_code)
        except KeyboardInterrupt:
            # The outputs' names are text, not markup.
            err_console.print(f"[bold red]interrupted:[/] "
                              f"{escape(interrupted_text(committed_outputs()))}",
                              highlight=False, soft_wrap=True)
            ctx.exit(EXIT_INTERRUPTED)


app = typer.Typer(
    cls=_UserErrorGroup,
    name="brakethermo",
    help="Carbon brake-disc temperature across the radius, from one IR spot sensor.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    add_completion=False,
)


def _version(value: bool) -> None:
    if value:
        console.print(f"brakethermo {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="Show the version and exit."
    ),
) -> None:
    """Carbon brake-disc temperature across the radius, from one IR spot sensor."""


R = TypeVar("R")


def print_warnings(lines: Iterable[str], *, soft_wrap: bool = False) -> None:
    """One ``warning:`` line per warning, printed as text (they quote file and channel
    names, which must not be read as markup); ``soft_wrap`` leaves each line unwrapped."""
    for warning in lines:
        console.print(f"[yellow]warning:[/] {escape(warning)}", highlight=False,
                      soft_wrap=soft_wrap)


def run_with_status(quiet: bool, message: str, work: Callable[[], R]) -> R:
    """Run ``work()`` behind a rich spinner, or silently when output must stay JSON."""
    if quiet:
        return work()
    with console.status(escape(message)):
        return work()
