"""Time stamps as real loggers write them: integer units, clock jumps, impossible spans.

Shared by every reader (:func:`settle` runs on each :class:`RawSession` before any
grid is planned), so a glitched clock costs a warning, never a 100 GiB allocation:

* :func:`integer_time_scale` infers the unit of an integer time column (s, ms, µs, ns)
  from its span and its step, and says which it assumed;
* :func:`settle` drops isolated samples far outside the bulk of the session (a logger
  clock jump) with a warning saying how many and where, and refuses a session whose
  span is implausible before anything is allocated.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from brakethermo.errors import DataError
from brakethermo.io.raw import RawChannel, RawSession

# Longest session accepted, s: a 24 h race with its warm-up, several times over.
MAX_SPAN_S = 7 * 86400.0
# A session's fastest channel is logged at 1 Hz or faster: the time column's typical step.
MAX_STEP_S = 1.0
# Units tried for an integer time column, coarsest first: (label, seconds per tick).
TIME_UNITS = (("s", 1.0), ("ms", 1e-3), ("µs", 1e-6), ("ns", 1e-9))
# Time units a file may name for its time column: seconds per unit.
TIME_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "ns": 1e-9}
# Samples further than this from the bulk of the session are a clock jump, s ...
OUTLIER_MARGIN_S = 60.0
# ... or this fraction of the bulk's span, whichever is longer.
OUTLIER_MARGIN_FRACTION = 0.05
# The bulk: the central part of all samples pooled; what lies outside its quantiles by
# more than the margin is isolated.
BULK_QUANTILE = 1e-3


def integer_time_scale(ticks: np.ndarray, *, path: Path, column: str) -> tuple[float, str | None]:
    """Seconds per tick of an integer time column with no unit.

    The unit is the coarsest of s, ms, µs, ns under which the column spans at most
    :data:`MAX_SPAN_S` and its median step is at most :data:`MAX_STEP_S` (the fastest
    channel of a log is sampled at 1 Hz or faster).

    Returns
    -------
    scale : float
        Seconds per tick.
    note : str or None
        A warning saying which unit was assumed (``None`` for seconds).

    Raises
    ------
    DataError
        No unit gives a plausible session.
    """
    t = np.unique(np.asarray(ticks))
    span = float(t[-1] - t[0]) if t.size else 0.0
    steps = np.diff(t)
    step = float(np.median(steps)) if steps.size else 0.0
    for label, scale in TIME_UNITS:
        if span * scale <= MAX_SPAN_S and step * scale <= MAX_STEP_S:
            if label == "s":
                return scale, None
            return scale, (
                f"time column '{column}' holds integers with no unit; assumed {label} (the"
                f" session spans {span * scale:.1f} s, median step {step * scale * 1e3:g} ms)."
                " Store time as float seconds or a timestamp type to be explicit"
            )
    raise DataError(
        f"time column '{column}' holds integers spanning {span:.6g} ticks with a median step"
        f" of {step:.6g}: no unit (s, ms, µs, ns) gives a plausible session; store the time"
        " as float seconds or a timestamp type",
        path=path,
        channel=column,
    )


def _fmt_s(seconds: float) -> str:
    if abs(seconds) >= 86400.0:
        return f"{seconds / 86400.0:.1f} days"
    if abs(seconds) >= 3600.0:
        return f"{seconds / 3600.0:.1f} h"
    return f"{seconds:.1f} s"


def settle(raw: RawSession) -> RawSession:
    """Drop non-finite and isolated far-away samples, check the span, rebase to t = 0.

    Returns
    -------
    RawSession
        The same session, times again from the earliest kept sample (``origin_s``
        moved with them), a warning for each kind of sample dropped.

    Raises
    ------
    DataError
        The kept samples span more than :data:`MAX_SPAN_S`.
    """
    channels = [c for c in raw.channels]
    warnings = list(raw.warnings)
    bad_t = {c.name: int((~np.isfinite(c.t)).sum()) for c in channels}
    if any(bad_t.values()):
        channels = [_keep(c, np.isfinite(c.t)) for c in channels]
        named = ", ".join(f"'{n}' ({k})" for n, k in bad_t.items() if k)
        warnings.append(f"dropped {sum(bad_t.values())} sample(s) with no valid time: {named}")
    pooled = [c.t for c in channels if c.t.size]
    if not pooled:
        return dataclasses.replace(raw, channels=tuple(channels), warnings=tuple(warnings))
    every = np.concatenate(pooled)
    lo, hi = np.quantile(every, [BULK_QUANTILE, 1.0 - BULK_QUANTILE])
    margin = max(OUTLIER_MARGIN_S, OUTLIER_MARGIN_FRACTION * float(hi - lo))
    first, last = float(every.min()), float(every.max())
    if first < lo - margin or last > hi + margin:
        dropped: dict[str, int] = {}
        where: list[float] = []
        kept = []
        for c in channels:
            inside = (c.t >= lo - margin) & (c.t <= hi + margin)
            if not inside.all():
                dropped[c.name] = int((~inside).sum())
                where.extend(c.t[~inside][:3].tolist())
            kept.append(_keep(c, inside))
        channels = kept
        at = ", ".join(
            f"{_fmt_s(t - lo)} after" if t > hi else f"{_fmt_s(lo - t)} before" for t in where[:3]
        )
        n = sum(dropped.values())
        warnings.append(
            f"dropped {n} isolated sample(s) with timestamps far outside the session (a logger"
            f" clock jump?): {at} the bulk of the data; channels "
            + ", ".join(f"'{k}' ({v})" for k, v in dropped.items())
        )
    starts = [float(c.t.min()) for c in channels if c.t.size]
    ends = [float(c.t.max()) for c in channels if c.t.size]
    t0, t1 = min(starts), max(ends)
    if t1 - t0 > MAX_SPAN_S:
        raise DataError(
            f"the samples span {_fmt_s(t1 - t0)}, longer than any session"
            f" ({_fmt_s(MAX_SPAN_S)} at most): the time stamps are not in the unit the file"
            " says, or the logger clock jumped; check the time column / log times",
            path=raw.path,
        )
    steps = [float(np.median(np.diff(np.sort(c.t)))) for c in channels if c.t.size > 2]
    fastest = min((d for d in steps if d > 0), default=0.0)
    if fastest > MAX_STEP_S:
        raise DataError(
            f"its fastest channel is logged every {_fmt_s(fastest)} and the samples span"
            f" {_fmt_s(t1 - t0)}: no brake log is that slow; the time stamps are likely in"
            f" milliseconds labelled seconds (that would be {1e3 / fastest:.0f} Hz over"
            f" {_fmt_s((t1 - t0) / 1e3)}); fix the time column's unit",
            path=raw.path,
        )
    if t0 != 0.0:
        channels = [RawChannel(c.name, c.t - t0, c.v, c.unit) for c in channels]
    origin = None if raw.origin_s is None else raw.origin_s + t0
    return dataclasses.replace(
        raw, channels=tuple(channels), origin_s=origin, warnings=tuple(warnings)
    )


def _keep(c: RawChannel, mask: np.ndarray) -> RawChannel:
    if mask.all():
        return c
    return RawChannel(c.name, c.t[mask], c.v[mask], c.unit)
