"""Per-lap wall time of ``estimate`` against the race budget (MISSION.md: 5 min per race).

Each lap is estimated on its own (the session cut to that lap), timed with a wall
clock around the whole estimate of that lap: filter, smoother, model set-up and the
output frame, so a slow lap cannot hide behind fast ones the way an average would.
One-time start-up costs (imports, compilation, caches) are paid by a short warm-up
run on a mid-session slice first and reported apart.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from brakethermo.errors import ConfigError
from brakethermo.io.session import Session

WARMUP_STEPS = 100  # grid points of the warm-up run (taken mid-session)


@dataclass(frozen=True)
class LapTiming:
    """Wall time of one lap's estimate.

    Attributes
    ----------
    lap : int
    data_s : float — s
        Length of the lap's data.
    wall_s : float — s
        Wall time to estimate it.
    """

    lap: int
    data_s: float
    wall_s: float


@dataclass(frozen=True)
class TimingReport:
    """Per-lap timings and the verdict against the budget.

    Attributes
    ----------
    laps : tuple of LapTiming
    budget_per_lap_s : float — s
        ``budget_s / race_laps``.
    startup_s : float — s
        Wall time of the warm-up run (one-time costs).
    """

    laps: tuple[LapTiming, ...]
    budget_per_lap_s: float
    startup_s: float

    @property
    def worst(self) -> LapTiming:
        """The slowest lap."""
        return max(self.laps, key=lambda lap: lap.wall_s)

    @property
    def passed(self) -> bool:
        """Whether every lap fits its share of the budget."""
        return self.worst.wall_s <= self.budget_per_lap_s

    @property
    def total_s(self) -> float:
        """Start-up plus the sum of the laps, s."""
        return self.startup_s + sum(lap.wall_s for lap in self.laps)

    def to_json(self) -> dict[str, Any]:
        """JSON-able record."""
        return {
            "budget_per_lap_s": self.budget_per_lap_s,
            "startup_s": round(self.startup_s, 4),
            "total_s": round(self.total_s, 4),
            "worst_lap": self.worst.lap,
            "worst_wall_s": round(self.worst.wall_s, 4),
            "passed": self.passed,
            "laps": [
                {"lap": t.lap, "data_s": round(t.data_s, 3), "wall_s": round(t.wall_s, 4)}
                for t in self.laps
            ],
        }


def session_slice(session: Session, start: int, stop: int) -> Session:
    """The session cut to grid points ``[start, stop)`` (time base kept)."""
    frame = session.frame.iloc[start:stop].reset_index(drop=True)
    laps_in = set(np.unique(frame["lap"].to_numpy()).tolist())
    return replace(session, frame=frame, laps=tuple(lp for lp in session.laps if lp.lap in laps_in))


def time_laps(
    session: Session,
    estimate: Callable[[Session], object],
    budget_s: float = 300.0,
    race_laps: int = 25,
) -> TimingReport:
    """Estimate each lap of ``session`` on its own and time it.

    Parameters
    ----------
    session : Session
    estimate : callable
        ``estimate(session)``, e.g. ``lambda s: estimate_from_session(s, options)``.
    budget_s : float — s
        Budget for a whole race.
    race_laps : int
        Laps in that race; the per-lap budget is ``budget_s / race_laps``.

    Raises
    ------
    ConfigError
        A budget that is not a finite number > 0, or fewer than one race lap.
    """
    if not (math.isfinite(budget_s) and budget_s > 0) or race_laps < 1:
        raise ConfigError(
            f"budget {budget_s} s for {race_laps} laps: need a finite budget > 0 and >= 1 lap"
        )
    lap_col = session.frame["lap"].to_numpy()
    t0 = time.perf_counter()
    # Warm up mid-session: the start of an out-lap may have no IR reading at all.
    mid = max(0, len(lap_col) // 2 - WARMUP_STEPS // 2)
    estimate(session_slice(session, mid, min(mid + WARMUP_STEPS, len(lap_col))))
    startup = time.perf_counter() - t0
    bounds = np.flatnonzero(np.diff(lap_col, prepend=lap_col[0] - 1) != 0)
    ends = np.append(bounds[1:], len(lap_col))
    dt = float(np.median(np.diff(session.time))) if len(lap_col) > 1 else 0.1
    timings = []
    for a, b in zip(bounds, ends, strict=True):
        lap_session = session_slice(session, int(a), int(b))
        t = time.perf_counter()
        estimate(lap_session)
        timings.append(LapTiming(int(lap_col[a]), (b - a) * dt, time.perf_counter() - t))
    return TimingReport(tuple(timings), budget_s / race_laps, startup)
