"""``brakethermo estimate SESSION``: disc temperature at every radius from one IR spot."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer
from rich.table import Table

from brakethermo.cli._app import app, console, run_with_status
from brakethermo.cli._options import AliasesOpt, AmbientOpt, DiscOpt, JsonOpt, OutDir, TuningOpt
from brakethermo.pipelines.estimate import (
    EstimateOptions,
    EstimateResult,
    disc_of,
    estimate_session,
    write_estimate,
)
from brakethermo.pipelines.outputs import to_json


def _lap_label(lap: int) -> str:
    return "out" if lap == 0 else str(lap)


def _fmt(x: Any, spec: str = ".1f") -> str:
    return "-" if x is None else format(x, spec)


def render_laps(result: EstimateResult) -> None:
    """Per-lap rich table: lap time, peaks per spot, time vs the operating window."""
    run = result.summary["run"]
    lo, hi = result.summary["run"]["window_c"]
    table = Table(
        title=f"{result.stem}: disc temperature per lap, °C ({run['nodes']} nodes x "
        f"{run['layers']} layers, spot {run['measured_spot']} measured, "
        f"{'smoother' if run['smoother'] else 'filter only'})",
        title_justify="left",
        caption=f"time below / in / above the {lo:.0f}-{hi:.0f} °C window, contact-band average",
        caption_justify="left",
    )
    table.add_column("lap", justify="right")
    table.add_column("time", justify="right", no_wrap=True)
    for i in range(1, 5):
        table.add_column(f"pk S{i}", justify="right")
    table.add_column("mean", justify="right")
    table.add_column("window s", justify="right", no_wrap=True)
    for lap in result.summary["laps"]:
        peaks = [lap["peak"].get(f"spot{i}", {}).get("temp_c") for i in range(1, 5)]
        m, s = divmod(lap["lap_time_s"], 60.0)
        table.add_row(
            _lap_label(lap["lap"]), f"{int(m)}:{s:04.1f}", *[_fmt(p, ".0f") for p in peaks],
            _fmt(lap["mean_contact_c"], ".0f"),
            f"{lap['time_below_window_s']:.0f}/{lap['time_in_window_s']:.0f}/"
            f"{lap['time_above_window_s']:.0f}",
        )  # fmt: skip
    console.print(table)


def render_scores(scores: dict[str, Any]) -> None:
    """The paper's Tables 3 and 4 for this session, plus peaks and band coverage."""
    table = Table(
        title=f"accuracy against the measured spots (spot {scores['measured_spot']} is the "
        "filter's input; RMSE °C)",
        title_justify="left",
    )
    table.add_column("method", no_wrap=True)
    for col in ("spot1", "spot2", "spot3", "spot4", "contact", "ratio"):
        table.add_column(col, justify="right")
    ratios = scores["contact_ratio_vs_single_spot"]
    for row in scores["table"]:
        ratio = ratios.get(row["method"])
        table.add_row(
            row["method"], *[_fmt(row[f"spot{i}"]) for i in range(1, 5)],
            _fmt(row["contact_avg"]), "1.00x" if ratio is None else f"{ratio:.2f}x",
        )  # fmt: skip
    console.print(table)
    peak = scores["peak"][f"spot{scores['measured_spot']}"]
    cov = ", ".join(f"{k} {v * 100:.0f} %" for k, v in scores["coverage95"].items())
    console.print(
        f"peak error at spot {scores['measured_spot']}: mean |{_fmt(peak['mean_abs_pct'])}| %"
        f" over {peak['zones']} braking zones, session peak {_fmt(peak['max_peak_pct'], '+.1f')} %"
    )
    console.print(f"95 % band coverage of the unmeasured spots: {cov}")


@app.command("estimate")
def estimate_command(
    session: Annotated[Path, typer.Argument(help="Session file (.mcap, .parquet, .csv).")],
    out: OutDir = Path("out"),
    spot: Annotated[int, typer.Option(min=1, max=4, help="Spot used as measurement.")] = 3,
    h_law: Annotated[
        Path | None, typer.Option("--h-law", help="h_law.toml from identify-h.")
    ] = None,
    nodes: Annotated[int | None, typer.Option(min=10, help="Radial nodes.")] = None,
    layers: Annotated[
        int | None, typer.Option(min=1, max=8, help="Layers over the half thickness.")
    ] = None,
    smoother: Annotated[
        bool | None, typer.Option("--smoother/--no-smoother", help="RTS smoother (offline).")
    ] = None,
    adapt_power: Annotated[
        bool | None,
        typer.Option("--adapt-power/--no-adapt-power", help="Braking-power scale as a state."),
    ] = None,
    disc: DiscOpt = None,
    tuning: TuningOpt = None,
    aliases: AliasesOpt = None,
    ambient: AmbientOpt = None,
    report: Annotated[
        bool, typer.Option("--report/--no-report", help="Write the per-lap HTML/PNG reports.")
    ] = True,
    as_json: JsonOpt = False,
    workers: Annotated[
        int,
        typer.Option(min=1, max=64, help="Threads smoothing windows in parallel (fine meshes)."),
    ] = 1,
) -> None:
    """Estimate the disc temperature at every radius, per lap, with 1-sigma bands."""
    options = EstimateOptions(
        spot=spot, h_law=h_law, disc=disc, tuning=tuning, nodes=nodes, layers=layers,
        smoother=smoother, adapt_power=adapt_power, aliases=aliases, ambient_c=ambient,
        workers=workers,
    )  # fmt: skip
    result = run_with_status(as_json, f"estimating {session.name} ...",
                             lambda: estimate_session(session, options))
    folder = write_estimate(result, out)
    if report:
        from brakethermo.report.lap_report import write_session_report

        write_session_report(result.frame, result.session, folder,
                             node_radii=result.node_radii, disc=disc_of(result))
    if as_json:
        print(to_json({**result.summary, "output": str(folder)}))
        return
    render_laps(result)
    if result.scores:
        render_scores(result.scores)
    for warning in result.summary["run"]["warnings"]:
        console.print(f"[yellow]warning:[/] {warning}")
    console.print(
        f"wrote {folder / 'estimate.parquet'} and summary.json "
        f"({result.timings['total_s']:.2f} s)"
        + (f"; open {folder / 'index.html'} for the per-lap reports" if report else "")
    )
