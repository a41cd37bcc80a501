"""CSV session reader (CHANNELS.md §1): first column time in s, headers ``name [unit]``."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd

from brakethermo.errors import DataError
from brakethermo.io.raw import RawChannel, RawSession, rebase_s

_HEADER = re.compile(r"^\s*(?P<name>.*?)\s*(?:\[(?P<unit>[^\]]*)\])?\s*$")
_TIME_SCALE = {None: 1.0, "": 1.0, "s": 1.0, "ms": 1.0e-3}


def _split_header(cell: str) -> tuple[str, str | None]:
    match = _HEADER.match(cell)
    assert match is not None  # the pattern accepts any string
    unit = match["unit"]
    return match["name"], unit.strip() if unit is not None else None


def _as_float(column: pd.Series, name: str, path: Path) -> np.ndarray | None:
    """Parse a column to float64 (NaN = empty cell).

    Returns ``None`` for a column of text only (a comment or event column, not a
    channel); a column mixing numbers and text is an error naming the first bad cell.
    """
    if pd.api.types.is_numeric_dtype(column.dtype):
        return column.to_numpy(dtype=np.float64, na_value=np.nan)
    parsed = pd.to_numeric(column, errors="coerce")
    bad = parsed.isna().to_numpy() & column.notna().to_numpy()
    if parsed.isna().all():
        return None
    if bad.any():
        row = int(np.argmax(bad))
        raise DataError(
            f"non-numeric value {column.iloc[row]!r} in data row {row + 1} (line {row + 2});"
            " every sample must be a number or empty",
            path=path,
            channel=name,
        )
    return parsed.to_numpy(dtype=np.float64, na_value=np.nan)


def read_csv(path: Path) -> RawSession:
    """Read a CSV session export into native-rate channels.

    Parameters
    ----------
    path : Path
        The ``.csv`` file; first column the time in s (``time`` or ``time [s]``), then
        one column per channel with header ``name [unit]`` or ``name``; an empty cell is
        no sample.

    Raises
    ------
    DataError
        Unparsable file, no data rows, a time unit other than s/ms, a column mixing
        numbers and text (a column of text only is skipped with a warning).
    """
    try:
        frame = pd.read_csv(path, skipinitialspace=True, dtype_backend="numpy_nullable")
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise DataError(f"not a readable CSV file ({exc})", path=path) from None
    if frame.shape[1] < 2 or frame.shape[0] == 0:
        raise DataError(
            "the CSV needs a header row, a time column, at least one channel and one data row",
            path=path,
        )
    headers = [_split_header(str(c)) for c in frame.columns]
    time_name, time_unit = headers[0]
    if time_unit not in _TIME_SCALE:
        raise DataError(
            f"time column unit '{time_unit}' is not supported; use s or ms", path=path,
            channel=time_name,
        )
    t = _as_float(frame.iloc[:, 0], time_name, path)
    if t is None:
        raise DataError("the first column must be the time in s; it holds text", path=path,
                        channel=time_name)
    t = t * _TIME_SCALE[time_unit]
    if np.isnan(t).any():
        row = int(np.argmax(np.isnan(t)))
        raise DataError(f"empty time in data row {row + 1}; every row needs a time", path=path,
                        channel=time_name)
    (t,), epoch = rebase_s([t])
    channels = []
    warnings = []
    for i, (name, unit) in enumerate(headers[1:], start=1):
        v = _as_float(frame.iloc[:, i], name, path)
        if v is None:
            warnings.append(f"column '{name}' holds text, not numbers; ignored")
            continue
        keep = ~np.isnan(v)
        channels.append(RawChannel(name, t[keep], v[keep], unit))
    return RawSession(path, tuple(channels), {}, epoch, tuple(warnings))
