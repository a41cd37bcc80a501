"""``brakethermo batch FOLDER --out OUT``: every session of a folder, reports on disk."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich import box
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from brakethermo.cli._app import app, console
from brakethermo.cli._options import AliasesOpt, JsonOpt
from brakethermo.pipelines.batch import (
    DEFAULT_LAW,
    SESSION_SUFFIXES,
    BatchOptions,
    BatchResult,
    SessionOutcome,
    run_batch,
)

STATUS_STYLE = {"ok": "green", "skipped": "cyan", "failed": "bold red"}
SPOTS = ("spot1", "spot2", "spot3", "spot4")


def _law_tag(source: str) -> str:
    """Short h-law tag for the table; the full source is printed under it."""
    if source.startswith("identified:"):
        return "batch"
    return {"identified": "own", "given": "given", DEFAULT_LAW: "default"}.get(source, "-")


def _table(result: BatchResult, out: Path) -> Table:
    table = Table(
        title=escape(f"batch: {len(result.outcomes)} sessions -> {out}"),
        title_justify="left",
        box=box.SIMPLE_HEAD,
        show_edge=False,
        pad_edge=False,
    )
    table.add_column("file", overflow="fold", min_width=12)
    table.add_column("kind", min_width=6)
    table.add_column("laps", justify="right", min_width=4)
    table.add_column("status", min_width=7)
    table.add_column("wall s", justify="right")
    for i in range(1, 5):
        table.add_column(f"S{i}", justify="right")
    table.add_column("h law")
    for o in result.outcomes:
        peaks = [f"{o.peaks[s]:.0f}" if s in o.peaks else "-" for s in SPOTS]
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
        "S1..S4: peak estimated spot temperature, °C. h law: own = identified from the "
        "session; batch = the most recent identified in this batch; default = shipped law"
    )
    return table


@app.command("batch")
def batch(
    folder: Annotated[
        Path,
        typer.Argument(
            metavar="FOLDER", help="Folder searched recursively for .mcap, .parquet, .csv sessions."
        ),
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output root; one folder per session.")],
    h_law: Annotated[
        Path | None,
        typer.Option(
            "--h-law",
            help="h law TOML for race (single-spot) sessions; default: the most recent "
            "law identified in this batch, else the shipped default.",
        ),
    ] = None,
    workers: Annotated[int, typer.Option(min=1, help="Local worker processes.")] = 1,
    scheduler: Annotated[
        str | None,
        typer.Option(help="Dask scheduler address (tcp://host:8786); also DASK_SCHEDULER_ADDRESS."),
    ] = None,
    force: Annotated[
        bool, typer.Option("--force", help="Re-process sessions whose outputs are up to date.")
    ] = False,
    nodes: Annotated[int | None, typer.Option(min=10, help="Radial nodes.")] = None,
    aliases: AliasesOpt = None,
    mcap_out: Annotated[
        bool,
        typer.Option("--mcap-out", help="Also write OUT/<session>/estimate.mcap for Foxglove."),
    ] = False,
    mdf_out: Annotated[
        bool,
        typer.Option("--mdf-out", help="Also write OUT/<session>/estimate.mf4 (ASAM MDF4)."),
    ] = False,
    no_reports: Annotated[
        bool, typer.Option("--no-reports", help="Skip the per-lap HTML reports.")
    ] = False,
    as_json: JsonOpt = False,
) -> None:
    """Estimate every session in FOLDER and write per-lap reports; failures are isolated."""
    options = BatchOptions(
        out=out,
        h_law=h_law,
        nodes=nodes,
        aliases=aliases,
        reports=not no_reports,
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
        progress = Progress(
            TextColumn("[bold]{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[last]}"),
            TimeElapsedColumn(),
            console=console,
        )
        with progress:
            files = progress.add_task("sessions", total=None, last="")
            laps = progress.add_task("laps", total=None, last="")

            def on_event(kind: str, payload: SessionOutcome | int) -> None:
                if kind == "start":
                    progress.update(files, total=int(payload))  # type: ignore[arg-type]
                    return
                assert isinstance(payload, SessionOutcome)
                progress.update(files, advance=1, last=escape(f"{payload.name}: {payload.status}"))
                task = progress.tasks[laps]
                progress.update(laps, total=(task.total or 0) + payload.laps, advance=payload.laps)

            result = run_batch(folder, options, on_event=on_event)
        if not result.outcomes:
            console.print(f"[yellow]no session files ({', '.join(SESSION_SUFFIXES)}) under"
                          f" {escape(str(folder))}[/]")
            return
        console.print(_table(result, out))
        sources = {o.h_law_source for o in result.outcomes if o.kind == "single"}
        for source in sorted(sources - {""}):
            console.print(f"race sessions estimated with h law: {escape(str(source))}")
        share = ", ".join(
            f"{k.removesuffix('_s')} {v:.1f} s ({f:.0%})"
            for k, (v, f) in result.step_shares().items()
        )
        console.print(f"wall time {result.wall_s:.1f} s" + (f"  ({share})" if share else ""))
        if options.reports:
            console.print(f"open [bold]{escape(str(out / 'index.html'))}[/] for the reports")
        for o in result.failed:
            where = "" if str(o.path) in o.reason else f"{o.path}: "
            console.print(f"[bold red]failed:[/] {escape(f'{where}{o.reason}')}", soft_wrap=True)
    if result.exit_code:
        raise typer.Exit(result.exit_code)
