"""The smoother's gain store: its dtype, and its first touch ahead of the filter.

The RTS smoother needs two n x n matrices per step from the forward pass (float32 from
:data:`FLOAT32_STORE_N` states: about 400 MB for a 25-lap race at 41 states). Fresh
memory costs its first write, not its allocation: on a virtual machine whose host backs
guest pages lazily, about 2 µs per 4 KiB page — 1.5 s of that race, against 0.8 s for
the gains' arithmetic. The filter itself runs on one core, so :func:`prefault` has the
kernel fault the store in on the other, ahead of the filter's writes:
``madvise(MADV_POPULATE_WRITE)`` (Linux 5.14+) maps the pages writable without changing
what they hold, so the filter may write to any part of the store meanwhile. Elsewhere
(another OS, an older kernel) it does nothing and the filter faults as before.
"""

from __future__ import annotations

import ctypes
import sys
import threading

import numpy as np

from brakethermo.errors import ConfigError

MIN_BYTES = 32 * 2**20  # smaller stores are not worth a thread
PAGE = 4096  # bytes
CHUNK = 16 * 2**20  # bytes per call: the pages ahead of the filter come first
MADV_POPULATE_WRITE = 23  # <linux/mman.h>, Linux 5.14+
# From this state size on, the smoother's gains are stored as float32 by default: for a
# 25 000-step race at n = 30 (10 nodes x 3 layers) two float64 (K, n, n) stacks are
# 360 MB, and first writes to fresh memory (page faults) cost as much as the arithmetic
# on this class of machine; float32 halves both at ~1e-7 relative precision, far below
# the temperature uncertainty.
FLOAT32_STORE_N = 24


def gain_dtype(n: int, store_dtype: type[np.floating] | np.dtype | None) -> np.dtype:
    """The dtype the smoother's gains are stored in for state size ``n``."""
    if store_dtype is None:
        store_dtype = np.float64 if n < FLOAT32_STORE_N else np.float32
    dtype = np.dtype(store_dtype)
    if dtype not in (np.dtype(np.float64), np.dtype(np.float32)):
        raise ConfigError(f"store_dtype must be float64 or float32, got {store_dtype}")
    return dtype


def _libc_madvise() -> ctypes._CFuncPtr | None:  # type: ignore[name-defined]
    """libc's madvise (ctypes releases the GIL during the call), or None off Linux."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        fn = ctypes.CDLL(None, use_errno=True).madvise
    except (OSError, AttributeError):
        return None
    fn.argtypes = (ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int)
    fn.restype = ctypes.c_int
    return fn


_MADVISE = _libc_madvise()


def prefault(store: np.ndarray) -> threading.Thread | None:
    """Fault ``store``'s pages in on a background thread, first pages first; its
    contents are untouched. Returns the thread (None when there is nothing to do)."""
    if _MADVISE is None or store.nbytes < MIN_BYTES:
        return None
    address = store.ctypes.data
    start = -(-address // PAGE) * PAGE
    end = (address + store.nbytes) // PAGE * PAGE

    def populate(keep: np.ndarray = store) -> None:  # keep: the memory outlives the calls
        for a in range(start, end, CHUNK):
            if _MADVISE(a, min(CHUNK, end - a), MADV_POPULATE_WRITE) != 0:
                return  # not supported here: the filter's writes fault as they always did

    thread = threading.Thread(target=populate, daemon=True, name="brakethermo-prefault")
    thread.start()
    return thread
