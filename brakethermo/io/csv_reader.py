"""CSV session reader (CHANNELS.md §1): first column time in s, headers ``name [unit]``.

Exports from European spreadsheets are read too: the separator (``,`` ``;`` tab) is
detected from the first lines, and decimal commas with it (``12,5`` under a ``;`` or tab
separator). The text must be UTF-8 (a UTF-8 byte-order mark is fine); a UTF-16 or
Windows-1252 file gets a message saying how to save it.
"""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path

import numpy as np
import pandas as pd

from brakethermo.errors import DataError
from brakethermo.io.raw import Format, RawChannel, RawSession, rebase_s
from brakethermo.io.timebase import TIME_SCALE, integer_time_scale

_HEADER = re.compile(r"^\s*(?P<name>.*?)\s*(?:\[(?P<unit>[^\]]*)\])?\s*$")
_TIME_SCALE = {None: 1.0, "": 1.0, **TIME_SCALE}  # no unit: seconds
_SEPARATORS = (",", ";", "\t", "|")
_SNIFF_LINES = 50
_DECIMAL_COMMA = re.compile(r"^\s*[-+]?\d+,\d+\s*$")
_SAVE_AS = "save it as UTF-8 (Excel: Save As > 'CSV UTF-8 (Comma delimited)')"


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


def _text(path: Path) -> str:
    """The file as text; UTF-16 and non-UTF-8 (Windows-1252...) files are refused clearly."""
    data = path.read_bytes()
    if data.startswith((b"\xff\xfe", b"\xfe\xff")) or data[:200].count(b"\x00") > 10:
        raise DataError(f"the CSV is UTF-16 text (Excel 'Unicode Text'); {_SAVE_AS}", path=path)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        byte = data[exc.start : exc.start + 1]
        guess = byte.decode("cp1252", errors="replace")
        raise DataError(
            f"the CSV is not UTF-8: byte 0x{byte.hex()} on line {line} ('{guess}' in"
            f" Windows-1252, the usual Excel encoding); {_SAVE_AS}",
            path=path,
        ) from None


def _dialect(text: str, path: Path) -> tuple[str, str]:
    """Separator and decimal mark, from the first lines of the file."""
    lines = [ln for ln in text.splitlines()[:_SNIFF_LINES] if ln.strip()]
    if not lines:
        raise DataError("the CSV is empty (no header row)", path=path)
    best, best_fields = ",", 1
    for sep in _SEPARATORS:
        counts = [len(row) for row in csv.reader(lines, delimiter=sep)]
        # A separator splits every line into the header's number of fields (a short last
        # line may be cut by a logger losing power).
        body = counts[1:-1] if len(counts) > 2 else counts[1:]
        if counts[0] > best_fields and all(c == counts[0] for c in body):
            best, best_fields = sep, counts[0]
    if best_fields < 2:
        first = lines[0][:80]
        raise DataError(
            f"cannot find the column separator: the first line is '{first}' and no separator"
            " (comma, semicolon, tab, |) splits the lines into the same number of columns;"
            " the CSV needs a header row 'time,<channel>,...' and one row per sample",
            path=path,
        )
    decimal = "."
    if best != ",":
        cells = [c for row in csv.reader(lines[1:], delimiter=best) for c in row if c.strip()]
        if cells and sum(bool(_DECIMAL_COMMA.match(c)) for c in cells) >= 0.5 * len(cells):
            decimal = ","
    return best, decimal


def _cut_last_row(text: str) -> str | None:
    """The text without its last row when the file ends inside it (no line end after a
    data row: ``185.15`` cut to ``18``), else None. A file of one line is left to the
    header checks."""
    if not text or text.endswith(("\n", "\r")):
        return None
    head, sep, _ = text.rpartition("\n")
    return head + sep if sep and "\n" in head else None


def read_csv(path: Path, indexed: bool = False) -> RawSession:
    """Read a CSV session export into native-rate channels.

    Parameters
    ----------
    path : Path
        The ``.csv`` file; first column the time (``time`` or ``time [s]``, also
        ``[ms]``, ``[us]``, ``[ns]``; integers without a unit have their unit inferred),
        then one column per channel with header ``name [unit]`` or ``name``; an empty
        cell is no sample. Separator ``,`` ``;`` tab or ``|``; decimal comma with ``;``
        or tab.
    indexed : bool
        A table of points, not a time series (a (slip, μ) point set): every column is a
        channel and row ``i`` is at ``i`` seconds.

    Raises
    ------
    DataError
        Not UTF-8, no separator found, no data rows, an unknown time unit, a column
        mixing numbers and text (a column of text only is skipped with a warning).
    """
    text = _text(path)
    # a time series cut short loses its last sample; a point table (hand-made, often
    # without a final line end) keeps every point
    cut = None if indexed else _cut_last_row(text)
    if cut is not None:
        text = cut
    sep, decimal = _dialect(text, path)
    try:
        frame = pd.read_csv(io.StringIO(text), sep=sep, decimal=decimal, skipinitialspace=True,
                            dtype_backend="numpy_nullable")
    except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as exc:
        raise DataError(f"not a readable CSV file ({exc})", path=path) from None
    if indexed:
        return _indexed(frame, path)
    if frame.shape[1] < 2 or frame.shape[0] == 0:
        raise DataError(
            "the CSV needs a header row, a time column, at least one channel and one data row"
            f" (found {frame.shape[1]} column(s) separated by {_name(sep)} and"
            f" {frame.shape[0]} data row(s))",
            path=path,
        )
    headers = [_split_header(str(c)) for c in frame.columns]
    time_name, time_unit = headers[0]
    if time_unit not in _TIME_SCALE:
        raise DataError(
            f"time column unit '{time_unit}' is not supported; use s, ms, us or ns", path=path,
            channel=time_name,
        )
    column = frame.iloc[:, 0]
    t = _as_float(column, time_name, path)
    if t is None:
        raise DataError("the first column must be the time in s; it holds text", path=path,
                        channel=time_name)
    if np.isnan(t).any():
        row = int(np.argmax(np.isnan(t)))
        raise DataError(f"empty time in data row {row + 1}; every row needs a time", path=path,
                        channel=time_name)
    warnings = [] if cut is None else [
        "the file ends inside its last row (no line end: a copy or a log cut short); that"
        " row is dropped"]
    if time_unit is None and pd.api.types.is_integer_dtype(column.dtype):
        scale, note = integer_time_scale(t, path=path, column=time_name)
        if note:
            warnings.append(note)
        t = t * scale
    else:
        t = t * _TIME_SCALE[time_unit]
    (t,), origin = rebase_s([t])
    channels = _channels(frame, headers, 1, t, path, warnings)
    return RawSession(path, channels, {}, origin, tuple(warnings))


def _channels(frame: pd.DataFrame, headers: list[tuple[str, str | None]], first: int,
              t: np.ndarray, path: Path, warnings: list[str]) -> tuple[RawChannel, ...]:
    """Columns ``first``... as channels on times ``t`` (s); a text column is skipped with
    a warning, an empty cell is no sample."""
    channels = []
    for i, (name, unit) in enumerate(headers[first:], start=first):
        v = _as_float(frame.iloc[:, i], name, path)
        if v is None:
            warnings.append(f"column '{name}' holds text, not numbers; ignored")
            continue
        keep = ~np.isnan(v)
        channels.append(RawChannel(name, t[keep], v[keep], unit))
    return tuple(channels)


def _name(sep: str) -> str:
    return {",": "commas", ";": "semicolons", "\t": "tabs", "|": "'|'"}[sep]


def _indexed(frame: pd.DataFrame, path: Path) -> RawSession:
    """Every column a channel on the row index (s), for a table of points."""
    if frame.shape[0] == 0:
        raise DataError("the CSV holds a header and no data rows", path=path)
    warnings: list[str] = []
    headers = [_split_header(str(c)) for c in frame.columns]
    channels = _channels(frame, headers, 0, np.arange(frame.shape[0], dtype=float), path,
                         warnings)
    return RawSession(path, channels, {}, None, tuple(warnings))


FORMAT = Format("CSV", (".csv",), read_csv)
