"""`brakethermo clamp-force`: EMB clamp force from resolver and current, by Kalman fusion."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.table import Table

from brakethermo.cli._app import app, console, print_warnings, run_with_status
from brakethermo.cli._options import AliasesOpt, JsonOpt, OutDir


@app.command("clamp-force")
def clamp_force_cmd(
    session: Annotated[Path, typer.Argument(help="Caliper session to estimate.")],
    train: Annotated[
        Path, typer.Option("--train", help="Session with the clamp-force sensor to train on.")
    ],
    out: OutDir = Path("out"),
    retrain: Annotated[
        Path | None,
        typer.Option("--retrain", help="Short worn-pad session with the sensor to re-train on."),
    ] = None,
    factor_walk: Annotated[
        float,
        typer.Option("--factor-walk", help="Random walk of the adaptive stiffness factor, 1/√s."),
    ] = 0.02,
    aliases: AliasesOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Clamp force without a force sensor: paper's KF, ML fusion, each model, adaptive KF."""
    from brakethermo.pipelines.clamp_force import (
        MAX_FACTOR_WALK,
        UNITS,
        clamp_force,
        result_frame,
        summary,
    )
    from brakethermo.pipelines.output_dir import check_session_output
    from brakethermo.pipelines.outputs import to_json
    from brakethermo.pipelines.rig_outputs import write_rig_outputs
    from brakethermo.report.clamp_force_page import page

    if not (math.isfinite(factor_walk) and 0 < factor_walk <= MAX_FACTOR_WALK):
        raise typer.BadParameter(
            f"--factor-walk {factor_walk:g}: give a random walk in (0, {MAX_FACTOR_WALK:g}]"
            " 1/√s (default 0.02; pads soften over seconds — a larger walk hands the"
            " estimate to the torque balance alone and lets the stiffness factor go negative)")
    check_session_output(out, session, "clamp_force")  # before the work
    res = run_with_status(
        as_json,
        "clamp-force…",
        lambda: clamp_force(
            session, train, retrain_path=retrain, factor_walk=factor_walk, aliases=aliases
        ),
    )
    summ = summary(res)
    folder = write_rig_outputs(
        out, Path(session).stem, "clamp_force", result_frame(res), summ, page(res, summ), UNITS
    )
    summ["output"] = str(folder)
    if as_json:
        typer.echo(to_json(summ))
        return
    tab = Table(title=f"clamp-force — {escape(Path(session).name)}")
    tab.add_column("estimator")
    tab.add_column("RMSE (kN)", justify="right")
    tab.add_column("peak, held 5 ms (kN)", justify="right")
    tab.add_column("mean applied (kN)", justify="right")
    est = summ["estimate_kn"]
    rmses = {**summ["rmse_kn"], "kf_paper": summ["rmse_kn_kf_paper"],
             "kf_adaptive": summ["rmse_kn_adaptive"]}
    for k, v in rmses.items():
        m = est[k]["mean_applied"]
        tab.add_row(k, "–" if v is None else f"{v:.3f}", f"{est[k]['peak']:.2f}",
                    "–" if m is None else f"{m:.2f}")
    console.print(tab)
    # The band of the reported estimate: the KF's, or the fallback's held-out RMSE.
    label = "KF" if summ.get("kf_source", "kf") == "kf" else "reported"
    console.print(f"{label} 95 % band: ± {est['kf_band95_median']:.2f} kN (median over the"
                  f" session); kf is {summ['kf_noise'].split(':')[0]} (why: summary.json"
                  " kf_noise, the page)", highlight=False)
    if summ["sensor_lag"]["text"]:
        console.print(summ["sensor_lag"]["text"], highlight=False)
    if all(v is None for v in rmses.values()):
        console.print("RMSE –: this session has no usable clamp-force sensor to score against"
                      " (the estimates do not need it)", highlight=False)
    print_warnings(summ["warnings"])
    if "wear" in summ:
        console.print(f"estimates of the models re-trained on {escape(Path(retrain).name)}"
                      " (the training session's models' beside them on the page)")
    console.print(f"written: {folder}")
