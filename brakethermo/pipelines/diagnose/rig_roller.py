"""``diagnose`` on a roller-rig session: the rig datasheet's creep law against the roller
shaft's torque transducer, with the verdict engine of the other rigs
(:func:`brakethermo.pipelines.diagnose.rig.run_case`).

1. **Reference**: the creep law the rolling-radius filter uses (Polach's, or FASTSIM, on
   Hertz's contact from the datasheet), at the wheel radius the free-rolling speed ratio
   gives (model-free), F = f(ξ, N).
2. **Data**: creepage ξ from the wheel and roller speeds, the load, and the measured
   creep force (roller shaft torque over the roller radius), each averaged over
   :data:`AVERAGE_S`: the encoders' quantisation and once-per-revolution eccentricity
   are larger than a traction creepage sample by sample.
3. **Which**: :data:`brakethermo.models.rig_effects.ROLLER_EFFECTS` — the creep curve's
   slope, the friction level, a creepage offset — fitted on half of the traction
   blocks, scored on the others.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from brakethermo.errors import DataError
from brakethermo.io.load import load_session
from brakethermo.io.session import Session
from brakethermo.models.rig_effects import ROLLER_EFFECTS, RigContext
from brakethermo.models.roller_rig import RollerRigModel
from brakethermo.pipelines.diagnose.rig import RigCase, effect_names, run_case
from brakethermo.pipelines.roller_rig import (
    CHANNELS,
    FORCE_RATIO_RANGE,
    free_rolling_radius_mm,
    rig_inputs,
    rolling_sign,
    session_spec,
)
from brakethermo.results.rig_diagnosis import RigDiagnosis
from brakethermo.rigs.roller_rig import Friction, load_roller_rig

FORCE_FLOOR_N = 25.0  # a shaft torque transducer's accuracy (0.5 % of 2 kN m) at the roller
REST_SHARE = 0.2  # creepage below this share of its 95th percentile: the rig is not pulling
# s, moving average of speeds, load and force: several revolutions of wheel and roller, so
# that the encoders' once-per-revolution errors and an out-of-round roller average out (a
# single wheel revolution left creepage swings of +-0.7e-3, larger than traction's)
AVERAGE_S = 4.0
MIN_SPAN_WINDOWS = 3  # a log this many averaging windows long, at least: what is held out


def diagnose_roller_rig(
    path: str | Path | Session,
    *,
    rig: str = "roller-rig",
    creep_law: str = "polach",
    aliases: str | Path | None = None,
    effects: str | None = "all",
) -> RigDiagnosis:
    """Diagnose a roller-rig session with the roller torque transducer (module docstring).

    ``path`` may be the session itself, loaded as :func:`run_roller_rig` loads it (its
    ``--with-effect auto`` reads the file once).
    """
    t_start = time.perf_counter()
    names = effect_names(effects, ROLLER_EFFECTS, "roller-rig")
    spec = load_roller_rig(rig)
    session = path if isinstance(path, Session) else load_session(
        path, rate_hz=None, channels=CHANNELS, aliases=aliases)
    spec = session_spec(session, spec)[0]
    if not session.has("roller_torque"):
        raise DataError(
            "has no roller torque transducer: diagnose compares the creep law with the"
            " measured creep force, so it needs a session that logs roller_torque (one"
            " without can only be estimated: brakethermo roller-rig)",
            path=session.path, channel="roller_torque")
    w_w, w_r, torque, normal, _, free, traction, both = rig_inputs(session, spec)
    span = float(session.time[-1] - session.time[0])
    if span + session.dt < MIN_SPAN_WINDOWS * AVERAGE_S:
        raise DataError(
            f"is {span:.1f} s long; the diagnosis averages speeds and forces over"
            f" {AVERAGE_S:g} s (several revolutions) and fits on some stretches, checks on"
            f" others, so it needs at least {MIN_SPAN_WINDOWS * AVERAGE_S:g} s (a 5 s log"
            " named a creep slope 4x the truth's with 89 % shrink)", path=session.path)
    radius = free_rolling_radius_mm(session, spec, w_w, w_r, free & both) * 1e-3
    force = (rolling_sign(session.values("roller_omega")) * session.values("roller_torque")
             / spec.roller_radius)
    _check_force(session, force[traction], torque[traction] / radius)
    window = max(1, round(AVERAGE_S / session.dt))
    w_w, w_r, normal, force = (_moving_mean(v, window) for v in (w_w, w_r, normal, force))
    model = RollerRigModel.from_spec(spec, creep_law=creep_law)
    r_w = np.full(w_w.size, radius)
    xi, _ = model.creep(w_w, w_r, r_w, normal)
    v_r = w_r * spec.roller_radius

    def curve(x: np.ndarray) -> np.ndarray:
        # the wheel speed that gives creepage x at the measured roller speed
        omega_w = v_r * (1.0 + 0.5 * x) / (1.0 - 0.5 * x) / radius
        return model.creep(omega_w, w_r, r_w, normal)[1]

    t = session.time - session.time[0]
    rest = REST_SHARE * float(np.nanpercentile(xi, 95))
    case = RigCase(
        "roller-rig", session, {n: ROLLER_EFFECTS[n] for n in names},
        RigContext(xi, np.gradient(xi, t), t, curve), force, rest=rest,
        floor=FORCE_FLOOR_N, unit="N", input_name="creepage", input_unit="-",
        reference_text=f"the creep law of the rig datasheet {spec.id} ({creep_law}) at the"
                       f" free-rolling radius {radius * 1e3:.1f} mm, F = f(ξ, N), as the"
                       " rolling-radius filter uses it (not refitted here)",
        reference_fit={"radius_mm": radius * 1e3, "mu0": spec.friction.mu0,
                       "k_a": spec.friction.k_a, "creep_law": creep_law},
        next_step=lambda n, fit: _next_step(n, fit, spec.friction),
        cycle="creep episode", phases=("creep rising", "creep falling", "creep steady"))
    return run_case(case, t_start)


def _check_force(session: Session, force: np.ndarray, pull: np.ndarray) -> None:
    """In traction the wheel's torque reaches the roller through the contact: the creep
    force the transducer gives must be of the size the torque request asks for (bearing
    losses and inertia take a few per cent, not a factor)."""
    ratio = float(np.nanmedian(force) / np.nanmedian(pull))
    if not FORCE_RATIO_RANGE[0] <= ratio <= FORCE_RATIO_RANGE[1]:
        raise DataError(
            f"gives a creep force of {np.nanmedian(force):.0f} N in traction, {ratio:.3g}"
            f" times the {np.nanmedian(pull):.0f} N the wheel torque request asks for: check"
            " its unit (N m at the roller shaft) and its sign",
            path=session.path, channel="roller_torque")


def _moving_mean(v: np.ndarray, window: int) -> np.ndarray:
    """Moving mean over ``window`` samples, NaN-aware."""
    ok = np.isfinite(v)
    k = np.ones(window)
    total = np.convolve(np.where(ok, v, 0.0), k, "same")
    count = np.convolve(ok.astype(float), k, "same")
    return np.where(count > 0, total / np.maximum(count, 1.0), np.nan)


def _next_step(name: str, fit: dict[str, float], friction: Friction) -> str:
    value = next(iter(fit.values()))
    carry = f"brakethermo roller-rig SESSION --with-effect {name}={value:+.4g}"
    if name == "creep_slope":
        k_a = friction.k_a * (1.0 + fit["slope_change"])
        return (f"carry it: {carry} (or --with-effect with this diagnosis.json); for good,"
                f" a copy of the rig datasheet with [friction] k_a = {k_a:.2f} and k_s ="
                f" {min(friction.k_s, k_a):.2f} (were {friction.k_a:g}, {friction.k_s:g}:"
                " Polach's reduction of the initial slope; k_s may not exceed k_a), passed"
                " with --rig FILE")
    if name == "friction_level":
        mu0 = friction.mu0 * (1.0 + fit["mu_change"])
        return (f"carry it: {carry}, or set [friction] mu0 = {mu0:.3f} (was"
                f" {friction.mu0:g}) in a copy of the rig datasheet; a run with traction up"
                " to sliding pins it")
    return (f"carry it: {carry}; then check the radius the free-rolling ratio gives against"
            " a measured one (rolling_radius_ref), and free rolling at a second speed")
