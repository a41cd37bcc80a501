"""``roller-rig --with-effect auto``: what carrying the diagnosed creep curve does.

Per simulated session (strip-theory contact, richer than the estimator's Polach law): the
diagnosis's verdict, then the traction-phase radius error of the first guess with the
datasheet's law and with ``--with-effect auto`` (the run keeps the carried curve only
where the radius moves less between free rolling and traction), and the run's choice.
The radius reference is used only to score.

Run: ``python benchmarks/roller_rig_with_effect.py [--seeds 5 6 7] [--speeds 15 30]``
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from brakethermo.pipelines.diagnose.rig_roller import diagnose_roller_rig
from brakethermo.pipelines.roller_rig import (
    RollerRigOptions,
    run_roller_rig,
    traction_drift_mm,
)
from brakethermo.sim.roller_rig import (
    RollerRigSimConfig,
    simulate_roller_rig,
    write_roller_rig_simulation,
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[5, 6, 7])
    ap.add_argument("--speeds", type=float, nargs="+", default=[15.0, 30.0])
    ap.add_argument("--duration", type=float, default=120.0)
    args = ap.parse_args()
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
