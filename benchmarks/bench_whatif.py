"""`whatif` against truth: predict a changed race from the original one, score on the truth
of the race re-run with the change (same seed, same drive).

For each reporting seed: a four-spot test session of one bike → identify-h (default
command) → the law; a single-spot race of the same bike; the same race re-simulated with
the change (more face cooling, a hot day, another disc). ``whatif`` on the original race
predicts the contact band of the changed one; scored on the flying laps against the
changed race's truth: RMSE, bias, 95 % band coverage, next to the size of the change
itself (what "no change predicted" would miss) and the time of one scenario.

    python benchmarks/bench_whatif.py --seeds 3 --race-laps 4 --test-laps 3

Reporting seeds 52000+ (never used to develop whatif).
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from brakethermo.pipelines.identify_h import identify_h, write_identify
from brakethermo.pipelines.truth_score import read_truth
from brakethermo.pipelines.whatif import Scenario, WhatifOptions, whatif_session
from brakethermo.sim.session import SimConfig, simulate, write_simulation

SEED_BASE = 52000
# change name -> (the simulator's setting for the re-run, the whatif scenario)
CHANGES = {
    "cooling x1.2": ({"cooling": 1.2}, Scenario(cooling=1.2)),
    "ambient 35 C": ({"ambient_c": 35.0}, Scenario(ambient_c=35.0)),
    "disc cc-355-9": ({"disc": "cc-355-9"}, Scenario(disc="cc-355-9")),
}


def contact_truth(truth) -> np.ndarray:
    return truth[["spot2", "spot3", "spot4"]].mean(axis=1).to_numpy()


def run_seed(seed: int, test_laps: int, race_laps: int, changes: list[str], work: Path
             ) -> list[dict[str, float]]:
    test, _ = write_simulation(simulate(SimConfig(
        laps=test_laps, sensor="multi", seed=seed, bike_seed=seed)), work / "test.mcap")
    law = write_identify(identify_h(test), work / "id") / "h_law.toml"
    race_cfg = SimConfig(laps=race_laps, sensor="single", seed=seed + 1, bike_seed=seed)
    race, race_truth_path = write_simulation(simulate(race_cfg), work / "race.parquet")
    base_truth = contact_truth(read_truth(race_truth_path))
    rows = []
    for name in changes:
        sim_change, scenario = CHANGES[name]
        _, changed_truth_path = write_simulation(
            simulate(dataclasses.replace(race_cfg, **sim_change)), work / "changed.parquet")
        truth = read_truth(changed_truth_path)
        target = contact_truth(truth)
        t0 = time.perf_counter()
        res = whatif_session(race, WhatifOptions(scenarios=(scenario,), h_law=law))
        wall = time.perf_counter() - t0
        pred = res.replays[0]
        n = min(target.size, pred.contact.size)
        flying = res.frame["lap"].to_numpy()[:n] >= 1
        err = (pred.contact[:n] - target[:n])[flying]
        std = pred.contact_std[:n][flying]
        est_err = (res.base.contact[:n] - base_truth[:n])[flying]
        rows.append({
            "change": name, "seed": seed,
            "rmse_c": float(np.sqrt(np.mean(err**2))), "bias_c": float(np.mean(err)),
            "coverage_pct": float(100 * np.mean(np.abs(err) <= 1.96 * std)),
            "change_size_c": float(np.sqrt(np.mean((target[:n] - base_truth[:n])[flying] ** 2))),
            "estimate_rmse_c": float(np.sqrt(np.mean(est_err**2))),
            "replay_s": float(res.summary["run"]["replay_s"][0]), "whatif_s": wall,
        })
        r = rows[-1]
        print(f"{name:14s} seed {seed}: prediction RMSE {r['rmse_c']:5.1f} C (bias"
              f" {r['bias_c']:+5.1f}), 95 % coverage {r['coverage_pct']:3.0f} %, the change"
              f" itself {r['change_size_c']:5.1f} C RMS, the estimate of the original race"
              f" {r['estimate_rmse_c']:4.1f} C; replay {r['replay_s']:.1f} s, whatif"
              f" {r['whatif_s']:.1f} s", flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--test-laps", type=int, default=3)
    ap.add_argument("--race-laps", type=int, default=4)
    ap.add_argument("--changes", default=",".join(CHANGES))
    args = ap.parse_args()
    rows = []
    with threadpool_limits(1):
        for r in range(args.seeds):
            with tempfile.TemporaryDirectory(prefix="bench-whatif-") as tmp:
                rows += run_seed(SEED_BASE + 10 * r, args.test_laps, args.race_laps,
                                 args.changes.split(","), Path(tmp))
    print("\nchange          RMSE C mean (min-max)   coverage % mean (min-max)   change C")
    for name in args.changes.split(","):
        sel = [r for r in rows if r["change"] == name]
        rm = np.array([r["rmse_c"] for r in sel])
        cov = np.array([r["coverage_pct"] for r in sel])
        size = np.mean([r["change_size_c"] for r in sel])
        print(f"{name:14s}  {rm.mean():5.1f} ({rm.min():.1f}-{rm.max():.1f})"
              f"            {cov.mean():3.0f} ({cov.min():.0f}-{cov.max():.0f})"
              f"                  {size:5.1f}")


if __name__ == "__main__":
    main()
