"""``batch``: every session of a folder to estimates, per-lap reports and (optionally) MCAP.

The unit of work is one session (:func:`process_session`); the same function runs
in-process, in local worker processes or on a Dask distributed cluster. Multi-spot
(test) sessions are identified and estimated first; each single-spot (race) session is
then estimated with a law chosen deliberately (:func:`choose_law`: same disc, then same
track and vehicle, then the newest), never silently with another disc's law.

Each session's outputs go to ``OUT/<name>/`` through :func:`replace_session_dir`: the
batch's own entries are swapped in, another command's (a diagnosis, a what-if) are kept;
a failure or an interruption leaves the previous outputs as they were. A manifest in that directory
(hash of the input bytes, of the options and the package version) lets a re-run skip
sessions whose outputs are up to date.
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing
import os
import shutil
import time
import traceback
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal, Protocol

import numpy as np
import pandas as pd

from brakethermo import __version__
from brakethermo.config import config_dir
from brakethermo.errors import (
    EXIT_BATCH_PARTIAL,
    EXIT_OK,
    BrakethermoError,
    ConfigError,
    Interrupted,
)
from brakethermo.io.atomic import write_text_atomic
from brakethermo.io.formats import SUFFIXES as FORMAT_SUFFIXES
from brakethermo.io.session import Session
from brakethermo.io.writers import TRUTH_SUFFIX
from brakethermo.pipelines.output_dir import BATCH_FILES, replace_session_dir
from brakethermo.pipelines.outputs import write_json
from brakethermo.results.laps import flying_laps, round_temp
from brakethermo.thermal.disc import DiscSpec

SESSION_SUFFIXES = FORMAT_SUFFIXES  # every registered reader (brakethermo.io.formats)
MANIFEST = "batch_manifest.json"
MULTI_SPOT = tuple(f"disc_temp_spot{i}" for i in range(1, 5))
DEFAULT_LAW = "default (shipped)"
# Top-level steps of a session's wall time (sub-steps such as estimate_filter_s nest in them).
STEPS = ("read_s", "identify_s", "estimate_s", "write_s", "report_s", "mcap_s", "mdf_s")
SCHEDULER_TIMEOUT_S = 30.0  # connecting to a Dask scheduler
WORKER_PRELOAD = ("brakethermo.pipelines.batch", "brakethermo.report.lap_report")

Status = Literal["ok", "skipped", "failed", "deferred"]
Kind = Literal["multi", "single"]


@dataclass(frozen=True)
class BatchOptions:
    """What a batch run does; only :meth:`output_key` fields change the outputs.

    Attributes
    ----------
    out : Path
        Output root; each session writes ``out/<name>/``.
    h_law : Path or None
        h law TOML for single-spot sessions; None means the most recent law
        identified in this batch, else the shipped default.
    nodes : int or None
        Finite-element nodes of the estimate (the pipeline's default when None).
    aliases : Path or None
        User alias table for the readers.
    reports : bool
        Write the per-lap reports.
    mcap_out : bool
        Write ``estimate.mcap`` beside the estimate.
    mdf_out : bool
        Write ``estimate.mf4`` (ASAM MDF4) beside the estimate.
    workers : int
        Local worker processes (1 runs in this process).
    scheduler : str or None
        Dask scheduler address (``tcp://host:8786``); overrides ``workers``.
    force : bool
        Re-process sessions whose outputs are up to date.
    """

    out: Path
    h_law: Path | None = None
    nodes: int | None = None
    aliases: Path | None = None
    reports: bool = True
    mcap_out: bool = False
    mdf_out: bool = False
    workers: int = 1
    scheduler: str | None = None
    force: bool = False

    def output_key(self) -> str:
        """Hash of everything in the options that changes a session's outputs.

        The shipped configuration (datasheets, tuning, default h laws, aliases) is part
        of it: editing a shipped file re-processes the sessions it affects.
        """
        aliases = file_sha256(self.aliases) if self.aliases is not None else None
        key = {
            "nodes": self.nodes,
            "aliases": aliases,
            "reports": self.reports,
            "mcap_out": self.mcap_out,
            **({"mdf_out": True} if self.mdf_out else {}),  # old keys unchanged without it
            "configs": _configs_digest(),
        }
        return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()


@dataclass(frozen=True)
class RunOutput:
    """What the science of one session produced (written into the staging directory).

    Attributes
    ----------
    frame : DataFrame
        Estimate frame of OUTPUTS.md.
    node_radii : ndarray — m
    h_law : Path or None
        The ``h_law.toml`` identified from this session (multi-spot only), in the stage.
    timings : dict of str to float — s
        Wall time of the steps, e.g. ``identify_s``, ``estimate_s``, ``write_s``.
    disc : DiscSpec or None
        The datasheet the session was processed with (the session's ``disc`` fact or
        the default disc when None).
    """

    frame: pd.DataFrame
    node_radii: np.ndarray
    h_law: Path | None = None
    timings: dict[str, float] = field(default_factory=dict)
    disc: DiscSpec | None = None


class SessionRunner(Protocol):
    """The science of a batch: load a session; identify and/or estimate it."""

    def load(self, path: Path, options: BatchOptions) -> Session:
        """Read a session file."""
        ...

    def run(
        self, session: Session, stage: Path, options: BatchOptions, h_law: Path | None
    ) -> RunOutput:
        """Identify (multi-spot) and estimate ``session``, writing outputs into ``stage``.

        ``h_law`` is the law to estimate a single-spot session with (None: default).
        """
        ...


@dataclass(frozen=True)
class SessionTask:
    """One session to process.

    Attributes
    ----------
    path : Path
        Session file.
    name : str
        Output directory name under ``options.out``.
    options : BatchOptions
    input_sha256 : str
        Hash of the file's bytes (for the manifest).
    h_law : Path or None
        Law for a single-spot session; None means the shipped default.
    h_law_source : str
        Where that law comes from, for the table (``given``, ``identified: <name>``,
        ``default (shipped)``).
    h_law_reason : str
        Why that law was chosen (printed and recorded).
    defer_single : bool
        Return a single-spot session unprocessed (status ``deferred``, loaded session
        attached) because its h law is not known yet.
    session : Session or None
        Already loaded session (a deferred one), to avoid reading the file again.
    """

    path: Path
    name: str
    options: BatchOptions
    input_sha256: str
    h_law: Path | None = None
    h_law_source: str = DEFAULT_LAW
    defer_single: bool = False
    session: Session | None = None
    h_law_reason: str = ""


@dataclass
class SessionOutcome:
    """What happened to one session.

    Attributes
    ----------
    path : Path
    name : str
    status : {"ok", "skipped", "failed", "deferred"}
    kind : {"multi", "single"} or None
        None when the file could not be read.
    laps : int
    wall_s : float — s
    peaks : dict of str to float — degC
        Peak estimated temperature per spot over the session.
    reason : str
        Why it failed (or why it was skipped).
    h_law_source : str
        The h law a single-spot session was estimated with; for a multi-spot one,
        ``identified``.
    h_law_file : str or None
        Path of the law identified from this session (multi-spot).
    h_law_used : str or None
        Final path of the law the estimate used (None: the shipped default).
    h_law_reason : str
        Why that law was chosen.
    session_date : str
        The session's ``date`` fact, to find the most recent identified law.
    facts : dict of str to str
        ``disc`` (the datasheet id the session is processed with), ``track``,
        ``vehicle``, ``date`` — what :func:`choose_law` matches on.
    timings : dict of str to float — s
        ``read_s``, ``identify_s``, ``estimate_s``, ``report_s``, ``mcap_s``...
    session : Session or None
        The loaded session of a deferred outcome.
    """

    path: Path
    name: str
    status: Status
    kind: Kind | None = None
    laps: int = 0
    wall_s: float = 0.0
    peaks: dict[str, float] = field(default_factory=dict)
    reason: str = ""
    h_law_source: str = ""
    h_law_file: str | None = None
    h_law_used: str | None = None
    h_law_reason: str = ""
    session_date: str = ""
    facts: dict[str, str] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    session: Session | None = None

    def to_json(self) -> dict[str, Any]:
        """JSON-able record (without the session)."""
        return {
            "file": str(self.path),
            "name": self.name,
            "status": self.status,
            "kind": self.kind,
            "laps": self.laps,
            "wall_s": round(self.wall_s, 3),
            "peaks_c": {k: round_temp(v) for k, v in self.peaks.items()},
            "reason": self.reason,
            "h_law": self.h_law_source,
            "h_law_file": self.h_law_used,
            "h_law_reason": self.h_law_reason,
            "facts": self.facts,
            "timings_s": {k: round(v, 3) for k, v in self.timings.items()},
        }


@dataclass
class BatchResult:
    """Outcome of :func:`run_batch`, one entry per session file in discovery order."""

    outcomes: list[SessionOutcome]
    wall_s: float
    not_read: list[str] = field(default_factory=list)  # folders discovery did not enter

    @property
    def failed(self) -> list[SessionOutcome]:
        """The sessions that failed."""
        return [o for o in self.outcomes if o.status == "failed"]

    @property
    def exit_code(self) -> int:
        """0, or 3 when any session failed (OUTPUTS.md)."""
        return EXIT_BATCH_PARTIAL if self.failed else EXIT_OK

    def timing_totals(self) -> dict[str, float]:
        """Sum of each step's wall time over the processed sessions, s."""
        totals: dict[str, float] = {}
        for o in self.outcomes:
            for k, v in o.timings.items():
                totals[k] = totals.get(k, 0.0) + v
        return totals

    def step_shares(self) -> dict[str, tuple[float, float]]:
        """Seconds and share of the summed session time of each top-level step."""
        totals = self.timing_totals()
        steps = {k: totals[k] for k in STEPS if k in totals}
        whole = sum(steps.values()) or 1.0
        return {k: (v, v / whole) for k, v in steps.items()}

    def to_json(self) -> dict[str, Any]:
        """JSON-able summary of the run."""
        return {
            "wall_s": round(self.wall_s, 3),
            "step_share": {k: round(f, 4) for k, (_, f) in self.step_shares().items()},
            "exit_code": self.exit_code,
            "timings_s": {k: round(v, 3) for k, v in self.timing_totals().items()},
            "sessions": [o.to_json() for o in self.outcomes],
            "not_read": list(self.not_read),
        }


def _configs_digest() -> str:
    """SHA-256 over the shipped TOML configuration files (names and bytes)."""
    digest = hashlib.sha256()
    root = config_dir()
    for path in sorted(root.rglob("*.toml")):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def file_sha256(path: str | Path) -> str:
    """SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with Path(path).open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def discover_sessions(folder: str | Path, exclude: Iterable[Path] = (),
                      not_read: list[str] | None = None) -> list[Path]:
    """Session files under ``folder``, recursively, sorted.

    Files of every registered reader (extension case-insensitive); simulator truth files
    (``*.truth.parquet``), hidden files and directories, and anything under ``exclude``
    (the output root when it lies inside the folder) are left out. Sub-folders that
    cannot be read, and links to folders (a link can loop or lead out of the folder), are
    not entered; each is said in ``not_read`` (one sentence per folder) when given.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ConfigError("is not a folder; give the folder holding the session files", path=folder)
    excluded = [Path(e).resolve() for e in exclude]
    said = not_read if not_read is not None else []

    def unreadable(exc: OSError) -> None:
        said.append(f"{exc.filename}: cannot be read ({exc.strerror}); its sessions are"
                    " not in this batch")

    found = []
    for top, dirs, files in os.walk(folder, onerror=unreadable):
        here = Path(top)
        for d in list(dirs):
            if d.startswith("."):
                dirs.remove(d)
            elif (here / d).is_symlink():
                dirs.remove(d)
                said.append(f"{here / d}: a link to a folder, not followed (it could loop"
                            " or lead outside); pass its target as a batch of its own")
        for name in files:
            path = here / name
            if name.startswith(".") or path.suffix.lower() not in SESSION_SUFFIXES:
                continue
            if name.lower().endswith(TRUTH_SUFFIX):
                continue
            resolved = path.resolve()
            if any(resolved.is_relative_to(e) for e in excluded):
                continue
            if not path.is_file():
                if path.is_symlink():
                    said.append(f"{path}: a link to {os.readlink(path)}, which does not exist;"
                                " fix or remove the link")
                continue
            found.append(path)
    return sorted(found)


def output_names(files: list[Path], folder: Path) -> list[str]:
    """Output directory name of each file: its stem, made unique when stems collide.

    Colliding files are named after their path inside the folder, parts joined
    by ``__`` (and the extension appended if that still collides).
    """
    stems = [f.stem for f in files]
    names = []
    for f, stem in zip(files, stems, strict=True):
        if stems.count(stem) == 1:
            names.append(stem)
            continue
        rel = f.relative_to(folder)
        names.append("__".join((*rel.parent.parts, stem)))
    clashes = {n for n in names if names.count(n) > 1}
    names = [
        f"{n}_{f.suffix.lstrip('.').lower()}" if n in clashes else n
        for n, f in zip(names, files, strict=True)
    ]
    # Still one folder per session: ``s.mcap`` and ``s.MCAP`` (or ``s.mcap`` beside
    # ``s_mcap.mcap``) must not share one, also on a file system that folds case.
    final: list[str] = []
    seen: set[str] = set()
    for n in names:
        cand, k = n, 2
        while cand.casefold() in seen:
            cand, k = f"{n}_{k}", k + 1
        seen.add(cand.casefold())
        final.append(cand)
    return final


def is_multi_spot(session: Session) -> bool:
    """Whether a session carries the four-spot sensor (a test session)."""
    return all(session.has(c) for c in MULTI_SPOT)


def read_manifest(out_dir: Path) -> dict[str, Any] | None:
    """The batch manifest of a session's output directory, or None."""
    try:
        return json.loads((out_dir / MANIFEST).read_text())
    except (OSError, ValueError):
        return None


def _peaks(frame: pd.DataFrame) -> dict[str, float]:
    return {
        s: float(np.nanmax(frame[s].to_numpy(dtype=float)))
        for s in ("spot1", "spot2", "spot3", "spot4", "contact_avg")
        if s in frame and np.isfinite(frame[s].to_numpy(dtype=float)).any()
    }


def _reason(exc: BaseException) -> str:
    if isinstance(exc, BrakethermoError):
        return str(exc)
    where = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
    at = f" (at {Path(where.filename).name}:{where.lineno})" if where else ""
    return f"internal error {type(exc).__name__}: {exc}{at}"


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


def session_facts(session: Session) -> dict[str, str]:
    """What the h-law choice matches on: disc id as processed, track, vehicle, date."""
    from brakethermo.pipelines.models import DEFAULT_DISC

    meta = session.metadata
    facts = {"disc": str(meta.get("disc") or DEFAULT_DISC)}
    for key in ("track", "vehicle", "date"):
        if meta.get(key):
            facts[key] = str(meta[key])
    return facts


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
        outcome.status, outcome.reason = "failed", _reason(exc)
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
        }
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
            _flatten(write_identify(ident, stage), stage)
            if ident.diagnosis is not None:
                # the effect selection diagnosed the session: its verdict is a page too
                from brakethermo.pipelines.diagnose import write_diagnosis

                _flatten(write_diagnosis(ident.diagnosis, stage), stage)
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
            result.frame, np.asarray(result.node_radii), law_out, timings, disc=disc_of(result)
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


# ----------------------------------------------------------------------------- orchestration

Job = Callable[[SessionTask], SessionOutcome]
Event = Callable[[str, Any], None]


@contextmanager
def _executor(options: BatchOptions) -> Iterator[Executor | None]:
    """The executor the options ask for; None means run in this process."""
    address = options.scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS")
    if address:
        from distributed import Client

        try:
            client = Client(address, timeout=f"{SCHEDULER_TIMEOUT_S}s")
        except (OSError, TimeoutError) as exc:
            raise ConfigError(
                f"cannot reach the Dask scheduler at {address} ({exc}); check the address"
                " or run without --scheduler"
            ) from None
        try:
            yield client.get_executor(pure=False)
        finally:
            client.close()
    elif options.workers > 1:
        # A fork server (single-threaded, never forks this possibly threaded parent) with the
        # heavy imports done once, instead of every worker importing them on its own.
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(list(WORKER_PRELOAD))
        with ProcessPoolExecutor(max_workers=options.workers, mp_context=ctx) as pool:
            yield pool
    else:
        yield None


def _run_tasks(
    tasks: list[SessionTask], executor: Executor | None, job: Job, on_event: Event | None
) -> list[SessionOutcome]:
    outcomes: list[SessionOutcome] = []

    def finished(outcome: SessionOutcome) -> None:
        outcomes.append(outcome)
        if on_event is not None and outcome.status != "deferred":
            on_event("done", outcome)

    if executor is None:
        for task in tasks:
            if job is process_session and on_event is not None:
                # In this process the session can tell where it is; a worker cannot.
                finished(process_session(task, progress=lambda p: on_event("phase", p)))
            else:
                finished(job(task))
        return outcomes
    futures: dict[Future, SessionTask] = {executor.submit(job, t): t for t in tasks}
    for fut in as_completed(futures):
        task = futures[fut]
        try:
            outcome = fut.result()
        except Exception as exc:  # a worker died; the session is lost, not the batch
            outcome = SessionOutcome(task.path, task.name, "failed", reason=_reason(exc))
        finished(outcome)
    return outcomes


def _up_to_date(manifest: dict[str, Any] | None, sha: str, key: str) -> bool:
    return (
        manifest is not None
        and manifest.get("input_sha256") == sha
        and manifest.get("options_key") == key
        and manifest.get("version") == __version__
        # Written before the law choice recorded session facts: redo it once.
        and isinstance(manifest.get("facts"), dict)
    )


def _skipped(path: Path, name: str, manifest: dict[str, Any], out: Path) -> SessionOutcome:
    law_file = out / name / "h_law.toml" if manifest.get("kind") == "multi" else None
    return SessionOutcome(
        path=path,
        name=name,
        status="skipped",
        kind=manifest.get("kind"),
        laps=int(manifest.get("laps", 0)),
        peaks=dict(manifest.get("peaks_c", {})),
        reason="up to date",
        h_law_source=str(manifest.get("h_law_source", "")),
        h_law_file=str(law_file) if law_file is not None and law_file.is_file() else None,
        h_law_used=manifest.get("h_law_used"),
        h_law_reason=str(manifest.get("h_law_reason", "")),
        session_date=str(manifest.get("session_date", "")),
        facts={str(k): str(v) for k, v in dict(manifest.get("facts") or {}).items()},
    )


@dataclass(frozen=True)
class LawChoice:
    """The h law a single-spot session is estimated with, and why.

    Attributes
    ----------
    path : Path or None
        The law file; None is the law shipped for the session's disc.
    source : str
        Short tag for tables: ``given``, ``identified: <session>``, ``default (shipped)``.
    reason : str
        One sentence for the console, the batch JSON, the manifest and summary.json.
    """

    path: Path | None
    source: str
    reason: str


def choose_law(facts: dict[str, str], outcomes: Iterable[SessionOutcome]) -> LawChoice:
    """Choose the identified law for a single-spot session with ``facts``.

    Only laws identified for the same disc qualify (a law of another disc is never
    used); among them the one from the same track and vehicle wins, then the newest
    (session date, then file time). Without a qualifying law, the law shipped for the
    disc — and the reason says which other laws were passed over.
    """
    laws = [o for o in outcomes if o.kind == "multi" and o.h_law_file and o.status != "failed"]
    disc = facts.get("disc", "")
    same_disc = [o for o in laws if o.facts.get("disc") == disc]
    if not same_disc:
        others = sorted(f"{o.name} ({o.facts.get('disc', '?')})" for o in laws)
        passed = f"; laws of other discs not used: {', '.join(others)}" if others else ""
        return LawChoice(
            None, DEFAULT_LAW,
            f"no law identified in this batch for disc {disc}: shipped default{passed}",
        )  # fmt: skip

    def matches(o: SessionOutcome, key: str) -> bool:
        return bool(facts.get(key)) and o.facts.get(key) == facts.get(key)

    def rank(o: SessionOutcome) -> tuple[bool, bool, str, float]:
        try:
            mtime = o.path.stat().st_mtime
        except OSError:
            mtime = 0.0
        return matches(o, "track"), matches(o, "vehicle"), o.session_date, mtime

    best = max(same_disc, key=rank)
    why = [f"same disc {disc}"]
    why += [f"same {k} {facts[k]}" for k in ("track", "vehicle") if matches(best, k)]
    if len(same_disc) > 1:
        why.append(f"newest of {len(same_disc)} for this disc")
    return LawChoice(
        Path(str(best.h_law_file)), f"identified: {best.name}",
        f"identified from {best.name} ({', '.join(why)})",
    )  # fmt: skip


def preflight(options: BatchOptions) -> None:
    """The user's errors, before any session is touched (exit 1, not a batch of failures).

    Raises
    ------
    ConfigError
        An output place that cannot be written, a broken ``--h-law`` or ``--aliases``.
    """
    from brakethermo.io.aliases import load_aliases
    from brakethermo.pipelines.models import read_calibration
    from brakethermo.pipelines.output_dir import check_output_dir
    from brakethermo.pipelines.tuning import check_overrides

    check_output_dir(options.out)
    check_overrides({"nodes": options.nodes}, "--nodes:")
    load_aliases(options.aliases)
    if options.h_law is not None:
        read_calibration(options.h_law)


def _interrupted(files: list[Path], names: list[str], done: dict[Path, SessionOutcome]
                 ) -> Interrupted:
    """What an interrupt leaves: finished sessions complete, the others untouched."""
    finished = [o.name for o in done.values() if o.status in ("ok", "skipped")]
    pending = [n for p, n in zip(files, names, strict=True)
               if p not in done or done[p].status == "deferred"]
    return Interrupted(
        f"interrupted: {len(finished)} of {len(files)} sessions finished"
        f" ({', '.join(finished) or 'none'}) and their outputs are complete; not done:"
        f" {', '.join(pending) or 'none'}, their folders as before. Run the same command"
        " again to resume (finished sessions are skipped)")


def _check_places(folder: Path, out: Path) -> None:
    """The output folder may sit inside the input folder, not be it or hold it."""
    f, o = folder.resolve(), out.resolve()
    if f == o:
        raise ConfigError(f"--out {out} is the input folder: its outputs would be read as"
                          " sessions; give another folder, e.g. --out out")
    if f.is_relative_to(o):
        raise ConfigError(f"the input folder {folder} is inside --out {out}: give an output"
                          " folder outside it")


def _second_pass(
    known_single: list[tuple[Path, str, str, dict[str, Any]]], first: list[SessionTask],
    done: dict[Path, SessionOutcome], options: BatchOptions, out: Path,
    on_event: Event | None,
) -> list[SessionTask]:
    """The single-spot sessions, once the test sessions of this batch have their laws: the
    ones deferred in the first pass, and the ones up to date unless their law changed
    (those are skipped here, into ``done``)."""
    identified = [o for o in done.values() if o.kind == "multi"]
    second: list[SessionTask] = []
    for path, name, sha, manifest in known_single:
        facts = {str(k): str(v) for k, v in dict(manifest["facts"]).items()}
        choice = choose_law(facts, identified)
        law_sha = file_sha256(choice.path) if choice.path is not None else DEFAULT_LAW
        if manifest.get("h_law_sha256") == law_sha:
            done[path] = _skipped(path, name, manifest, out)
            if on_event is not None:
                on_event("done", done[path])
            continue
        second.append(SessionTask(path, name, options, sha, choice.path, choice.source,
                                  h_law_reason=choice.reason))
    for o in [o for o in done.values() if o.status == "deferred"]:
        task = next(t for t in first if t.path == o.path)
        choice = choose_law(o.facts, identified)
        second.append(replace(task, h_law=choice.path, h_law_source=choice.source,
                              h_law_reason=choice.reason, defer_single=False,
                              session=o.session))
    return second


def run_batch(
    folder: str | Path,
    options: BatchOptions,
    *,
    job: Job = process_session,
    on_event: Event | None = None,
) -> BatchResult:
    """Process every session file under ``folder`` (see the module docstring).

    Parameters
    ----------
    folder : path
        Searched recursively for ``.mcap``, ``.parquet``, ``.csv`` session files.
    options : BatchOptions
    job : callable, optional
        ``SessionTask -> SessionOutcome``; :func:`process_session` by default. It must
        be picklable for worker processes and Dask.
    on_event : callable, optional
        ``on_event("start", n_files)`` once, then ``on_event("done", outcome)`` as each
        session finishes (or is skipped) — for progress display.

    Returns
    -------
    BatchResult
        One outcome per file; :attr:`BatchResult.exit_code` is 3 when any failed.
    """
    t0 = time.perf_counter()
    folder = Path(folder)
    out = Path(options.out)
    _check_places(folder, out)
    not_read: list[str] = []
    files = discover_sessions(folder, exclude=[out], not_read=not_read)
    preflight(options)
    names = output_names(files, folder)
    if on_event is not None:
        on_event("start", len(files))
    key = options.output_key()
    given_sha = file_sha256(options.h_law) if options.h_law is not None else None

    done: dict[Path, SessionOutcome] = {}
    known_single: list[tuple[Path, str, str, dict[str, Any]]] = []
    first: list[SessionTask] = []
    sizes: dict[Path, int] = {}
    for path, name in zip(files, names, strict=True):
        try:
            sha = file_sha256(path)
            sizes[path] = path.stat().st_size
        except OSError as exc:
            done[path] = SessionOutcome(path, name, "failed", reason=f"{path}: cannot read ({exc})")
            continue
        manifest = None if options.force else read_manifest(out / name)
        if _up_to_date(manifest, sha, key):
            assert manifest is not None
            if manifest.get("kind") == "multi" or (
                given_sha is not None and manifest.get("h_law_sha256") == given_sha
            ):
                done[path] = _skipped(path, name, manifest, out)
                continue
            if given_sha is None and manifest.get("kind") == "single":
                known_single.append((path, name, sha, manifest))
                continue
        first.append(
            SessionTask(
                path=path,
                name=name,
                options=options,
                input_sha256=sha,
                h_law=options.h_law,
                h_law_source="given" if options.h_law is not None else DEFAULT_LAW,
                h_law_reason="given with --h-law" if options.h_law is not None else "",
                defer_single=options.h_law is None,
            )
        )
    if on_event is not None:
        for o in done.values():
            on_event("done", o)

    try:
        # Longest first keeps a pool busy to the end; file size stands in for session length.
        first.sort(key=lambda task: -sizes[task.path])
        with _executor(options) as executor:
            for o in _run_tasks(first, executor, job, on_event):
                done[o.path] = o
            second = _second_pass(known_single, first, done, options, out, on_event)
            for o in _run_tasks(second, executor, job, on_event):
                first_pass = done.get(o.path)
                if first_pass is not None and first_pass.status == "deferred":
                    # The file was read in the first pass; count that read in this session.
                    o.wall_s += first_pass.wall_s
                    o.timings["read_s"] = (o.timings.get("read_s", 0.0)
                                           + first_pass.timings["read_s"])
                done[o.path] = o
    except KeyboardInterrupt:
        raise _interrupted(files, names, done) from None
    result = BatchResult([done[p] for p in files], time.perf_counter() - t0, not_read)
    if options.reports and files:
        from brakethermo.report.index import write_batch_index

        write_batch_index(out, folder, (o.to_json() for o in result.outcomes))
    return result
