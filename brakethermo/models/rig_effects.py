"""Unmodelled effects of the rigs' trained input–output relations, per rig.

Each rig's estimator leans on a relation trained once: the E-Booster's static p–V curve
p = f(s2) (:mod:`brakethermo.models.ebooster`), the EMB caliper's dynamic stiffness
F = g(θ) (eq. 6, :mod:`brakethermo.models.clamp_force`). A real rig departs from it in ways
a relation fitted once does not follow; each candidate below is that relation extended by
one or two parameters, fitted on some apply cycles of a session with the output's sensor
and scored on the others by the diagnosis engine (:mod:`brakethermo.diagnosis.verdict`).

E-Booster (:data:`BOOSTER_EFFECTS`, x = s2 in mm, v its speed in mm/s):

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

EMB caliper (:data:`EMB_EFFECTS`, x = motor angle θ in rad, v its speed in rad/s, the
force in kN):

- ``stiffness_scale``: F = (1 + a) g(θ) (pads stiffer or softer: temperature, wear);
- ``stiffness_drift``: F = (1 + a + b t/T) g(θ) (pads heating up during the session);
- ``gap_shift``: F = g(θ − d) (pad wear or thermal growth moves the contact angle);
- ``rate_dependent``: F = g(θ) + k v (viscous damping of pads and caliper);
- ``hysteresis``: F = g(θ) + c tanh(v / v0) (friction in the gear and the pad guides).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from brakethermo.rigs.tyre import magic_formula_mu, relaxation_lag

Array = NDArray[np.float64]
HYSTERESIS_V0_MM_S = 0.5  # mm/s: below this screw speed the direction is not yet set
HYSTERESIS_V0_RAD_S = 2.0  # rad/s: the same for the caliper's motor


@dataclass(frozen=True)
class RigContext:
    """What a candidate sees of a session: the input, its rate and the trained relation.

    Attributes
    ----------
    x : ndarray (K,) — the input (s2 mm, or θ rad).
    v : ndarray (K,) — its rate (smoothed), per s.
    t : ndarray (K,) — s from the session start.
    curve : callable — the trained relation, input array -> output array.
    aux : dict of str to ndarray (K,) — further signals some candidates read (the tyre
        rig's carriage speed ``speed`` in m/s and load ``load`` in N).
    """

    x: Array
    v: Array
    t: Array
    curve: Callable[[Array], Array]
    aux: dict[str, Array] = field(default_factory=dict)


@dataclass(frozen=True)
class RigEffect:
    """One candidate: its parameters, prediction, and what tells it from look-alikes."""

    name: str
    params: tuple[str, ...]
    units: tuple[str, ...]
    start: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    extension: str
    separate_by: str
    predict: Callable[[Array, RigContext], Array]


def _shifted(ctx: RigContext, d: Array | float) -> Array:
    return ctx.curve(np.clip(ctx.x - d, 0.0, None))


def _ramp(ctx: RigContext) -> Array:
    return ctx.t / max(float(ctx.t[-1]), 1e-9)


BOOSTER_EFFECTS: dict[str, RigEffect] = {e.name: e for e in (
    RigEffect(
        "pv_shift", ("shift_mm",), ("mm",), (0.0,), (-3.0,), (3.0,),
        "the training p-V curve moved along the stroke: p = f(s2 - d)",
        "a run at another fluid temperature, or after bleeding: a shift that stays is the"
        " seals' and fluid's state; one that moves during a session is drift",
        lambda th, c: _shifted(c, th[0]),
    ),
    RigEffect(
        "pv_scale", ("scale",), ("-",), (0.0,), (-0.5,), (1.0,),
        "the training p-V curve stiffer or softer: p = (1 + a) f(s2)",
        "the pressure at full stroke against the travel where it starts to rise: a scale"
        " changes the first, a shift the second",
        lambda th, c: (1.0 + th[0]) * c.curve(c.x),
    ),
    RigEffect(
        "pv_drift", ("shift_mm", "drift_mm"), ("mm", "mm over the session"), (0.0, 0.0),
        (-3.0, -3.0), (3.0, 3.0),
        "a shift along the stroke that moves during the session: p = f(s2 - d0 - d1 t/T)",
        "the same apply repeated at the start and the end of a session",
        lambda th, c: _shifted(c, th[0] + th[1] * _ramp(c)),
    ),
    RigEffect(
        "rate_dependent", ("k_mpa_per_mm_s",), ("MPa/(mm/s)",), (0.0,), (-0.5,), (0.5,),
        "a pressure term in the screw speed: p = f(s2) + k v (flow through ports and hoses)",
        "slow against fast applies to the same travel: flow grows with speed, hysteresis"
        " does not",
        lambda th, c: c.curve(c.x) + th[0] * c.v,
    ),
    RigEffect(
        "hysteresis", ("offset_mpa",), ("MPa",), (0.0,), (-2.0,), (2.0,),
        "a pressure offset of opposite sign going in and out: p = f(s2) + c tanh(v/v0)",
        "a slow apply held and released: hysteresis keeps its offset at any speed, flow"
        " vanishes as the screw stops",
        lambda th, c: c.curve(c.x) + th[0] * np.tanh(c.v / HYSTERESIS_V0_MM_S),
    ),
)}

EMB_EFFECTS: dict[str, RigEffect] = {e.name: e for e in (
    RigEffect(
        "stiffness_scale", ("scale",), ("-",), (0.0,), (-0.8,), (2.0,),
        "the trained dynamic stiffness scaled: F = (1 + a) g(θ)",
        "a cold against a hot apply to the same angle, or a session before and after"
        " re-bedding the pads: temperature moves the scale within a session, wear across",
        lambda th, c: (1.0 + th[0]) * c.curve(c.x),
    ),
    RigEffect(
        "stiffness_drift", ("scale", "drift"), ("-", "- over the session"), (0.0, 0.0),
        (-0.8, -0.8), (2.0, 2.0),
        "a stiffness scale that moves during the session: F = (1 + a + b t/T) g(θ)",
        "the pad temperature logged beside the force, or the same apply at the start and"
        " the end of a session",
        lambda th, c: (1.0 + th[0] + th[1] * _ramp(c)) * c.curve(c.x),
    ),
    RigEffect(
        "gap_shift", ("shift_rad",), ("rad",), (0.0,), (-20.0,), (20.0,),
        "the contact angle moved: F = g(θ − d) (pad wear, thermal growth)",
        "the motor angle at first contact, at rest, before and after: a gap moves it, a"
        " stiffness does not",
        lambda th, c: c.curve(c.x - th[0]),
    ),
    RigEffect(
        "rate_dependent", ("k_kn_per_rad_s",), ("kN/(rad/s)",), (0.0,), (-0.5,), (0.5,),
        "a force term in the motor speed: F = g(θ) + k ω (viscous pads and caliper)",
        "slow against fast applies to the same clamp force: damping grows with speed,"
        " friction does not",
        lambda th, c: c.curve(c.x) + th[0] * c.v,
    ),
    RigEffect(
        "hysteresis", ("offset_kn",), ("kN",), (0.0,), (-5.0,), (5.0,),
        "a force offset of opposite sign applying and releasing: F = g(θ) + c tanh(ω/ω0)",
        "a slow apply held and released: hysteresis keeps its offset at any speed,"
        " damping vanishes as the motor stops",
        lambda th, c: c.curve(c.x) + th[0] * np.tanh(c.v / HYSTERESIS_V0_RAD_S),
    ),
)}

# The roller rig's creep law, F = f(ξ, N) (Polach or FASTSIM on Hertz, the rig datasheet),
# against the roller shaft's torque transducer.
ROLLER_EFFECTS: dict[str, RigEffect] = {e.name: e for e in (
    RigEffect(
        "creep_slope", ("slope_change",), ("-",), (0.0,), (-0.8,), (2.0,),
        "the creep curve's initial slope off the contact theory's: F = f((1 + a) ξ)"
        " (Polach's k_A: a contaminated or rough surface, another contact theory)",
        "traction up to sliding: a slope changes the force at small creepage, the friction"
        " level only where the curve saturates",
        lambda th, c: c.curve((1.0 + th[0]) * c.x),
    ),
    RigEffect(
        "friction_level", ("mu_change",), ("-",), (0.0,), (-0.8,), (2.0,),
        "the friction coefficient off the datasheet's: F = (1 + a) f(ξ / (1 + a))"
        " (Kalker's similarity: F / (μN) depends on ξ / μ)",
        "traction up to sliding: only the saturated force tells the friction level",
        lambda th, c: (1.0 + th[0]) * c.curve(c.x / (1.0 + th[0])),
    ),
    RigEffect(
        "creepage_offset", ("offset",), ("-",), (0.0,), (-0.01,), (0.01,),
        "a creepage the speeds carry at zero force: F = f(ξ - d) (the free-rolling radius"
        " off the rolling one, or drag in the bearings while free rolling)",
        "free rolling at two speeds: an offset from the radius stays, one from drag grows"
        " with speed",
        lambda th, c: c.curve(c.x - th[0]),
    ),
)}


def _relaxed(mu: Array, c: RigContext, length_m: float) -> Array:
    """``mu`` through the tyre's first-order lag over ``length_m`` of travel."""
    return relaxation_lag(mu, c.t, c.aux["speed"], length_m)


# The tyre rig's two-parameter curve (Rudd), fitted on the session's own fitting blocks,
# against the measured μ = drag / load.
TYRE_EFFECTS: dict[str, RigEffect] = {e.name: e for e in (
    RigEffect(
        "sliding_speed", ("fall_per_mps",), ("1/(m/s)",), (0.0,), (-0.2,), (0.2,),
        "friction falling with the sliding speed: μ = f(s) (1 - a s V) (rubber on a"
        " rough surface: adhesion and hysteresis both fall with speed)",
        "ramps at two carriage speeds: a sliding-speed law moves the curve with speed, a"
        " shape does not",
        lambda th, c: c.curve(c.x) * (1.0 - th[0] * c.x * c.aux["speed"]),
    ),
    RigEffect(
        "curve_shape", ("B", "C", "D", "E"), ("-", "-", "-", "-"), (10.0, 1.5, 1.0, 0.0),
        (1.0, 1.0, 0.05, -5.0), (80.0, 2.5, 3.0, 1.0),
        "another curve than the two-parameter one: Pacejka's Magic Formula"
        " μ = D sin(C atan(B s - E (B s - atan(B s)))) (a sharper peak, a plateau after it)",
        "ramps at two carriage speeds: a shape stays, a sliding-speed law moves the curve",
        lambda th, c: magic_formula_mu(c.x, *th),
    ),
    RigEffect(
        "load_sensitivity", ("fall_per_load",), ("-",), (0.0,), (-2.0,), (2.0,),
        "friction falling with the load: μ = f(s) (1 - a (F_z / F_z,mean - 1))",
        "ramps at two loads: only the load moves the curve",
        lambda th, c: c.curve(c.x) * (1.0 - th[0] * (c.aux["load"] / np.mean(c.aux["load"])
                                                      - 1.0)),
    ),
    RigEffect(
        "relaxation", ("length_m",), ("m",), (0.05,), (0.0,), (2.0,),
        "the force builds over a relaxation length: μ follows f(s) with a lag of σ / V",
        "a slow against a fast ramp: a relaxation lag grows with the ramp's rate",
        lambda th, c: _relaxed(c.curve(c.x), c, th[0]),
    ),
)}

