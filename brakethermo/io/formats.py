"""The session file formats brakethermo reads: one reader module each, one line here."""

from __future__ import annotations

from brakethermo.io import csv_reader, mcap_reader, mdf_reader, parquet_reader, xrk_reader
from brakethermo.io.raw import Format

FORMATS: tuple[Format, ...] = (
    mcap_reader.FORMAT,
    parquet_reader.FORMAT,
    csv_reader.FORMAT,
    mdf_reader.FORMAT,
    xrk_reader.FORMAT,
)

BY_SUFFIX: dict[str, Format] = {s: f for f in FORMATS for s in f.suffixes}

SUFFIXES: tuple[str, ...] = tuple(BY_SUFFIX)
