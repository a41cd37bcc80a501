"""``brakethermo ebooster SESSION``: full-state UKF vs EKF observation of an E-Booster.

Bench sessions come from ``brakethermo simulate --rig ebooster --set scenario=...``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer
from rich.table import Table

from brakethermo.cli._app import app, console, print_warnings, run_with_status
from brakethermo.cli._options import AliasesOpt, JsonOpt, OutDir


@app.command("ebooster")
def ebooster_command(
    session: Annotated[Path, typer.Argument(help="Booster session (s2 and delta).")],
    train: Annotated[
        Path | None,
        typer.Option("--train", help="Training session (constant screw speed up and down, "
                     "with master-cylinder pressure and pedal force)."),
    ] = None,
    fit: Annotated[
        Path | None,
        typer.Option("--fit", help="Training result TOML (from --save-fit); default: shipped."),
    ] = None,
    save_fit: Annotated[
        Path | None, typer.Option("--save-fit", help="Write the training result here.")
    ] = None,
    bench: Annotated[str, typer.Option("--bench", help="Bench datasheet id or TOML.")] = (
        "ebooster"
    ),
    smooth: Annotated[
        bool, typer.Option("--smooth/--no-smooth", help="RTS smoothing after each filter.")
    ] = True,
    with_effect: Annotated[
        str | None,
        typer.Option(help="p-V departure carried from a diagnosis: 'none', 'auto' (diagnose"
                          " this session first: needs the pressure sensor), a diagnosis.json"
                          " of a booster session of the day (any effect it names,"
                          " pv_drift included), or NAME=VALUE (pv_shift, pv_scale,"
                          " rate_dependent, hysteresis).  [default: auto where the session"
                          " logs the master-cylinder pressure, else none]",
                     show_default=False),
    ] = None,
    out: OutDir = Path("out"),
    aliases: AliasesOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Observe p_m, p_f, p_r and the reaction-disk state with a UKF and an EKF (paper 004)."""
    import pandas as pd

    from brakethermo.pipelines.ebooster import frame_columns, observe
    from brakethermo.pipelines.outputs import to_json
    from brakethermo.pipelines.rig_outputs import write_rig_outputs
    from brakethermo.report.ebooster import booster_page

    if save_fit is not None:  # before the run, not after it
        from brakethermo.pipelines.output_dir import check_output_file

        check_output_file(save_fit, "--save-fit")
    from brakethermo.pipelines.output_dir import check_session_output

    check_session_output(out, session, "ebooster")  # before the work
    result = run_with_status(
        as_json, f"observing {session.name} ...",
        lambda: observe(session, train_path=train, fit_path=fit, bench=bench, aliases=aliases,
                        smooth=smooth, with_effect=with_effect),
    )
    if save_fit is not None:
        from brakethermo.io.atomic import write_text_atomic

        write_text_atomic(save_fit, result.fit.toml_text())
    cols, units = frame_columns(result)
    folder = write_rig_outputs(out, result.session.path.stem, "ebooster", pd.DataFrame(cols),
                               result.summary, booster_page(result), units)
    s = result.summary
    if as_json:
        print(to_json({**s, "output": str(folder)}))
        return
    console.print(_observers_table(result.session.path.name, s))
    if s["improvement_pct"] is not None:
        console.print(f"UKF improvement over EKF (residual RMSE): {s['improvement_pct']:.1f} %")
    if s["with_effect"] is not None:
        from brakethermo.results.rig_diagnosis import carried_text

        console.print(f"p-V carries: {carried_text(s['with_effect'])}", highlight=False)
    print_warnings(s["warnings"])
    console.print(f"wrote {folder}")


def _observers_table(name: str, s: dict[str, Any]) -> Table:
    """UKF against EKF: residual and pressure RMSE, 95 % coverage (all and while braking).

    Parameters
    ----------
    name : str
        The session file's name, for the title.
    s : dict
        The observation's summary.
    """
    from brakethermo.pipelines.ebooster import OBSERVERS, PRESSURES

    tab = Table(title=f"{name}: UKF vs EKF (paper 004 Table 1)", title_justify="left")
    tab.add_column("observer")
    tab.add_column("δ residual RMSE mm", justify="right")
    for state in PRESSURES:
        tab.add_column(f"{state} RMSE MPa", justify="right")
    tab.add_column("95 % coverage", justify="right")
    tab.add_column("while braking", justify="right")
    for w in OBSERVERS:
        pr = s["pressure_rmse_mpa"][w]
        cov, cov_b = s["coverage_95"][w], s["coverage_95_braking"][w]
        res = s["residual_rmse_mm"][w]
        tab.add_row(w.upper(), "–" if res is None else f"{res:.4f}",
                    *("–" if pr[k] is None else f"{pr[k]:.3f}" for k in PRESSURES),
                    *("–" if c is None else f"{100 * c:.1f} %" for c in (cov, cov_b)))
    return tab
