"""``run_batch``: discovery, the first pass (test sessions, and races with a given law),
the second (races with the laws just identified), the index."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from brakethermo.errors import (
    ConfigError,
    DataError,
    Interrupted,
    record_output,
)
from brakethermo.io.atomic import remove_own_stages
from brakethermo.pipelines.batch.discovery import (
    SESSION_SUFFIXES,
    discover_sessions,
    earlier_sessions,
    output_names,
    read_manifest,
    skipped_outcome,
    up_to_date,
)
from brakethermo.pipelines.batch.laws import second_pass
from brakethermo.pipelines.batch.scheduling import executor_for, run_tasks
from brakethermo.pipelines.batch.session import process_session
from brakethermo.pipelines.batch.tasks import (
    DEFAULT_LAW,
    BatchOptions,
    BatchResult,
    Event,
    Job,
    SessionOutcome,
    SessionTask,
    file_sha256,
)
from brakethermo.pipelines.output_dir import check_same_session
from brakethermo.pipelines.preflight import preflight
from brakethermo.report.index import is_batch_index

# an up-to-date single-spot session whose law the second pass chooses again
KnownSingle = tuple[Path, str, str, dict[str, Any]]  # path, name, sha256, manifest


def _interrupted(files: list[Path], names: list[str], done: dict[Path, SessionOutcome],
                 force: bool = False) -> Interrupted:
    """What an interrupt leaves: finished sessions complete, the others untouched."""
    finished = [o.name for o in done.values() if o.status in ("ok", "skipped")]
    pending = [n for p, n in zip(files, names, strict=True)
               if p not in done or done[p].status == "deferred"]
    resume = (" (without --force, which redoes every session, finished sessions are"
              " skipped)" if force else " (finished sessions are skipped)")
    return Interrupted(
        f"interrupted: {len(finished)} of {len(files)} sessions finished"
        f" ({', '.join(finished) or 'none'}) and their outputs are complete; not done:"
        f" {', '.join(pending) or 'none'}, their folders as before. Run the same command"
        f" again to resume{resume}")


def _finish(out: Path, folder: Path, result: BatchResult, index: bool) -> None:
    """Record the sessions written (in worker processes, whose records the CLI does not
    see: an interrupt after this reports them) and write the batch index."""
    for o in result.outcomes:
        if o.status == "ok":
            record_output(out / o.name)
    if index:
        _write_index(out, folder, result.outcomes)


def _write_index(out: Path, folder: Path, outcomes: list[SessionOutcome]) -> None:
    """``out/index.html``: these sessions, then those earlier batches left in ``out``."""
    from brakethermo.pipelines.batch.index import earlier_rows, write_index

    rows = [*(o.to_json() for o in outcomes), *earlier_sessions(out, [o.name for o in outcomes])]
    write_index(out, folder, [*rows, *earlier_rows(out, rows)])


def _check_places(folder: Path, out: Path) -> None:
    """The output folder may sit inside the input folder, not be it or hold it."""
    f, o = folder.resolve(), out.resolve()
    if f == o:
        raise ConfigError(f"--out {out} is the input folder: its outputs would be read as"
                          " sessions; give another folder, e.g. --out out")
    if f.is_relative_to(o):
        raise ConfigError(f"the input folder {folder} is inside --out {out}: give an output"
                          " folder outside it")


def _sessions_under(folder: Path, out: Path) -> tuple[list[Path], list[str]]:
    """The session files under ``folder`` and the folders not read; none is an error."""
    not_read: list[str] = []
    files = discover_sessions(folder, exclude=[out], not_read=not_read)
    if not files:
        unread = f"; not read: {'; '.join(not_read)}" if not_read else ""
        raise DataError(f"no session files ({', '.join(SESSION_SUFFIXES)}) under this folder"
                        f"{unread}: give the folder the logger's files are in",
                        path=folder)
    return files, not_read


def _plan(files: list[Path], names: list[str], options: BatchOptions, out: Path
          ) -> tuple[dict[Path, SessionOutcome], list[KnownSingle], list[SessionTask],
                     dict[Path, int]]:
    """What each session needs: done already (unreadable, or up to date), up to date but
    its law to be chosen again (a single-spot session, on the second pass), or a
    first-pass task; and each readable file's size, bytes."""
    key = options.output_key()
    given_sha = file_sha256(options.h_law) if options.h_law is not None else None
    done: dict[Path, SessionOutcome] = {}
    known_single: list[KnownSingle] = []
    first: list[SessionTask] = []
    sizes: dict[Path, int] = {}
    for path, name in zip(files, names, strict=True):
        try:
            sha = file_sha256(path)
            sizes[path] = path.stat().st_size
            check_same_session(out / name, path, fix="give the batch another --out (or"
                               " rename one of the files); the other sessions were run")
        except OSError as exc:
            done[path] = SessionOutcome(path, name, "failed", reason=f"{path}: cannot read ({exc})")
            continue
        except ConfigError as exc:
            done[path] = SessionOutcome(path, name, "failed", reason=str(exc))
            continue
        manifest = None if options.force else read_manifest(out / name)
        if up_to_date(manifest, sha, key, out / name, options.reports):
            assert manifest is not None
            if manifest.get("kind") == "multi" or (
                given_sha is not None and manifest.get("h_law_sha256") == given_sha
            ):
                done[path] = skipped_outcome(path, name, manifest, out)
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
    return done, known_single, first, sizes


def _run_passes(first: list[SessionTask], known_single: list[KnownSingle],
                sizes: dict[Path, int], done: dict[Path, SessionOutcome],
                options: BatchOptions, out: Path, job: Job, on_event: Event | None) -> None:
    """Both passes, each outcome into ``done`` as it comes (an interrupt leaves there what
    finished); a session deferred by the first pass has its read counted in the second."""
    # Longest first keeps a pool busy to the end; file size stands in for session length.
    first.sort(key=lambda task: -sizes[task.path])
    with executor_for(options) as executor:
        for o in run_tasks(first, executor, job, on_event):
            done[o.path] = o
        second = second_pass(known_single, first, done, options, out, on_event)
        for o in run_tasks(second, executor, job, on_event):
            first_pass = done.get(o.path)
            if first_pass is not None and first_pass.status == "deferred":
                # The file was read in the first pass; count that read in this session.
                o.wall_s += first_pass.wall_s
                o.timings["read_s"] = (o.timings.get("read_s", 0.0)
                                       + first_pass.timings["read_s"])
            done[o.path] = o


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
    files, not_read = _sessions_under(folder, out)
    preflight(out=out, nodes=options.nodes, aliases=options.aliases, h_law=options.h_law)
    names = output_names(files, folder)
    if on_event is not None:
        on_event("start", len(files))
    done, known_single, first, sizes = _plan(files, names, options, out)
    if on_event is not None:
        for o in done.values():
            on_event("done", o)

    try:
        _run_passes(first, known_single, sizes, done, options, out, job, on_event)
    except KeyboardInterrupt:
        remove_own_stages(out)  # the interrupted session as before: no stage left beside it
        if options.reports:  # the finished sessions' pages link back to it
            _write_index(out, folder, [o for o in done.values()
                                       if o.status in ("ok", "skipped")])
        raise _interrupted(files, names, done, options.force) from None
    result = BatchResult([done[p] for p in files], time.perf_counter() - t0, not_read)
    # without reports, an index an earlier batch left is still redrawn: it lists these too
    _finish(out, folder, result, index=bool(files) and (
        options.reports or is_batch_index(out / "index.html")))
    return result
