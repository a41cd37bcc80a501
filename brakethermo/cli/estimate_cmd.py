"""``brakethermo estimate SESSION``: disc temperature at every radius from one IR spot."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich import box
from rich.markup import escape
from rich.table import Table

from brakethermo.cli._app import app, console, print_warnings, run_with_status
from brakethermo.cli._options import (
    SESSION_FORMATS,
    AliasesOpt,
    AmbientOpt,
    DiscOpt,
    JsonOpt,
    LayersOpt,
    LegacyReportOpt,
    NodesOpt,
    NoReportsOpt,
    OutDir,
    TuningOpt,
)

if TYPE_CHECKING:
    from brakethermo.pipelines.estimate import EstimateResult


def _fmt(x: Any, spec: str = ".1f") -> str:
    return "-" if x is None else format(x, spec)


def render_laps(result: EstimateResult) -> None:
    """Per-lap rich table: lap time, peaks per spot, hottest radius, time vs the window.

    Sized for 80 columns (CI logs, pipes): short headers, no wrapping inside cells.
    """
    from brakethermo.results.laps import lap_label, lap_time_text, temp_text

    run = result.summary["run"]
    lo, hi = run["window_c"]
    table = Table(
        title=f"{escape(result.stem)}: disc °C per lap ({run['nodes']}x{run['layers']} nodes, "
        f"spot {run['measured_spot']} measured, "
        f"{'smoother' if run['smoother'] else 'filter only'})",
        title_justify="left",
        caption=f"peaks °C; hot = hottest radius °C @ mm; window {lo:.0f}-{hi:.0f} °C: "
        "contact band s below/in/above, hottest radius s above",
        caption_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    table.add_column("lap", justify="right", no_wrap=True)
    table.add_column("time", justify="right", no_wrap=True)
    for i in range(1, 5):
        table.add_column(f"S{i}", justify="right", no_wrap=True)
    table.add_column("hot @mm", justify="right", no_wrap=True)
    table.add_column("contact", justify="right", no_wrap=True)
    table.add_column("hot>", justify="right", no_wrap=True)
    for lap in result.summary["laps"]:
        peaks = [lap["peak"].get(f"spot{i}", {}).get("temp_c") for i in range(1, 5)]
        hot = lap.get("hottest") or {}
        radius = hot.get("radius_mm")
        hot_text = temp_text(hot.get("temp_c")) + (f"@{radius:.0f}" if radius is not None else "")
        above_hot = hot.get("time_above_window_s", 0.0)
        table.add_row(
            lap_label(lap["lap"]),
            lap_time_text(lap["lap_time_s"]) + (" partial" if lap.get("partial") else ""),
            *[temp_text(p) for p in peaks],
            f"[bold red]{hot_text}[/]" if above_hot > 0 else hot_text,
            f"{lap['time_below_window_s']:.0f}/{lap['time_in_window_s']:.0f}/"
            f"{lap['time_above_window_s']:.0f}",
            f"[bold red]{above_hot:.0f}[/]" if above_hot > 0 else f"{above_hot:.0f}",
        )  # fmt: skip
    console.print(table)


def render_scores(scores: dict[str, Any]) -> None:
    """The paper's Tables 3 and 4 for this session, plus peaks and band coverage."""
    table = Table(
        title=f"accuracy against the measured spots (spot {scores['measured_spot']} is the "
        "filter's input; RMSE °C)"
        + (" — IN SAMPLE: the h law was identified on this session" if scores.get("in_sample")
           else ""),
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
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
    spot = scores["measured_spot"]
    peaks = ", ".join(
        f"{k}{' (input)' if k == f'spot{spot}' else ''} |{_fmt(p['mean_abs_pct'])}| %"
        for k, p in scores["peak"].items())
    some = scores["peak"][f"spot{spot}"]
    console.print(f"peak error per braking zone, mean over {some['zones']} of"
                  f" {some.get('zones_total', some['zones'])} zones: {peaks}")
    cov = ", ".join(f"{k} {v * 100:.0f} %" for k, v in scores["coverage95"].items())
    written = ", ".join(f"{k} {v * 100:.0f} %"
                        for k, v in scores.get("coverage95_written_band", {}).items())
    console.print(f"95 % coverage of the spots the filter does not read: {cov} by the"
                  " filter's own spread" + (
                      f"; {written} by the band estimate.parquet carries (+ the pyrometer's"
                      " calibration, which these readings share, and the pads' crown"
                      " balance)" if written else ""))


def _write_outputs(result: EstimateResult, out: Path, mdf_out: bool, reports: bool,
                   mcap_out: bool = False) -> Path:
    """The estimate's folder, swapped in whole: parquet, summary, MDF / MCAP, lap pages,
    links."""
    from brakethermo.pipelines.estimate import disc_of, write_estimate
    from brakethermo.pipelines.output_dir import refresh_indexes, replace_session_dir

    folder = out / result.stem
    with replace_session_dir(folder) as stage:
        write_estimate(result, out, folder=stage)
        if mdf_out:
            from brakethermo.report.mdf_export import write_estimate_mdf

            write_estimate_mdf(result.frame, stage / "estimate.mf4",
                               node_radii=result.node_radii, spot_radii=result.disc.spot_radii,
                               start_epoch_s=result.session.start_epoch_s,
                               source=result.session.path.name,
                               date=result.session.metadata.get("date"))
        if mcap_out:
            from brakethermo.report.mcap_export import write_estimate_mcap

            write_estimate_mcap(result.frame, stage / "estimate.mcap",
                                node_radii=result.node_radii,
                                spot_radii=result.disc.spot_radii,
                                start_epoch_s=result.session.start_epoch_s,
                                source=result.session.path.name)
        if reports:
            from brakethermo.report.index import is_batch_index
            from brakethermo.report.lap_report import write_session_report

            # Beside a batch's sessions the page keeps the batch index's back link.
            up = "../index.html" if is_batch_index(Path(out) / "index.html") else None
            write_session_report(result.frame, result.session, stage,
                                 node_radii=result.node_radii, disc=disc_of(result),
                                 summary=result.summary, back_href=up)
    refresh_indexes(folder)
    return folder


def _render(result: EstimateResult, folder: Path, law_reason: str, mdf_out: bool,
            reports: bool) -> None:
    """The console's lap table, scores, law, warnings and what was written."""
    run = result.summary["run"]
    render_laps(result)
    if result.scores:
        render_scores(result.scores)
    console.print(f"h law: {escape(str(run['h_law']))} ({law_reason})", soft_wrap=True)
    print_warnings(run["warnings"], soft_wrap=True)
    console.print(
        f"wrote {escape(str(folder / 'estimate.parquet'))}"
        f"{', estimate.mf4' if mdf_out else ''} and summary.json "
        f"({result.timings['total_s']:.2f} s)"
        + (f"; open {escape(str(folder / 'index.html'))} for the per-lap reports"
           if reports else ""),
        soft_wrap=True,
    )


MdfOutOpt = Annotated[bool, typer.Option(
    "--mdf-out", help="Also write OUT/<session>/estimate.mf4 (ASAM MDF4, for WinTAX / ATLAS /"
    " asammdf beside the source log).")]
McapOutOpt = Annotated[bool, typer.Option(
    "--mcap-out", help="Also write OUT/<session>/estimate.mcap (MCAP, for Foxglove beside the"
    " source log; as batch --mcap-out).")]
EstimateHLawOpt = Annotated[Path | None, typer.Option(
    "--h-law", help="h_law.toml from identify-h; default: the one identify-h wrote for this "
    "session in --out, else the law shipped for the disc.")]
ModesOpt = Annotated[int | None, typer.Option(
    "--modes", min=0, max=40, help="Reduced-order filter on at most this many thermal modes; "
    "0 = the full filter. Default: reduced above 24 temperature states (the default 10 x 4 "
    "mesh and any finer one: a fine mesh at the cost of a coarse one), full below.")]


def _state_flag(name: str, help_text: str) -> Any:
    """An ``--adapt-NAME/--no-adapt-NAME`` option: unset lets the race (or the tuning) say."""
    return Annotated[bool | None, typer.Option(f"--adapt-{name}/--no-adapt-{name}",
                                               help=help_text)]


AdaptPowerOpt = _state_flag("power", "Braking-power scale as a state.")
AdaptKzOpt = _state_flag("kz", "Through-thickness conductivity factor as a state (a race "
                         "disc that differs from the test session's).")
AdaptSlipstreamOpt = _state_flag("slipstream", "An off-brake h factor as a state "
                                 "(slipstream, traffic).")
AdaptBalanceOpt = _state_flag("balance", "The inner/outer pad-pressure balance as a state "
                              "(pads that press unlike the test session's).")
RaceDecidesOpt = Annotated[
    bool,
    typer.Option("--race-decides/--law-as-written",
                 help="The race's own laps decide its online states and which of the h "
                 "law's test-session effects hold for it (μ(T) only where the race earns "
                 "it); --law-as-written uses the law unchanged and the --adapt-* flags as "
                 "given."),
]


@app.command("estimate")
def estimate_command(
    session: Annotated[Path, typer.Argument(help=f"Session file ({SESSION_FORMATS}).")],
    out: OutDir = Path("out"),
    spot: Annotated[int, typer.Option(min=1, max=4, help="Spot used as measurement.")] = 3,
    h_law: EstimateHLawOpt = None,
    nodes: NodesOpt = None,
    layers: LayersOpt = None,
    smoother: Annotated[
        bool | None, typer.Option("--smoother/--no-smoother", help="RTS smoother (offline).")
    ] = None,
    adapt_power: AdaptPowerOpt = None,
    adapt_kz: AdaptKzOpt = None,
    adapt_slipstream: AdaptSlipstreamOpt = None,
    adapt_balance: AdaptBalanceOpt = None,
    race_decides: RaceDecidesOpt = True,
    disc: DiscOpt = None,
    tuning: TuningOpt = None,
    aliases: AliasesOpt = None,
    ambient: AmbientOpt = None,
    no_reports: NoReportsOpt = False,
    legacy_report: LegacyReportOpt = None,
    mdf_out: MdfOutOpt = False,
    mcap_out: McapOutOpt = False,
    as_json: JsonOpt = False,
    workers: Annotated[
        int,
        typer.Option(min=1, max=64, help="Threads smoothing windows in parallel (fine meshes)."),
    ] = 1,
    modes: ModesOpt = None,
) -> None:
    """Estimate the disc temperature at every radius, per lap, with 1-sigma bands."""
    from brakethermo.pipelines.estimate import (
        EstimateOptions,
        estimate_from_session,
    )
    from brakethermo.pipelines.inputs import load_timed
    from brakethermo.pipelines.models import (
        SHIPPED_DEFAULT,
        SHIPPED_LAW_NOTE,
        choose_h_law,
        disc_for,
    )
    from brakethermo.pipelines.output_dir import check_session_folder
    from brakethermo.pipelines.outputs import to_json
    from brakethermo.pipelines.preflight import preflight

    reports = not no_reports and legacy_report is not False
    preflight(out=out, tuning=tuning, h_law=h_law, aliases=aliases, disc=disc)
    check_session_folder(out, session, "estimate")
    loaded, read_s = run_with_status(as_json, f"reading {session.name} ...",
                                     lambda: load_timed(session, aliases))
    law, law_reason = choose_h_law(h_law, out / session.stem, loaded, disc_for(loaded, disc))
    options = EstimateOptions(
        spot=spot, h_law=law, disc=disc, tuning=tuning, nodes=nodes, layers=layers,
        smoother=smoother, adapt_power=adapt_power, adapt_kz=adapt_kz,
        adapt_slipstream=adapt_slipstream, adapt_balance=adapt_balance, aliases=aliases,
        ambient_c=ambient, workers=workers, modes=modes, online_auto=race_decides,
    )  # fmt: skip
    result = run_with_status(as_json, f"estimating {session.name} ...",
                             lambda: estimate_from_session(loaded, options))
    run = result.summary["run"]
    result.timings["read_s"] = read_s
    run["timings_s"]["read_s"] = read_s
    run["wall_time_s"] += read_s
    run["h_law_choice"] = law_reason
    if law_reason.startswith(SHIPPED_DEFAULT):
        run["warnings"].append(f"no h law of this bike: {SHIPPED_LAW_NOTE}")
    folder = _write_outputs(result, out, mdf_out, reports, mcap_out)
    if as_json:
        print(to_json({**result.summary, "output": str(folder)}))
        return
    _render(result, folder, law_reason, mdf_out, reports)
