"""``brakethermo inspect SESSION``: format, channels, units, rates, gaps and laps of a session.

Everything printed from the file (names, units, facts, warnings) is escaped: a channel
called ``[/b]`` is shown as written, never read as rich markup.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich import box
from rich.markup import escape
from rich.table import Table

from brakethermo.cli._app import app, console, print_warnings
from brakethermo.errors import ConfigError

if TYPE_CHECKING:
    from brakethermo.io import Session


def summary(session: Session) -> dict[str, Any]:
    """The machine-readable summary printed by ``inspect --json``."""
    from brakethermo.io.aliases import resolve

    mapped = set(resolve(session.aliases, session.available).values())
    return {
        "path": str(session.path),
        "format": session.format,
        "channels": [
            {
                "name": c.name,
                "source": c.source,
                "unit": c.unit,
                "si_unit": c.si_unit,
                "rate_hz": round(c.rate_hz, 6),
                "samples": c.samples,
                "gaps": [[round(s, 6), round(d, 6)] for s, d in c.gaps],
                "spikes": c.spikes,
            }
            for c in session.channels.values()
        ],
        "laps": [
            {"lap": lap.lap, "start_s": round(lap.start_s, 6),
             "duration_s": round(lap.duration_s, 6)}
            for lap in session.laps
        ],
        "session": session.metadata,
        "duration_s": float(session.time[-1]) if len(session.frame) else 0.0,
        "grid_points": len(session.frame),
        "start_epoch_s": session.start_epoch_s,
        "constants": dict(session.constants),
        "unusable": dict(session.unusable),
        "sources": list(session.available),
        "unmapped": [n for n in session.available if n not in mapped],
        "warnings": list(session.warnings),
    }


def _render(session: Session) -> None:
    from brakethermo.io.aliases import resolve
    from brakethermo.io.units import si_unit
    from brakethermo.results.laps import lap_time_text, partial_laps

    found = resolve(session.aliases, session.available)
    channels = Table(title=escape(f"{session.path.name} ({session.format}): channels"),
                     title_justify="left", box=box.SIMPLE_HEAD, show_edge=False,
                     collapse_padding=True,
                     pad_edge=False,
                     caption="source '=': logged under the canonical name; gaps: count,"
                             " then the longest (s) and where it starts (t, s)",
                     caption_justify="left")
    channels.add_column("channel", no_wrap=True)
    # names stay whole (a source folded into "disc_te / mp.spot / 1" reads as three);
    # the gaps' text wraps instead
    channels.add_column("source", no_wrap=True, min_width=6)
    channels.add_column("unit", no_wrap=True)
    for col in ("rate Hz", "samples", "gaps", "spikes"):
        channels.add_column(col, justify="right", no_wrap=col != "gaps")
    for c in session.channels.values():
        gap_text = "-"
        if c.gaps:
            start, longest = max(c.gaps, key=lambda g: g[1])
            gap_text = f"{len(c.gaps)}: {longest:.1f} @ {start:.1f}"
        source = "=" if c.source == c.name else escape(c.source)
        channels.add_row(c.name, source, escape(c.unit), f"{c.rate_hz:.1f}",
                         str(c.samples), gap_text, str(c.spikes))
    for name, value in session.constants.items():
        channels.add_row(name, escape(found.get(name, "")), si_unit(name), "once",
                         f"1 (= {value:g})", "-", "-")
    for name, why in session.unusable.items():
        channels.add_row(name, escape(found.get(name, "")), "-", "-", "0", escape(why), "-")
    console.print(channels)
    info = summary(session)
    if info["unmapped"]:
        console.print("[dim]not mapped to a canonical channel:[/] "
                      + escape(", ".join(info["unmapped"])), highlight=False)

    if all(lap.lap == 0 for lap in session.laps):
        # a rig session, or a log without a lap marker: one stretch, no lap to time
        console.print(f"laps: none marked (one stretch of {session.time[-1]:.1f}"
                      " s, no lap to time)", highlight=False)
    else:
        laps = Table(title="laps", title_justify="left")
        laps.add_column("lap", justify="right")
        laps.add_column("start s", justify="right")
        laps.add_column("lap time", justify="right")
        partial = partial_laps(session.laps)
        for lap in session.laps:
            label = "out-lap" if lap.lap == 0 else str(lap.lap)
            laps.add_row(label, f"{lap.start_s:.2f}", lap_time_text(lap.duration_s)
                         + (" partial" if lap.lap in partial else ""))
        console.print(laps)

    facts = Table(title="session", title_justify="left", show_header=False)
    facts.add_column("key")
    facts.add_column("value")
    for key, value in session.metadata.items():
        facts.add_row(escape(str(key)), escape(str(value)))
    facts.add_row("format", escape(session.format))
    facts.add_row("duration", _duration_text(session, info))
    if session.start_epoch_s is not None:
        facts.add_row("start (epoch s)", f"{session.start_epoch_s:.3f}")
    console.print(facts)
    print_warnings(session.warnings)


def _duration_text(session: Session, info: dict[str, Any]) -> str:
    """The session's length and its grid, and the rate it is logged at where faster: a
    1 kHz rig log read "6167 points at 10 Hz", the disc pipelines' grid, not what the
    rig commands read."""
    text = f"{info['duration_s']:.1f} s ({info['grid_points']} points at {session.rate_hz:g} Hz"
    native = max((c.rate_hz for c in session.channels.values()), default=0.0)
    if native > 1.5 * session.rate_hz:
        # the rig commands read a rig log at its own rate; a disc session's fast channels
        # (100 Hz wheel speed) are read on the grid
        from brakethermo.io.kinds import session_kind

        rig = session_kind({*session.available, *session.channels}) not in (None, "disc")
        text += (f", the disc pipelines' grid; logged at up to {native:.6g} Hz"
                 + (", the rate the rig commands read" if rig else ""))
    return text + ")"


@app.command("inspect")
def inspect(
    session_file: Annotated[
        Path,
        typer.Argument(metavar="SESSION",
                       help="Session file: MCAP, Parquet, CSV, MDF (.mf4/.mdf), AiM (.xrk/.xrz)."),
    ],
    aliases: Annotated[
        Path | None,
        typer.Option("--aliases", help="Alias TOML merged over the shipped channel names."),
    ] = None,
    gap_limit: Annotated[
        float, typer.Option("--gap-limit", help="Longest gap bridged by interpolation, s.")
    ] = 1.0,
    require: Annotated[
        list[str] | None,
        typer.Option("--require", metavar="CHANNEL",
                     help="Fail unless this canonical channel is present (repeatable)."),
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object instead.")] = False,
) -> None:
    """Channels, units, rates, gaps and laps of a logged session."""
    from brakethermo.io import load_session
    from brakethermo.io.units import CANONICAL_CHANNELS

    unknown = [c for c in require or () if c not in CANONICAL_CHANNELS]
    if unknown:
        raise ConfigError(f"--require {', '.join(unknown)}: not a canonical channel; the"
                          f" channels are {', '.join(CANONICAL_CHANNELS)}")
    session = load_session(session_file, aliases=aliases, gap_limit_s=gap_limit)
    session.require(*(require or ()))
    if as_json:
        typer.echo(json.dumps(summary(session)))
    else:
        _render(session)
