"""`brakethermo simulate-emb` / `simulate-tyre`: rig sessions of our own simulators, plus truth."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from brakethermo.cli._app import app, console
from brakethermo.errors import ConfigError
from brakethermo.io.writers import infer_format
from brakethermo.sim.emb import SCENARIOS, simulate_emb, write_emb_simulation
from brakethermo.sim.tyre_rig import TYRES, simulate_tyre_rig, write_tyre_simulation

OutFile = Annotated[
    Path, typer.Option("--out", help="Session file to write (.mcap, .parquet, .csv).")
]
Seed = Annotated[int, typer.Option("--seed", help="Random seed; same seed, same bytes.")]
Fmt = Annotated[
    str | None, typer.Option("--format", help="mcap, parquet or csv (default: extension).")
]


def _report(session: Path, truth: Path, as_json: bool, **extra: object) -> None:
    info = {"session": str(session), "truth": str(truth), **extra}
    if as_json:
        typer.echo(json.dumps(info))
    else:
        console.print(f"written: {session} and {truth}")


@app.command("simulate-emb")
def simulate_emb_cmd(
    out: OutFile,
    scenario: Annotated[
        str, typer.Option("--scenario", help=f"One of: {', '.join(SCENARIOS)}.")
    ] = "nominal",
    duration: Annotated[float, typer.Option("--duration", help="Length, s.")] = 60.0,
    no_sensor: Annotated[
        bool, typer.Option("--no-sensor", help="Leave out the clamp-force sensor channel.")
    ] = False,
    seed: Seed = 0,
    fmt: Fmt = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print a JSON summary.")] = False,
) -> None:
    """Simulate an electro-mechanical caliper session (uniform random angle demand)."""
    fmt = infer_format(out, fmt)
    res = simulate_emb(scenario, duration_s=duration, seed=seed, with_sensor=not no_sensor)
    s, t = write_emb_simulation(res, out, fmt)
    _report(s, t, as_json, scenario=scenario, seed=seed)


@app.command("simulate-tyre")
def simulate_tyre_cmd(
    out: OutFile,
    tyre: Annotated[str, typer.Option("--tyre", help=f"One of: {', '.join(TYRES)}.")] = (
        "burckhardt"
    ),
    duration: Annotated[
        float | None, typer.Option("--duration", help="Pad with free rolling to this length, s.")
    ] = None,
    log_slip: Annotated[
        bool, typer.Option("--log-slip", help="Also log the rig's slip_ratio channel.")
    ] = False,
    seed: Seed = 0,
    fmt: Fmt = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print a JSON summary.")] = False,
) -> None:
    """Simulate a μ–slip rig session: free rolling, brake ramp to lock, release."""
    if tyre not in TYRES:
        raise ConfigError(f"unknown tyre '{tyre}'; use one of {', '.join(TYRES)}")
    fmt = infer_format(out, fmt)
    res = simulate_tyre_rig(tyre, seed=seed, duration_s=duration, log_slip=log_slip)
    s, t = write_tyre_simulation(res, out, fmt)
    _report(s, t, as_json, tyre=tyre, seed=seed, peak_mu=res.peak[0], peak_slip=res.peak[1])
