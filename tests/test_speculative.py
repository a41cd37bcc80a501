"""A run started on a guess (pipelines/speculative.py): its result, or stopped at once."""

from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest

from brakethermo.pipelines import speculative
from brakethermo.pipelines.speculative import Cancelled, Speculation, cancellable


def test_result_and_the_core_it_held() -> None:
    cores = os.cpu_count() or 1
    started = threading.Event()

    def run(cancel: threading.Event) -> int:
        started.set()
        time.sleep(0.05)
        return 42

    guess = Speculation(run)
    started.wait()
    assert speculative.free_cores() == max(1, cores - 1)
    assert guess.result() == 42
    assert speculative.free_cores() == cores


def test_abandon_stops_the_run_at_its_next_step() -> None:
    steps: list[int] = []

    def run(cancel: threading.Event) -> None:
        f = cancellable(lambda X, k: X + 1.0, cancel)
        X = np.zeros(3)
        for k in range(10**9):
            X = f(X, k)
            steps.append(k)

    guess = Speculation(run)
    while not steps:
        time.sleep(0.001)
    t0 = time.perf_counter()
    guess.abandon()
    assert time.perf_counter() - t0 < 2.0
    done = len(steps)
    time.sleep(0.02)
    assert len(steps) == done  # nothing runs any more
    assert speculative.free_cores() == (os.cpu_count() or 1)


def test_cancellable_raises_only_once_cancelled() -> None:
    cancel = threading.Event()
    f = cancellable(lambda X, k: X * 2.0, cancel)
    np.testing.assert_array_equal(f(np.ones(2), 0), [2.0, 2.0])
    cancel.set()
    with pytest.raises(Cancelled):
        f(np.ones(2), 1)
