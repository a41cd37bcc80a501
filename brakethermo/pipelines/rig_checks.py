"""Physical plausibility of a rig session's channels, before any estimate is made.

A rig log can be wrong in ways no reader sees: a sensor zeroed or frozen, a channel of
the wrong sign, a unit off by a thousand. Each rig states what its channels must look
like (:class:`Expect`); a channel the estimate is made from refuses the run with a line
naming the channel, the fault and the likely cause, and a channel that only scores the
estimate (a pressure beside a pressure observer) is kept with a warning, because an
estimate scored against it would be scored against nonsense.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from brakethermo.errors import DataError
from brakethermo.io.session import Session
from brakethermo.io.units import parse_unit
from brakethermo.numeric import held_max, true_runs

# A 95 % band covering less than this of the applies on the session's own sensor is said
# (an observer's band is checked wherever the session logs what it estimates): the low end
# of the 85-99 % a band that admits its model's error should cover (an independent
# caliper's validation session covered 81.5 % of its applies, unsaid at 80 %)
LOW_COVERAGE = 0.85
Z95 = 1.959963984540054  # two-sided 95 % of a Gaussian
MIN_APPLIED = 200  # applied samples needed to score a band while the brake is applied


def in_band(measured: np.ndarray, est: np.ndarray, std: np.ndarray, applied_above: float
            ) -> tuple[np.ndarray, np.ndarray]:
    """A session's own sensor against an estimate's 95 % band, over the samples where both
    are finite: whether each reading lies inside, and whether the brake is applied there
    by either side's account (idle samples, both near 0, flatter a pooled figure, and the
    estimate's onsets and releases belong in it), in the sensor's unit."""
    ok = np.isfinite(measured) & np.isfinite(est) & np.isfinite(std)
    inside = np.abs(est[ok] - measured[ok]) <= Z95 * np.maximum(std[ok], 1e-12)
    return inside, np.maximum(measured[ok], est[ok]) > applied_above


@dataclass(frozen=True)
class Expect:
    """What a channel of a rig must look like, in SI units.

    Attributes
    ----------
    channel : str — canonical name.
    unit : str — SI unit, for the messages.
    most : float — the largest magnitude any such rig reaches (beyond it: a unit error).
    positive : bool — the quantity is not negative in use (a force pressing, a pressure).
    role : ``"input"`` (the estimate is made from it) or ``"score"`` (it only scores).
    measured : bool — a sensor's reading (False: a command, which may hold a value
        exactly, as a torque request of 0 in free rolling does).
    setpoint : bool — a rig may log it as a set-point, one value throughout (an air
        spring's load): taken, with a warning, where a measured channel would be refused.
    least : float — the smallest largest-magnitude any use of such a rig reaches (below
        it: a unit error, as kN labelled N; 0: not checked).
    """

    channel: str
    unit: str
    most: float
    positive: bool = False
    role: Literal["input", "score"] = "input"
    measured: bool = True
    setpoint: bool = False
    least: float = 0.0


def _as_logged(session: Session, e: Expect) -> Callable[[float], str]:
    """A value of the channel (SI) in words, in the unit the file logs it in ("9.5 mm",
    not "0.0095 m"): the figure the user finds in the log."""
    info = session.channels.get(e.channel)
    unit = parse_unit(info.unit) if info is not None and info.unit.strip() else None
    if info is None or unit is None or (unit.scale == 1.0 and unit.offset == 0.0):
        return lambda x: f"{x:.4g} {e.unit}"
    return lambda x: f"{(x - unit.offset) / unit.scale:.4g} {info.unit}"


def _fault(v: np.ndarray, e: Expect, shown: Callable[[float], str] | None = None
           ) -> str | None:
    """What is wrong with one channel's finite values, in words (None: nothing); a single
    value (a constant of the log) is judged on its range and sign only. ``shown``: a
    value (SI) in words (default: in SI, :func:`_as_logged` in the log's unit)."""
    scale = float(np.percentile(np.abs(v), 99.5))
    shown = shown or (lambda x: f"{x:.4g} {e.unit}")
    if v.size == 1 and e.positive and not v[0] > 0.0:
        return f"is {shown(float(v[0]))}: it must be positive"
    if v.size > 1 and np.ptp(v) <= 1e-9 * max(scale, 1e-30):
        return (f"does not move (constant {shown(float(v[0]))} throughout): nothing was"
                " applied in this session, or the sensor is zeroed, frozen or not connected")
    if scale > e.most:
        return (f"reaches {scale:.4g} {e.unit}, beyond any such rig (at most about"
                f" {e.most:g} {e.unit}): check the channel's unit")
    low, high = (float(np.percentile(v, q)) for q in (5, 95))
    if e.positive and low < -0.2 * scale:
        if -low < 2.0 * high:  # as far below zero as above: noise, not a reversed sign
            return (f"reads only noise around zero (5th to 95th percentile {low:.4g} to"
                    f" {high:.4g} {e.unit}): nothing was applied in this session, or the"
                    " sensor is zeroed or not connected")
        return (f"is mostly negative (5th percentile {low:.4g} {e.unit}"
                f" against a largest magnitude of {scale:.4g}): the sign is reversed")
    # after the noise test: a sensor reading noise around zero is said so, not a unit slip
    if e.least and (peak := _held_peak(v)) < e.least:
        return (f"reaches at most {shown(peak)}, less than any use of such a rig (at least"
                f" about {shown(e.least)}): check the channel's unit (a thousand times too"
                " small: kN logged as N, MPa as Pa)")
    return None


HELD_SAMPLES = 5  # a peak held this many samples is a load, not a spike


def _held_peak(v: np.ndarray) -> float:
    """The largest magnitude held over :data:`HELD_SAMPLES` samples (a running median's
    maximum): the applies of a session, however few (a 99.5th percentile of a log that
    clamps 0.4 % of the time is its rest level: a 0.25 s apply of 8 kN in 60 s at 1 kHz
    read as 36 N, 'a thousand times too small')."""
    return held_max(np.abs(v), HELD_SAMPLES)


def channel_warnings(session: Session, channel: str) -> list[str]:
    """The warnings :func:`check_rig_channels` gave ``channel`` (in ``session.warnings``):
    a channel so flagged is not trusted beyond being read."""
    return [w for w in session.warnings if w.startswith(f"channel '{channel}'")]


def check_rig_channels(session: Session, expects: Sequence[Expect]) -> list[str]:
    """Check the channels ``expects`` names that the session has.

    Returns
    -------
    list of str — warnings for scoring channels that fail.

    Raises
    ------
    DataError
        An input channel fails (named, with the likely cause).
    """
    warnings = []
    for e in expects:
        if e.channel in session.constants:
            v = np.array([session.constants[e.channel]])
        elif session.has(e.channel):
            v = session.values(e.channel)
            v = v[np.isfinite(v)]
            if v.size < 2:
                continue
        else:
            continue
        shown = _as_logged(session, e)
        if e.setpoint and v.size > 1 and np.ptp(v) == 0.0 and 0.0 < v[0] <= e.most:
            warnings.append(f"channel '{e.channel}' holds {shown(float(v[0]))} throughout:"
                            " taken as the rig's set-point (a frozen sensor would read so"
                            " too)")
            continue
        fault = _fault(v, e, shown)
        if fault is None:
            if e.measured and e.channel not in session.constants:
                warnings.extend(_frozen_stretches(session, e))
            continue
        if e.role == "input":
            raise DataError(fault, path=session.path, channel=e.channel)
        warnings.append(f"channel '{e.channel}' {fault}; it only scores the estimate, whose"
                        " figures against it mean nothing")
    return warnings


# A stretch of exactly repeated values this long (samples and seconds, both) in a channel
# that otherwise changes at nearly every sample is a sensor that froze or dropped out.
FROZEN_SAMPLES = 100
FROZEN_S = 0.1
MAX_REPEAT_SHARE = 0.05  # a channel repeating more often is quantised: not judged


def frozen_stretches(session: Session, channel: str, unit: str) -> tuple[np.ndarray, str]:
    """Stretches where a noisy channel holds one value exactly (a dropout to zero, a frozen
    sensor) while the rest of the log moves: a per-sample mask and the stretches in words
    ('' when none).

    A channel that repeats values at more than :data:`MAX_REPEAT_SHARE` of its samples
    elsewhere (quantised, or an input held between applications) is not judged, nor a
    stretch that starts or ends the log.
    """
    v = session.values(channel)
    mask = np.zeros(v.size, bool)
    same = np.diff(v) == 0.0
    if same.size < 2 * FROZEN_SAMPLES:
        return mask, ""
    starts, ends = true_runs(same).T
    need = max(FROZEN_SAMPLES, int(np.ceil(FROZEN_S / session.dt)))
    long = (ends - starts) + 1 >= need  # a run of k equal differences holds k + 1 samples
    inside = int((ends - starts)[long].sum())
    # at the log's ends the rig may simply not have started yet (a resolver at rest)
    long &= (starts > 0) & (ends < same.size)
    if not long.any() or (same.sum() - inside) / max(same.size - inside, 1) > MAX_REPEAT_SHARE:
        return mask, ""
    for a, b in zip(starts[long], ends[long], strict=True):
        mask[a: b + 1] = True
    t = session.time
    spans = ", ".join(f"{t[a]:.2f}–{t[b]:.2f} s at {v[a]:.4g}"
                      for a, b in zip(starts[long][:4], ends[long][:4], strict=True))
    return mask, (f"channel '{channel}' holds one value exactly ({spans}"
                  f"{' …' if long.sum() > 4 else ''} {unit}) where it otherwise changes at"
                  " every sample: the sensor froze or dropped out there")


def _frozen_stretches(session: Session, e: Expect) -> list[str]:
    said = frozen_stretches(session, e.channel, e.unit)[1]
    return [f"{said}, and the estimate over that stretch stands on a value the rig did not"
            " have"] if said else []
