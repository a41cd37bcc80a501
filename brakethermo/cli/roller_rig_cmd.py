"""``brakethermo roller-rig SESSION``: rolling radius of a tram wheel on the roller rig."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.table import Table

from brakethermo.cli._app import app, console, print_warnings, run_with_status
from brakethermo.cli._options import SESSION_FORMATS, AliasesOpt, JsonOpt, OutDir, option_values
from brakethermo.pipelines.tuning import ROLLER_RIG_TUNINGS

if TYPE_CHECKING:
    from brakethermo.pipelines.roller_rig import RollerRigResult


def _fmt(x: float | None, spec: str = ".2f") -> str:
    return "-" if x is None else format(x, spec)


def render(result: RollerRigResult, folder: Path) -> None:
    """Per-guess table (the paper's Table 1 for this session) and the naive comparison."""
    s = result.summary
    ref = s["reference_radius_mm"]
    table = Table(
        title=f"{result.stem}: rolling radius, mm (reference {_fmt(ref)}; "
        f"{'smoother' if result.options.smoother else 'filter only'}, tuning "
        f"{s['filter']['tuning']})",
        title_justify="left",
    )
    for col in ("r0", "radius", "1σ", "converged s", "filter RMSE", "RMSE", "RMSE %"):
        table.add_column(col, justify="right")
    for r in s["runs"]:
        table.add_row(
            f"{r['r0_mm']:g}", f"{r['radius_mm']:.3f}", f"{r['radius_std_mm']:.3f}",
            "restarted" if r["restarted"] else _fmt(r["convergence_time_s"]),
            _fmt(r["filter_rmse_vs_ref_mm"], ".3f"),
            _fmt(r["rmse_vs_ref_mm"], ".3f"), _fmt(r["rmse_vs_ref_pct"], ".3f"),
        )  # fmt: skip
    console.print(table)
    for r in s["runs"]:
        if r["restarted"]:
            console.print(f"[yellow]r0 {r['r0_mm']:g} mm:[/] {r['restarted']}", highlight=False)
    c = s["naive_vs_ukf"]
    line = (
        f"naive ω_r·R_r/ω_w: {_fmt(c['naive_free_mm'], '.3f')} mm free rolling, "
        f"{_fmt(c['naive_traction_mm'], '.3f')} mm under traction; UKF under traction "
        f"{_fmt(c['ukf_traction_mm'], '.3f')} mm"
    )
    console.print(line, highlight=False)
    carried = s["filter"]["with_effect"]
    if carried is not None:
        from brakethermo.results.rig_diagnosis import carried_text

        console.print(f"creep law carries: {carried_text(carried)}", highlight=False)
    print_warnings(s["warnings"])
    console.print(f"wrote {folder}", highlight=False)


@app.command("roller-rig")
def roller_rig_cmd(
    session: Annotated[Path, typer.Argument(help=f"Roller-rig session ({SESSION_FORMATS}).")],
    out: OutDir = Path("out"),
    r0: Annotated[
        list[float] | None,
        typer.Option("--r0", help="Starting guess of the radius, mm; repeat for several."),
    ] = None,
    smoother: Annotated[
        bool, typer.Option("--smoother/--filter-only", help="Unscented RTS smoother (offline).")
    ] = True,
    tuning: Annotated[
        str,
        typer.Option(help=f"Filter noise: {' or '.join(ROLLER_RIG_TUNINGS)} (the paper's P0/Q/R)."),
    ] = "measured",
    creep: Annotated[
        str, typer.Option(help="Creep law: polach, or fastsim (Kalker, 20 x 20, slower).")
    ] = "polach",
    rig: Annotated[str, typer.Option(help="Rig datasheet id or TOML file.")] = "roller-rig",
    with_effect: Annotated[
        str,
        typer.Option(help="Creep-curve effects carried from a diagnosis: 'none' (the"
                          " datasheet's law), 'auto' (diagnose this session first: needs"
                          " roller_torque), a diagnosis.json of a roller-rig session, or"
                          " NAME=VALUE pairs (creep_slope, friction_level, creepage_offset)."),
    ] = "none",
    supply_hz: Annotated[
        float | None, typer.Option(help="Roller-motor supply, Hz (else the session's fact).")
    ] = None,
    aliases: AliasesOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Rolling radius of the tram wheel by joint UKF from every starting guess."""
    from brakethermo.pipelines.output_dir import check_session_output
    from brakethermo.pipelines.outputs import to_json
    from brakethermo.pipelines.roller_rig import RollerRigOptions, run_roller_rig, write_roller_rig

    with option_values():
        options = RollerRigOptions(
            r0_mm=tuple(r0) if r0 else RollerRigOptions().r0_mm,
            smoother=smoother,
            rig=rig,
            supply_hz=supply_hz,
            aliases=aliases,
            tuning=tuning,
            creep_law=creep,
            with_effect=with_effect,
        ).validated()
    check_session_output(out, session, "roller_rig")  # before the work
    result = run_with_status(as_json, "estimating the rolling radius…",
                             lambda: run_roller_rig(session, options))  # fmt: skip
    folder = write_roller_rig(result, out)
    if as_json:
        typer.echo(to_json(result.summary))
        return
    render(result, folder)
