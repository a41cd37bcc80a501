"""Model inputs on the 10 Hz grid, derived from a session's channels."""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from brakethermo.io.load import load_session
from brakethermo.io.plausibility import (
    check_pressure,
    check_pyrometer,
    check_speeds,
    unusable_readings,
)
from brakethermo.io.session import Session
from brakethermo.thermal.disc import DiscSpec

MULTI_SPOT = ("disc_temp_spot1", "disc_temp_spot2", "disc_temp_spot3", "disc_temp_spot4")
SINGLE_SPOT = "disc_temp"
SINGLE_SPOT_INDEX = 3  # the race sensor sits at the spot-3 radius (CHANNELS.md §2)
STEADY_MARGIN = 10  # grid points (1 s) kept clear of a brake application


@dataclass(frozen=True)
class DiscInputs:
    """Everything the disc model and the filter read from a session, on the grid.

    Attributes
    ----------
    time : ndarray — s
    lap : ndarray of int
    speed : ndarray — m/s
    q_brk : ndarray — W
        Braking power entering this disc at nominal friction (datasheet formula).
    t_amb : ndarray — degC
    spots : ndarray — degC, shape (K, 4)
        Measured spot temperatures; NaN where a spot is not logged or in a gap.
    measured : tuple of int
        Spot numbers (1..4) the session logs.
    warnings : tuple of str
    per_reading : tuple of 4 int
        Grid points per native reading of each spot's pyrometer (1 at or above the grid
        rate; 5 for a 2 Hz pyrometer on the 10 Hz grid, whose points in between are
        interpolated, not measured).
    """

    time: np.ndarray
    lap: np.ndarray
    speed: np.ndarray
    q_brk: np.ndarray
    t_amb: np.ndarray
    spots: np.ndarray
    measured: tuple[int, ...]
    warnings: tuple[str, ...] = ()
    per_reading: tuple[int, ...] = (1, 1, 1, 1)

    def head(self, steps: int) -> DiscInputs:
        """The inputs of the first ``steps`` grid points (the race's first laps)."""
        return replace(self, time=self.time[:steps], lap=self.lap[:steps],
                       speed=self.speed[:steps], q_brk=self.q_brk[:steps],
                       t_amb=self.t_amb[:steps], spots=self.spots[:steps])

    @property
    def steady(self) -> np.ndarray:
        """Grid points a second or more from any brake application (the reading's own
        noise is measured there when the pyrometer is slower than the grid)."""
        busy = self.braking.astype(float)
        near = np.convolve(busy, np.ones(2 * STEADY_MARGIN + 1), mode="same") > 0
        return ~near

    @property
    def braking(self) -> np.ndarray:
        """Grid points where the brake is applied (more than 1 % of the peak power)."""
        peak = np.nanmax(self.q_brk) if self.q_brk.size else 0.0
        return self.q_brk > 0.01 * max(peak, 1.0)

    @property
    def is_multi_spot(self) -> bool:
        return len(self.measured) == 4


def _bridge(values: np.ndarray) -> tuple[np.ndarray, int]:
    """Linearly interpolate NaNs (edges held); return the filled array and NaN count."""
    bad = ~np.isfinite(values)
    n_bad = int(bad.sum())
    if n_bad == 0:
        return values, 0
    if n_bad == values.size:
        return np.zeros_like(values), n_bad
    idx = np.arange(values.size)
    filled = values.copy()
    filled[bad] = np.interp(idx[bad], idx[~bad], values[~bad])
    return filled, n_bad


def disc_inputs(session: Session, disc: DiscSpec, ambient_c: float | None = None) -> DiscInputs:
    """Build :class:`DiscInputs` from a session.

    Braking power follows the datasheet, ``Q = share · torque_per_Pa · p · ω``. Wheel
    speed falls back to ``speed / tyre_rolling_radius`` when the session has no
    ``wheel_speed_front``; gaps in the inputs are bridged linearly and reported.
    """
    session.require("speed", "brake_pressure_front")
    warnings: list[str] = []
    speed, n_speed = _bridge(session.values("speed"))
    pressure, n_p = _bridge(session.values("brake_pressure_front"))
    if session.has("wheel_speed_front"):
        omega, n_w = _bridge(session.values("wheel_speed_front"))
    else:
        omega, n_w = speed / disc.tyre_rolling_radius, 0
        warnings.append(
            "no wheel_speed_front channel: wheel speed taken as speed / tyre rolling radius"
        )
    for name, n in (("speed", n_speed), ("brake_pressure_front", n_p), ("wheel_speed_front", n_w)):
        if n:
            warnings.append(f"{name}: {n * 0.1:.1f} s of gaps bridged by linear interpolation")
    sources = {name: info.source for name, info in session.channels.items()}
    check_speeds(session.values("speed"),
                 session.values("wheel_speed_front") if session.has("wheel_speed_front")
                 else None, disc.tyre_rolling_radius, session.path, sources)
    check_pressure(session.values("brake_pressure_front"), session.path,
                   sources.get("brake_pressure_front", "brake_pressure_front"))
    q_brk = disc.braking_power(np.clip(pressure, 0.0, None), omega)

    n = len(session.frame)
    spots = np.full((n, 4), np.nan)
    measured: list[int] = []
    for i, name in enumerate(MULTI_SPOT):
        if session.has(name):
            spots[:, i] = session.values(name)
            measured.append(i + 1)
    if not measured and session.has(SINGLE_SPOT):
        spots[:, SINGLE_SPOT_INDEX - 1] = session.values(SINGLE_SPOT)
        measured.append(SINGLE_SPOT_INDEX)
    if not measured:
        session.require(SINGLE_SPOT)
    t_amb = session.ambient_c(ambient_c)
    braking = q_brk > 0.01 * max(float(np.nanmax(q_brk)), 1.0)
    dt = float(np.median(np.diff(session.time))) if n > 1 else 0.1
    per_reading = [1, 1, 1, 1]
    slow: dict[str, float] = {}
    for i in measured:
        name = MULTI_SPOT[i - 1] if session.has(MULTI_SPOT[i - 1]) else SINGLE_SPOT
        warnings.extend(check_pyrometer(spots[:, i - 1], braking, float(np.nanmedian(t_amb)),
                                        dt, session.path, sources.get(name, name)))
        bad, said = unusable_readings(spots[:, i - 1], dt, sources.get(name, name))
        spots[bad, i - 1] = np.nan
        warnings.extend(said)
        per_reading[i - 1] = grid_points_per_reading(session, name)
        if per_reading[i - 1] > 1:
            slow[sources.get(name, name)] = session.channels[name].rate_hz
    if slow:
        warnings.append(
            f"{', '.join(slow)}: logged at"
            f" {', '.join(dict.fromkeys(f'{r:.1f}' for r in slow.values()))} Hz,"
            f" below the {session.rate_hz:.0f} Hz grid: the values between readings are"
            " interpolated, so each reading counts once (its noise measured at its own"
            " rate)")
    return DiscInputs(
        time=session.time,
        lap=session.lap,
        speed=speed,
        q_brk=q_brk,
        t_amb=t_amb,
        spots=spots,
        measured=tuple(measured),
        warnings=tuple(warnings),
        per_reading=tuple(per_reading),
    )


def grid_points_per_reading(session: Session, name: str) -> int:
    """Grid points per native reading of channel ``name`` (1 when it is logged at the
    grid's rate or faster)."""
    rate = session.channels[name].rate_hz
    if not (np.isfinite(rate) and rate > 0):
        return 1
    return max(1, round(session.rate_hz / rate))


def load_timed(path: str | Path, aliases: str | Path | None) -> tuple[Session, float]:
    """Load a session file; also return the seconds it took (pipelines report it)."""
    t0 = time.perf_counter()
    session = load_session(path, aliases=aliases)
    return session, time.perf_counter() - t0
