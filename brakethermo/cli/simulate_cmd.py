"""`brakethermo simulate`: a realistic session from the truth model, plus its truth file."""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from brakethermo.cli._app import app, console
from brakethermo.io.writers import infer_format
from brakethermo.sim.effects import EFFECT_NAMES
from brakethermo.sim.rigs import RIG_SIMULATORS, simulate_rig
from brakethermo.sim.session import SimConfig, simulate, write_simulation


@app.command("simulate")
def simulate_cmd(
    out: Annotated[
        Path, typer.Option("--out", help="Session file to write (.mcap, .parquet, .csv).")
    ],
    track: Annotated[str, typer.Option("--track", help="Track name or TOML path.")] = (
        "mugello-like"
    ),
    laps: Annotated[int, typer.Option("--laps", help="Flying laps after the out-lap.")] = 5,
    effects: Annotated[
        str,
        typer.Option(
            "--effects",
            help=f"Effects at their strong level, comma separated: {', '.join(EFFECT_NAMES)}.",
        ),
    ] = "",
    sensor: Annotated[
        str, typer.Option("--sensor", help="IR sensor: 'multi' (4 spots) or 'single'.")
    ] = "multi",
    fmt: Annotated[
        str | None,
        typer.Option("--format", help="mcap, parquet or csv (default: from the extension)."),
    ] = None,
    seed: Annotated[int, typer.Option("--seed", help="Random seed; same seed, same bytes.")] = 0,
    disc: Annotated[str, typer.Option("--disc", help="Disc datasheet id or TOML path.")] = (
        "cc-340-8"
    ),
    grouped: Annotated[
        bool,
        typer.Option(
            "--grouped", help="MCAP: write the IR spots as one grouped topic 'disc_temp'."
        ),
    ] = False,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print a machine-readable summary.")
    ] = False,
    rig: Annotated[
        str | None,
        typer.Option("--rig", help=f"Simulate a rig session instead: {', '.join(RIG_SIMULATORS)}."),
    ] = None,
    rig_set: Annotated[
        list[str] | None,
        typer.Option("--set", help="Rig simulation setting KEY=VALUE (with --rig); repeat."),
    ] = None,
) -> None:
    """Simulate a session with named effects; write it and <stem>.truth.parquet beside it."""
    fmt = infer_format(out, fmt)
    if rig is not None:
        _simulate_rig(rig, rig_set or [], seed, out, fmt, as_json)
        return
    cfg = SimConfig(
        track=track,
        laps=laps,
        effects=tuple(e for e in effects.split(",") if e.strip()),
        sensor=sensor,
        seed=seed,
        disc=disc,
    )
    t0 = time.perf_counter()
    result = simulate(cfg)
    t1 = time.perf_counter()
    session_path, truth_path = write_simulation(result, out, fmt, grouped=grouped)
    t2 = time.perf_counter()
    truth = result.truth
    summary = {
        "session": str(session_path),
        "truth": str(truth_path),
        "format": fmt,
        "track": result.session.facts["track"],
        "laps": laps,
        "seed": seed,
        "effects": list(cfg.effects),
        "duration_s": float(truth.column("time")[-1].as_py()),
        "channels": [c.name for c in result.session.channels],
        "peak_spot_c": float(max(max(truth.column(f"spot{i}").to_pylist()) for i in range(1, 5))),
        "simulate_s": round(t1 - t0, 3),
        "write_s": round(t2 - t1, 3),
    }
    if as_json:
        typer.echo(json.dumps(summary))
        return
    tab = Table(title=f"simulated {summary['track']} — {laps} laps, seed {seed}")
    tab.add_column("item")
    tab.add_column("value")
    tab.add_row("session", summary["session"])
    tab.add_row("truth", summary["truth"])
    tab.add_row("effects (strong)", ", ".join(cfg.effects) or "none (all mild)")
    tab.add_row("duration", f"{summary['duration_s']:.1f} s")
    tab.add_row("channels", ", ".join(summary["channels"]))
    tab.add_row("hottest spot (truth)", f"{summary['peak_spot_c']:.0f} °C")
    tab.add_row("time", f"simulate {summary['simulate_s']:.1f} s, write {summary['write_s']:.1f} s")
    console.print(tab)


def _simulate_rig(
    rig: str, settings: list[str], seed: int, out: Path, fmt: str, as_json: bool
) -> None:
    """``simulate --rig``: one rig session and its truth file."""
    t0 = time.perf_counter()
    cfg, session_path, truth_path = simulate_rig(rig, settings, seed, out, fmt)
    summary = {
        "rig": rig,
        "session": str(session_path),
        "truth": str(truth_path),
        "format": fmt,
        "seed": seed,
        "config": dataclasses.asdict(cfg),
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
        tab.add_row(key, str(value))
    tab.add_row("time", f"{summary['simulate_s']:.1f} s")
    console.print(tab)
