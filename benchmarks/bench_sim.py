"""Benchmark: a 25-lap race on the fast track simulated and written as MCAP (target < 60 s).

Run: ``python benchmarks/bench_sim.py [--laps 25] [--out DIR]``. Prints seconds per stage.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from brakethermo.sim.session import SimConfig, simulate, write_simulation

TARGET_S = 60.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--laps", type=int, default=25)
    parser.add_argument("--track", default="mugello-like")
    parser.add_argument("--out", type=Path, default=None, help="directory for the files")
    args = parser.parse_args()

    cfg = SimConfig(track=args.track, laps=args.laps, seed=2026, sensor="single")
    stages: dict[str, float] = {}
    t0 = time.perf_counter()
    result = simulate(cfg, timings=stages)
    with tempfile.TemporaryDirectory() as tmp:
        out = (args.out or Path(tmp)) / "race.mcap"
        t1 = time.perf_counter()
        session_path, truth_path = write_simulation(result, out)
        stages["write (mcap + truth)"] = time.perf_counter() - t1
        sizes = session_path.stat().st_size, truth_path.stat().st_size
    total = time.perf_counter() - t0
    duration = float(result.truth.column("time")[-1].as_py())

    print(f"{args.laps}-lap race on {args.track}: {duration:.0f} s of session")
    for name, sec in stages.items():
        print(f"  {name:<22s} {sec:7.2f} s  ({sec / total:5.1%})")
    print(
        f"  {'total':<22s} {total:7.2f} s  (target < {TARGET_S:.0f} s: "
        f"{'OK' if total < TARGET_S else 'MISSED'}; {total / TARGET_S:.2f} of budget)"
    )
    print(f"  real time / wall time  {duration / total:7.0f}x")
    print(f"  files: session {sizes[0] / 1e6:.1f} MB, truth {sizes[1] / 1e6:.1f} MB")


if __name__ == "__main__":
    main()
