"""Export an estimate as ASAM MDF4, to open in WinTAX / ATLAS / asammdf beside the source log.

One channel group on the estimate's 10 Hz time base, every channel with its unit:

- ``BT_spot1`` … ``BT_spot4``, ``BT_contact_avg`` — estimate, degC; ``<name>_std``
  (1-sigma), ``<name>_lower`` / ``<name>_upper`` (the ±1σ band edges), degC; the spot
  radius in the channel comment;
- ``BT_node_<k>`` — node temperatures inner to outer radius, degC, the radius (m) in
  the comment; other families ``<family>_<k>`` likewise (``BT_mid_<k>``);
- ``BT_lap`` — lap number;
- any other numeric column of the frame (``braking_power`` W, ``h`` W/(m2 K),
  ``power_scale``...) with its ``_std`` when present.

The ``BT_`` prefix keeps the estimate's channels apart from the logger's when both
files are open together. Time: the header start time is the session's epoch start when
the source log carried absolute time (so both files line up), else the Unix epoch and
the header comment says the time base is the session start.
"""

from __future__ import annotations

import datetime as dt
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING
from xml.sax.saxutils import escape as xml_escape

import numpy as np
import pandas as pd

from brakethermo import __version__
from brakethermo.io.atomic import atomic_path
from brakethermo.report.mcap_export import (
    ARRAY_UNITS,
    BANDED,
    SCALAR_UNITS,
    SPOT_RADII_DEFAULT,
    array_families,
    scalar_columns,
)

if TYPE_CHECKING:
    from asammdf import Signal

PREFIX = "BT_"


def _header_comment(source: str, start_epoch_s: float | None, date: str | None = None) -> str:
    base = ("epoch" if start_epoch_s is not None else
            f"session start on {date} (time of day unknown: 00:00 UTC)" if date else
            "session start")
    props = {"source": source, "time_base": base, "writer": f"brakethermo {__version__}"}
    entries = "".join(
        f'<e name="{k}">{xml_escape(str(v))}</e>' for k, v in props.items()
    )
    text = xml_escape(f"brakethermo {__version__} disc temperature estimate of {source}")
    return f"<HDcomment><TX>{text}</TX><common_properties>{entries}</common_properties></HDcomment>"


def _iso_date(text: str | None) -> dt.date | None:
    try:
        return dt.date.fromisoformat(str(text).strip()[:10]) if text else None
    except ValueError:
        return None


def write_estimate_mdf(
    frame: pd.DataFrame,
    path: str | Path,
    *,
    node_radii: Sequence[float] | np.ndarray | None = None,
    spot_radii: Sequence[float] = SPOT_RADII_DEFAULT,
    start_epoch_s: float | None = None,
    source: str = "",
    date: str | None = None,
) -> Path:
    """Write an estimate frame to ``path`` as MDF 4.10, atomically.

    Parameters
    ----------
    frame : DataFrame
        Estimate frame of OUTPUTS.md (``time`` s, ``lap``, ``spot<i>``, ``spot<i>_std``,
        ``contact_avg``, ``node_<k>``... degC).
    path : path
        Target ``.mf4`` file.
    node_radii : array — m, optional
        Radius of each ``node_<k>``; written in the channel comments.
    spot_radii : sequence of float — m
        Radii of spot 1..4, written in the spot channels' comments.
    start_epoch_s : float — s, optional
        Epoch time of grid point 0 when the source log carried absolute time.
    source : str
        Name of the source log, recorded in the header.
    date : str, optional
        The session's date (ISO ``YYYY-MM-DD``, from its metadata) when the log carries
        relative time only: the header starts at 00:00 UTC of that day, and says so.
    """
    from asammdf import MDF

    path = Path(path)
    signals = _estimate_signals(frame, node_radii, spot_radii)
    mdf = MDF(version="4.10")
    day = _iso_date(date) if start_epoch_s is None else None
    mdf.header.start_time = _start_time(start_epoch_s, day)
    mdf.header.comment = _header_comment(source, start_epoch_s,
                                         day.isoformat() if day else None)
    mdf.append(signals, comment="brakethermo estimate, 10 Hz")
    with atomic_path(path) as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mdf.save(tmp, overwrite=True, compression=2)
        mdf.close()
    return path


def _estimate_signals(frame: pd.DataFrame, node_radii: Sequence[float] | np.ndarray | None,
                      spot_radii: Sequence[float]) -> list[Signal]:
    """One signal per exported column on the frame's time base (module docstring).

    Parameters
    ----------
    frame : DataFrame
        Estimate frame of OUTPUTS.md (``time`` s).
    node_radii : array — m, optional
        Radius of each ``node_<k>``, for the channel comments.
    spot_radii : sequence of float — m
        Radii of spot 1..4, for the spot channels' comments.
    """
    from asammdf import Signal

    t = frame["time"].to_numpy(dtype=np.float64)
    signals: list[Signal] = []

    def add(name: str, values: np.ndarray, unit: str, comment: str) -> None:
        signals.append(Signal(np.asarray(values), t, name=PREFIX + name, unit=unit,
                              comment=comment))

    for col in (c for c in BANDED if c in frame):
        value = frame[col].to_numpy(dtype=np.float64)
        where = (f" at r = {float(spot_radii[int(col[4:]) - 1]):.3f} m"
                 if col.startswith("spot") else " (pad contact band average)")
        add(col, value, "degC", f"estimated disc temperature{where}")
        std_col = f"{col}_std"
        if std_col in frame:
            std = frame[std_col].to_numpy(dtype=np.float64)
            add(std_col, std, "degC", f"1-sigma of {PREFIX}{col}")
            add(f"{col}_lower", value - std, "degC", f"{PREFIX}{col} - 1 sigma")
            add(f"{col}_upper", value + std, "degC", f"{PREFIX}{col} + 1 sigma")
    families = array_families(frame.columns)
    for family, cols in families.items():
        for k, col in cols:
            radius = (f" at r = {float(node_radii[k]):.4f} m"
                      if node_radii is not None and k < len(node_radii) else "")
            add(col, frame[col].to_numpy(dtype=np.float64), ARRAY_UNITS.get(family, ""),
                f"{family} temperature {k} (inner to outer){radius}")
    if "lap" in frame:
        add("lap", frame["lap"].to_numpy(dtype=np.int64), "", "lap number (0 = out-lap)")
    for col in scalar_columns(frame, families):
        unit = SCALAR_UNITS.get(col, "")
        add(col, frame[col].to_numpy(dtype=np.float64), unit, f"estimated {col}")
        if f"{col}_std" in frame:
            add(f"{col}_std", frame[f"{col}_std"].to_numpy(dtype=np.float64), unit,
                f"1-sigma of {PREFIX}{col}")
    return signals


def _start_time(start_epoch_s: float | None, day: dt.date | None) -> dt.datetime:
    """The header's start time: the source log's epoch start, else 00:00 UTC of the
    session's ``day``, else the Unix epoch (``start_epoch_s`` s)."""
    if start_epoch_s is not None:
        return dt.datetime.fromtimestamp(float(start_epoch_s), tz=dt.UTC)
    if day is not None:
        return dt.datetime.combine(day, dt.time(), tzinfo=dt.UTC)
    return dt.datetime.fromtimestamp(0.0, tz=dt.UTC)
