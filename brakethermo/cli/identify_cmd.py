"""``brakethermo identify-h SESSION``: the disc convection law from a four-spot session."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from brakethermo.cli._app import app, console, print_warnings, run_with_status
from brakethermo.cli._options import (
    SESSION_FORMATS,
    AliasesOpt,
    AmbientOpt,
    DiscOpt,
    JsonOpt,
    NodesOpt,
    OutDir,
    TuningOpt,
)

if TYPE_CHECKING:
    from brakethermo.io.session import Session
    from brakethermo.pipelines.identify_h import IdentifyResult, StructureFit


@app.command("identify-h")
def identify_command(
    session: Annotated[
        Path, typer.Argument(help=f"Four-spot test session file ({SESSION_FORMATS}).")
    ],
    out: OutDir = Path("out"),
    nodes: NodesOpt = None,
    structure: Annotated[
        bool,
        typer.Option(
            "--structure/--no-structure",
            help="Also fit crown weights, k_z ratio and power scale (and refine h).",
        ),
    ] = True,
    with_effect: Annotated[
        str,
        typer.Option(help="Effects fitted jointly with h(V): 'auto' (default: the"
                          " diagnosis's forward selection on held-out laps), 'none' (the"
                          " plain law), or a comma-separated list of effect names."),
    ] = "auto",
    disc: DiscOpt = None,
    tuning: TuningOpt = None,
    aliases: AliasesOpt = None,
    ambient: AmbientOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Identify h(V) (joint UKF, h as a random walk) and the disc model's structure."""
    from brakethermo.pipelines.identify_h import IdentifyOptions, identify_h, write_identify
    from brakethermo.pipelines.outputs import to_json
    from brakethermo.pipelines.preflight import preflight

    preflight(out=out, tuning=tuning, aliases=aliases, disc=disc)
    from brakethermo.pipelines.output_dir import check_session_folder

    check_session_folder(out, session, "estimate")  # beside this session's estimate only
    if with_effect.strip().lower() not in ("auto", "none", ""):
        from brakethermo.errors import ConfigError
        from brakethermo.models.effects import parse_effects

        try:  # a bad name before the work, with 'auto' beside the others
            parse_effects(with_effect)
        except ConfigError as exc:
            raise ConfigError(f"--with-effect {with_effect!r}: {exc.detail} (or alone 'auto',"
                              " the default)") from None
    options = IdentifyOptions(disc=disc, tuning=tuning, nodes=nodes, aliases=aliases,
                              ambient_c=ambient, fit_structure=structure,
                              with_effects=with_effect)
    result = run_with_status(as_json, f"identifying h(V) on {session.name} ...",
                             lambda: identify_h(session, options))
    folder = write_identify(result, out)
    from brakethermo.pipelines.output_dir import refresh_indexes

    refresh_indexes(folder)
    if as_json:
        print(to_json({**result.summary, "output": str(folder)}))
        return
    _print_law(result)
    if result.structure is not None:
        _print_structure(result.structure, result.session, disc)
    _print_evidence(result.summary.get("evidence"))
    sel = result.summary["effect_selection"]
    console.print(f"effects carried: {', '.join(sel['selected']) or 'none'} —"
                  f" {escape(sel['why'])}", highlight=False)
    print_warnings(result.summary["run"]["warnings"], soft_wrap=True)
    console.print(f"wrote {escape(str(folder / 'h_law.toml'))}, h_samples.parquet, h_law.png "
                  f"({result.timings['total_s']:.1f} s)")


def _print_law(result: IdentifyResult) -> None:
    """The h(V) law as a table of speeds, then its parameters and the samples it rests on.

    Parameters
    ----------
    result : IdentifyResult
        The identification.
    """
    law = result.law
    table = Table(title=f"{escape(result.stem)}: h(V) law", title_justify="left")
    table.add_column("speed km/h", justify="right")
    table.add_column("h W/(m² K)", justify="right")
    fitted = result.samples["speed"].to_numpy()[result.fit_mask] * 3.6
    top = float(fitted.max()) if fitted.size else 0.0
    for v in (50, 100, 150, 200, 250, 280, 300, 330, 350):
        table.add_row(str(v), f"{float(law(v / 3.6)):.1f}" + (" (beyond the samples)"
                                                              if v > top else ""))
    console.print(table)
    fit = result.summary["fit"]
    console.print(
        f"power law a={law.a:.1f} b={law.b:.3f} below {law.knee:.2f}·V_ref"
        f" (V_ref {law.v_ref * 3.6:.0f} km/h), cubic above; "
        f"{fit['samples_off_brake']} off-brake samples of {fit['samples_total']}, up to"
        f" {top:.0f} km/h (the paper's fit to the filter's h samples alone, before the"
        " open-loop refit: identify.json law_ukf_only and h_law.png)"
    )


def _print_structure(s: StructureFit, session: Session, disc: str | None) -> None:
    """The fitted structure: crown weights, k_z ratio, power scale, effects, open-loop RMSE.

    Parameters
    ----------
    s : StructureFit
        The structure fitted with the law.
    session : Session
        The session identified on, whose disc sets the k_z ratio against the datasheet.
    disc : str or None
        The ``--disc`` option.
    """
    from brakethermo.models.effects import EFFECTS

    console.print(
        f"crown weights w = [{s.weights[0]:.3f}, {s.weights[1]:.3f}, {s.weights[2]:.3f}], "
        f"k_z ratio {s.kz_ratio:.3f} ({_kz_text(s.kz_ratio, session, disc)}), power"
        f" scale {s.power_scale:.3f} ({s.nodes} nodes x {s.layers} layers)", highlight=False
    )
    for name, values in s.effects.items():
        units = {p.name: p.unit for p in EFFECTS[name].params} if name in EFFECTS else {}
        # in h_law.toml kz_factor is a share of the in-plane k(T), as the law's k_z ratio
        console.print(f"effect {name}: " + ", ".join(
            (f"{k} = {v:.3g}{_unit_text(units.get(k, ''))}"
             + (f" ({_kz_text(v, session, disc)})" if k == "kz_factor" else ""))
            if isinstance(v, float) else _vector_text(k, v)
            for k, v in values.items()), highlight=False)
    console.print(
        "open-loop RMSE per spot °C: "
        + ", ".join(f"{k} {v:.1f} (uniform {s.rmse_uniform_c[k]:.1f})"
                    for k, v in s.rmse_c.items())
    )


def _print_evidence(ev: dict[str, Any] | None) -> None:
    """The straights' evidence against the law, printed only when it disagrees with it.

    Parameters
    ----------
    ev : dict or None
        The summary's ``evidence``: straights, factor on h and its 95 % interval.
    """
    if ev and ev.get("straights", 0) >= 2 and not ev["ci95"][0] <= 1.0 <= ev["ci95"][1]:
        console.print(
            f"evidence: on {ev['straights']} off-brake straights the estimate's layered model"
            f" cools as measured with this law x{ev['factor']:.3f}"
            f" [{ev['ci95'][0]:.3f}, {ev['ci95'][1]:.3f}] (h_law.png; identify.json"
            " evidence); the law is written as fitted", highlight=False)


def _vector_text(name: str, values: list[float]) -> str:
    """A per-segment parameter (a slipstream's straight factors, a zone's crown balance)
    in one line: how many, their range and median (h_law.toml has them all)."""
    if not values:
        return f"{name}: none"
    v = np.asarray(values, float)
    return (f"{name} x{v.size} from {v.min():.3g} to {v.max():.3g}, median"
            f" {float(np.median(v)):.3g}")


def _unit_text(unit: str) -> str:
    """A parameter's unit as printed after its value ("" when it is a pure number)."""
    return {"": "", "-": "", "degC": " °C"}.get(unit, f" {unit}")


def _kz_text(ratio: float, session: Session, disc_option: str | Path | None) -> str:
    """What the law's k_z ratio (to the in-plane k(T), the model's base; ``kz_factor`` of
    an effect carries the same base) means in W/(m K) and against the datasheet's k_z."""
    from brakethermo.pipelines.models import disc_for

    spec = disc_for(session, disc_option)
    k = ratio * float(spec.conductivity(400.0))
    vs = f", {k / spec.k_z:.2f} x the datasheet's {spec.k_z:g}" if spec.k_z else ""
    return f"of the in-plane k(T): k_z {k:.1f} W/(m K) at 400 °C{vs}"
