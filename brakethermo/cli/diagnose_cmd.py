"""``brakethermo diagnose SESSION``: the sim-to-real gap, its cause and how far it shrinks."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from brakethermo.cli._app import app, console, print_warnings
from brakethermo.cli._options import (
    SESSION_FORMATS,
    AliasesOpt,
    AmbientOpt,
    DiscOpt,
    JsonOpt,
    OutDir,
    TuningOpt,
    option_values,
)
from brakethermo.errors import ConfigError
from brakethermo.models.effects import EFFECT_NAMES

if TYPE_CHECKING:
    from brakethermo.pipelines.diagnose import DiagnoseOptions, DiagnoseResult


def _laps(text: str | None) -> tuple[int, ...] | None:
    if not text:
        return None
    try:
        return tuple(int(v) for v in text.replace(" ", "").split(",") if v)
    except ValueError:
        raise ConfigError(f"--holdout-laps {text!r}: give lap numbers like 2,4,6") from None


def _not_empty(value: str) -> str:
    """Refuse an empty ``--effects`` as a usage error: taken as 'all', ``--effects ''``
    quietly ran all seven effects, the opposite of what an empty list reads as."""
    if not value.strip():
        raise typer.BadParameter("an empty list of effects; give 'all' (the default) or"
                                 f" effect names: {', '.join(EFFECT_NAMES)}")
    return value


@app.command("diagnose")
def diagnose_command(
    sessions: Annotated[
        list[Path],
        typer.Argument(help=f"Four-spot test session file(s) ({SESSION_FORMATS}), a"
                       " single-spot race, or a rig session (E-Booster, EMB, roller rig,"
                       " tyre rig); several sessions of one bike and disc are also"
                       " pooled."),
    ],
    out: OutDir = Path("out"),
    effects: Annotated[
        str, typer.Option(help=f"'all' or a comma-separated list of: {', '.join(EFFECT_NAMES)}.",
                          callback=_not_empty)
    ] = "all",
    holdout_laps: Annotated[
        str | None,
        typer.Option(help="Laps to hold out, e.g. 2,4 (default: every other flying lap)."),
    ] = None,
    h_law: Annotated[
        Path | None, typer.Option(help="h_law.toml to start the reference fit from.")
    ] = None,
    disc: DiscOpt = None,
    tuning: TuningOpt = None,
    aliases: AliasesOpt = None,
    ambient: AmbientOpt = None,
    rig: Annotated[
        str | None,
        typer.Option(help="Diagnose a rig session: 'ebooster', 'emb', 'roller-rig' or 'tyre'"
                     " (found from the channels when not given)."),
    ] = None,
    train: Annotated[
        Path | None,
        typer.Option(help="Rig: training session whose fit is the reference (else --fit, else"
                     " the shipped fit)."),
    ] = None,
    fit: Annotated[
        Path | None, typer.Option(help="Rig: a saved training result (TOML).")
    ] = None,
    radius: Annotated[
        float | None,
        typer.Option("--radius", help="Tyre rig: wheel radius, m (else the session's"
                     " slip_ratio channel or its fact wheel_radius_m)."),
    ] = None,
    as_json: JsonOpt = False,
) -> None:
    """Where the model parts from the disc (or rig), which effect causes it, how far the gap
    shrinks."""
    if radius is not None and not 0.05 <= radius <= 2.0:
        raise ConfigError(f"--radius {radius} m is not a wheel radius; give metres, 0.05 to 2")
    if rig is not None and RIG_NAMES.get(rig, rig) not in RIGS:
        # a rig name the command does not know is a usage error (exit 2), as simulate's
        with option_values():
            raise ConfigError(f"--rig {rig!r}: diagnose reads rig sessions of"
                              f" {', '.join(RIGS)}")
    # the first session says which: several rig sessions are refused one clear line on
    if rig is None and sessions and not sessions[0].suffix.lower() == ".toml":
        from brakethermo.io.kinds import detect_rig

        rig = detect_rig(sessions[0], aliases)
    if rig is not None:
        disc_only = [name for name, given in (
            ("--holdout-laps", holdout_laps), ("--h-law", h_law), ("--disc", disc),
            ("--tuning", tuning), ("--ambient", ambient)) if given is not None]
        if disc_only:  # taken silently, they would seem to have been used
            raise ConfigError(f"{', '.join(disc_only)}: options of a disc diagnosis; this"
                              f" session is from the {rig} rig — leave them out")
        _diagnose_rig(RIG_NAMES.get(rig, rig), sessions, out, effects, train, fit, radius,
                      aliases, as_json)
        return
    from brakethermo.pipelines.diagnose import DiagnoseOptions

    options = DiagnoseOptions(effects=effects, holdout_laps=_laps(holdout_laps), h_law=h_law,
                              disc=disc, tuning=tuning, aliases=aliases, ambient_c=ambient)
    _diagnose_discs(sessions, out, options, as_json)


def _diagnose_discs(sessions: list[Path], out: Path, options: DiagnoseOptions,
                    as_json: bool) -> None:
    """Diagnose disc sessions (pooled when several), write each folder and report them.

    Parameters
    ----------
    sessions : list of Path
        The disc sessions; more than one are also pooled.
    out : Path
        Output root.
    options : DiagnoseOptions
        The diagnosis's options.
    as_json : bool
        Print the JSON summary (the pooled one when several) instead of tables.
    """
    from brakethermo.pipelines.diagnose import write_diagnosis, write_pooled
    from brakethermo.pipelines.diagnose.sessions import distinct_sessions
    from brakethermo.pipelines.output_dir import check_session_folder
    from brakethermo.pipelines.outputs import to_json

    distinct_sessions(sessions)  # one folder each, none the pooled one's
    for session in sessions:  # beside each session's own estimate only, before the work
        check_session_folder(out, session, "estimate")
    if len(sessions) > 1:
        _pooled_free(out, None)
    results, pooled = _run_with_progress(sessions, options, as_json)
    folders = [write_diagnosis(r, out) for r in results]
    pooled_path = write_pooled(pooled, out) if pooled is not None else None
    if as_json:
        if pooled is None:
            print(to_json({**results[0].summary, "output": str(folders[0])}))
        else:
            print(to_json({**pooled, "output": str(pooled_path)}))
        return
    for result, folder in zip(results, folders, strict=True):
        _render(result, folder)
    if pooled is not None:
        console.print(f"[bold]pooled over {len(results)} sessions[/]: verdict "
                      f"[bold]{_verdict_text(pooled)}[/]")
        _next_steps(pooled)
        for note in pooled["notes"]:
            console.print(f"  [yellow]note:[/] {escape(note)}")
        console.print(f"wrote {escape(str(pooled_path))} and its page"
                      f" {escape(str(pooled_path.parent / 'index.html'))}")


def _run_with_progress(sessions: list[Path], options: DiagnoseOptions,
                       as_json: bool) -> tuple[list[DiagnoseResult], dict | None]:
    """The diagnoses behind a transient progress bar: per session, and pooled when several.

    Parameters
    ----------
    sessions : list of Path
        The disc sessions.
    options : DiagnoseOptions
        The diagnosis's options.
    as_json : bool
        No bar: the output must stay JSON.

    Returns
    -------
    results : list of DiagnoseResult
        One per session.
    pooled : dict or None
        The pooled summary, None for a single session.
    """
    from brakethermo.pipelines.diagnose import diagnose, diagnose_many

    name = sessions[0].name if len(sessions) == 1 else f"{len(sessions)} sessions"
    # A transient bar is erased when done; off a terminal it cannot be drawn, and only
    # left a blank line before the output (or before an error's one line).
    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TimeElapsedColumn(), console=console, transient=True,
                  disable=as_json or not console.is_terminal) as bar:
        task = bar.add_task(f"diagnosing {escape(name)}", total=None)

        def progress(label: str, done: int, total: int) -> None:
            bar.update(task, completed=done, total=total,
                       description=f"diagnosing {escape(name)}: {escape(label)}")

        if len(sessions) == 1:
            return [diagnose(sessions[0], options, progress)], None
        return diagnose_many(sessions, options, progress)


RIGS = ("ebooster", "emb", "roller-rig", "tyre")
RIG_NAMES = {"mu-slip": "tyre"}  # the tyre rig by its command's name


def _diagnose_rig(rig: str, sessions: list[Path], out: Path, effects: str,
                  train: Path | None, fit: Path | None, radius: float | None,
                  aliases: Path | None, as_json: bool) -> None:
    """Diagnose rig sessions, each in its folder, pooled into ``OUT/pooled`` when several."""
    import shlex

    from brakethermo.pipelines.diagnose._common import filled
    from brakethermo.pipelines.diagnose.rig import write_rig_diagnosis
    from brakethermo.pipelines.outputs import to_json

    if rig not in RIGS:
        raise ConfigError(f"--rig {rig!r}: diagnose reads rig sessions of {', '.join(RIGS)}")
    if fit is not None and (train is not None or rig != "ebooster"):
        raise ConfigError("--fit is a saved E-Booster training result, the reference instead"
                          " of --train: give one of the two, and only for a booster session")
    if rig == "emb" and train is None:
        raise ConfigError("--rig emb needs --train SESSION: the caliper session the"
                          " stiffness model is trained on (with the clamp-force sensor)")
    from brakethermo.io.kinds import KINDS, detect_rig, rig_kind
    from brakethermo.pipelines.diagnose.sessions import distinct_sessions
    from brakethermo.pipelines.output_dir import check_output_dir, check_session_folder

    check_output_dir(out)
    distinct_sessions(sessions)  # one folder each, none the pooled one's
    mine = rig_kind(rig).words  # every name of RIGS is a kind's
    for path in sessions:
        other = detect_rig(path, aliases) if len(sessions) > 1 else rig
        if RIG_NAMES.get(other, other) != rig:  # None: a disc session, or no session
            # the kinds' own words ("an EMB caliper rig"), not their ids ("a emb")
            what = f"{KINDS[other].words} session" if other in KINDS else "no rig session"
            raise ConfigError(f"{path}: {what}, while the others are of {mine}; diagnose"
                              " pools the sessions of one rig: give each rig its own call")
        check_session_folder(out, path, rig_kind(rig).table)
    if len(sessions) > 1:
        _pooled_free(out, rig)
    results = [_one_rig(rig, path, effects, train, fit, radius, aliases) for path in sessions]
    folders = [write_rig_diagnosis(r, out) for r in results]
    pooled = pooled_path = None
    if len(results) > 1:
        from brakethermo.pipelines.diagnose import write_pooled
        from brakethermo.pipelines.diagnose.rig_pooled import pool_rig

        pooled = filled(pool_rig(results), {"DIR/": f"{shlex.quote(str(out))}/"})
        pooled_path = write_pooled(pooled, out)
    if as_json:
        print(to_json({**pooled, "output": str(pooled_path)} if pooled is not None else
                      {**results[0].summary, "output": str(folders[0])}))
        return
    for result, folder in zip(results, folders, strict=True):
        _render_rig(result, folder, rig)
    if pooled is not None:
        console.print(f"[bold]pooled over {len(results)} sessions[/]: verdict "
                      f"[bold]{escape(_verdict_text(pooled))}[/]")
        _next_steps(pooled)
        for note in pooled["notes"]:
            console.print(f"  note: {escape(note)}", highlight=False)
        console.print(f"wrote {escape(str(pooled_path))} and its page"
                      f" {escape(str(pooled_path.parent / 'index.html'))}")


def _pooled_free(out: Path, rig: str | None) -> None:
    """Refuse, before the work, to pool over ``OUT/pooled`` of another rig or of disc
    sessions (or, for disc sessions, of a rig's): a second pooled call replaced the
    first's diagnosis.json and page, no word.

    Parameters
    ----------
    out : Path
        The ``--out`` folder.
    rig : str or None
        The rig of this call's sessions; None for disc sessions.
    """
    import json

    from brakethermo.io.kinds import rig_kind

    there = out / "pooled" / "diagnosis.json"
    try:
        held = json.loads(there.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return
    was = held.get("rig") if isinstance(held, dict) else None
    if was == rig:
        return  # the same rig's (or disc) pooled diagnosis, re-run: replaced as any output

    def words(kind: str | None) -> str:
        known = rig_kind(kind) if kind else None
        return (f"sessions of {known.words}" if known is not None else
                f"sessions of rig '{kind}'" if kind else "disc sessions")

    n = len(held.get("sessions") or []) if isinstance(held, dict) else 0
    raise ConfigError(f"{there}: holds the pooled diagnosis of {n or 'several'} {words(was)};"
                      f" this call pools {words(rig)} and would replace it: give another"
                      " --out")


def _one_rig(rig: str, path: Path, effects: str, train: Path | None, fit: Path | None,
             radius: float | None, aliases: Path | None) -> Any:
    """One rig session's diagnosis (a RigDiagnosis)."""
    if rig == "roller-rig":
        from brakethermo.pipelines.diagnose.rig_roller import diagnose_roller_rig

        return diagnose_roller_rig(path, aliases=aliases, effects=effects)
    if rig == "tyre":
        from brakethermo.pipelines.diagnose.rig_tyre import diagnose_tyre

        return diagnose_tyre(path, radius_m=radius, aliases=aliases, effects=effects)
    from brakethermo.pipelines.diagnose.rig import diagnose_booster, diagnose_emb

    if rig == "emb":
        assert train is not None  # refused before any session was read
        return diagnose_emb(path, train_path=train, aliases=aliases, effects=effects)
    return diagnose_booster(path, train_path=train, fit_path=fit, aliases=aliases,
                            effects=effects)


def _render_rig(result: Any, folder: Path, rig: str) -> None:
    """A rig diagnosis on the console."""
    from brakethermo.io.units import unit_suffix

    s = result.summary
    us = unit_suffix(s["unit"])
    console.print(f"[bold]{escape(result.stem)}[/] ({rig}): the reference relation's held-out"
                  f" RMSE {s['gap']['rmse']:.3f}{us}, bias {s['gap']['bias']:+.3f}{us}"
                  f" ({s['units']}s {s['heldout_units']} held out)")
    console.print(_effects_table(s["effects"], s["unit"], 3))
    console.print(f"verdict: [bold]{escape(_verdict_text(s))}[/]")
    for reason in s.get("verdict_reasons", []):
        console.print(f"  {escape(reason)}", highlight=False)
    _next_steps(s)
    console.print(f"wrote {escape(str(folder / 'diagnosis.json'))} and "
                  f"{escape(str(folder / 'diagnosis' / 'index.html'))}")


def _effects_table(effects: list[dict], unit: str, digits: int) -> Table:
    """The candidates in the verdict's order, as a console table."""
    from brakethermo.io.units import unit_suffix

    weak = any(e.get("negligible") for e in effects)
    table = Table(title="Effects in the verdict's order (held-out shrink)" + (
        "; negligible ones after, by shrink" if weak else ""), title_justify="left")
    said = unit_suffix(unit)
    for col in ("effect", f"before{said}", f"after{said}", "shrink %", "95 % interval"):
        table.add_column(col, justify="left" if col == "effect" else "right", no_wrap=True)
    for e in effects:
        lo, hi = e["shrink_ci95_pct"]
        table.add_row(e["name"] + (" (negligible)" if e.get("negligible") else ""),
                      f"{e['rmse_before']:.{digits}f}",
                      f"{e['rmse_after']:.{digits}f}", f"{e['shrink_pct']:+.1f}",
                      _interval(lo, hi))
    return table


def _interval(lo: float, hi: float) -> str:
    """A shrink interval for a table; '–' where none was drawn (too few units)."""
    return f"{lo:+.0f} … {hi:+.0f}" if math.isfinite(lo) and math.isfinite(hi) else "–"


def _next_steps(s: dict) -> None:
    for step in s["next_steps"]:
        # soft-wrapped: a command cut mid-line by the console no longer pastes
        console.print(f"  next: {escape(step)}", highlight=False, soft_wrap=True)


def _verdict_text(s: dict) -> str:
    from brakethermo.report.page import verdict_text

    return verdict_text(s)


def _render(result: Any, folder: Path) -> None:  # a DiagnoseResult (imported lazily)
    s = result.summary
    console.print(f"[bold]{escape(result.stem)}[/]: reference model held-out RMSE "
                  f"{s['gap']['rmse_c']:.1f} °C (train laps {s['train_laps']}, held-out "
                  f"{s['heldout_laps']})")
    console.print(escape(s["consistency"]["summary"]))
    console.print(_effects_table(s["effects"], "°C", 1))
    for e in s["effects"][:3]:
        console.print(f"  {e['name']}: {escape(e['evidence'])}", highlight=False)
    for e in s.get("not_identifiable_from_one_spot", []):
        console.print(f"  {e['name']}: not diagnosed here — {escape(e['reason'])}",
                      highlight=False)
    for e in s["effects"]:
        if e["name"] in s["verdict_set"] and e.get("size_text"):
            console.print(f"  size of {e['name']}: {escape(e['size_text'])}", highlight=False)
    console.print(f"verdict: [bold]{escape(_verdict_text(s))}[/]; combined model: "
                  f"{' + '.join(s['combined']['effects']) or 'none'}")
    _next_steps(s)
    # the session's own warnings too (a renumbered or misplaced lap beacon, gaps): the
    # lap split above is built on them
    print_warnings([*s["warnings"], *s["run"].get("input_warnings", [])])
    console.print(f"wrote {escape(str(folder / 'diagnosis.json'))} and "
                  f"{escape(str(folder / 'diagnosis' / 'index.html'))} "
                  f"({s['run']['wall_time_s']:.1f} s)")
