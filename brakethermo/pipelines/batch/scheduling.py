"""Where the sessions run: in this process, in local worker processes (a fork server
with the heavy imports done once) or on a Dask cluster."""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Iterator
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from contextlib import contextmanager

from brakethermo.errors import (
    ConfigError,
)
from brakethermo.estimation.urts import share_store_budget
from brakethermo.pipelines.batch.session import failure_reason, process_session
from brakethermo.pipelines.batch.tasks import BatchOptions, Event, Job, SessionOutcome, SessionTask

SCHEDULER_TIMEOUT_S = 30.0  # connecting to a Dask scheduler
WORKER_PRELOAD = ("brakethermo.pipelines.batch", "brakethermo.report.lap_report")


@contextmanager
def executor_for(options: BatchOptions) -> Iterator[Executor | None]:
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
        # each worker smooths in its share of the memory budget, not the whole of it
        with ProcessPoolExecutor(max_workers=options.workers, mp_context=ctx,
                                 initializer=share_store_budget,
                                 initargs=(options.workers,)) as pool:
            yield pool
    else:
        yield None


def run_tasks(
    tasks: list[SessionTask], executor: Executor | None, job: Job, on_event: Event | None
) -> Iterator[SessionOutcome]:
    """Each task's outcome as it finishes (a generator: an interrupt leaves the caller
    holding every outcome finished before it, not none of them)."""

    def finished(outcome: SessionOutcome) -> SessionOutcome:
        if on_event is not None and outcome.status != "deferred":
            on_event("done", outcome)
        return outcome

    if executor is None:
        for task in tasks:
            if job is process_session and on_event is not None:
                # In this process the session can tell where it is; a worker cannot.
                yield finished(process_session(task, progress=lambda p: on_event("phase", p)))
            else:
                yield finished(job(task))
        return
    futures: dict[Future, SessionTask] = {executor.submit(job, t): t for t in tasks}
    for fut in as_completed(futures):
        task = futures[fut]
        try:
            outcome = fut.result()
        except Exception as exc:  # a worker died; the session is lost, not the batch
            outcome = SessionOutcome(task.path, task.name, "failed", reason=failure_reason(exc))
        yield finished(outcome)
