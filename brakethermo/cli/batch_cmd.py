"""``brakethermo batch FOLDER --out OUT``: every session of a folder, reports on disk."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich import box
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from brakethermo.cli._app import app, console, print_warnings
from brakethermo.cli._options import (
    SESSION_FORMATS,
    AliasesOpt,
    JsonOpt,
    LegacyReportOpt,
    NodesOpt,
    NoReportsOpt,
)

if TYPE_CHECKING:
    from brakethermo.pipelines.batch import BatchOptions, BatchResult

STATUS_STYLE = {"ok": "green", "skipped": "cyan", "failed": "bold red", "rig session": "cyan"}
SPOTS = ("spot1", "spot2", "spot3", "spot4")


def _law_tag(source: str) -> str:
    """Short h-law tag for the table; the full source is printed under it."""
    from brakethermo.pipelines.batch import DEFAULT_LAW

    if source.startswith("identified:"):
        return "batch"
    return {"identified": "own", "given": "given", DEFAULT_LAW: "default"}.get(source, "-")


def _table(result: BatchResult, out: Path) -> Table:
    from brakethermo.results.laps import temp_text

    table = Table(
        title=f"batch: {len(result.outcomes)} sessions -> {escape(str(out))}",
        title_justify="left",
        box=box.SIMPLE_HEAD,
        show_edge=False,
        pad_edge=False,
        collapse_padding=True,  # room for the session names at 80 columns
    )
    table.add_column("file", overflow="fold", min_width=8)
    table.add_column("kind", min_width=6)
    table.add_column("laps", justify="right", min_width=4)
    table.add_column("status", min_width=7)
    table.add_column("wall s", justify="right")
    for i in range(1, 5):
        table.add_column(f"S{i}", justify="right")
    table.add_column("h law", min_width=7, no_wrap=True)
    for o in result.outcomes:
        peaks = [temp_text(o.peaks[s]) if s in o.peaks else "-" for s in SPOTS]
        table.add_row(
            escape(o.name),
            o.kind or "-",
            str(o.laps) if o.laps else "-",
            f"[{STATUS_STYLE.get(o.status, 'white')}]{o.status}[/]",
            f"{o.wall_s:.1f}" if o.status != "skipped" else "-",
            *peaks,
            escape(_law_tag(o.h_law_source)),
        )
    table.caption = (
        "S1..S4: peak estimated spot temperature, °C. laps: flying laps (out-lap not "
        "counted). h law: own = identified from the session; batch = identified in this "
        "batch for the same disc (reason below); default = shipped for the disc"
    )
    return table


@app.command("batch")
def batch(
    folder: Annotated[
        Path,
        typer.Argument(
            metavar="FOLDER", help=f"Folder searched recursively for sessions ({SESSION_FORMATS})."
        ),
    ],
    out: Annotated[
        Path, typer.Option("--out", "-o", help="Output root; one folder per session.")
    ] = Path("out"),
    h_law: Annotated[
        Path | None,
        typer.Option(
            "--h-law",
            help="h law TOML for race (single-spot) sessions; default: a law identified in "
            "this batch for the same disc (same track/vehicle first, then the newest), "
            "else the law shipped for the disc.",
        ),
    ] = None,
    workers: Annotated[int, typer.Option(min=1, max=256, help="Local worker processes.")] = 1,
    scheduler: Annotated[
        str | None,
        typer.Option(help="Dask scheduler address (tcp://host:8786); also DASK_SCHEDULER_ADDRESS."),
    ] = None,
    force: Annotated[
        bool,
        typer.Option(
            "--force", metavar="", help="Re-process sessions whose outputs are up to date."
        ),
    ] = False,
    nodes: NodesOpt = None,
    aliases: AliasesOpt = None,
    mcap_out: Annotated[
        bool,
        typer.Option(
            "--mcap-out", metavar="", help="Also write OUT/<session>/estimate.mcap for Foxglove."
        ),
    ] = False,
    mdf_out: Annotated[
        bool,
        typer.Option("--mdf-out", metavar="",
                     help="Also write OUT/<session>/estimate.mf4 (ASAM MDF4)."),
    ] = False,
    no_reports: NoReportsOpt = False,
    legacy_report: LegacyReportOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Estimate every session in FOLDER and write per-lap reports; failures are isolated."""
    from brakethermo.pipelines.batch import BatchOptions, run_batch

    options = BatchOptions(
        out=out,
        h_law=h_law,
        nodes=nodes,
        aliases=aliases,
        reports=not no_reports and legacy_report is not False,
        mcap_out=mcap_out,
        mdf_out=mdf_out,
        workers=workers,
        scheduler=scheduler,
        force=force,
    )
    if as_json:
        result = run_batch(folder, options)
        print(json.dumps(result.to_json(), indent=2))
    else:
        result = _run_with_progress(folder, options)
        _render(result, out, options.reports)
    if result.exit_code:
        raise typer.Exit(result.exit_code)


def _render(result: BatchResult, out: Path, reports: bool) -> None:
    """The console's account of a batch: unread files, the table, law reasons, wall time,
    where the reports are and why sessions failed.

    Parameters
    ----------
    result : BatchResult
        The finished batch.
    out : Path
        The output root the sessions were written under.
    reports : bool
        Whether per-lap reports (and so ``OUT/index.html``) were written.
    """
    for note in result.not_read:
        console.print(f"[yellow]not read:[/] {escape(note)}", highlight=False)
    console.print(_table(result, out))
    for o in result.outcomes:
        if o.kind == "single" and o.h_law_reason:
            console.print(f"{escape(o.name)}: h law {escape(_law_tag(o.h_law_source))} — "
                          f"{escape(o.h_law_reason)}")
    # the disc assumed, or a law of another disc, was said only inside summary.json
    print_warnings(f"{o.name}: {w}" for o in result.outcomes for w in o.warnings)
    share = ", ".join(
        f"{k.removesuffix('_s')} {v:.1f} s ({f:.0%})"
        for k, (v, f) in result.step_shares().items()
    )
    console.print(f"wall time {result.wall_s:.1f} s" + (f"  ({share})" if share else ""))
    if reports:
        console.print(f"open [bold]{escape(str(out / 'index.html'))}[/] for the reports")
    for o in result.outcomes:
        if o.status == "rig session":
            console.print(f"[cyan]not a disc session:[/] {escape(str(o.path))}: "
                          f"{escape(o.reason)}", soft_wrap=True)
    for o in result.failed:
        where = "" if str(o.path) in o.reason else f"{o.path}: "
        console.print(f"[bold red]failed:[/] {escape(where + o.reason)}", soft_wrap=True)


def _run_with_progress(folder: Path, options: BatchOptions) -> BatchResult:
    """Run the batch behind two bars: sessions done, and the current session's phase/laps."""
    from brakethermo.pipelines.batch import Phase, SessionOutcome, run_batch

    progress = Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(bar_width=20),
        MofNCompleteColumn(),
        TextColumn("{task.fields[last]}"),
        TimeElapsedColumn(),
        console=console,
    )
    # Drawn once the sessions are found: a bad folder or option is then one line alone.
    files = progress.add_task("sessions", total=None, last="")
    current = progress.add_task("waiting", total=None, last="", visible=False)

    def on_event(kind: str, payload: object) -> None:
        if kind == "start":
            progress.start()
            progress.update(files, total=int(payload))  # type: ignore[call-overload]
            if options.workers > 1 or options.scheduler:
                progress.update(files, last=f"on {options.workers} workers")
            return
        if kind == "phase":
            assert isinstance(payload, Phase)
            total = payload.total or None
            progress.reset(current, total=total, completed=payload.done, visible=True,
                           description=escape(f"{payload.name}: {payload.phase}"),
                           last="laps" if total else "")
            return
        assert isinstance(payload, SessionOutcome)
        progress.update(files, advance=1, last=escape(f"{payload.name}: {payload.status}"))
        progress.update(current, visible=False)

    try:
        return run_batch(folder, options, on_event=on_event)
    finally:  # not started when the folder or an option was refused: nothing to close
        if progress.live.is_started:
            progress.stop()
