"""The record walk of an MCAP byte range, compiled: a file (or chunk) without message
indexes holds one record per sample, and a Python loop over millions of them was most of
the read (0.6 s of a 25-lap session's 0.9 s; minutes for a multi-GiB log).

Imported lazily by :mod:`brakethermo.io.mcap_reader`, so that commands which never read
an MCAP file do not load numba.
"""

from __future__ import annotations

import numba
import numpy as np

OPCODE_INVALID = 0x00  # reserved by the MCAP spec: no writer emits it (zeroed bytes do)
OPCODE_CHANNEL = 0x04
OPCODE_MESSAGE = 0x05
OPCODE_CHUNK = 0x06
OPCODE_METADATA = 0x0C
OPCODE_DATA_END = 0x0F
BATCH = 1 << 20  # records per kernel call: bounded memory on a file of any size


@numba.njit(cache=True, nogil=True)
def _walk_nb(buf: np.ndarray, pos: int, end: int, max_records: int
             ) -> tuple[np.ndarray, np.ndarray, int, int]:  # pragma: no cover - compiled
    """Offsets of Message records and of the records Python must read (Channel, Chunk,
    Metadata, DataEnd) from ``pos``, until ``end``, a cut or zeroed record, DataEnd, or
    ``max_records`` records. Returns them, where the walk stopped, and a status: 0 the
    batch is full, 1 stopped (cut, zeroed or the end), 2 DataEnd reached."""
    messages = np.empty(max_records, np.int64)
    others = np.empty(max_records, np.int64)
    n_msg = 0
    n_other = 0
    for _ in range(max_records):
        if pos + 9 > end:
            return messages[:n_msg], others[:n_other], pos, 1
        opcode = buf[pos]
        length = np.int64(0)
        for i in range(8):
            length |= np.int64(buf[pos + 1 + i]) << np.int64(8 * i)
        nxt = pos + 9 + length
        if length < 0 or nxt > end or opcode == OPCODE_INVALID:
            return messages[:n_msg], others[:n_other], pos, 1
        if opcode == OPCODE_MESSAGE:
            messages[n_msg] = pos
            n_msg += 1
        elif (opcode == OPCODE_CHANNEL or opcode == OPCODE_CHUNK or opcode == OPCODE_METADATA
              or opcode == OPCODE_DATA_END):
            others[n_other] = pos
            n_other += 1
            if opcode == OPCODE_DATA_END:
                return messages[:n_msg], others[:n_other], nxt, 2
        pos = nxt
    return messages[:n_msg], others[:n_other], pos, 0


def walk(buf: np.ndarray, pos: int, end: int) -> tuple[np.ndarray, np.ndarray, int, bool]:
    """Message offsets, the offsets of the records to read in Python (in file order), the
    offset just after the last complete record, and whether the walk reached DataEnd."""
    messages, others = [], []
    while True:
        m, o, pos, status = _walk_nb(buf, pos, end, min(BATCH, (end - pos) // 9 + 1))
        messages.append(m)
        others.append(o)
        if status:
            return np.concatenate(messages), np.concatenate(others), pos, status == 2
