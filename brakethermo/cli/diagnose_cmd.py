"""``brakethermo diagnose SESSION``: the sim-to-real gap, its cause and how far it shrinks."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from brakethermo.cli._app import app, console
from brakethermo.cli._options import AliasesOpt, AmbientOpt, DiscOpt, JsonOpt, OutDir, TuningOpt
from brakethermo.errors import ConfigError
from brakethermo.models.effects import EFFECT_NAMES


def _laps(text: str | None) -> tuple[int, ...] | None:
    if not text:
        return None
    try:
        return tuple(int(v) for v in text.replace(" ", "").split(",") if v)
    except ValueError:
        raise ConfigError(f"--holdout-laps {text!r}: give lap numbers like 2,4,6") from None


@app.command("diagnose")
def diagnose_command(
    session: Annotated[Path, typer.Argument(help="Four-spot test session file.")],
    out: OutDir = Path("out"),
    effects: Annotated[
        str, typer.Option(help=f"'all' or a comma-separated list of: {', '.join(EFFECT_NAMES)}.")
    ] = "all",
    holdout_laps: Annotated[
        str | None,
        typer.Option(help="Laps to hold out, e.g. 2,4 (default: every other flying lap)."),
    ] = None,
    h_law: Annotated[
        Path | None, typer.Option(help="h_law.toml to start the reference fit from.")
    ] = None,
    disc: DiscOpt = None,
    tuning: TuningOpt = None,
    aliases: AliasesOpt = None,
    ambient: AmbientOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Where the model parts from the disc, which effect causes it, how far the gap shrinks."""
    from brakethermo.pipelines.diagnose import DiagnoseOptions, diagnose, write_diagnosis
    from brakethermo.pipelines.outputs import to_json

    options = DiagnoseOptions(effects=effects, holdout_laps=_laps(holdout_laps), h_law=h_law,
                              disc=disc, tuning=tuning, aliases=aliases, ambient_c=ambient)
    if as_json:
        result = diagnose(session, options)
    else:
        with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/"
                      "{task.total}"), TimeElapsedColumn(), console=console) as bar:
            task = bar.add_task(f"diagnosing {escape(session.name)}", total=None)

            def progress(label: str, done: int, total: int) -> None:
                bar.update(task, completed=done, total=total,
                           description=f"diagnosing {escape(session.name)}: {escape(label)}")

            result = diagnose(session, options, progress)
    folder = write_diagnosis(result, out)
    s = result.summary
    if as_json:
        print(to_json({**s, "output": str(folder)}))
        return
    console.print(f"[bold]{escape(result.stem)}[/]: reference model held-out RMSE "
                  f"{s['gap']['rmse_c']:.1f} °C (train laps {s['train_laps']}, held-out "
                  f"{s['heldout_laps']})")
    console.print(escape(s["consistency"]["summary"]))
    table = Table(title="Effects ranked by held-out shrink", title_justify="left")
    for col in ("effect", "before °C", "after °C", "shrink %", "95 % interval"):
        table.add_column(col, justify="left" if col == "effect" else "right", no_wrap=True)
    for e in s["effects"]:
        lo, hi = e["shrink_ci95_pct"]
        table.add_row(e["name"], f"{e['rmse_before']:.1f}", f"{e['rmse_after']:.1f}",
                      f"{e['shrink_pct']:+.1f}", f"{lo:+.0f} … {hi:+.0f}")
    console.print(table)
    for e in s["effects"][:3]:
        console.print(f"  {e['name']}: {escape(e['evidence'])}", highlight=False)
    for e in s.get("not_identifiable_from_one_spot", []):
        console.print(f"  {e['name']}: not diagnosed here — {escape(e['reason'])}",
                      highlight=False)
    console.print(f"verdict: [bold]{s['verdict']}[/]; combined model: "
                  f"{' + '.join(s['combined']['effects']) or 'none'}")
    for w in s["warnings"]:
        console.print(f"[yellow]warning:[/] {escape(w)}")
    console.print(f"wrote {escape(str(folder / 'diagnosis.json'))} and "
                  f"{escape(str(folder / 'diagnosis' / 'index.html'))} "
                  f"({s['run']['wall_time_s']:.1f} s)")
