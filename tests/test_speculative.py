"""A run started on a guess (pipelines/speculative.py): its result, or stopped at once."""

from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest

from brakethermo.pipelines import speculative
from brakethermo.pipelines.speculative import Cancelled, Speculation, cancellable


def test_result_and_the_core_it_holds_while_it_runs() -> None:
    """A pass waiting for a core gets the guess's the moment the guess is done."""
    cores = os.cpu_count() or 1
    release = threading.Event()

    def run(cancel: threading.Event) -> int:
        release.wait()
        return 42

    guess = Speculation(run)
    got: list[float] = []
    hold = threading.Event()

    def passes() -> None:
        with speculative.core():
            got.append(time.perf_counter())
            hold.wait(10.0)  # a pass holds its core while it runs

    threads = [threading.Thread(target=passes) for _ in range(cores)]
    for th in threads:
        th.start()
    time.sleep(0.1)
    assert len(got) == cores - 1  # every core but the guess's
    t_release = time.perf_counter()
    release.set()
    assert guess.result() == 42
    time.sleep(0.1)
    assert len(got) == cores and max(got) >= t_release
    hold.set()
    for th in threads:
        th.join()


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
    with speculative.core():  # and its core is free again
        pass


def test_cancellable_raises_only_once_cancelled() -> None:
    cancel = threading.Event()
    f = cancellable(lambda X, k: X * 2.0, cancel)
    np.testing.assert_array_equal(f(np.ones(2), 0), [2.0, 2.0])
    cancel.set()
    with pytest.raises(Cancelled):
        f(np.ones(2), 1)


def test_an_error_of_the_run_reaches_the_caller_and_frees_its_core() -> None:
    def run(cancel: threading.Event) -> None:
        raise ValueError("the disc model broke down")

    guess = Speculation(run)
    with pytest.raises(ValueError, match="broke down"):
        guess.result()
    with speculative.core():
        pass


def test_abandon_is_idempotent_from_any_thread() -> None:
    """The decision's thread stops the guess the moment it learns k_z; the caller's later
    abandon (or its error path's) is then a no-op."""
    def run(cancel: threading.Event) -> None:
        while not cancel.wait(0.001):
            pass

    guess = Speculation(run)
    assert not guess.abandoned
    threads = [threading.Thread(target=guess.abandon) for _ in range(2)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    guess.abandon()
    assert guess.abandoned
    with speculative.core():  # its core is free again
        pass
