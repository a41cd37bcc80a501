"""Writing a rig pipeline's outputs (OUTPUTS.md, "Rig pipelines") as one folder.

Every rig command writes ``DIR/<stem>/<pipeline>.parquet`` (``time`` in s from the
session start, then its named columns, each with its unit in the field metadata),
``DIR/<stem>/summary.json`` and a report page ``DIR/<stem>/index.html`` with its PNGs.
The files are staged and swapped in together; the command owns its parquet, its summary,
its page and PNGs, so a re-run never leaves files of an earlier run beside new ones, a
failure leaves the previous results untouched, and what another command wrote into the
same folder (``diagnose``'s ``diagnosis.json`` and ``diagnosis/``) stays, and the page
links it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import pandas as pd

from brakethermo.io.atomic import atomic_entries, write_bytes_atomic
from brakethermo.pipelines.output_dir import refresh_indexes
from brakethermo.pipelines.outputs import write_json, write_parquet
from brakethermo.report.page import Page, Section, write_page

WARNINGS = "Warnings"


def write_rig_outputs(
    out: Path,
    stem: str,
    pipeline: str,
    frame: pd.DataFrame,
    summary: Mapping[str, Any],
    page: Page,
    units: Mapping[str, str] | None = None,
    attachments: Mapping[str, bytes] | None = None,
) -> Path:
    """Write the parquet, the summary and the report page of one rig run.

    Parameters
    ----------
    out : Path
        Output root (``--out``).
    stem : str
        Session file stem: the folder name.
    pipeline : str
        Parquet file stem (``roller_rig``, ``ebooster``, ``clamp_force``, ``mu_slip``).
    frame : DataFrame
        Columns to write; ``time`` first where the table is a time series.
    summary : mapping
        JSON-serialisable summary (numpy scalars and non-finite floats are handled).
    page : Page
        The report page.
    units : mapping of str to str, optional
        Unit string per column, stored in the field metadata under ``unit``.
    attachments : mapping of str to bytes, optional
        Further files of the run (an animation, ...) by file name, written in the folder.

    Returns
    -------
    Path
        The session's output folder.
    """
    folder = Path(out) / stem
    meta = {name: {"unit": unit} for name, unit in (units or {}).items() if name in frame}
    said = [str(w) for w in summary.get("warnings") or ()]
    if said and not any(s.heading == WARNINGS for s in page.sections):
        # what the console and summary.json warn of, first on the page too
        page = replace(page, sections=[Section(WARNINGS, paragraphs=said), *page.sections])
    page = replace(page, sibling_pages=True)
    owned = (f"{pipeline}.parquet", "summary.json", "index.html", "*.png",
             *(attachments or {}))
    with atomic_entries(folder, owned) as tmp:
        write_parquet(tmp / f"{pipeline}.parquet", frame, field_meta=meta)
        write_json(tmp / "summary.json", dict(summary))
        write_page(page, tmp)
        for name, data in (attachments or {}).items():
            write_bytes_atomic(tmp / name, data)
    refresh_indexes(folder)  # a diagnosis already beside it is linked; a batch's index too
    return folder
