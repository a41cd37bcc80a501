"""Writers for the OUTPUTS.md tables: Parquet with units/radii in field metadata, JSON."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from brakethermo.io.atomic import atomic_path, write_text_atomic


def frame_to_table(
    frame: pd.DataFrame,
    field_meta: dict[str, dict[str, str]] | None = None,
    file_meta: dict[str, str] | None = None,
) -> pa.Table:
    """Arrow table of ``frame`` with per-column and file key-value metadata."""
    field_meta = field_meta or {}
    fields = []
    arrays = []
    for name in frame.columns:
        arr = pa.array(frame[name].to_numpy())
        meta = field_meta.get(name)
        fields.append(pa.field(name, arr.type, metadata=meta))
        arrays.append(arr)
    schema = pa.schema(fields, metadata=file_meta or None)
    return pa.Table.from_arrays(arrays, schema=schema)


def write_parquet(
    path: Path,
    frame: pd.DataFrame,
    field_meta: dict[str, dict[str, str]] | None = None,
    file_meta: dict[str, str] | None = None,
) -> Path:
    """Write ``frame`` to ``path`` atomically (zstd), keeping the metadata."""
    table = frame_to_table(frame, field_meta, file_meta)
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, compression="zstd")
    return path


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def to_json(obj: Any) -> str:
    """JSON text with NaN/inf as null and numpy scalars as Python numbers."""
    return json.dumps(_jsonable(obj), indent=2)


def write_json(path: Path, obj: Any) -> Path:
    """Write ``obj`` as JSON to ``path`` atomically."""
    write_text_atomic(path, to_json(obj) + "\n")
    return path
