"""`brakethermo mu-slip`: tyre μ–slip peak of a braking-to-lock rig session."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.table import Table

from brakethermo.cli._app import app, console, print_warnings, run_with_status
from brakethermo.cli._options import AliasesOpt, JsonOpt, OutDir, option_values


@app.command("mu-slip")
def mu_slip_cmd(
    session: Annotated[Path, typer.Argument(help="μ–slip rig session (brake ramp to lock).")],
    out: OutDir = Path("out"),
    radius: Annotated[
        float | None,
        typer.Option("--radius", help="Wheel radius, m (else the session fact wheel_radius_m)."),
    ] = None,
    mu_max: Annotated[
        float, typer.Option("--mu-max", help="High end of the expected peak μ (EKF start).")
    ] = 1.5,
    slip_max: Annotated[
        float, typer.Option("--slip-max", help="High end of the expected peak slip (EKF start).")
    ] = 0.3,
    points: Annotated[
        bool,
        typer.Option("--points", metavar="",
                     help="The file is a (slip, μ) point set, no time ramp: slip_ratio with"
                          " drag_force and normal_force, or with μ (friction_coefficient; a"
                          " CSV of two columns 'slip,mu' will do); every point with"
                          " 0 < slip <= 1."),
    ] = False,
    aliases: AliasesOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Peak μ and slip: Rudd's EKF, batch LM, and the curve family with the best held-out fit."""
    from brakethermo.pipelines.mu_slip import (
        UNITS,
        MuSlipOptions,
        mu_slip,
        result_frame,
        summary,
    )
    from brakethermo.pipelines.output_dir import check_session_output
    from brakethermo.pipelines.outputs import to_json
    from brakethermo.pipelines.rig_outputs import write_rig_outputs
    from brakethermo.report.mu_slip_page import animation_gif, page

    with option_values():
        opts = MuSlipOptions(mu_range=(0.1, mu_max), slip_range=(0.05, slip_max),
                             radius_m=radius, points=points)
    check_session_output(out, session, "mu_slip")  # before the work
    res = run_with_status(as_json, "mu-slip…", lambda: mu_slip(session, opts, aliases=aliases))
    summ = summary(res)
    folder = write_rig_outputs(
        out,
        Path(session).stem,
        "mu_slip",
        result_frame(res),
        summ,
        page(res, summ),
        UNITS,
        attachments={"ekf_animation.gif": animation_gif(res)},
    )
    summ["output"] = str(folder)
    if as_json:
        typer.echo(to_json(summ))
        return
    tab = Table(title=f"mu-slip — {escape(Path(session).name)}")
    for c in ("estimate", "μ peak", "slip peak"):
        tab.add_column(c)
    for key in ("ekf", "lm_one_pass", "lm_converged"):
        tab.add_row(key, f"{summ[key]['mu_peak']:.3f}", f"{summ[key]['slip_peak']:.3f}")
    tab.add_row(
        f"peak ({summ['peak']['model']})",
        f"{summ['peak']['mu']:.3f}",
        f"{summ['peak']['slip']:.3f}",
    )
    console.print(tab)
    console.print(summ["shape_mismatch"]["words"])
    print_warnings(summ["warnings"])
    console.print(f"written: {folder}")
