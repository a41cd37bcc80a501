"""Entry points: one session, several pooled, and the writers of diagnosis.json, the
parquet and the page."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from brakethermo import __version__
from brakethermo.diagnosis.verdict import (
    decide,
)
from brakethermo.errors import ConfigError, DataError
from brakethermo.pipelines.diagnose._common import (
    REFERENCE_WARNING,
    RULE,
    DiagnoseOptions,
    DiagnoseResult,
    with_out,
)
from brakethermo.pipelines.diagnose.data_power import READS_LIKE
from brakethermo.pipelines.diagnose.four_spot import diagnose_session
from brakethermo.pipelines.diagnose.pooled import (
    end_to_end,
    leading,
    pooled_consistency,
    pooled_effect,
    pooled_gap,
)
from brakethermo.pipelines.inputs import load_timed
from brakethermo.pipelines.models import disc_for


def diagnose(path: str | Path, options: DiagnoseOptions | None = None,
             progress: Callable[[str, int, int], None] | None = None) -> DiagnoseResult:
    """Load a session file and diagnose it (:func:`diagnose_session`)."""
    options = options or DiagnoseOptions()
    session, read_s = load_timed(path, options.aliases)
    result = diagnose_session(session, options, progress)
    result.timings["read_s"] = read_s
    return result


def diagnose_many(paths: Sequence[str | Path], options: DiagnoseOptions | None = None,
                  progress: Callable[[str, int, int], None] | None = None
                  ) -> tuple[list[DiagnoseResult], dict[str, Any]]:
    """Diagnose several sessions of one bike and disc, then pool their evidence.

    Raises
    ------
    DataError
        Sessions of different discs, or a session without the four spots pooling needs.
    """
    options = options or DiagnoseOptions()
    distinct_sessions(paths)
    sessions = [load_timed(p, options.aliases)[0] for p in paths]
    discs = {s.path.name: disc_for(s, options.disc).id for s in sessions}
    if len(set(discs.values())) > 1:
        listing = ", ".join(f"{n}: {d}" for n, d in discs.items())
        raise DataError(f"diagnose pools sessions of one disc; these run {listing}: diagnose"
                        " each disc's sessions in their own call")
    for s in sessions:
        have = [i for i in range(1, 5) if s.has(f"disc_temp_spot{i}")]
        if len(have) < 4:
            logs = (f"spot(s) {', '.join(map(str, have))} only" if have else
                    "the race sensor only (disc_temp)" if s.has("disc_temp") else
                    "no disc temperature")
            raise DataError(
                f"pooling several sessions needs the four-spot sensor in each; this one logs"
                f" {logs}: diagnose it alone", path=s.path)
    results = []
    for i, s in enumerate(sessions):
        def tick(label: str, done: int, total: int, i: int = i, name: str = s.path.name
                 ) -> None:
            if progress:
                progress(f"{name} ({i + 1}/{len(sessions)}): {label}", done, total)
        results.append(diagnose_session(s, options, tick))
    return results, pool(results)


POOLED_FOLDER = "pooled"  # write_pooled's OUT/pooled/, beside the sessions' OUT/<stem>/


def distinct_sessions(paths: Sequence[str | Path]) -> None:
    """Each session once and each in its own output folder (``OUT/<stem>/``): a file given
    twice would count its evidence twice, two files of one stem would share a folder, and
    a session named ``pooled`` would have its diagnosis replaced by the pooled one.

    Raises
    ------
    ConfigError
        A file given twice, two files of one stem, or a session of stem ``pooled`` among
        several (checked before any session is read).
    """
    seen: dict[str, Path] = {}
    for p in map(Path, paths):
        other = seen.get(p.stem.casefold())
        if other is not None and other.resolve() == p.resolve():
            raise ConfigError(f"{p} is given twice: pool each session once")
        if other is not None:
            raise ConfigError(f"{other} and {p} share the name '{p.stem}', and each session's"
                              " diagnosis goes to OUT/<name>/: rename one (or diagnose them"
                              " in separate calls)")
        seen[p.stem.casefold()] = p
    clash = next((p for p in map(Path, paths) if p.stem.casefold() == POOLED_FOLDER), None)
    if clash is not None and len(seen) > 1:
        raise ConfigError(f"{clash}: a session named '{clash.stem}' would have its diagnosis"
                          f" in OUT/{clash.stem}/, where the pooled diagnosis of these sessions"
                          " goes: rename it (or diagnose it in a separate call)")


def pool(results: Sequence[DiagnoseResult]) -> dict[str, Any]:
    """One verdict from several sessions: their held-out braking cycles resampled together.

    Per-session verdicts stay beside the pooled one; an effect significant in one run only
    is said so (a one-off — a gusty session, one set of pads — is not the disc).
    """
    names = [e.name for e in results[0].evidence]
    by_session = [{e.name: e for e in r.evidence} for r in results]
    ref = np.concatenate([r.reference_sse for r in results if r.reference_sse is not None])
    # a fit at a bound in any run is said pooled too (as a rig's pooled diagnosis does):
    # the pooled row was never at a bound, and a slipstream straight at 1.6 went unsaid
    evidence = [end_to_end([b[n] for b in by_session], leading(_rows(results, n)),
                           n_params=0, signature=None, at_bound="; ".join(
                               f"{b[n].at_bound} (in {r.stem})" for r, b
                               in zip(results, by_session, strict=True) if b[n].at_bound))
                for n in names if all(n in b for b in by_session)]
    blind_sets = [{u["name"]: u["why"] for u in r.summary.get("untestable", [])}
                  for r in results]
    blind = {n: f"in every session (in {results[0].stem}: {why})"
             for n, why in blind_sets[0].items() if all(n in b for b in blind_sets)}
    decision = decide(ref, evidence, RULE, untestable=blind, reads_like=READS_LIKE)
    stems = [r.stem for r in results]
    summaries = [r.summary for r in results]
    seen_in = {n: [r.stem for r in results for e in r.summary["effects"]
                   if e["name"] == n and e["significant"]] for n in names}
    rows = []
    for row in decision.rows:
        per = {r.stem: next(e["shrink_pct"] for e in r.summary["effects"]
                            if e["name"] == row["name"]) for r in results}
        pooled = pooled_effect(row["name"], summaries, stems, row["shrink_pct"])
        rows.append({"name": row["name"], **pooled, **row, "per_session_shrink_pct": per,
                     "significant_in": seen_in[row["name"]]})
    shrinks = {row["name"]: row["per_session_shrink_pct"] for row in rows}
    notes = [f"{n} is significant in {seen_in[n][0]} only (held-out shrink per session: "
             + ", ".join(f"{k} {v:+.0f} %" for k, v in shrinks.get(n, {}).items())
             + "): a one-off of that run (a gusty day, one set of pads) or a difference"
             " between the runs" for n in names if len(seen_in[n]) == 1]
    own = {r.stem: r.summary["verdict"] for r in results if r.summary["verdict"] != "none"}
    if len(set(own.values())) > 1:
        notes.append("the sessions' own verdicts differ ("
                     + "; ".join(f"{k}: {v}" for k, v in own.items())
                     + "): the pooled figures weigh each run's braking cycles by the size of"
                     " its gap, so the run with the larger gap leads them — read the"
                     " per-session verdicts")
    first = results[0].summary
    return {
        "sessions": [str(r.session.path) for r in results],
        "reference": first["reference"],
        "train_laps": {r.stem: r.summary["train_laps"] for r in results},
        "heldout_laps": {r.stem: r.summary["heldout_laps"] for r in results},
        "gap": pooled_gap(summaries, stems),
        "where": {r.stem: r.summary["where"]["by_spot_phase"] for r in results},
        "consistency": pooled_consistency(summaries, stems),
        "effects": rows,
        **decision.summary(),
        "per_session": [{"session": r.stem, "verdict": r.summary["verdict"],
                         "verdict_set": r.summary["verdict_set"]} for r in results],
        "notes": notes,
        # each run's warnings on its own reference fit (an h law flat with speed)
        "warnings": [f"{r.stem}: {w}" for r in results for w in r.summary.get("warnings", [])
                     if w.startswith(REFERENCE_WARNING)],
        "run": {"brakethermo": __version__, "disc": first["run"]["disc"],
                "pooled_units": int(ref.shape[0])},
    }


def _rows(results: Sequence[DiagnoseResult], name: str) -> list[dict[str, Any]]:
    """Each session's ``effects`` entry of ``name``, in session order."""
    return [next(e for e in r.summary["effects"] if e["name"] == name) for r in results]


def write_pooled(summary: dict[str, Any], out_dir: str | Path) -> Path:
    """``<out>/pooled/diagnosis.json`` and its page ``index.html`` beside it (disc and rig
    pools); returns the JSON's path (``summary``'s suggested commands are given ``--out
    out_dir``, in place)."""
    from brakethermo.pipelines.outputs import write_json
    from brakethermo.report.page import write_page
    from brakethermo.report.pooled_diagnosis_page import pooled_page

    summary.update(with_out(summary, out_dir))
    from brakethermo.pipelines.output_dir import refresh_out_index

    path = write_json(Path(out_dir) / POOLED_FOLDER / "diagnosis.json", summary)
    write_page(pooled_page(summary), path.parent)
    refresh_out_index(out_dir)  # a batch's index there links the pooled page
    return path


def write_diagnosis(result: DiagnoseResult, out_dir: str | Path,
                    shown_out: str | Path | None = None) -> Path:
    """Write ``<out>/<stem>/diagnosis.json``, ``diagnosis.parquet`` and the report page.

    The page and its PNGs go to ``<out>/<stem>/diagnosis/`` (staged and swapped in whole)
    so they never mix with the estimate's per-lap reports in the same session folder.
    ``shown_out``: the ``--out`` the suggested commands name, when ``out_dir`` is a
    staging folder (batch).
    """
    import pandas as pd

    from brakethermo.io.atomic import atomic_dir
    from brakethermo.pipelines.output_dir import refresh_indexes
    from brakethermo.pipelines.outputs import write_json, write_parquet
    from brakethermo.report.diagnose_report import diagnosis_page
    from brakethermo.report.page import write_page

    folder = Path(out_dir) / result.stem
    folder.mkdir(parents=True, exist_ok=True)
    # the commands it suggests write where this one did
    result.summary = with_out(result.summary, shown_out or out_dir)
    cols: dict[str, np.ndarray] = {"time": result.time, "lap": result.lap.astype(np.int64),
                                   "lap_distance": result.lap_distance}
    for i in range(4):
        cols[f"spot{i + 1}"] = result.y[:, i]
        cols[f"reference_spot{i + 1}"] = result.reference_pred[:, i]
        if result.best_pred is not None:
            cols[f"best_spot{i + 1}"] = result.best_pred[:, i]
    cols["nis"] = result.nis
    units = {c: {"unit": "degC"} for c in cols if "spot" in c}
    units.update(time={"unit": "s"}, lap_distance={"unit": "m"})
    write_parquet(folder / "diagnosis.parquet", pd.DataFrame(cols), units,
                  {"brakethermo": __version__, "session": str(result.session.path)})
    write_json(folder / "diagnosis.json", result.summary)
    page = diagnosis_page(result.summary, result.time, result.lap, result.y,
                          result.reference_pred, result.best_pred, result.lap_distance,
                          result.nis, result.stem)
    with atomic_dir(folder / "diagnosis") as tmp:
        write_page(page, tmp)
    refresh_indexes(folder)  # the session index links the page (or a small one does)
    return folder

