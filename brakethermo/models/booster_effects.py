"""Unmodelled effects of an electric brake booster's pressure–volume relation.

The observer (:mod:`brakethermo.models.ebooster`) maps the screw travel s2 to the
master-cylinder pressure through the static p–V curve f(s2) of a training session. A real
booster departs from it in ways a polynomial fitted once does not follow; each candidate
below is that curve extended by one or two parameters, fitted on some apply cycles of a
session with a pressure sensor and scored on the others by the diagnosis engine
(:mod:`brakethermo.diagnosis.verdict`):

- ``pv_shift``: the curve moved along the stroke, p = f(s2 - d) (seal and rubber state,
  fluid: the dead stroke before the central valve closes differs from the training day);
- ``pv_scale``: the curve stiffer or softer, p = (1 + a) f(s2) (air in the fluid, hoses
  and caliper seals of another compliance);
- ``pv_drift``: a shift that moves during the session, p = f(s2 - d0 - d1 t/T) (fluid
  warming, seals bedding in);
- ``rate_dependent``: a pressure term in the screw speed, p = f(s2) + k v (flow through
  the ports and hoses: the calipers fill behind the master cylinder);
- ``hysteresis``: a pressure offset of opposite sign going in and out,
  p = f(s2) + c tanh(v / v0) (seal friction and rubber hysteresis of the piston).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
HYSTERESIS_V0_MM_S = 0.5  # mm/s: below this screw speed the direction is not yet set


@dataclass(frozen=True)
class BoosterContext:
    """What a candidate sees of a session: the inputs and the training curve.

    Attributes
    ----------
    s2 : ndarray (K,) — mm, screw travel.
    v : ndarray (K,) — mm/s, screw speed (smoothed).
    t : ndarray (K,) — s from the session start.
    curve : callable — the training session's p–V curve, mm -> MPa.
    """

    s2: Array
    v: Array
    t: Array
    curve: Callable[[Array], Array]


@dataclass(frozen=True)
class BoosterEffect:
    """One candidate: its parameters, prediction, and what tells it from look-alikes."""

    name: str
    params: tuple[str, ...]
    units: tuple[str, ...]
    start: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    extension: str
    separate_by: str
    predict: Callable[[Array, BoosterContext], Array]


def _shifted(ctx: BoosterContext, d: Array | float) -> Array:
    return ctx.curve(np.clip(ctx.s2 - d, 0.0, None))


BOOSTER_EFFECTS: dict[str, BoosterEffect] = {e.name: e for e in (
    BoosterEffect(
        "pv_shift", ("shift_mm",), ("mm",), (0.0,), (-3.0,), (3.0,),
        "the training p-V curve moved along the stroke: p = f(s2 - d)",
        "a run at another fluid temperature, or after bleeding: a shift that stays is the"
        " seals' and fluid's state; one that moves during a session is drift",
        lambda th, c: _shifted(c, th[0]),
    ),
    BoosterEffect(
        "pv_scale", ("scale",), ("-",), (0.0,), (-0.5,), (1.0,),
        "the training p-V curve stiffer or softer: p = (1 + a) f(s2)",
        "the pressure at full stroke against the travel where it starts to rise: a scale"
        " changes the first, a shift the second",
        lambda th, c: (1.0 + th[0]) * c.curve(c.s2),
    ),
    BoosterEffect(
        "pv_drift", ("shift_mm", "drift_mm"), ("mm", "mm over the session"), (0.0, 0.0),
        (-3.0, -3.0), (3.0, 3.0),
        "a shift along the stroke that moves during the session: p = f(s2 - d0 - d1 t/T)",
        "the same apply repeated at the start and the end of a session",
        lambda th, c: _shifted(c, th[0] + th[1] * c.t / max(float(c.t[-1]), 1e-9)),
    ),
    BoosterEffect(
        "rate_dependent", ("k_mpa_per_mm_s",), ("MPa/(mm/s)",), (0.0,), (-0.5,), (0.5,),
        "a pressure term in the screw speed: p = f(s2) + k v (flow through ports and hoses)",
        "slow against fast applies to the same travel: flow grows with speed, hysteresis"
        " does not",
        lambda th, c: c.curve(c.s2) + th[0] * c.v,
    ),
    BoosterEffect(
        "hysteresis", ("offset_mpa",), ("MPa",), (0.0,), (-2.0,), (2.0,),
        "a pressure offset of opposite sign going in and out: p = f(s2) + c tanh(v/v0)",
        "a slow apply held and released: hysteresis keeps its offset at any speed, flow"
        " vanishes as the screw stops",
        lambda th, c: c.curve(c.s2) + th[0] * np.tanh(c.v / HYSTERESIS_V0_MM_S),
    ),
)}
