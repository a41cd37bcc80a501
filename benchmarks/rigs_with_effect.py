"""The rig commands' ``--with-effect``: what carrying a diagnosed effect does.

Roller rig, per simulated session (strip-theory contact, richer than the estimator's
Polach law): the diagnosis's verdict, then the traction-phase radius error of the first
guess with the datasheet's law and with ``--with-effect auto`` (the run keeps the
carried curve only where the radius moves less between free rolling and traction), and
the run's choice. The radius reference is used only to score.

E-Booster (``--booster``), per seed and p-V shift: a bench session of the day with the
pressure sensor (open loop) is diagnosed against the training session's curve; a
vehicle-like session of the same day (same shift, no use of its pressures) is observed
with the trained curve and with ``--with-effect`` that diagnosis.json; p_m RMSE and 95 %
coverage of the UKF.

Run: ``python benchmarks/rigs_with_effect.py [--seeds 5 6 7] [--speeds 15 30]``,
``python benchmarks/rigs_with_effect.py --booster --seeds 31 32 33 [--shifts 0.3 -0.3]``
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from brakethermo.pipelines.diagnose.rig import diagnose_booster
from brakethermo.pipelines.diagnose.rig_roller import diagnose_roller_rig
from brakethermo.pipelines.ebooster import observe
from brakethermo.pipelines.roller_rig import (
    RollerRigOptions,
    run_roller_rig,
    traction_drift_mm,
)
from brakethermo.sim.ebooster import EboosterSimConfig, simulate_ebooster, write_ebooster_session
from brakethermo.sim.roller_rig import (
    RollerRigSimConfig,
    simulate_roller_rig,
    write_roller_rig_simulation,
)


def booster(seeds: list[int], shifts: list[float]) -> None:
    """The E-Booster table (module docstring)."""
    print("| seed | p-V shift | diagnosis of the day's bench session | p_m RMSE, trained curve |"
          " with --with-effect | 95 % coverage, trained / carried |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        train_path = write_ebooster_session(
            simulate_ebooster(EboosterSimConfig("train", seed=8)), work / "train.mcap")[0]
        for seed in seeds:
            for shift in shifts:
                day = write_ebooster_session(simulate_ebooster(EboosterSimConfig(
                    "open", seed=seed, pv_shift_mm=shift)), work / f"day{seed}.mcap")[0]
                found = diagnose_booster(day, train_path=train_path).summary
                diag = work / f"diagnosis{seed}.json"
                diag.write_text(json.dumps(found))
                veh = write_ebooster_session(simulate_ebooster(EboosterSimConfig(
                    "vehicle", seed=seed + 100, pv_shift_mm=shift)),
                    work / f"veh{seed}.mcap")[0]
                runs = [observe(veh, train_path=train_path, with_effect=w).summary
                        for w in ("none", str(diag))]
                verdict = " / ".join(found["verdict_set"]) or "none"
                best = next(e for e in found["effects"] if e["name"] == found["verdict"])
                fitted = ", ".join(f"{v:+.2f}" for v in best["params"].values())
                rm = [r["pressure_rmse_mpa"]["ukf"]["p_m"] for r in runs]
                cov = [100 * r["coverage_95"]["ukf"] for r in runs]
                print(f"| {seed} | {shift:+.2f} mm | {verdict} ({fitted}) | {rm[0]:.3f} MPa |"
                      f" {rm[1]:.3f} MPa | {cov[0]:.1f} / {cov[1]:.1f} % |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[5, 6, 7])
    ap.add_argument("--speeds", type=float, nargs="+", default=[15.0, 30.0])
    ap.add_argument("--duration", type=float, default=120.0)
    ap.add_argument("--booster", action="store_true", help="the E-Booster table instead")
    ap.add_argument("--shifts", type=float, nargs="+", default=[0.3, -0.3])
    args = ap.parse_args()
    if args.booster:
        booster(args.seeds, args.shifts)
        return
    print("| session | verdict | traction error, datasheet law | with --with-effect auto |"
          " radius drift free -> traction, law / carried | kept |")
    print("|---|---|---|---|---|---|")
    errors: dict[str, list[float]] = {"law": [], "auto": []}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in args.seeds:
            for speed in args.speeds:
                cfg = RollerRigSimConfig(speed_kmh=speed, duration_s=args.duration, free_s=20,
                                         seed=seed, radius_m=0.3416)
                path = write_roller_rig_simulation(simulate_roller_rig(cfg),
                                                   Path(tmp) / f"rr_{seed}_{speed:g}.mcap")[0]
                found = diagnose_roller_rig(path).summary
                row = {}
                for key, src in (("law", "none"), ("auto", "auto")):
                    res = run_roller_rig(path, RollerRigOptions(r0_mm=(340.0,),
                                                                with_effect=src))
                    run = res.runs[0]
                    trac = res.traction & np.isfinite(run.radius_mm)
                    row[key] = (float(np.mean(run.radius_mm[trac])) - res.reference_mm,
                                res.summary["filter"]["with_effect"],
                                traction_drift_mm(run.radius_mm, res.free, res.traction))
                    errors[key].append(abs(row[key][0]))
                fact = row["auto"][1] or {}
                drift = fact.get("traction_drift_mm")
                verdict = " / ".join(found["verdict_set"]) or "none"
                params = ", ".join(f"{v:+.3f}" for e in found["effects"][:1]
                                   for v in e["params"].values())
                print(f"| seed {seed}, {speed:g} km/h | {verdict} ({params}) |"
                      f" {row['law'][0]:+.3f} mm | {row['auto'][0]:+.3f} mm |"
                      + (f" {drift['datasheet']:+.3f} / {drift['carried']:+.3f} mm |"
                         if drift else " – |")
                      + f" {fact.get('kept', 'nothing to carry')} |")
    print(f"\nmean |traction error|: datasheet law {np.mean(errors['law']):.3f} mm,"
          f" --with-effect auto {np.mean(errors['auto']):.3f} mm")


if __name__ == "__main__":
    main()
