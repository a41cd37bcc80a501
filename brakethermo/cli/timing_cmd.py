"""``brakethermo timing-check SESSION``: per-lap estimate wall time against the race budget."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.markup import escape
from rich.table import Table

from brakethermo.cli._app import app, console
from brakethermo.cli._options import AliasesOpt, JsonOpt, NodesOpt, positive_finite
from brakethermo.errors import BrakethermoError

if TYPE_CHECKING:
    from brakethermo.pipelines.timing import TimingReport


def _table(report: TimingReport, name: str) -> Table:
    from brakethermo.results.laps import lap_label

    table = Table(
        title=f"{escape(name)}: estimate wall time per lap "
        f"(budget {report.budget_per_lap_s:.1f} s/lap)",
        title_justify="left",
    )
    for col in ("lap", "data s", "wall s", "share of budget"):
        table.add_column(col, justify="right")
    for t in report.laps:
        share = t.wall_s / report.budget_per_lap_s
        style = "bold red" if share > 1 else ("yellow" if share > 0.5 else "green")
        table.add_row(
            lap_label(t.lap), f"{t.data_s:.1f}", f"{t.wall_s:.3f}", f"[{style}]{share:.1%}[/]"
        )
    return table


@app.command("timing-check")
def timing_check(
    session_path: Annotated[Path, typer.Argument(metavar="SESSION", help="Session file.")],
    budget_s: Annotated[
        float, typer.Option(callback=positive_finite, help="Budget for a whole race, s (> 0).")
    ] = 300.0,
    race_laps: Annotated[int, typer.Option(min=1, max=1000, help="Laps in that race.")] = 25,
    h_law: Annotated[Path | None, typer.Option("--h-law", help="h law TOML.")] = None,
    nodes: NodesOpt = None,
    aliases: AliasesOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Estimate each lap on its own; fail (exit 1) if the slowest lap exceeds its budget.

    The paper's budget check: each lap as the filter would meet it live. A whole-race
    `estimate` costs more than the sum — the race's online decision on its first laps
    (one lap alone has nothing to decide on) and the reports (README, Speed).
    """
    from brakethermo.io.load import load_session
    from brakethermo.pipelines.estimate import EstimateOptions, estimate_from_session
    from brakethermo.pipelines.preflight import preflight
    from brakethermo.pipelines.timing import time_laps
    from brakethermo.results.laps import lap_name

    preflight(h_law=h_law, aliases=aliases)
    session = load_session(session_path, aliases=aliases)
    options = EstimateOptions(h_law=h_law, nodes=nodes, aliases=aliases, score=False)
    report = time_laps(session, lambda s: estimate_from_session(s, options), budget_s, race_laps)
    if as_json:
        print(json.dumps(report.to_json(), indent=2))
    else:
        console.print(_table(report, session_path.name))
        console.print(
            f"start-up {report.startup_s:.2f} s, total {report.total_s:.2f} s for "
            f"{len(report.laps)} laps, each estimated alone (a whole-race estimate adds the"
            " race's online decision on its first laps and the reports)", highlight=False
        )
    if not report.passed:
        worst = report.worst
        raise BrakethermoError(
            f"{lap_name(worst.lap)} took {worst.wall_s:.2f} s to estimate, over the budget of "
            f"{report.budget_per_lap_s:.2f} s/lap ({budget_s:g} s for {race_laps} laps);"
            " use fewer --nodes or profile the filter",
            path=session_path,
        )
    if not as_json:
        console.print(
            f"[green]ok:[/] worst: {lap_name(report.worst.lap)} {report.worst.wall_s:.2f} s "
            f"<= {report.budget_per_lap_s:.2f} s/lap"
        )
