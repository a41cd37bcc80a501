"""Which files of a folder are sessions, the output folder each gets, and the manifest
that says whether its outputs are up to date."""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from brakethermo import __version__
from brakethermo.errors import (
    ConfigError,
)
from brakethermo.io.formats import SUFFIXES as FORMAT_SUFFIXES
from brakethermo.io.writers import TRUTH_SUFFIX
from brakethermo.pipelines.batch.tasks import SessionOutcome, file_sha256

SESSION_SUFFIXES = FORMAT_SUFFIXES  # every registered reader (brakethermo.io.formats)
MANIFEST = "batch_manifest.json"


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


def read_manifest(out_dir: Path) -> dict[str, Any] | None:
    """The batch manifest of a session's output directory, or None."""
    try:
        return json.loads((out_dir / MANIFEST).read_text())
    except (OSError, ValueError):
        return None


# What a batch wrote that another command sharing the folder may replace (estimate,
# identify-h): fingerprinted in the manifest so that a later batch redoes the session
# instead of reporting the manifest's numbers for files that are no longer the batch's.
FINGERPRINTED = ("summary.json", "estimate.parquet", "h_law.toml")


def output_fingerprints(folder: Path) -> dict[str, str]:
    """SHA-256 of the batch's replaceable outputs present in a session's folder."""
    return {name: file_sha256(folder / name) for name in FINGERPRINTED
            if (folder / name).is_file()}


def up_to_date(manifest: dict[str, Any] | None, sha: str, key: str,
               folder: Path | None = None, reports: bool = False) -> bool:
    """Whether the session's folder still holds this batch's results for this input and
    these options: the manifest matches, and (given ``folder``) the outputs are the ones
    the batch wrote — none replaced by another command since, and the lap reports there
    when ``reports``."""
    if not (
        manifest is not None
        and manifest.get("input_sha256") == sha
        and manifest.get("options_key") == key
        and manifest.get("version") == __version__
        # Written before the law choice recorded session facts: redo it once.
        and isinstance(manifest.get("facts"), dict)
    ):
        return False
    if folder is None:
        return True
    written = manifest.get("outputs_sha256")
    if not isinstance(written, dict):
        return False  # a manifest that predates the fingerprints: redo once
    if reports and not (folder / "index.html").is_file():
        return False
    try:
        return output_fingerprints(folder) == written
    except OSError:
        return False


def outputs_replaced(folder: Path) -> bool | None:
    """Whether another command replaced what the batch wrote in a session's folder since
    (None: no manifest, or one from before the fingerprints, cannot say)."""
    manifest = read_manifest(folder)
    written = manifest.get("outputs_sha256") if isinstance(manifest, dict) else None
    if not isinstance(written, dict):
        return None
    try:
        return output_fingerprints(folder) != written
    except OSError:
        return True


REPLACED = "its results were replaced by another command since (peaks on its own page)"


def earlier_sessions(out: Path, current: Iterable[str]) -> list[dict[str, Any]]:
    """Index records of the session folders an earlier batch left in ``out`` that this
    batch did not process (another input folder into the same ``--out``): kept and
    listed, never dropped from the index. Their peaks are the manifest's while the
    folder still holds that batch's outputs (or cannot say: a manifest from before the
    fingerprints)."""
    skip = {n.casefold() for n in current}
    rows = []
    try:
        folders = sorted(p for p in out.iterdir() if p.is_dir())
    except OSError:
        return rows
    for folder in folders:
        manifest = read_manifest(folder)
        if folder.name.casefold() in skip or not isinstance(manifest, dict):
            continue
        replaced = outputs_replaced(folder)
        same = None if replaced is None else not replaced
        row = skipped_outcome(Path(str(manifest.get("input", ""))), folder.name, manifest,
                              out).to_json()
        row["status"] = "earlier batch"
        row["reason"] = (f"from an earlier batch of {manifest.get('input', '?')}" + (
            "" if same else " (not checked since: an older manifest)" if same is None else
            f"; {REPLACED}"))
        if same is False:
            row["peaks_c"] = {}
        rows.append(row)
    return rows


def skipped_outcome(path: Path, name: str, manifest: dict[str, Any], out: Path) -> SessionOutcome:
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
        warnings=[str(w) for w in manifest.get("warnings") or []],
    )
