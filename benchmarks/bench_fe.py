"""Seconds per lap (1000 steps at 10 Hz) of the batched disc-model step, side by side.

For each mesh the batch is the UKF's sigma-point set, B = 2 n + 1 (n = state size,
plus one for an ``h`` state where h varies per member). Columns:

* ``numba``   — fused assembly + LDL^T kernel (default path of ``DiscFEModel.step``)
* ``numpy``   — numpy assembly + numpy banded LDL^T fallback (no numba)
* ``scipy``   — numpy assembly + ``scipy.linalg.solveh_banded`` per member (reference)
* ``shared``  — one matrix from the mean state, factorised once, B right-hand sides

Run: ``python benchmarks/bench_fe.py [--steps 300]`` (times are scaled to 1000 steps).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
import scipy.linalg
from threadpoolctl import threadpool_limits

from brakethermo.thermal.banded import HAVE_NUMBA
from brakethermo.thermal.disc import load_disc
from brakethermo.thermal.model import DiscFEModel

STEPS_PER_LAP = 1000
Stepper = Callable[[np.ndarray, int], np.ndarray]
CASES = (  # (nodes, layers, h per member, target s/lap for the numba path)
    (10, 1, False, 0.03),
    (20, 1, False, None),
    (50, 1, False, None),
    (51, 1, True, 0.3),
    (100, 1, False, None),
    (150, 1, False, 0.5),
    (51, 3, True, None),
    (150, 3, False, None),
)


def _drive(k: int) -> float:
    """Braking power of a lap-like cycle: 1 s of 60 kW every 5 s, W."""
    return 6.0e4 if k % 50 < 10 else 0.0


def _time(
    step: Callable[[np.ndarray, int], np.ndarray], T0: np.ndarray, steps: int, repeats: int = 3
) -> float:
    """Best of ``repeats`` runs (the machine is shared), scaled to seconds per lap."""
    step(T0, 0)  # compile / warm up
    best = np.inf
    for _ in range(repeats):
        T = T0.copy()
        t = time.perf_counter()
        for k in range(steps):
            T = step(T, k)
        best = min(best, time.perf_counter() - t)
    return best / steps * STEPS_PER_LAP


def _model_step(model: DiscFEModel, h: float | np.ndarray, shared: bool = False) -> Stepper:
    def step(T: np.ndarray, k: int) -> np.ndarray:
        ref = T.mean(axis=0) if shared else None
        return model.step(T, _drive(k), h, 25.0, shared_matrix_from=ref)

    return step


def _scipy_step(model: DiscFEModel, h: float | np.ndarray) -> Stepper:
    """numpy assembly, then ``scipy.linalg.solveh_banded`` member by member."""

    def step(T: np.ndarray, k: int) -> np.ndarray:
        ab, rhs = model.system(T, _drive(k), h, 25.0)
        return np.stack(
            [scipy.linalg.solveh_banded(ab[b], rhs[b], lower=True) for b in range(len(T))]
        )

    return step


def bench(steps: int) -> None:
    disc = load_disc()
    print(f"numba available: {HAVE_NUMBA}; BLAS pinned to 1 thread; s/lap = 1000 steps")
    head = f"{'N':>4} {'L':>2} {'B':>4} {'h/memb':>6} {'numba':>8} {'numpy':>8} {'scipy':>8}"
    print(head + f" {'shared':>8} {'np/nb':>6} {'sp/nb':>6} {'target':>7}")
    rng = np.random.default_rng(0)
    for N, L, h_member, target in CASES:
        fast = DiscFEModel(disc, N, L, use_numba=HAVE_NUMBA)
        slow = DiscFEModel(disc, N, L, use_numba=False)
        n = fast.n_state
        B = 2 * (n + h_member) + 1
        T0 = 300.0 + 30.0 * rng.standard_normal((B, n))
        h = np.linspace(60.0, 110.0, B) if h_member else 80.0
        few = max(steps // 3, 20)
        t_nb = _time(_model_step(fast, h), T0, steps)
        t_np = _time(_model_step(slow, h), T0, few)
        t_sp = _time(_scipy_step(slow, h), T0, few)
        t_sh = float("nan") if h_member else _time(_model_step(fast, h, shared=True), T0, steps)
        tgt = f"{target:.2f}" if target else "-"
        print(
            f"{N:>4} {L:>2} {B:>4} {h_member!s:>6} {t_nb:8.3f} {t_np:8.3f} {t_sp:8.3f}"
            f" {t_sh:8.3f} {t_np / t_nb:6.1f} {t_sp / t_nb:6.1f} {tgt:>7}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300, help="steps timed per case")
    args = parser.parse_args()
    with threadpool_limits(limits=1):
        bench(args.steps)


if __name__ == "__main__":
    main()
