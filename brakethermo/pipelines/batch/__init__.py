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

The package, one step each: :mod:`.tasks` (options, tasks, outcomes, hashes),
:mod:`.discovery` (session files, output names, manifests), :mod:`.laws` (which law a
race gets), :mod:`.session` (one session start to finish), :mod:`.scheduling` (in
process, worker processes, Dask), :mod:`.run` (:func:`run_batch`).
"""

from __future__ import annotations

from brakethermo.pipelines.batch.discovery import (
    MANIFEST,
    SESSION_SUFFIXES,
    discover_sessions,
    output_names,
    read_manifest,
)
from brakethermo.pipelines.batch.laws import LawChoice, choose_law, is_multi_spot, session_facts
from brakethermo.pipelines.batch.run import run_batch
from brakethermo.pipelines.batch.scheduling import SCHEDULER_TIMEOUT_S, WORKER_PRELOAD
from brakethermo.pipelines.batch.session import Phase, PipelineRunner, process_session
from brakethermo.pipelines.batch.tasks import (
    DEFAULT_LAW,
    STEPS,
    BatchOptions,
    BatchResult,
    RunOutput,
    SessionOutcome,
    SessionRunner,
    SessionTask,
    file_sha256,
)

__all__ = [
    "DEFAULT_LAW", "MANIFEST", "SCHEDULER_TIMEOUT_S", "SESSION_SUFFIXES", "STEPS",
    "WORKER_PRELOAD", "BatchOptions", "BatchResult", "LawChoice", "Phase", "PipelineRunner",
    "RunOutput", "SessionOutcome", "SessionRunner", "SessionTask", "choose_law",
    "discover_sessions", "file_sha256", "is_multi_spot", "output_names",
    "process_session", "read_manifest", "run_batch", "session_facts",
]  # fmt: skip
