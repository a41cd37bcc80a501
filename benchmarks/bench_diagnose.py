"""Diagnosis test matrix: does ``diagnose`` name the withheld effect?

For each track and each of the seven effects (and a baseline with every effect mild),
simulate four-spot sessions with that effect at a strength drawn from its realistic
range, on reporting seeds never used to develop the diagnosis, and diagnose them with
every effect as a candidate. Prints the confusion matrix (true effect x verdict), how
often the withheld effect is named alone or first in a set of at most two, the rate of
confident wrong names (a single name that is not the withheld effect), the mean size of
set verdicts, the held-out shrink of the verdict, and the time split per candidate.

    python benchmarks/bench_diagnose.py                      # full matrix, 2 workers
    python benchmarks/bench_diagnose.py --seeds 1 --tracks tight-like --workers 1
    python benchmarks/bench_diagnose.py --json matrix.json

Targets (issue): the verdict names the withheld effect top-1 for at least 6 of the 7
effects on both tracks; baselines give "none" or a shrink inside the lap-to-lap spread.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from brakethermo.models.effects import EFFECT_NAMES
from brakethermo.pipelines.diagnose import diagnose
from brakethermo.sim.effects import random_strengths
from brakethermo.sim.session import SimConfig, simulate, write_simulation

BASELINE = "baseline"
SEED_BASE = 40000  # reporting seeds of diagnosis v2: never used while developing it


def run_case(track: str, effect: str, seed: int, laps: int) -> dict:
    from threadpoolctl import threadpool_limits

    rng = np.random.default_rng(seed)
    strengths = {} if effect == BASELINE else random_strengths(rng, (effect,))
    with tempfile.TemporaryDirectory() as tmp, threadpool_limits(1):
        path = Path(tmp) / f"{effect}.mcap"
        write_simulation(simulate(SimConfig(track=track, laps=laps, sensor="multi", seed=seed,
                                            effects=strengths)), path)
        t0 = time.perf_counter()
        result = diagnose(path)
        wall = time.perf_counter() - t0
    s = result.summary
    top = s["effects"][0]
    return {
        "track": track, "effect": effect, "seed": seed, "strengths": strengths,
        "verdict": s["verdict"], "verdict_set": s["verdict_set"],
        "verdict_kind": s["verdict_kind"], "top": top["name"], "shrink_pct": top["shrink_pct"],
        "shrink_ci95_pct": top["shrink_ci95_pct"], "gap_c": s["gap"]["rmse_c"],
        "combined": s["combined"]["effects"], "wall_s": wall,
        "timings_s": s["run"]["timings_s"], "warnings": s["warnings"],
    }


def _named(case: dict) -> bool:
    """The withheld effect named alone or first in a set of at most two ("none" for a
    baseline)."""
    if case["effect"] == BASELINE:
        return case["verdict"] == "none"
    vs = case["verdict_set"]
    return bool(vs) and vs[0] == case["effect"] and len(vs) <= 2


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tracks", default="mugello-like,tight-like")
    ap.add_argument("--effects", default=",".join((*EFFECT_NAMES, BASELINE)))
    ap.add_argument("--seeds", type=int, default=2, help="seeds per (track, effect)")
    ap.add_argument("--seed-base", type=int, default=SEED_BASE)
    ap.add_argument("--laps", type=int, default=6, help="flying laps per session")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    tracks, effects = args.tracks.split(","), args.effects.split(",")
    jobs = [(track, effect, args.seed_base + 100 * t + 10 * e + s, args.laps)
            for t, track in enumerate(tracks) for e, effect in enumerate(effects)
            for s in range(args.seeds)]
    with ProcessPoolExecutor(args.workers) as pool:
        cases = list(pool.map(run_case, *zip(*jobs, strict=True)))
    labels = [*EFFECT_NAMES, "none"]
    for track in tracks:
        print(f"\n== {track}: rows = withheld effect, columns = verdict")
        print(f"{'':22s}" + "".join(f"{c[:10]:>11s}" for c in labels))
        for effect in effects:
            row = [c for c in cases if c["track"] == track and c["effect"] == effect]
            counts = [sum(c["verdict"] == lab for c in row) for lab in labels]
            print(f"{effect:22s}" + "".join(f"{n:>11d}" for n in counts))
        named = [e for e in effects if e != BASELINE and all(
            _named(c) for c in cases if c["track"] == track and c["effect"] == e)]
        print(f"effects named (alone, or first in a set of at most two) on every seed:"
              f" {len(named)} of {len([e for e in effects if e != BASELINE])}")
    wrong = [c for c in cases if c["verdict_kind"] == "single" and c["verdict"] != c["effect"]]
    sets = [len(c["verdict_set"]) for c in cases if c["verdict_kind"] == "set"]
    print("\nconfident wrong names (a single name that is not the withheld effect):"
          f" {len(wrong)} of {len(cases)} sessions"
          + "".join(f"\n  {c['track']} {c['effect']} -> {c['verdict']}" for c in wrong))
    print(f"set verdicts: {len(sets)} of {len(cases)}, mean size"
          f" {np.mean(sets) if sets else float('nan'):.1f}")
    print("\nper case: track, withheld (strength), verdict, shrink % [95 % interval], s")
    for c in cases:
        lo, hi = c["shrink_ci95_pct"]
        strength = ", ".join(f"{v:.2f}" for v in c["strengths"].values()) or "-"
        shown = " / ".join(c["verdict_set"]) or "none"
        print(f"{c['track']:13s} {c['effect']:21s} ({strength:>5s}) -> {shown:40s}"
              f" {c['shrink_pct']:+6.1f} [{lo:+.0f}, {hi:+.0f}]  {c['wall_s']:.0f} s")
    keys = sorted({k for c in cases for k in c["timings_s"]})
    print("\nmedian time per step of the diagnosis, s: " + ", ".join(
        f"{k.removesuffix('_s')} {np.median([c['timings_s'].get(k, 0.0) for c in cases]):.1f}"
        for k in keys))
    print(f"median wall time per session: {np.median([c['wall_s'] for c in cases]):.1f} s")
    if args.json:
        args.json.write_text(json.dumps(cases, indent=1))


if __name__ == "__main__":
    main()
