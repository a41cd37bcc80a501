"""A computation started on a guess while the work that decides it goes on.

A race's estimate waits for its online decision (filter passes over its first laps,
:mod:`brakethermo.pipelines.online_choice`) before its own filter and smoother run. Most
races switch nothing on and drop nothing of the h law, and the decision's passes leave a
core idle part of the time: the estimate starts the filter for that outcome at once, on
its own thread, and uses it when the decision agrees — the same function on the same
inputs, so the same numbers — or stops it at its next model step (within its compiled
span of 256 steps) when it does not.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from typing import Generic, TypeVar

import numpy as np

T = TypeVar("T")


class Cancelled(Exception):
    """Raised inside a speculative run nobody needs any more."""


def cancellable(f: Callable[[np.ndarray, int], np.ndarray], cancel: threading.Event
                ) -> Callable[[np.ndarray, int], np.ndarray]:
    """A filter's model step that stops the run once ``cancel`` is set."""

    def step(X: np.ndarray, k: int) -> np.ndarray:
        if cancel.is_set():
            raise Cancelled
        return f(X, k)

    return step


def cancellable_steps(steps: Callable[..., None] | None, cancel: threading.Event
                      ) -> Callable[..., None] | None:
    """A filter's compiled steps (:meth:`DiscStateSpace.compiled_steps`) that stop the
    run once ``cancel`` is set, at the start of their next call."""
    if steps is None:
        return None

    def run(*args: object) -> None:
        if cancel.is_set():
            raise Cancelled
        steps(*args)

    return run


# One permit per core: a speculative run holds one while it runs, each of the decision's
# passes one while it runs (:func:`core`), so the guess keeps its core and a pass takes
# the core it frees the moment it is done.
_cores = threading.Semaphore(os.cpu_count() or 1)


@contextmanager
def core() -> Iterator[None]:
    """Hold one core's permit for the duration of the block (waiting for one)."""
    with _cores:
        yield


class Speculation(Generic[T]):
    """``fn(cancel)`` running on its own thread from construction on."""

    def __init__(self, fn: Callable[[threading.Event], T]) -> None:
        self._cancel = threading.Event()
        self._lock = threading.Lock()  # abandon from the decision's threads and the caller's
        self._abandoned = False
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="brakethermo-speculative")
        _cores.acquire()
        self._future = self._pool.submit(fn, self._cancel)
        self._future.add_done_callback(lambda _: _cores.release())

    def result(self) -> T:
        """The run's result (waiting for it); its exception if it raised one."""
        try:
            value = self._future.result()
        except BaseException:  # its own error, or Ctrl-C while waiting: stop it first
            self.abandon()
            raise
        self._pool.shutdown(wait=False)
        return value

    @property
    def abandoned(self) -> bool:
        """Whether :meth:`abandon` was called: the run has no result any more."""
        return self._abandoned

    def abandon(self) -> None:
        """Stop the run (at its next model step or compiled span of steps) and drop
        whatever it did or raised; from any thread, once or more (it returns when the run
        has stopped)."""
        with self._lock:
            if self._abandoned:
                return
            self._abandoned = True
            self._cancel.set()
            self._future.cancel()
            self._pool.shutdown(wait=True)
            del self._future  # with its traceback: the run's memory is free on return
