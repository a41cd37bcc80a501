"""`brakethermo simulate`: a realistic session from the truth model, plus its truth file."""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.markup import escape
from rich.table import Table

from brakethermo.cli._app import app, console
from brakethermo.cli._options import JsonOpt, option_values
from brakethermo.errors import ConfigError
from brakethermo.sim.effects import EFFECT_NAMES, STRENGTH_MAX, parse_effects
from brakethermo.sim.rigs import RIG_SIMULATORS, rig_name

if TYPE_CHECKING:
    from brakethermo.sim.session import SimConfig


@app.command("simulate")
def simulate_cmd(
    out: Annotated[
        Path, typer.Option("--out", "-o", help="Session file to write (.mcap, .parquet, .csv).")
    ],
    track: Annotated[str, typer.Option("--track", help="Track name or TOML path.")] = (
        "mugello-like"
    ),
    laps: Annotated[
        int, typer.Option("--laps", min=1, max=200, help="Flying laps after the out-lap.")
    ] = 5,
    effects: Annotated[
        str,
        typer.Option(
            "--effects",
            help="Effect strengths, name=strength comma separated (0 = mild baseline,"
            f" 1 = strong, up to {STRENGTH_MAX}; a bare name = 1; unnamed effects 0),"
            f" e.g. friction_temperature=0.8,sensor_lag. Names: {', '.join(EFFECT_NAMES)}.",
        ),
    ] = "",
    sensor: Annotated[
        str, typer.Option("--sensor", help="IR sensor: 'multi' (4 spots) or 'single'.")
    ] = "multi",
    fmt: Annotated[
        str | None,
        typer.Option("--format", help="mcap, parquet or csv (default: from the extension)."),
    ] = None,
    seed: Annotated[
        int, typer.Option("--seed", min=0, help="Random seed; same seed, same bytes.")
    ] = 0,
    disc: Annotated[str, typer.Option("--disc", help="Disc datasheet id or TOML path.")] = (
        "cc-340-8"
    ),
    grouped: Annotated[
        bool,
        typer.Option(
            "--grouped", metavar="",
            help="MCAP: write the IR spots as one grouped topic 'disc_temp'.",
        ),
    ] = False,
    as_json: JsonOpt = False,
    rig: Annotated[
        str | None,
        typer.Option("--rig", help=f"Simulate a rig session instead: {', '.join(RIG_SIMULATORS)}."),
    ] = None,
    rig_set: Annotated[
        list[str] | None,
        typer.Option("--set", help="Setting KEY=VALUE; repeat. With --rig, the rig's settings;"
                     " for a disc session cooling=F (convection factor) and ambient_c=C (air"
                     " temperature, degC): the same seed replays the same drive."),
    ] = None,
) -> None:
    """Simulate a session with named effects; write it and <stem>.truth.parquet beside it."""
    from brakethermo.io.writers import infer_format
    from brakethermo.pipelines.output_dir import check_output_file
    from brakethermo.sim.session import SimConfig

    rig = _known_rig(rig)
    check_output_file(out)
    fmt = infer_format(out, fmt)
    if grouped and fmt != "mcap":
        raise ConfigError(f"--grouped is an MCAP layout; {out.name} is {fmt}")
    if rig is not None:
        _no_disc_options(rig, {"--effects": effects != "", "--sensor": sensor != "multi",
                               "--track": track != "mugello-like", "--laps": laps != 5,
                               "--disc": disc != "cc-340-8", "--grouped": grouped})
        _simulate_rig(rig, rig_set or [], seed, out, fmt, as_json)
        return
    cfg = SimConfig(track=track, laps=laps, effects=parse_effects(effects), sensor=sensor,
                    seed=seed, disc=disc, **_disc_settings(rig_set or []))
    summary = _simulate_disc(cfg, out, fmt, grouped)
    if as_json:
        typer.echo(json.dumps(summary))
        return
    _render(summary)


DISC_SETTINGS = ("cooling", "ambient_c")


def _known_rig(rig: str | None) -> str | None:
    """``--rig`` as given, or None; an unknown rig is a usage error (exit 2), said before
    the output's checks (it was a KeyError traceback)."""
    if rig is None:
        return None
    with option_values():
        return rig_name(rig)


def _no_disc_options(rig: str, given: dict[str, bool]) -> None:
    """A rig session reads none of the disc session's options: refuse those given."""
    named = [name for name, was in given.items() if was]
    if named:
        raise ConfigError(f"{', '.join(named)}: disc-session options, not read for --rig"
                          f" {rig}; its settings go with --set KEY=VALUE")


def _disc_settings(settings: list[str]) -> dict[str, float]:
    """``--set cooling=1.2 --set ambient_c=35`` for a disc session (a key it does not
    take, a value not a number or outside the simulator's range: a usage error, exit 2)."""
    from brakethermo.sim.session import check_air

    out: dict[str, float] = {}
    with option_values():
        for item in settings:
            key, sep, value = item.partition("=")
            if not sep or key.strip() not in DISC_SETTINGS:
                raise ConfigError(f"--set {item}: a disc session takes"
                                  f" {', '.join(DISC_SETTINGS)} as KEY=VALUE (rig settings"
                                  " need --rig)")
            try:
                out[key.strip()] = float(value)
            except ValueError:
                raise ConfigError(f"--set {item}: {value!r} is not a number") from None
            try:  # the simulator's own range, before anything is simulated
                check_air(out.get("cooling", 1.0), out.get("ambient_c"))
            except ConfigError as exc:
                raise ConfigError(f"--set {item}: {exc}") from None
    return out


def _simulate_disc(cfg: SimConfig, out: Path, fmt: str, grouped: bool) -> dict[str, Any]:
    """Simulate a disc session, write it and its truth file, and summarise both.

    Parameters
    ----------
    cfg : SimConfig
        What to simulate.
    out : Path
        Session file to write; the truth file goes beside it.
    fmt : str
        The session file's format (mcap, parquet or csv).
    grouped : bool
        MCAP: the IR spots as one grouped topic.

    Returns
    -------
    dict
        The summary printed (as JSON or a table): paths, facts, peak spot °C, times in s.
    """
    from brakethermo.sim.session import simulate, write_simulation

    t0 = time.perf_counter()
    result = simulate(cfg)
    t1 = time.perf_counter()
    session_path, truth_path = write_simulation(result, out, fmt, grouped=grouped)
    t2 = time.perf_counter()
    truth = result.truth
    return {
        "session": str(session_path),
        "truth": str(truth_path),
        "format": fmt,
        "track": result.session.facts["track"],
        "laps": cfg.laps,
        "seed": cfg.seed,
        "effects": {n: v for n, v in cfg.strengths.items() if v > 0},
        "duration_s": float(truth.column("time")[-1].as_py()),
        "channels": [c.name for c in result.session.channels],
        "peak_spot_c": float(max(max(truth.column(f"spot{i}").to_pylist()) for i in range(1, 5))),
        "simulate_s": round(t1 - t0, 3),
        "write_s": round(t2 - t1, 3),
    }


def _simulate_rig(
    rig: str, settings: list[str], seed: int, out: Path, fmt: str, as_json: bool
) -> None:
    """``simulate --rig``: one rig session and its truth file."""
    from brakethermo.sim.rigs import rig_settings

    t0 = time.perf_counter()
    # a --set key the rig lacks, a value not of its type or outside the simulator's own
    # range: all usage errors (exit 2), as option_values says of any value a command checks
    with option_values():
        kwargs = rig_settings(rig, settings, seed)
        cfg = RIG_SIMULATORS[rig].config(**kwargs)
    session_path, truth_path = RIG_SIMULATORS[rig].run(cfg, out, fmt)
    facts = RIG_SIMULATORS[rig].truth_facts
    truth_facts = facts(cfg) if facts else {}
    summary = {
        "rig": rig,
        "session": str(session_path),
        "truth": str(truth_path),
        "format": fmt,
        "seed": seed,
        "config": dataclasses.asdict(cfg),
        **truth_facts,
        "simulate_s": round(time.perf_counter() - t0, 3),
    }
    if as_json:
        typer.echo(json.dumps(summary))
        return
    tab = Table(title=f"simulated {rig} session, seed {seed}")
    tab.add_column("item")
    tab.add_column("value")
    tab.add_row("session", summary["session"])
    tab.add_row("truth", summary["truth"])
    for key, value in summary["config"].items():
        tab.add_row(key, "scenario's default" if value is None else str(value))
    for key, value in truth_facts.items():
        tab.add_row(f"{key} (truth)", f"{value:.4f}")
    tab.add_row("time", f"{summary['simulate_s']:.1f} s")
    console.print(tab)


def _render(summary: dict[str, Any]) -> None:
    """The disc simulation's summary as a table."""
    tab = Table(title=f"simulated {escape(summary['track'])} — {summary['laps']} laps,"
                      f" seed {summary['seed']}")
    tab.add_column("item")
    tab.add_column("value")
    tab.add_row("session", escape(summary["session"]))
    tab.add_row("truth", escape(summary["truth"]))
    tab.add_row(
        "effect strengths",
        ", ".join(f"{n}={v:g}" for n, v in summary["effects"].items()) or "none (all mild)",
    )
    tab.add_row("duration", f"{summary['duration_s']:.1f} s")
    tab.add_row("channels", escape(", ".join(summary["channels"])))
    tab.add_row("hottest spot (truth)", f"{summary['peak_spot_c']:.0f} °C")
    tab.add_row("time", f"simulate {summary['simulate_s']:.1f} s, write {summary['write_s']:.1f} s")
    console.print(tab)
