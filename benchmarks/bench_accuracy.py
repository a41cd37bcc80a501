"""Accuracy against simulator truth on strong-effect sessions the tuning did not use.

For every named effect (and a session with mild effects only): simulate a four-spot
test session and identify h(V) + structure on it; simulate a different race session
(other seed, four spots so it can also be scored the paper's way); estimate it from
spot 3 alone with the layered and the one-layer model; score against the truth.

    python benchmarks/bench_accuracy.py                 # reporting seeds
    python benchmarks/bench_accuracy.py --seed-base 500 # another seed set
    python benchmarks/bench_accuracy.py --effects power_distribution,slipstream

Prints the paper's Table 3/4 quantities per session and a verdict line per target.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from brakethermo.pipelines.estimate import EstimateOptions, estimate_session, write_estimate
from brakethermo.pipelines.identify_h import identify_h, write_identify
from brakethermo.sim.effects import EFFECT_NAMES
from brakethermo.sim.score import read_truth, score_against_truth
from brakethermo.sim.session import SimConfig, simulate, write_simulation

SENSOR_FAULTS = ("sensor_lag", "emissivity_error")


def run_case(effect: str, seed: int, work: Path, test_laps: int, race_laps: int) -> dict:
    effects = () if effect == "none" else (effect,)
    test = write_simulation(
        simulate(SimConfig(laps=test_laps, effects=effects, sensor="multi", seed=seed)),
        work / f"{effect}_test.mcap",
    )[0]
    race, truth_path = write_simulation(
        simulate(SimConfig(laps=race_laps, effects=effects, sensor="multi", seed=seed + 1)),
        work / f"{effect}_race.parquet",
    )
    ident = identify_h(test)
    law_path = write_identify(ident, work) / "h_law.toml"
    truth = read_truth(truth_path)
    out = {"effect": effect, "seed": seed}
    # "L3": the calibrated layered model (the default); "L1": the paper's one layer
    for key, layers in (("L3", None), ("L1", 1)):
        t0 = time.perf_counter()
        res = estimate_session(race, EstimateOptions(h_law=law_path, layers=layers))
        wall = time.perf_counter() - t0
        write_estimate(res, work / key)
        measured = res.session.values("disc_temp_spot3")
        sc = score_against_truth(res.frame, truth, measured, res.open_loop)
        sc["wall_s"] = wall
        sc["layers"] = res.summary["run"]["layers"]
        sc["paper_scores"] = res.scores
        out[key] = sc
    return out


def verdicts(case: dict) -> list[str]:
    sc = case["L3"]
    rows = {r["method"]: r for r in sc["table"]}
    sm, ol, base = rows["smoother"], rows["open-loop 1D-FE"], rows["single-spot"]
    ratio = sc["contact_ratio"]["smoother"]
    # issue 4: <= 0.6x with a strong model effect, <= 1.0x without one; none for sensor faults
    limit = {"none": 1.0, **dict.fromkeys(SENSOR_FAULTS)}.get(case["effect"], 0.6)
    cov = [sc["coverage95"][s] for s in ("spot1", "spot2", "spot4")]
    verdict = "no target (sensor fault)" if limit is None else (
        f"target <= {limit}x: " + ("ok" if ratio <= limit else "MISS"))
    out = [
        f"contact ratio {ratio:.2f}x ({verdict})",
        "spot2 < baseline & open-loop: "
        + ("ok" if sm["spot2"] < min(base["spot2"], ol["spot2"]) else "MISS"),
        "spot4 < baseline & open-loop: "
        + ("ok" if sm["spot4"] < min(base["spot4"], ol["spot4"]) else "MISS"),
        f"spot3 peak mean |err| {sc['peak_spot3']['mean_abs_pct']:.1f} % (< 5): "
        + ("ok" if sc["peak_spot3"]["mean_abs_pct"] < 5 else "MISS"),
        f"coverage95 {np.mean(cov) * 100:.0f} % (85-99): "
        + ("ok" if 0.85 <= np.mean(cov) <= 0.99 else "MISS"),
        "layered beats 1-layer: "
        + ("ok" if ratio < case["L1"]["contact_ratio"]["smoother"] else "MISS"),
    ]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--effects", default=",".join(("none", *EFFECT_NAMES)))
    ap.add_argument("--seed-base", type=int, default=9000, help="reporting seeds: 9000+")
    ap.add_argument("--test-laps", type=int, default=3)
    ap.add_argument("--race-laps", type=int, default=6)
    ap.add_argument("--json", type=Path, help="also write all scores to this file")
    args = ap.parse_args()
    cases = []
    with tempfile.TemporaryDirectory() as tmp, threadpool_limits(1):
        for i, effect in enumerate(args.effects.split(",")):
            case = run_case(effect, args.seed_base + 10 * i, Path(tmp), args.test_laps,
                            args.race_laps)
            cases.append(case)
            sc = case["L3"]
            print(f"\n== {effect} (seeds {case['seed']}/{case['seed'] + 1}) "
                  f"estimate {sc['wall_s']:.1f} s, {sc['layers']} layers")
            print(f"{'method':18s} {'spot1':>7s} {'spot2':>7s} {'spot3':>7s} {'spot4':>7s} "
                  f"{'contact':>8s} {'ratio':>6s}")
            for layers in ("L3", "L1"):
                for row in case[layers]["table"]:
                    if layers == "L1" and row["method"] != "smoother":
                        continue
                    name = row["method"] + (" (1 layer)" if layers == "L1" else "")
                    ratio = case[layers]["contact_ratio"][row["method"]]
                    print(f"{name:18s} " + " ".join(f"{row[s]:7.1f}" for s in
                          ("spot1", "spot2", "spot3", "spot4")) +
                          f" {row['contact_avg']:8.1f} {ratio:5.2f}x")
            for v in verdicts(case):
                print("  " + v)
    if args.json:
        args.json.write_text(json.dumps(cases, indent=1, default=float))


if __name__ == "__main__":
    main()
