"""Accuracy against simulator truth on strong-effect sessions the tuning did not use.

For every named effect (and a session with mild effects only) and every replicate
seed: simulate a four-spot test session and identify h(V) + structure on it twice —
for the layered estimation model (the default) and for the paper's one-layer model —
simulate a different race session (other seed, four spots so it can also be scored the
paper's way); estimate it from spot 3 alone with each model and its own law; score
against the truth. Every figure is reported over the replicates as mean and min-max.

    python benchmarks/bench_accuracy.py                      # reporting seeds 9000+
    python benchmarks/bench_accuracy.py --replicates 1       # quicker, one seed per row
    python benchmarks/bench_accuracy.py --effects power_distribution,slipstream
    python benchmarks/bench_accuracy.py --workers 2          # cases in parallel processes
    python benchmarks/bench_accuracy.py --json acc.json      # keep every case; a re-run
                                                             # skips the cases already there

Seeds: case (effect i, replicate r) uses ``seed_base + 100 r + 10 i`` for the test
session and that + 1 for the race. Tuning used 500-579; report on 9000+.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from brakethermo.errors import DataError
from brakethermo.pipelines.estimate import EstimateOptions, estimate_session
from brakethermo.pipelines.identify_h import IdentifyOptions, identify_h, write_identify
from brakethermo.pipelines.truth_score import read_truth, score_against_truth
from brakethermo.sim.effects import EFFECT_NAMES
from brakethermo.sim.session import SimConfig, simulate, write_simulation

SENSOR_FAULTS = ("sensor_lag", "emissivity_error")
# identify-h for the one-layer model: the structure fit and the band calibration on one
# layer; a thin-skin switch would add layers back, so it is off
ONE_LAYER_TUNING = "[estimate]\nlayers = 1\nthin_skin_kz_ratio = 0.0\n"
MODELS = ("layered", "one_layer")


def run_case(effect: str, seed: int, test_laps: int, race_laps: int) -> dict:
    """Simulate, identify (per model), estimate and score one (effect, seed) case."""
    effects = () if effect == "none" else (effect,)
    # a test session and a race of one bike: the same brake-chain errors (bike_seed), the
    # rider, traffic, disc and effect draws of each session its own
    with tempfile.TemporaryDirectory(prefix="bench-acc-") as tmp, threadpool_limits(1):
        work = Path(tmp)
        test = write_simulation(
            simulate(SimConfig(laps=test_laps, effects=effects, sensor="multi", seed=seed,
                               bike_seed=seed)),
            work / "test.mcap",
        )[0]
        race, truth_path = write_simulation(
            simulate(SimConfig(laps=race_laps, effects=effects, sensor="multi", seed=seed + 1,
                               bike_seed=seed)),
            work / "race.parquet",
        )
        one_layer = work / "one_layer.toml"
        one_layer.write_text(ONE_LAYER_TUNING)
        truth = read_truth(truth_path)
        out: dict = {"effect": effect, "seed": seed}
        for key, tuning in (("layered", None), ("one_layer", one_layer)):
            try:
                ident = identify_h(test, IdentifyOptions(tuning=tuning))
            except DataError as exc:  # a failure is a result: counted, not hidden
                return {"effect": effect, "seed": seed, "failed": f"identify-h ({key}): {exc}"}
            law_path = write_identify(ident, work / key) / "h_law.toml"
            t0 = time.perf_counter()
            res = estimate_session(race, EstimateOptions(h_law=law_path, tuning=tuning))
            wall = time.perf_counter() - t0
            measured = res.session.values("disc_temp_spot3")
            sc = score_against_truth(res.frame, truth, measured, res.open_loop)
            sc["wall_s"] = wall
            sc["layers"] = res.summary["run"]["layers"]
            sc["paper_scores"] = res.scores
            out[key] = sc
    return out


def figures(case: dict) -> dict[str, float]:
    """The README row's figures of one case."""
    sc = case["layered"]
    cov = [sc["coverage95"][s] for s in ("spot1", "spot2", "spot4")]
    return {
        "smoother": sc["contact_ratio"]["smoother"],
        "open_loop": sc["contact_ratio"]["open-loop 1D-FE"],
        "one_layer": case["one_layer"]["contact_ratio"]["smoother"],
        "peak_pct": sc["peak_spot3"]["mean_abs_pct"],
        "coverage_pct": 100.0 * float(np.mean(cov)),
        "layers": sc["layers"],
    }


def spread(values: list[float], fmt: str) -> str:
    """``mean (min-max)`` of the replicates; the bare value for one replicate."""
    v = np.asarray(values, dtype=float)
    if v.size == 1:
        return format(v[0], fmt)
    return f"{format(v.mean(), fmt)} ({format(v.min(), fmt)}–{format(v.max(), fmt)})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--effects", default=",".join(("none", *EFFECT_NAMES)))
    ap.add_argument("--seed-base", type=int, default=9000, help="reporting seeds: 9000+")
    ap.add_argument("--replicates", type=int, default=3, help="seeds per row")
    ap.add_argument("--test-laps", type=int, default=3)
    ap.add_argument("--race-laps", type=int, default=6)
    ap.add_argument("--workers", type=int, default=1, help="cases run in parallel processes")
    ap.add_argument("--json", type=Path, help="also write all scores to this file")
    ap.add_argument("--table-only", action="store_true",
                    help="print the table from the cases already in --json, run nothing")
    args = ap.parse_args()
    effects = args.effects.split(",")
    jobs = [(e, args.seed_base + 100 * r + 10 * i, args.test_laps, args.race_laps)
            for r in range(args.replicates) for i, e in enumerate(effects)]
    t0 = time.perf_counter()
    done = json.loads(args.json.read_text()) if args.json and args.json.exists() else []
    have = {(c["effect"], c["seed"]) for c in done}
    cases = [c for c in done if (c["effect"], c["seed"]) in {j[:2] for j in jobs}]
    todo = [] if args.table_only else [j for j in jobs if j[:2] not in have]

    def finished(case: dict) -> None:
        cases.append(case)
        done.append(case)
        if args.json:
            args.json.write_text(json.dumps(done, indent=1, default=float))
        if "failed" in case:
            print(f"{case['effect']:22s} seed {case['seed']}: FAILED {case['failed']}", flush=True)
            return
        f = figures(case)
        print(f"{case['effect']:22s} seed {case['seed']}/{case['seed'] + 1}: smoother "
              f"{f['smoother']:.2f}x, open-loop {f['open_loop']:.2f}x, one layer "
              f"{f['one_layer']:.2f}x, peak {f['peak_pct']:.1f} %, coverage "
              f"{f['coverage_pct']:.0f} % ({f['layers']} layers)", flush=True)

    if args.workers > 1:
        with ProcessPoolExecutor(args.workers) as pool:
            for fut in as_completed([pool.submit(run_case, *job) for job in todo]):
                finished(fut.result())
    else:
        for job in todo:
            finished(run_case(*job))
    print(f"\n{len(cases)} cases in {time.perf_counter() - t0:.0f} s; "
          "mean (min–max) over the seeds of each row (n)\n")
    print("| session | smoother, layered | open-loop 1D-FE | paper model (1 layer, own law) "
          "| spot-3 peak error | 95 % band coverage |")
    print("|---|---|---|---|---|---|")
    for effect in effects:
        rows = [figures(c) for c in cases if c["effect"] == effect and "failed" not in c]
        failed = sum("failed" in c for c in cases if c["effect"] == effect)
        if not rows:
            continue
        name = effect if effect != "none" else "mild effects only"
        if effect in SENSOR_FAULTS:
            name += " (sensor fault)"
        name += f" (n = {len(rows)}" + (f", {failed} failed" if failed else "") + ")"
        cols = [spread([r["smoother"] for r in rows], ".2f") + "x",
                spread([r["open_loop"] for r in rows], ".2f") + "x",
                spread([r["one_layer"] for r in rows], ".2f") + "x",
                spread([r["peak_pct"] for r in rows], ".1f") + " %",
                spread([r["coverage_pct"] for r in rows], ".0f") + " %"]
        print(f"| {name} | " + " | ".join(cols) + " |")


if __name__ == "__main__":
    main()
