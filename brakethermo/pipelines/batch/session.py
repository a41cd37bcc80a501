"""One session, start to finish: read, identify and/or estimate, write the pages and
exports into a staging folder that replaces the old outputs only when complete."""

from __future__ import annotations

import json
import os
import shutil
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from brakethermo import __version__
from brakethermo.errors import (
    BrakethermoError,
)
from brakethermo.io.atomic import write_text_atomic
from brakethermo.io.kinds import KINDS, detect_rig
from brakethermo.io.session import Session
from brakethermo.pipelines.batch.discovery import MANIFEST, output_fingerprints
from brakethermo.pipelines.batch.laws import DISC_ASSUMED_FACT, is_multi_spot, session_facts
from brakethermo.pipelines.batch.tasks import (
    DEFAULT_LAW,
    RIG_SESSION,
    BatchOptions,
    RunOutput,
    SessionOutcome,
    SessionRunner,
    SessionTask,
    file_sha256,
)
from brakethermo.pipelines.output_dir import BATCH_FILES, replace_session_dir
from brakethermo.pipelines.outputs import write_json
from brakethermo.results.laps import flying_laps


@dataclass(frozen=True)
class Phase:
    """Progress inside one session, for the batch progress display.

    Attributes
    ----------
    name : str
        The session's output name.
    phase : str
        ``reading``, ``identifying h(V)``, ``estimating``, ``writing``, ``reports``, ``mcap``.
    done, total : int
        Laps done of the session's laps in this phase (0/0 when the phase has no laps).
    """

    name: str
    phase: str
    done: int = 0
    total: int = 0


Progress = Callable[[Phase], None]


def _peaks(frame: pd.DataFrame) -> dict[str, float]:
    return {
        s: float(np.nanmax(frame[s].to_numpy(dtype=float)))
        for s in ("spot1", "spot2", "spot3", "spot4", "contact_avg")
        if s in frame and np.isfinite(frame[s].to_numpy(dtype=float)).any()
    }


def failure_reason(exc: BaseException) -> str:
    if isinstance(exc, BrakethermoError):
        return str(exc)
    where = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
    at = f" (at {Path(where.filename).name}:{where.lineno})" if where else ""
    return f"internal error {type(exc).__name__}: {exc}{at}"


def process_session(
    task: SessionTask, runner: SessionRunner | None = None, progress: Progress | None = None
) -> SessionOutcome:
    """Process one session into ``options.out/<name>/``, never raising.

    Loads the session (unless the task carries it), identifies and estimates it
    through ``runner``, writes the per-lap reports, the MCAP export if asked, and the
    manifest last; everything in a staging directory that replaces the old output
    directory only when complete.

    Parameters
    ----------
    task : SessionTask
    runner : SessionRunner, optional
        The science; :class:`PipelineRunner` (the project's pipelines) by default.
    progress : callable, optional
        Called with a :class:`Phase` as the session moves through its steps.
    """

    def report(phase: str, done: int = 0, total: int = 0) -> None:
        if progress is not None:
            progress(Phase(task.name, phase, done, total))

    if runner is None:
        runner = PipelineRunner()
        if hasattr(runner, "progress"):
            runner.progress = report
    t0 = time.perf_counter()
    outcome = SessionOutcome(path=task.path, name=task.name, status="failed")
    try:
        session = task.session
        if session is None:
            report("reading")
            session = runner.load(task.path, task.options)
        outcome.timings["read_s"] = time.perf_counter() - t0
        outcome.kind = "multi" if is_multi_spot(session) else "single"
        outcome.facts = session_facts(session)
        outcome.session_date = outcome.facts.get("date", "")
        if outcome.kind == "single" and task.defer_single:
            outcome.status, outcome.session = "deferred", session
            outcome.wall_s = time.perf_counter() - t0
            return outcome
        _write_outputs(task, session, runner, outcome, report)
        outcome.status = "ok"
    except Exception as exc:  # one bad file never stops the batch
        outcome.status, outcome.reason = "failed", failure_reason(exc)
        rig = detect_rig(task.path, task.options.aliases)
        if rig is not None:  # a rig log in the folder is not a disc session that failed
            kind = KINDS[rig]
            outcome.status, outcome.kind = RIG_SESSION, rig  # not "single": no disc spot
            # nor a disc: the facts had the default disc's id (disc: cc-340-8) for a rig
            outcome.facts.pop("disc", None)
            outcome.facts.pop(DISC_ASSUMED_FACT, None)  # nor a disc taken for want of one
            outcome.reason = (f"{kind.words} session, not a disc one: {kind.command} reads"
                              " it (batch estimates the disc sessions)")
    outcome.wall_s = time.perf_counter() - t0
    return outcome


def _finalise_summary(stage: Path, target: Path, choice: str) -> dict[str, Any] | None:
    """Point ``summary.json`` at the final folder (not the stage) and record the law choice."""
    path = stage / "summary.json"
    if not path.is_file():
        return None
    summary = json.loads(path.read_text())
    run = summary.setdefault("run", {})
    law = run.get("h_law")
    if isinstance(law, str) and law and Path(law).is_relative_to(stage):
        run["h_law"] = str(target / Path(law).relative_to(stage))
    run["h_law_choice"] = choice
    write_json(path, summary)
    return summary


def _write_outputs(
    task: SessionTask, session: Session, runner: SessionRunner, outcome: SessionOutcome,
    report: Callable[..., None],
) -> None:
    # Imported here: matplotlib loads only where sessions are processed (fast CLI start).
    from brakethermo.report.lap_report import write_session_report
    from brakethermo.report.mcap_export import write_estimate_mcap
    from brakethermo.report.session_links import refresh_page_links

    target = task.options.out / task.name
    single = outcome.kind == "single"
    with replace_session_dir(target, BATCH_FILES) as stage:
        report("identifying h(V)" if not single else "estimating")
        run = runner.run(session, stage, task.options, task.h_law if single else None)
        outcome.timings.update(run.timings)
        outcome.warnings = list(getattr(run, "warnings", []))
        if single:
            outcome.h_law_source = task.h_law_source
            outcome.h_law_reason = task.h_law_reason
            outcome.h_law_used = str(task.h_law) if task.h_law is not None else None
            law_sha = file_sha256(task.h_law) if task.h_law is not None else DEFAULT_LAW
        else:
            outcome.h_law_source = "identified"
            outcome.h_law_reason = "identified from this session"
            law_sha = file_sha256(run.h_law) if run.h_law is not None else None
            if run.h_law is not None:
                outcome.h_law_file = str(target / run.h_law.relative_to(stage))
                outcome.h_law_used = outcome.h_law_file
        summary = _finalise_summary(stage, target, outcome.h_law_reason)
        laps = [int(v) for v in pd.unique(run.frame["lap"])]
        if task.options.reports:
            t = time.perf_counter()
            write_session_report(
                run.frame, session, stage, node_radii=run.node_radii, disc=run.disc,
                summary=summary, progress=lambda done, total: report("reports", done, total),
                back_href="../index.html",
            )  # fmt: skip
            outcome.timings["report_s"] = time.perf_counter() - t
        # what both estimate exports (MCAP, MDF) record beside the frame
        export_kw: dict[str, Any] = {
            "node_radii": run.node_radii,
            **({"spot_radii": run.disc.spot_radii} if run.disc is not None else {}),
            "start_epoch_s": session.start_epoch_s,
            "source": task.path.name,
        }
        if task.options.mcap_out:
            report("mcap")
            t = time.perf_counter()
            write_estimate_mcap(run.frame, stage / "estimate.mcap", **export_kw)
            outcome.timings["mcap_s"] = time.perf_counter() - t
        if task.options.mdf_out:
            from brakethermo.report.mdf_export import write_estimate_mdf

            t = time.perf_counter()
            write_estimate_mdf(run.frame, stage / "estimate.mf4", **export_kw,
                               date=session.metadata.get("date"))
            outcome.timings["mdf_s"] = time.perf_counter() - t
        outcome.laps = flying_laps(laps)
        outcome.peaks = _peaks(run.frame)
        manifest = {
            "input": str(task.path),
            "input_sha256": task.input_sha256,
            "options_key": task.options.output_key(),
            "version": __version__,
            "kind": outcome.kind,
            "h_law_sha256": law_sha,
            "h_law_source": outcome.h_law_source,
            "h_law_file": outcome.h_law_file,
            "h_law_used": outcome.h_law_used,
            "h_law_reason": outcome.h_law_reason,
            "session_date": outcome.session_date,
            "facts": outcome.facts,
            "laps": outcome.laps,
            "peaks_c": outcome.peaks,
            "warnings": outcome.warnings,  # said again when a later batch skips it
        }
        manifest["outputs_sha256"] = output_fingerprints(stage)
        write_text_atomic(stage / MANIFEST, json.dumps(manifest, indent=2) + "\n")
    refresh_page_links(target)


class PipelineRunner:
    """The project's pipelines: ``identify-h`` then ``estimate`` (multi-spot), ``estimate``.

    Parameters
    ----------
    progress : callable, optional
        ``progress(phase, done, total)`` as the run moves from identification to estimation.
    """

    def __init__(self, progress: Callable[[str, int, int], None] | None = None):
        self.progress = progress

    def _phase(self, phase: str) -> None:
        if self.progress is not None:
            self.progress(phase, 0, 0)

    def load(self, path: Path, options: BatchOptions) -> Session:
        """Read ``path`` with the project's readers."""
        from brakethermo.io.load import load_session

        return load_session(path, aliases=options.aliases)

    def run(
        self, session: Session, stage: Path, options: BatchOptions, h_law: Path | None
    ) -> RunOutput:
        """Identify (multi-spot) and estimate, writing the pipelines' outputs into ``stage``."""
        from brakethermo.pipelines.estimate import (
            EstimateOptions,
            disc_of,
            estimate_from_session,
            write_estimate,
        )
        from brakethermo.pipelines.models import disc_warnings

        timings: dict[str, float] = {}
        law_out = None
        if is_multi_spot(session):
            from brakethermo.pipelines.identify_h import (
                IdentifyOptions,
                identify_from_session,
                write_identify,
            )

            t = time.perf_counter()
            ident = identify_from_session(session, IdentifyOptions(aliases=options.aliases))
            timings["identify_s"] = time.perf_counter() - t
            t = time.perf_counter()
            _flatten(write_identify(ident, stage, options.out), stage)
            if ident.diagnosis is not None:
                # the effect selection diagnosed the session: its verdict is a page too
                from brakethermo.pipelines.diagnose import write_diagnosis

                _flatten(write_diagnosis(ident.diagnosis, stage, options.out), stage)
            timings["write_s"] = time.perf_counter() - t
            law_out = stage / "h_law.toml"
            h_law = law_out
            self._phase("estimating")
        t = time.perf_counter()
        estimate_options = EstimateOptions(
            h_law=h_law, nodes=options.nodes, aliases=options.aliases
        )
        result = estimate_from_session(session, estimate_options)
        timings["estimate_s"] = time.perf_counter() - t
        self._phase("writing")
        for step in ("filter_s", "smoother_s", "scoring_s"):
            if step in result.timings:
                timings[f"estimate_{step}"] = result.timings[step]
        t = time.perf_counter()
        _flatten(write_estimate(result, stage), stage)
        timings["write_s"] = timings.get("write_s", 0.0) + time.perf_counter() - t
        return RunOutput(
            result.frame, np.asarray(result.node_radii), law_out, timings, disc=disc_of(result),
            warnings=disc_warnings(result.summary["run"]["warnings"]),
        )


def _flatten(written: Path, stage: Path) -> None:
    """Move what a pipeline writer put in ``stage/<stem>/`` up into ``stage``."""
    sub = Path(written)
    if sub.is_file():
        sub = sub.parent
    if sub.resolve() == stage.resolve() or not sub.is_dir():
        return
    for item in sub.iterdir():
        os.replace(item, stage / item.name)
    shutil.rmtree(sub, ignore_errors=True)
