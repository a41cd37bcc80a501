"""ASAM MDF reader (MDF4 ``.mf4`` and MDF 3 ``.mdf``/``.mf3``) through ``asammdf``.

Every channel group is read; each channel keeps its own group's time base until the
shared resampling. Values are the physical ones (the channel's conversion applied),
units from the channel's unit field, or its conversion's. Session facts come from the
file header: start time (``date``), comment, author/project/subject, and the MDF4
``common_properties`` (``vehicle``, ``track``...).

Not channels: the master (time) channels, value-to-text channels (text samples, e.g. a
gear or status name — skipped with a warning) and structured bus-logging records (raw
CAN/LIN/FlexRay frames and their components), which need a DBC to decode first.
"""

from __future__ import annotations

import datetime as dt
import gc
import sys
import warnings as py_warnings
from pathlib import Path
from typing import Any

import numpy as np

from brakethermo.errors import DataError
from brakethermo.io.raw import Format, RawChannel, RawSession, rebase_s

# Header dates before this are asammdf's or a logger's "no date" defaults (MDF 3: 1980).
_NO_DATE_BEFORE = dt.datetime(1990, 1, 1, tzinfo=dt.UTC)
_BUS_WORDS = ("CAN_", "LIN_", "FLX_", "ETH_", "MOST_")
_HEADER_FACTS = ("author", "department", "project", "subject")


def _open(path: Path) -> Any:
    try:
        from asammdf import MDF
    except ImportError:  # a declared dependency; only a broken install lacks it
        raise DataError(
            "reading MDF files needs the package asammdf; pip install asammdf", path=path
        ) from None
    # asammdf's destructor fails on the half-built object of a file it rejected and
    # Python would print that on stderr: silence it while the object is collected.
    hook = sys.unraisablehook
    sys.unraisablehook = lambda _info: None
    try:
        try:
            with py_warnings.catch_warnings():
                py_warnings.simplefilter("ignore")
                return MDF(path)
        except Exception as exc:  # asammdf raises bare Exception/struct/Value errors on junk
            problem = f"{type(exc).__name__}: {str(exc)[:160]}"
        gc.collect()
    finally:
        sys.unraisablehook = hook
    raise DataError(
        f"not a readable MDF file ({problem}); check that it is an ASAM MDF 3/4 log and not"
        " truncated or damaged",
        path=path,
    )


def _facts(mdf: Any) -> tuple[dict[str, str], float | None]:
    header = mdf.header
    facts: dict[str, str] = {}
    start = getattr(header, "start_time", None)
    epoch = None
    if isinstance(start, dt.datetime):
        aware = start if start.tzinfo else start.replace(tzinfo=dt.UTC)
        if aware >= _NO_DATE_BEFORE:
            epoch = aware.timestamp()
            facts["date"] = aware.date().isoformat()
    description = getattr(header, "description", None)
    if description is None and isinstance(getattr(header, "comment", None), str):
        description = header.comment
    if description and str(description).strip():
        facts["comment"] = str(description).strip()
    for key in _HEADER_FACTS:
        value = getattr(header, key, None)
        if isinstance(value, str) and value.strip():
            facts[key] = value.strip()
    common = getattr(header, "_common_properties", None) or {}
    for key, value in common.items():
        if isinstance(value, str | int | float) and str(value).strip():
            facts[str(key)] = str(value).strip()
    return facts, epoch


def _skip_names(group: Any) -> set[str]:
    """Structured channels (bus frames) and their components in one channel group."""
    parents = [
        ch.name for ch in group.channels
        if getattr(np.dtype(ch.dtype_fmt), "names", None) or ch.name.startswith(_BUS_WORDS)
    ]  # fmt: skip
    return {
        ch.name for ch in group.channels
        if ch.name in parents or any(ch.name.startswith(p + ".") for p in parents)
    }  # fmt: skip


def _unit(signal: Any) -> str | None:
    unit = signal.unit
    if (not unit) and signal.conversion is not None:
        unit = getattr(signal.conversion, "unit", "")
    return unit if isinstance(unit, str) and unit.strip() else None


def _label_copies(names: list[str], groups: list[int], values: list[np.ndarray],
                  units: list[str | None], warnings: list[str]) -> list[str]:
    """Labels for channels, one plain name per channel name and a warning per copy.

    A name in several groups (a stale copy, a second raster) keeps its plain name on the
    copy with the most samples (on a tie the later group, the newest write); the others
    become ``name [group k]``, which no alias matches, and the choice is said.
    """
    labels = list(names)
    for name in dict.fromkeys(names):
        idx = [i for i, n in enumerate(names) if n == name]
        if len(idx) < 2:
            continue
        keep = max(idx, key=lambda i: (values[i].size, groups[i]))
        for i in idx:
            if i != keep:
                labels[i] = f"{name} [group {groups[i]}]"
        others = [i for i in idx if i != keep]
        why = ("the most" if any(values[i].size < values[keep].size for i in others)
               else "a tie: the later group")
        # an average difference means something only between copies in one unit
        differ = ", ".join(
            f"{float(np.nanmean(values[keep]) - np.nanmean(values[i])):+.3g} on average"
            if units[i] == units[keep] else f"in {units[i] or 'no unit'}, not"
            f" {units[keep] or 'no unit'}" for i in others)
        warnings.append(
            f"channel '{name}' is in groups {', '.join(str(groups[i]) for i in idx)}: using "
            f"group {groups[keep]} ({values[keep].size} samples, "
            f"{why});"
            f" the other copies ({', '.join(labels[i] for i in others)}) differ ({differ})"
            " and are not used — drop the stale copy from the export if this is the wrong one"
        )
    return labels


def _wanted(mdf: Any) -> tuple[list[tuple[str, int, int]], int]:
    """The channels to read, as (name, group index, channel index), and how many bus
    frame channels (and their components) were left out."""
    wanted: list[tuple[str, int, int]] = []
    skipped_bus = 0
    for gi, group in enumerate(mdf.groups):
        skip = _skip_names(group)
        skipped_bus += len(skip)
        master = mdf.masters_db.get(gi)
        for ci, ch in enumerate(group.channels):
            if ci == master or ch.channel_type in (2, 3) or ch.name in skip:
                continue  # master (time) and virtual master channels
            wanted.append((ch.name, gi, ci))
    return wanted, skipped_bus


def _numeric(
    wanted: list[tuple[str, int, int]], signals: list[Any], warnings: list[str]
) -> tuple[list[str], list[int], list[np.ndarray], list[np.ndarray], list[str | None]]:
    """Names, groups, times (s), values and units of the numeric 1-D signals; a text
    channel is left out with a warning, other non-numeric records silently."""
    names: list[str] = []
    times: list[np.ndarray] = []
    values: list[np.ndarray] = []
    units: list[str | None] = []
    groups: list[int] = []
    for (name, gi, _), sig in zip(wanted, signals, strict=True):
        samples = np.asarray(sig.samples)
        if samples.ndim != 1 or samples.dtype.kind not in "biuf":
            if samples.dtype.kind in "SUO":
                warnings.append(
                    f"channel '{name}' holds text (a value-to-text conversion); ignored"
                )
            continue
        names.append(name)
        groups.append(gi)
        times.append(np.asarray(sig.timestamps, dtype=np.float64))
        values.append(samples.astype(np.float64))
        units.append(_unit(sig))
    return names, groups, times, values, units


def read_mdf(path: Path) -> RawSession:
    """Read an MDF 3/4 file into native-rate channels.

    Parameters
    ----------
    path : Path
        The ``.mf4`` / ``.mdf`` / ``.mf3`` file.

    Returns
    -------
    RawSession
        One channel per numeric, non-master channel of every group, named as in the
        file (a name used in several groups gets `` [group k]`` from the second on),
        times in s from the earliest sample, origin at the header start time.

    Raises
    ------
    DataError
        Not an MDF file, or a file with no numeric channel (e.g. a raw bus log).
    """
    mdf = _open(path)
    version = str(mdf.version)
    try:
        facts, start_epoch = _facts(mdf)
        wanted, skipped_bus = _wanted(mdf)
        signals = []
        if wanted:
            try:
                with py_warnings.catch_warnings():
                    py_warnings.simplefilter("ignore")
                    signals = mdf.select(wanted, raw=False, validate=False)
            except Exception as exc:  # a damaged data block surfaces here
                raise DataError(
                    f"MDF data blocks cannot be read ({type(exc).__name__}: {str(exc)[:160]});"
                    " the file is truncated or damaged",
                    path=path,
                ) from None
    finally:
        mdf.close()

    warnings: list[str] = []
    names, groups, times, values, units = _numeric(wanted, signals, warnings)
    names = _label_copies(names, groups, values, units, warnings)
    if not names:
        why = (" It looks like a raw bus log (CAN/LIN frames): decode it with the DBC first"
               " (asammdf: extract_bus_logging) and read the decoded file"
               if skipped_bus else "")
        raise DataError(f"the MDF file holds no numeric channel to read.{why}", path=path)
    times_s, origin = rebase_s(times)
    if origin is not None and start_epoch is not None:
        origin += start_epoch
    channels = tuple(
        RawChannel(n, t, v, u) for n, t, v, u in zip(names, times_s, values, units, strict=True)
    )
    return RawSession(path, channels, facts, origin, tuple(warnings), f"MDF {version}")


FORMAT = Format("MDF", (".mf4", ".mdf", ".mf3"), read_mdf)
