"""The smoother's gain store faulted in ahead of the filter (estimation/store.py)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from brakethermo.errors import ConfigError
from brakethermo.estimation import store


def test_prefault_keeps_what_the_filter_already_wrote() -> None:
    """The kernel maps the pages while the filter writes: nothing it wrote may change,
    whether it wrote before the pages were populated or while they were."""
    a = np.empty(store.MIN_BYTES // 8 + 12345, dtype=np.float64)
    a[::1000] = np.arange(a[::1000].size, dtype=float)  # the filter's first writes
    thread = store.prefault(a)
    a[7::1000] = -1.0  # and its writes meanwhile
    if thread is not None:
        thread.join()
    np.testing.assert_array_equal(a[::1000], np.arange(a[::1000].size, dtype=float))
    assert (a[7::1000] == -1.0).all()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="madvise is Linux's")
def test_prefault_runs_on_linux_and_skips_small_stores() -> None:
    assert store._MADVISE is not None
    big = np.empty(store.MIN_BYTES, dtype=np.uint8)
    thread = store.prefault(big)
    assert thread is not None
    thread.join()
    assert store.prefault(np.empty(store.MIN_BYTES - 1, dtype=np.uint8)) is None


def test_gain_dtype_float32_from_the_threshold_and_refuses_others() -> None:
    assert store.gain_dtype(store.FLOAT32_STORE_N - 1, None) == np.float64
    assert store.gain_dtype(store.FLOAT32_STORE_N, None) == np.float32
    with pytest.raises(ConfigError, match="store_dtype"):
        store.gain_dtype(10, np.float16)
