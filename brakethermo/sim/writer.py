"""Writing a simulated session together with its truth file.

Every simulator (track sessions and the rigs) writes its session through the real session
writers and the truth it was simulated from as ``<stem>.truth.parquet`` beside it; the
estimator never reads that file, only scoring does.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import pyarrow as pa

from brakethermo.io.writers import TRUTH_SUFFIX, SessionData, write_session, write_table_parquet


def truth_path_for(session_path: str | Path) -> Path:
    """``<stem>.truth.parquet`` beside ``session_path``."""
    session_path = Path(session_path)
    return session_path.with_name(f"{session_path.stem}{TRUTH_SUFFIX}")


def write_session_and_truth(
    out: str | Path,
    session: SessionData,
    truth: pa.Table,
    fmt: str | None = None,
    *,
    groups: Mapping[str, Mapping[str, str]] | None = None,
) -> tuple[Path, Path]:
    """Write ``session`` to ``out`` and ``truth`` to ``<stem>.truth.parquet`` beside it.

    Parameters
    ----------
    out : str or Path — session file (``.mcap``, ``.parquet`` or ``.csv``).
    session : SessionData — the logged channels.
    truth : pyarrow.Table — what the simulator knows and the estimator must not.
    fmt : str, optional — session format (default from the extension).
    groups : mapping, optional — MCAP grouped topics, as :func:`write_session`.

    Returns
    -------
    (session path, truth path)
    """
    session_path = write_session(out, session, fmt, groups=groups)
    truth_path = truth_path_for(session_path)
    write_table_parquet(truth_path, truth)
    return session_path, truth_path
