"""Seconds per lap (1000 steps at 10 Hz) of our UKF (+ unscented RTS smoother) vs filterpy.

Both filters run the SAME disc model (``DiscFEModel``, the 1-layer paper model) on the
SAME simulated data — filterpy as a Python model call per sigma point, ours compiled into
its step loop (``DiscStateSpace.compiled_steps``, the estimator's own path):

* ``estimate`` — state = N node temperatures, spot 3 measured (linear interpolation);
* ``identify-h`` — N = 51, state = [T_1..T_51, h] with h a random walk, four spots.

filterpy's ``UnscentedKalmanFilter`` calls the model once per sigma point (its fx is
per point); ours calls it once per step for all 2n + 1 points. filterpy is slow at
large N, so it is timed on ``--fp-steps`` steps and scaled to 1000 (said in the
output). filterpy has no smoother that takes inputs, so the ratio compares filters
only; our smoother time is shown next to it. BLAS is pinned to one thread.

With ``--race`` it times instead the default model's whole race, file to estimate
(read, filter, smoother, scores, ``estimate.parquet`` + ``summary.json``; no HTML
report): a ``--laps``-lap race is simulated first (not timed), a 1-lap run warms the
compiled kernels, then ``--repeat`` runs with ``--workers`` and ``--threads`` BLAS
threads. ``--race-file`` times that race instead of a simulated one, with ``--h-law``
(the k_z race of the README's speed table: a low-k_z race disc on which the race's
decision switches k_z on and the filter runs on the thin-skin 15 x 6 mesh).

Run: ``python benchmarks/bench_filter.py [--steps 1000] [--fp-steps 200] [--repeat 3]
[--threads 1] [--nodes 10,150]`` or ``python benchmarks/bench_filter.py --race [--laps 25]
[--workers 2] [--threads 2] [--race-file RACE --h-law h_law.toml]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable

import numpy as np
from filterpy_reference import run_filterpy_ukf
from threadpoolctl import threadpool_limits

from brakethermo.estimation import UnscentedKalmanFilter, urts_smooth
from brakethermo.models.disc import H_PARAM, DiscStateSpace, RandomWalkParam
from brakethermo.thermal.disc import load_disc
from brakethermo.thermal.model import DiscFEModel

STEPS_PER_LAP = 1000
T_AMB = 25.0
H_TRUE = 90.0  # W/(m^2 K)
ALPHA, BETA, KAPPA = 0.1, 2.0, 0.0
ESTIMATE_NODES = (10, 20, 50, 100, 150)
TARGETS = {("estimate", 10): 0.05, ("estimate", 150): 1.0, ("identify-h", 51): 0.5}


def braking_power(K: int) -> np.ndarray:
    """A lap-like cycle: 1.5 s of 40 kW braking every 6 s, W."""
    return np.where((np.arange(K) % 60) < 15, 4.0e4, 0.0)


class Case:
    """One benchmark case: batched model f, noise, measurement, data and prior."""

    def __init__(self, kind: str, N: int, K: int, seed: int = 0) -> None:
        disc = load_disc()
        model = DiscFEModel(disc, N)
        q = braking_power(K)
        rng = np.random.default_rng(seed)
        self.kind, self.N = kind, N
        ta = np.full(K, T_AMB)
        if kind == "estimate":
            ssm = DiscStateSpace(model, q, ta, np.full(K, H_TRUE), (),
                                 sigma_temp=np.sqrt(0.5), sigma_crown=0.0)
            H = model.spot_matrix([disc.spot_radii[2]])
            x_true = model.initial_state(150.0)
            x0, P0 = model.initial_state(140.0), np.eye(N) * 100.0
        else:
            walk = RandomWalkParam(H_PARAM, 60.0, 20.0, 2.0)
            ssm = DiscStateSpace(model, q, ta, None, (walk,), sigma_temp=np.sqrt(0.5),
                                 sigma_crown=0.0)
            H = ssm.H(disc.spot_radii)
            x_true = np.r_[model.initial_state(150.0), H_TRUE]
            x0 = np.r_[model.initial_state(140.0), 60.0]
            P0 = np.diag(np.r_[np.full(N, 100.0), 400.0])
        # the model both filters run: eq. 15 through every sigma point, given to filterpy
        # as the plain model call (the lightest Python f, the fairest to it); ours runs the
        # same arithmetic compiled inside its step loop (DiscStateSpace.compiled_steps)
        if kind == "estimate":

            def f(X: np.ndarray, k: int) -> np.ndarray:
                return model.step(X, q[k], H_TRUE, T_AMB)

        else:

            def f(X: np.ndarray, k: int) -> np.ndarray:
                out = np.empty_like(X)
                out[:, :N] = model.step(X[:, :N], q[k], X[:, N], T_AMB)
                out[:, N] = X[:, N]
                return out

        n, Q = ssm.n, ssm.Q(0)
        self.steps = ssm.compiled_steps()
        m = H.shape[0]
        R = np.eye(m) * 4.0
        y = np.empty((K, m))
        x = x_true
        for k in range(K):
            y[k] = H @ x + rng.normal(0.0, 2.0, m)
            x = f(x[None], k)[0]
        self.f, self.Q, self.R, self.H, self.y, self.x0, self.P0, self.n = f, Q, R, H, y, x0, P0, n


def time_ours(case: Case, smoother: bool, repeat: int, fused: bool = True
              ) -> tuple[float, float, np.ndarray]:
    """(filter s/lap, smoother s/lap, filtered means), best of ``repeat`` runs; ``fused``
    False calls the model and Q from Python every step (the loop before the fusion)."""
    ukf = UnscentedKalmanFilter(case.f, case.Q, case.R, H=case.H, alpha=ALPHA, beta=BETA,
                                steps=case.steps if fused else None)
    store = "smoother" if smoother else "diag"
    warm = ukf.run(case.x0, case.P0, case.y[:3], store=store)  # compile / warm up
    if smoother:
        urts_smooth(warm)
    K = case.y.shape[0]
    t_f = t_s = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        res = ukf.run(case.x0, case.P0, case.y, store=store)
        t_f = min(t_f, time.perf_counter() - t)
        if smoother:
            t = time.perf_counter()
            urts_smooth(res)
            t_s = min(t_s, time.perf_counter() - t)
    t_s = t_s if smoother else 0.0
    return t_f / K * STEPS_PER_LAP, t_s / K * STEPS_PER_LAP, res.x_filt


def time_filterpy(case: Case, K: int, repeat: int) -> tuple[float, np.ndarray]:
    """filterpy UKF on the first K steps: (s/lap, filtered means), best of ``repeat``."""
    best = np.inf
    for _ in range(repeat):
        t, xs = run_filterpy_ukf(case.f, case.H, case.Q, case.R, case.x0, case.P0, case.y, K,
                                 ALPHA, BETA, KAPPA)
        best = min(best, t)
    return best / K * STEPS_PER_LAP, xs


def row(
    kind: str, N: int, steps: int, fp_steps: int, repeat: int, out: Callable[[str], None]
) -> None:
    case = Case(kind, N, steps)
    smoother = kind == "estimate"
    t_f, t_s, xs = time_ours(case, smoother=True, repeat=repeat)
    if not smoother:
        t_f, _, xs = time_ours(case, smoother=False, repeat=repeat)
    t_py = time_ours(case, smoother=smoother, repeat=repeat, fused=False)[0]  # as t_f
    k_fp = min(fp_steps, steps)
    t_fp, xs_fp = time_filterpy(case, k_fp, repeat)
    dx = float(np.max(np.abs(xs[:k_fp] - xs_fp)))
    target = TARGETS.get((kind, N))
    total = t_f + t_s if smoother else t_f
    out(
        f"{kind:>10} {N:>4} {case.n:>4} {t_f:>9.4f} {t_s:>9.4f} {total:>9.4f} {t_fp:>9.3f}"
        f" {k_fp:>6} {t_fp / t_f:>7.1f} {dx:>9.1e} {t_py:>9.4f} {t_f / t_py:>6.2f} "
        + ("" if target is None else f"{target:>6}  {'ok' if total <= target else 'MISSED'}")
    )


def race(laps: int, workers: int, threads: int, repeat: int, race_file: str | None = None,
         h_law: str | None = None) -> None:
    """Time the default model's estimate of a simulated race (or of ``race_file`` with
    the law ``h_law``), file to outputs."""
    from pathlib import Path

    from brakethermo.pipelines.estimate import EstimateOptions, estimate_session, write_estimate
    from brakethermo.pipelines.race_filter import forget_modes
    from brakethermo.sim.session import SimConfig, simulate, write_simulation

    with tempfile.TemporaryDirectory(prefix="bench-race-") as tmp:
        work = Path(tmp)
        path = Path(race_file) if race_file else write_simulation(
            simulate(SimConfig(laps=laps - 1, sensor="single", seed=9100)), work / "race.mcap")[0]
        warm = write_simulation(simulate(SimConfig(laps=1, sensor="single", seed=9101)),
                                work / "warm.mcap")[0]
        options = EstimateOptions(workers=workers, h_law=h_law)
        with threadpool_limits(threads):
            write_estimate(estimate_session(warm, options), work / "out")
            best, res = np.inf, None
            for _ in range(repeat):
                forget_modes()  # each run computes its modes, as a command does
                t = time.perf_counter()
                res = estimate_session(path, options)
                write_estimate(res, work / "out")
                best = min(best, time.perf_counter() - t)
    run = res.summary["run"]
    what = f"{path.name} (law {h_law or 'shipped'})" if race_file else f"{laps}-lap race"
    print(f"estimate, default model ({run['nodes']} nodes x {run['layers']} layers), {what} "
          f"({run['steps']} steps, online effects switched on:"
          f" {run.get('online_choice', {}).get('chosen') or 'none'}), file to parquet +"
          f" summary: {best:.2f} s best of "
          f"{repeat} (workers {workers}, BLAS threads {threads}); stages of that run: "
          + ", ".join(f"{k} {v:.2f}" for k, v in run["timings_s"].items()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=STEPS_PER_LAP, help="steps timed for ours")
    ap.add_argument("--fp-steps", type=int, default=200, help="steps timed for filterpy")
    ap.add_argument("--repeat", type=int, default=3, help="best of this many runs")
    ap.add_argument("--threads", type=int, default=1, help="BLAS threads")
    ap.add_argument("--nodes", default=",".join(map(str, ESTIMATE_NODES)),
                    help="estimate cases, comma separated")
    ap.add_argument("--race", action="store_true", help="time the whole-race estimate instead")
    ap.add_argument("--laps", type=int, default=25, help="--race: laps incl. the out-lap")
    ap.add_argument("--workers", type=int, default=1, help="--race: estimate --workers")
    ap.add_argument("--race-file", help="--race: time this race instead of a simulated one")
    ap.add_argument("--h-law", help="--race: the h law (h_law.toml) of --race-file")
    args = ap.parse_args()
    if args.race:
        race(args.laps, args.workers, args.threads, args.repeat, args.race_file, args.h_law)
        return
    print(f"s/lap = seconds per 1000 steps; BLAS threads: {args.threads}; model = DiscFEModel,"
          " L = 1")
    print(f"filterpy timed on min(--fp-steps={args.fp_steps}, --steps) steps, scaled to 1000")
    print(f"each time is the best of {args.repeat} runs (the machine is shared)")
    print(
        "ratio = filterpy / ours (filter only); |dx| = max |ours - filterpy| of the filtered"
        " means over the filterpy steps, degC; py_loop = ours with the model and Q called"
        " from Python every step (filter only), fused/py = ours_filt / py_loop"
    )
    print(
        f"{'case':>10} {'N':>4} {'n':>4} {'ours_filt':>9} {'ours_smth':>9} {'ours_tot':>9}"
        f" {'filterpy':>9} {'fp_stp':>6} {'ratio':>7} {'|dx|':>9} {'py_loop':>9}"
        f" {'fused/py':>6} target"
    )
    with threadpool_limits(args.threads):
        for N in map(int, args.nodes.split(",")):
            row("estimate", N, args.steps, args.fp_steps, args.repeat, print)
        row("identify-h", 51, args.steps, args.fp_steps, args.repeat, print)
    print("estimate: ours_tot = filter + unscented RTS smoother; identify-h: filter only")


if __name__ == "__main__":
    main()
