"""What a batch is made of: its options, the task of one session, what happened to it,
and the run's result; the hashes that tell an up-to-date output."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Protocol

import numpy as np
import pandas as pd

from brakethermo.config import config_dir
from brakethermo.errors import (
    EXIT_BATCH_PARTIAL,
    EXIT_OK,
)
from brakethermo.io.session import Session
from brakethermo.results.laps import round_temp
from brakethermo.thermal.disc import DiscSpec

DEFAULT_LAW = "default (shipped)"


# Top-level steps of a session's wall time (sub-steps such as estimate_filter_s nest in them).
STEPS = ("read_s", "identify_s", "estimate_s", "write_s", "report_s", "mcap_s", "mdf_s")


Status = Literal["ok", "skipped", "failed", "deferred"]


# a disc session's spots, or the rig (io.kinds.KINDS) a rig log in the folder is of
Kind = Literal["multi", "single", "ebooster", "emb", "roller-rig", "mu-slip"]


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
            "configs": configs_digest(),
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
    warnings : list of str
        The estimate's warnings about the disc (assumed; a law of another disc), which
        the batch says on its console.
    """

    frame: pd.DataFrame
    node_radii: np.ndarray
    h_law: Path | None = None
    timings: dict[str, float] = field(default_factory=dict)
    disc: DiscSpec | None = None
    warnings: list[str] = field(default_factory=list)


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


# a file of the folder that is a rig's log: listed, not estimated, and no failure
RIG_SESSION = "rig session"


@dataclass
class SessionOutcome:
    """What happened to one session.

    Attributes
    ----------
    path : Path
    name : str
    status : {"ok", "skipped", "failed", "deferred"}
    kind : {"multi", "single"}, a rig's name (a rig session) or None
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
    warnings : list of str
        What the console must say of the session's disc: assumed (no ``disc`` fact), or
        a law of another disc (:func:`~brakethermo.pipelines.models.disc_warnings`).
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
    warnings: list[str] = field(default_factory=list)

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
            "warnings": list(self.warnings),
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


def configs_digest() -> str:
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


Job = Callable[[SessionTask], SessionOutcome]
Event = Callable[[str, Any], None]
