"""Reduced-order vs full-order filter on the same session, and filterpy's N = 10 lap.

For each mesh (nodes x layers) the estimate pipeline runs on one simulated four-spot
session with the full-order UKF (``--modes 0``) and with the reduced-order one (the
default above 24 temperature states, the default 10 x 4 mesh included: POD modes of the
model's own open loop plus the crown-noise directions, ``brakethermo.models.reduced``);
printed side by side: modes, seconds of filter + smoother per 1000 steps, the contact
band's RMS and largest difference between the two (flying laps), the ratio of their mean
bands, and the peak memory of the reduced run. filterpy's UKF on the 10-node paper model
(``bench_filter``'s case) is timed in the same run for the issue's yardstick. Meshes
whose full filter would take minutes (over ``--full-max`` states) are run reduced only.

    python benchmarks/bench_reduced.py                      # 10x4, 30x4, 150x1, 150x4; 2 laps
    python benchmarks/bench_reduced.py --meshes 60x4 --laps 6 --full-max 300
"""

from __future__ import annotations

import argparse
import resource
import tempfile
from pathlib import Path

import numpy as np
from bench_filter import Case, time_filterpy
from threadpoolctl import threadpool_limits

from brakethermo.pipelines.estimate import EstimateOptions, EstimateResult, estimate_session
from brakethermo.sim.session import SimConfig, simulate, write_simulation

SEED = 61401  # not a tuning seed


def run(path: Path, nodes: int, layers: int, modes: int | None) -> tuple[EstimateResult, float]:
    """The estimate and its filter + smoother seconds per 1000 steps."""
    res = estimate_session(path, EstimateOptions(nodes=nodes, layers=layers, modes=modes,
                                                 online_auto=False, score=False))
    tm = res.summary["run"]["timings_s"]
    return res, (tm["filter_s"] + tm["smoother_s"]) * 1000.0 / res.summary["run"]["steps"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", default="10x4,30x4,150x1,150x4")
    ap.add_argument("--laps", type=int, default=2)
    ap.add_argument("--full-max", type=int, default=200,
                    help="largest temperature-state count also run full-order")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp, threadpool_limits(1):
        path = write_simulation(simulate(SimConfig(laps=args.laps, sensor="multi", seed=SEED)),
                                Path(tmp) / "s.parquet")[0]
        run(path, 10, 1, 0)  # compile the kernels before anything is timed
        t_fp, _ = time_filterpy(Case("estimate", 10, 200), 200, 2)
        print(f"filterpy UKF, 10-node paper model: {t_fp:.3f} s per 1000 steps (filter only)")
        print(f"{'mesh':>7} {'states':>6} {'modes':>5} {'full s/kstep':>12}"
              f" {'reduced s/kstep':>15} {'x filterpy':>10} {'contact RMS':>11}"
              f" {'max':>6} {'band ratio':>10}")
        for mesh in args.meshes.split(","):
            nodes, layers = (int(v) for v in mesh.split("x"))
            red, t_red = run(path, nodes, layers, None)
            order = red.summary["run"]["filter_order"]
            n_t = nodes * layers
            full_txt = diff_txt = "–"
            band = mx = "–"
            if n_t <= args.full_max:
                full, t_full = run(path, nodes, layers, 0)
                a, b = full.frame, red.frame
                fly = a["lap"].to_numpy() >= 1
                d = (a["contact_avg"] - b["contact_avg"]).to_numpy()[fly]
                full_txt = f"{t_full:.3f}"
                diff_txt = f"{np.sqrt(np.mean(d**2)):.2f} °C"
                mx = f"{np.abs(d).max():.1f}"
                band = f"{b['contact_avg_std'].mean() / a['contact_avg_std'].mean():.3f}"
            print(f"{mesh:>7} {n_t:>6} {order.get('modes', '–'):>5} {full_txt:>12}"
                  f" {t_red:>15.3f} {t_red / t_fp:>10.2f} {diff_txt:>11} {mx:>6} {band:>10}")
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(f"peak memory of the run: {peak:.0f} MiB")


if __name__ == "__main__":
    main()
