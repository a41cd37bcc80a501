"""``diagnose`` on a tyre-rig session: the paper's two-parameter μ–slip curve (Rudd)
against the measured μ = drag / load along the braking ramp, with the verdict engine of
the other rigs (:func:`brakethermo.pipelines.diagnose.rig.run_case`).

1. **Split**: the ramp (:func:`brakethermo.pipelines.mu_slip.ramp_points`, as ``mu-slip``
   finds it) is cut into
   :data:`BLOCK_S` blocks that alternate between fitting and held out.
2. **Reference**: Rudd's curve fitted (Levenberg–Marquardt to convergence) on the fitting
   blocks only — the held-out blocks are never seen by the reference either.
3. **Which**: :data:`brakethermo.models.rig_effects.TYRE_EFFECTS` — friction falling
   with the sliding speed, another curve shape, load sensitivity, a relaxation length —
   fitted on the same fitting blocks, scored on the held-out ones. On one ramp the
   sliding speed grows with the slip, so a speed law and a shape look alike: the verdict
   then names both and how to tell them apart (a second ramp at another speed).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from brakethermo.models.mu_slip import rudd_lm
from brakethermo.models.rig_effects import TYRE_EFFECTS, RigContext
from brakethermo.pipelines.diagnose.rig import RigCase, apply_units, effect_names, run_case
from brakethermo.pipelines.mu_slip import MuSlipOptions, ramp_points
from brakethermo.results.rig_diagnosis import RigDiagnosis
from brakethermo.rigs.signals import smoothed_rate
from brakethermo.rigs.tyre import rudd_mu

BLOCK_S = 0.1  # s, a ramp to lock lasts a few seconds
MU_FLOOR = 0.01  # μ: drag and load cells of 0.5 % of their range


def diagnose_tyre(
    path: str | Path,
    *,
    radius_m: float | None = None,
    aliases: str | Path | None = None,
    effects: str | None = "all",
) -> RigDiagnosis:
    """Diagnose a tyre-rig braking ramp (module docstring)."""
    t_start = time.perf_counter()
    names = effect_names(effects, TYRE_EFFECTS, "tyre")
    res = ramp_points(path, MuSlipOptions(radius_m=radius_m),
                      aliases=Path(aliases) if aliases is not None else None)
    session = res.session
    t = res.time - session.time[0]  # s from the session start, as every rig's context
    units, _ = apply_units(res.slip, t, 0.0, BLOCK_S)
    ids = np.unique(units[units >= 0])
    fitting = np.isin(units, ids[0::2])
    x0 = np.array([float(np.max(res.mu)), float(res.slip[np.argmax(res.mu)])])
    (mu_p, s_p), _ = rudd_lm(res.slip[fitting], res.mu[fitting], x0, None)
    speed = np.interp(res.time, session.time, session.values("vehicle_speed"))
    load = np.interp(res.time, session.time, session.values("normal_force"))
    case = RigCase(
        "tyre", session, {n: TYRE_EFFECTS[n] for n in names},
        RigContext(res.slip, smoothed_rate(res.slip, session.dt, 0.02), t,
                   lambda s: rudd_mu(s, mu_p, s_p), {"speed": speed, "load": load}),
        res.mu, rest=0.0, floor=MU_FLOOR, unit="-", input_name="slip", input_unit="-",
        reference_text=f"Rudd's two-parameter curve (paper 003) fitted on the ramp's fitting"
                       f" blocks: peak μ {mu_p:.3f} at slip {s_p:.3f}",
        reference_fit={"mu_p": float(mu_p), "s_p": float(s_p)},
        next_step=_next_step, block_s=BLOCK_S, cycle="slip episode",
        phases=("slip rising", "slip falling", "slip steady"))
    return run_case(case, t_start)


def _next_step(name: str, fit: dict[str, float]) -> str:
    if name == "sliding_speed":
        return (f"μ falls by {fit['fall_per_mps']:.3f} per m/s of sliding: brake a second ramp"
                " at another carriage speed to tell it from the curve's shape, and read the"
                " peak from mu-slip's best family (its `shape_mismatch` says how far the"
                " two-parameter curve is)")
    if name == "curve_shape":
        return ("use mu-slip's best family for the peak (the two-parameter curve's shape is"
                " off: `shape_mismatch`); a ramp at another speed tells a shape from a"
                " sliding-speed law")
    if name == "load_sensitivity":
        return "brake ramps at two loads: the peak's change per load is the tyre's own"
    return "a slow and a fast ramp: a relaxation lag grows with the ramp's rate"
