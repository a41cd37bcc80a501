"""Export an estimate as MCAP JSON topics, to open in Foxglove beside the source log.

Topics (``message_encoding = "json"``, ``jsonschema`` schemas, unit in the channel
metadata under ``unit``, as CHANNELS.md reads them back):

- ``/brakethermo/spot1`` … ``/brakethermo/spot4`` and ``/brakethermo/contact_avg``:
  ``{"value", "std", "lower", "upper"}`` — estimate, 1-sigma and the ±1σ band edges,
  degC; the spot radius in the channel metadata ``radius_m``;
- ``/brakethermo/disc_nodes``: ``{"temperature": [...]}`` — node temperatures, degC,
  node radii (m) as a JSON list in the channel metadata ``radius_m``; other column
  families ``<name>_<k>`` likewise (``mid_<k>``, mid-plane temperatures: ``disc_mid``);
- ``/brakethermo/lap``: ``{"value"}`` — lap number;
- any other numeric column of the frame (``power_scale``...) as ``{"value"[, "std"]}``.

``log_time`` is in nanoseconds on the session time base: relative to the session start,
or absolute epoch time when the source carried it (so both logs line up in Foxglove).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from mcap.writer import CompressionType, Writer

from brakethermo import __version__
from brakethermo.io.atomic import atomic_path

PREFIX = "/brakethermo/"
ARRAY_TOPICS = {"node": "disc_nodes", "mid": "disc_mid"}
ARRAY_UNITS = {"node": "degC", "mid": "degC"}
SCALAR_UNITS = {"braking_power": "W", "h": "W/(m2 K)", "power_scale": ""}
BANDED = ("spot1", "spot2", "spot3", "spot4", "contact_avg")  # estimate with a +-1 sigma band
_ARRAY_COLUMN = re.compile(r"^([A-Za-z]+)_(\d+)$")
SPOT_RADII_DEFAULT = (0.111, 0.130, 0.146, 0.162)  # m, cc-340-8 (CHANNELS.md §5)

_BAND_SCHEMA = {
    "type": "object",
    "properties": {
        "value": {"type": ["number", "null"], "description": "estimate"},
        "std": {"type": ["number", "null"], "description": "1-sigma"},
        "lower": {"type": ["number", "null"], "description": "estimate - 1 sigma"},
        "upper": {"type": ["number", "null"], "description": "estimate + 1 sigma"},
    },
}
_VALUE_SCHEMA = {"type": "object", "properties": {"value": {"type": ["number", "null"]}}}
_VALUE_STD_SCHEMA = {
    "type": "object",
    "properties": {"value": {"type": ["number", "null"]}, "std": {"type": ["number", "null"]}},
}
_NODES_SCHEMA = {
    "type": "object",
    "properties": {
        "temperature": {
            "type": "array",
            "items": {"type": ["number", "null"]},
            "description": "node temperatures from the inner to the outer radius, degC",
        }
    },
}


def _fmt(values: np.ndarray, decimals: int = 3) -> list[str]:
    """Numbers as JSON text; NaN and inf become ``null`` (JSON has no NaN)."""
    values = np.asarray(values, dtype=float)
    text = np.char.mod(f"%.{decimals}f", np.nan_to_num(values, nan=0.0, posinf=0.0, neginf=0.0))
    text[~np.isfinite(values)] = "null"
    return text.tolist()


def array_families(columns: Iterable[str]) -> dict[str, list[tuple[int, str]]]:
    """Columns ``<family>_<k>`` (``node_0``, ``mid_3``...) as ``{family: [(k, column)]}``.

    Families in the order they first appear, each in k order.
    """
    families: dict[str, list[tuple[int, str]]] = {}
    for col in columns:
        match = _ARRAY_COLUMN.match(str(col))
        if match:
            families.setdefault(match.group(1), []).append((int(match.group(2)), str(col)))
    return {f: sorted(cols) for f, cols in families.items()}


def scalar_columns(frame: pd.DataFrame, families: dict[str, list[tuple[int, str]]]) -> list[str]:
    """The numeric columns an export writes as scalars, in frame order.

    Everything but ``time``, ``lap``, the banded estimates, the array families and any
    ``*_std`` column (written beside its estimate).
    """
    in_family = {c for cols in families.values() for _, c in cols}
    skip = {"time", "lap", *in_family, *BANDED, *(f"{c}_std" for c in BANDED)}
    return [
        str(c)
        for c in frame.columns
        if c not in skip
        and not str(c).endswith("_std")
        and pd.api.types.is_numeric_dtype(frame[c])
    ]


def log_times_ns(time_s: np.ndarray, start_epoch_s: float | None) -> np.ndarray:
    """Message log times, ns: grid time plus the session's epoch start when known."""
    start_ns = round(start_epoch_s * 1e9) if start_epoch_s is not None else 0
    return start_ns + np.rint(np.asarray(time_s, dtype=float) * 1e9).astype(np.int64)


_Channel = Callable[[str, dict, str, dict[str, str]], int]
_Streams = list[tuple[int, list[str]]]


def _band_streams(frame: pd.DataFrame, banded: list[str], spot_radii: Sequence[float],
                  channel: _Channel) -> _Streams:
    """One channel per banded column: value, 1-sigma and the band's ends."""
    streams: _Streams = []
    for col in banded:
        value = frame[col].to_numpy(dtype=float)
        std_col = f"{col}_std"
        std = (frame[std_col].to_numpy(dtype=float) if std_col in frame
               else np.full_like(value, np.nan))
        meta = {"unit": "degC", "description": f"estimated {col} temperature with 1-sigma"}
        if col.startswith("spot"):
            meta["radius_m"] = repr(float(spot_radii[int(col[4:]) - 1]))
        cid = channel(col, _BAND_SCHEMA, "brakethermo.Band", meta)
        v, s, lo, hi = _fmt(value), _fmt(std), _fmt(value - std), _fmt(value + std)
        streams.append((cid, [f'{{"value":{a},"std":{b},"lower":{c},"upper":{d}}}'
                              for a, b, c, d in zip(v, s, lo, hi, strict=True)]))
    return streams


def _array_streams(frame: pd.DataFrame, families: dict[str, list[str]],
                   node_radii: Sequence[float] | np.ndarray | None, channel: _Channel
                   ) -> _Streams:
    """One array channel per family of indexed columns (the nodes first)."""
    streams: _Streams = []
    for family, cols in families.items():
        if not cols:
            continue
        radii = ([float(r) for r in node_radii]
                 if node_radii is not None and len(node_radii) == len(cols)
                 else [float("nan")] * len(cols))
        meta = {
            "unit": ARRAY_UNITS.get(family, ""),
            "radius_m": json.dumps(radii),
            "description": f"{family} temperatures, inner to outer radius",
        }
        topic = ARRAY_TOPICS.get(family, f"{family}_array")
        cid = channel(topic, _NODES_SCHEMA, "brakethermo.DiscNodes", meta)
        cells = np.array([_fmt(frame[c].to_numpy(dtype=float), 2) for c in cols]).T
        streams.append((cid, ['{"temperature":[' + ",".join(row) + "]}" for row in cells]))
    return streams


def _scalar_streams(frame: pd.DataFrame, extra: list[str], channel: _Channel) -> _Streams:
    """The lap, then each other scalar column (with its 1-sigma where it has one)."""
    streams: _Streams = []
    if "lap" in frame:
        cid = channel("lap", _VALUE_SCHEMA, "brakethermo.Value", {"unit": ""})
        streams.append((cid, [f'{{"value":{int(x)}}}' for x in frame["lap"].to_numpy()]))
    for col in extra:
        value = _fmt(frame[col].to_numpy(dtype=float), 6)
        meta = {"unit": SCALAR_UNITS.get(col, "")}
        std_col = f"{col}_std"
        if std_col in frame:
            std = _fmt(frame[std_col].to_numpy(dtype=float), 6)
            cid = channel(col, _VALUE_STD_SCHEMA, "brakethermo.ValueStd", meta)
            msgs = [f'{{"value":{a},"std":{b}}}' for a, b in zip(value, std, strict=True)]
        else:
            cid = channel(col, _VALUE_SCHEMA, "brakethermo.Value", meta)
            msgs = [f'{{"value":{a}}}' for a in value]
        streams.append((cid, msgs))
    return streams


def write_estimate_mcap(
    frame: pd.DataFrame,
    path: str | Path,
    *,
    node_radii: Sequence[float] | np.ndarray | None = None,
    spot_radii: Sequence[float] = SPOT_RADII_DEFAULT,
    start_epoch_s: float | None = None,
    source: str = "",
) -> Path:
    """Write an estimate frame to ``path`` as MCAP (zstd chunks), atomically.

    Parameters
    ----------
    frame : DataFrame
        Estimate frame of OUTPUTS.md.
    path : path
        Target ``.mcap`` file.
    node_radii : array — m, optional
        Radius of each ``node_<k>``; stored in the node channel's metadata.
    spot_radii : sequence of float — m
        Radii of spot 1..4, stored in the spot channels' metadata.
    start_epoch_s : float — s, optional
        Epoch time of grid point 0 when the source log carried absolute time.
    source : str
        Name of the source log, recorded in the file's metadata.
    """
    path = Path(path)
    t_ns = log_times_ns(frame["time"].to_numpy(), start_epoch_s)
    indexed = array_families(frame.columns)
    extra = scalar_columns(frame, indexed)
    families = {f: [c for _, c in cols] for f, cols in indexed.items()}
    nodes = families.pop("node", [])
    banded = [c for c in BANDED if c in frame]

    with atomic_path(path) as tmp, tmp.open("wb") as fh:
        writer = Writer(fh, compression=CompressionType.ZSTD)
        writer.start(profile="", library=f"brakethermo {__version__}")

        def channel(topic: str, schema: dict, name: str, meta: dict[str, str]) -> int:
            sid = writer.register_schema(
                name=name, encoding="jsonschema", data=json.dumps(schema).encode()
            )
            return writer.register_channel(
                topic=PREFIX + topic, message_encoding="json", schema_id=sid, metadata=meta
            )

        streams = [*_band_streams(frame, banded, spot_radii, channel),
                   *_array_streams(frame, {"node": nodes, **families}, node_radii, channel),
                   *_scalar_streams(frame, extra, channel)]

        times = t_ns.tolist()
        # Time-ordered interleaving so readers replay without reordering.
        for k, t in enumerate(times):
            for cid, msgs in streams:
                writer.add_message(
                    channel_id=cid, log_time=t, publish_time=t, sequence=k, data=msgs[k].encode()
                )
        writer.add_metadata(
            "brakethermo",
            {
                "version": __version__,
                "source": source,
                "start_epoch_s": "" if start_epoch_s is None else repr(float(start_epoch_s)),
                "time_base": "epoch" if start_epoch_s is not None else "session start",
            },
        )
        writer.finish()
    return path
