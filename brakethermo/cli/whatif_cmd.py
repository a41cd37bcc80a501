"""`brakethermo whatif`: the session's laps replayed with a bigger duct, another disc, a hot day."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.markup import escape
from rich.table import Table

from brakethermo.cli._app import app, console, print_warnings, run_with_status
from brakethermo.cli._options import (
    AliasesOpt,
    AmbientOpt,
    JsonOpt,
    OutDir,
    TuningOpt,
    option_values,
)
from brakethermo.errors import ConfigError

if TYPE_CHECKING:
    from brakethermo.pipelines.whatif import Scenario

SCENARIO_KEYS = ("cooling", "disc", "ambient", "pads")
FIELD = {"cooling": "cooling", "ambient": "ambient_c", "pads": "heat_share"}


def parse_scenario(text: str) -> dict[str, object]:
    """``cooling=1.2,ambient=35,disc=cc-355-9`` -> keyword arguments of a Scenario."""
    kw: dict[str, object] = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        key, sep, value = part.partition("=")
        key = key.strip()
        if not sep or key not in SCENARIO_KEYS:
            raise ConfigError(f"--scenario '{text}': give KEY=VALUE pairs separated by commas,"
                              f" KEY one of {', '.join(SCENARIO_KEYS)}")
        if FIELD.get(key, key) in kw:
            raise ConfigError(f"--scenario '{text}': {key} is given twice; one scenario takes"
                              " each key once (give another --scenario for the other value)")
        if key == "disc":
            kw["disc"] = value.strip()
            continue
        try:
            number = float(value)
        except ValueError:
            raise ConfigError(f"--scenario '{text}': {key}={value} is not a number") from None
        kw[FIELD[key]] = number
        _check_value(text, key, value, number)
    if not kw:
        raise ConfigError(f"--scenario '{text}' changes nothing")
    return kw


def _check_value(text: str, key: str, value: str, number: float) -> None:
    """The range check of one ``--scenario`` value, said as the user typed it
    (``--scenario 'cooling=0': cooling=0 …``, not the single option's ``--cooling 0.0``).

    Raises
    ------
    ConfigError
        ``number`` is outside the scenario's range for ``key``.
    """
    from brakethermo.pipelines.whatif import Scenario

    try:
        Scenario(**{FIELD[key]: number})  # type: ignore[arg-type]
    except ConfigError as exc:
        why = str(exc).partition(": ")[2] or str(exc)  # without the single option's name
        raise ConfigError(f"--scenario '{text}': {key}={value.strip()}: {why}") from None


def _fmt(x: float, spec: str = ".0f") -> str:
    return "–" if x is None or not math.isfinite(x) else format(x, spec)


@app.command("whatif")
def whatif_cmd(
    session: Annotated[Path, typer.Argument(help="Session to replay (any format estimate reads).")],
    h_law: Annotated[
        Path | None, typer.Option("--h-law", help="h_law.toml of this disc (identify-h).")
    ] = None,
    cooling: Annotated[
        list[float] | None,
        typer.Option("--cooling", help="Factor on the disc's convection (1.2 = a duct with 20 %"
                     " more cooling); each one given is a scenario."),
    ] = None,
    disc: Annotated[
        list[str] | None,
        typer.Option("--disc", help="Another disc (datasheet id or TOML); each one a scenario."),
    ] = None,
    ambient: Annotated[
        list[float] | None,
        typer.Option("--ambient", help="Air temperature, degC; each one a scenario."),
    ] = None,
    pads: Annotated[
        list[float] | None,
        typer.Option("--pads", help="Other pads, as the share of the friction heat entering"
                     " the disc (datasheet 0.9); each one a scenario."),
    ] = None,
    scenario: Annotated[
        list[str] | None,
        typer.Option("--scenario", help="Combined changes, e.g. 'cooling=1.2,ambient=35'"
                     " (keys cooling, disc, ambient, pads)."),
    ] = None,
    spot: Annotated[int, typer.Option(min=1, max=4, help="Measured spot of the estimate.")] = 3,
    session_disc: Annotated[
        str | None,
        typer.Option("--disc-of-session", help="The session's own disc (datasheet id or"
                     " TOML), if its facts do not name it."),
    ] = None,
    session_ambient: AmbientOpt = None,
    draws: Annotated[int, typer.Option(min=0, max=200,
                                       help="Replays over the h law's uncertainty.")] = 12,
    tyre_temp: Annotated[float, typer.Option("--tyre-temp",
                                             help="Tyre sidewall temperature, degC.")] = 60.0,
    tuning: TuningOpt = None,
    aliases: AliasesOpt = None,
    out: OutDir = Path("out"),
    as_json: JsonOpt = False,
) -> None:
    """Replay the session's own laps with a change: window, peaks, friction, heat to the tyre."""
    from brakethermo.pipelines.models import OWN_LAW, own_h_law
    from brakethermo.pipelines.output_dir import check_session_folder, refresh_indexes
    from brakethermo.pipelines.outputs import to_json
    from brakethermo.pipelines.whatif import WhatifOptions, whatif_session, write_whatif
    from brakethermo.report.whatif_page import write_whatif_page
    from brakethermo.thermal.tyre_radiation import TyreView

    # no change, or one change given twice, is a usage error too (exit 2), as a range is
    with option_values():
        scenarios = _scenarios(cooling, disc, ambient, pads, scenario)
        if not math.isfinite(tyre_temp) or not -20.0 <= tyre_temp <= 200.0:
            raise ConfigError(f"--tyre-temp {tyre_temp}: give the sidewall in degC, -20 to 200")
        opts = WhatifOptions(scenarios=tuple(scenarios), h_law=h_law, spot=spot,
                             disc=session_disc, tuning=tuning, aliases=aliases,
                             ambient_c=session_ambient, draws=draws,
                             tyre=TyreView(carcass_c=tyre_temp))
    check_session_folder(out, session, "estimate")  # beside this session's estimate only
    # as estimate chooses: the law identify-h wrote for this session beside its outputs
    # before the shipped one (whatif took the shipped law, and its page was then called
    # stale beside an estimate on the session's own)
    if h_law is None and (own := own_h_law(out / session.stem, session)) is not None:
        opts = replace(opts, h_law=own.source, h_law_reason=OWN_LAW)
    res = run_with_status(as_json, "whatif…", lambda: whatif_session(session, opts))
    folder = write_whatif(res, out)
    page = write_whatif_page(res.summary, res.frame, folder / "whatif")
    refresh_indexes(folder)
    res.summary["output"] = {"parquet": str(folder / "whatif.parquet"), "page": str(page)}
    if as_json:
        typer.echo(to_json(res.summary))
        return
    console.print(_laps_table(res.summary, session))
    console.print(f"h law: {escape(str(res.summary['run']['h_law']))}"
                  f" ({escape(res.summary['run']['h_law_choice'])})", highlight=False)
    print_warnings(res.summary["run"]["warnings"])
    console.print(f"written: {escape(str(folder / 'whatif.parquet'))}, {escape(str(page))}")


def _scenarios(cooling: list[float] | None, disc: list[str] | None, ambient: list[float] | None,
               pads: list[float] | None, scenario: list[str] | None) -> list[Scenario]:
    """One scenario per single change given, then one per ``--scenario``, in that order.

    Parameters
    ----------
    cooling : list of float or None
        Factors on the disc's convection (dimensionless).
    disc : list of str or None
        Other discs (datasheet ids or TOML files).
    ambient : list of float or None
        Air temperatures, degC.
    pads : list of float or None
        Shares of the friction heat entering the disc (dimensionless).
    scenario : list of str or None
        Combined changes, as :func:`parse_scenario` reads them.
    """
    from brakethermo.pipelines.whatif import Scenario

    scenarios = [Scenario(cooling=c) for c in cooling or []]
    scenarios += [Scenario(disc=d) for d in disc or []]
    scenarios += [Scenario(ambient_c=a) for a in ambient or []]
    scenarios += [Scenario(heat_share=p) for p in pads or []]
    scenarios += [Scenario(**parse_scenario(s)) for s in scenario or []]  # type: ignore[arg-type]
    return scenarios


def _laps_table(summary: dict[str, Any], session: Path) -> Table:
    """Per lap, the base and each scenario: contact-band peak °C (95 % band) and % in window.

    Parameters
    ----------
    summary : dict
        The what-if's summary (scenarios and laps).
    session : Path
        The replayed session, for the title.
    """
    from brakethermo.report.whatif_page import shown

    labels = [s["label"] for s in summary["scenarios"]]
    tab = Table(title=f"whatif — {escape(Path(session).name)}: contact band per lap")
    tab.add_column("lap")
    tab.add_column("base peak °C / in window %")
    for lab in labels:
        tab.add_column(escape(f"{shown(lab)}: peak °C (95 %) / in window %"))
    for row in summary["laps"]:
        b = row["base"]
        cells = ["out-lap" if row["lap"] == 0 else str(row["lap"]),
                 f"{_fmt(b['peak_contact_c'])} / {_fmt(b['time_in_window_pct'])}"]
        for lab in labels:
            s = row[lab]
            cells.append(f"{_fmt(s['peak_contact_c'])} (±{_fmt(s['peak_contact_band95_c'])})"
                         f" / {_fmt(s['time_in_window_pct'])}")
        tab.add_row(*cells)
    return tab
