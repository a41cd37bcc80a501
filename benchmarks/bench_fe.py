"""Seconds per lap (1000 steps at 10 Hz) of the batched disc-model step, side by side.

For each mesh the batch is the UKF's sigma-point set, B = 2 n + 1 (n = state size,
plus one for an ``h`` state where h varies per member). Columns:

* ``numba``   — fused assembly + LDL^T kernel (default path of ``DiscFEModel.step``)
* ``numpy``   — numpy assembly + numpy banded LDL^T fallback (no numba)
* ``scipy``   — numpy assembly + ``scipy.linalg.solveh_banded`` per member (reference)
* ``shared``  — one matrix from the mean state, factorised once, B right-hand sides

``--layers`` instead compares graded through-thickness layers (``layer_growth``) on the
estimator's mesh (N = 10, kz_ratio = 0.06): face-temperature error during a braking pulse
(60 kW for 3 s, then 10 s cooling, from 400 degC) against a 60-equal-layer reference and
against a converged surface temperature (80 layers, growth 1.05, thin face layer), with
the sigma-point step time per lap and its ratio to the same number of equal layers.

Run: ``python benchmarks/bench_fe.py [--steps 300] [--layers]`` (times scaled to 1000 steps).
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
# (layers, growth); equal layers first so each L has its equal-layer time to compare with
LAYER_CASES = (
    (3, 1.0), (3, 2.5), (4, 1.0), (4, 2.0), (4, 2.25), (4, 3.0), (6, 1.0), (6, 2.0), (8, 1.0),
    (12, 1.0),
)  # fmt: skip


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


def _pulse(L: int, growth: float) -> tuple[DiscFEModel, np.ndarray, np.ndarray]:
    """Face-layer and surface temperatures (K + 1, N) through the braking pulse, degC."""
    model = DiscFEModel(load_disc(), 10, L, kz_ratio=0.06, layer_growth=growth)
    q = np.concatenate((np.full(30, 6.0e4), np.zeros(100)))
    T = model.open_loop(model.initial_state(400.0), q, 80.0, 25.0)
    q_k = np.append(q, 0.0)
    surface = np.stack(
        [model.surface_temperature(T[k], q_k[k], 80.0, 25.0) for k in range(T.shape[0])]
    )
    return model, T[:, model.face_index], surface


def bench_layers(steps: int) -> None:
    contact = slice(3, None)  # nodes under the pads
    ref_face = _pulse(60, 1.0)[1][:, contact]
    ref_surface = _pulse(80, 1.05)[2][:, contact]
    print("face-layer error (max / rms over contact nodes and 13 s), K; s/lap with B = 2 n + 1")
    print(
        f"{'L':>3} {'growth':>6} {'d0 mm':>6} {'vs L60 face':>12} {'vs surface':>12}"
        f" {'s/lap':>7} {'/equal':>6}"
    )
    rng = np.random.default_rng(0)
    equal: dict[int, float] = {}
    for L, growth in LAYER_CASES:
        model, face, _ = _pulse(L, growth)
        e_ref = np.abs(face[:, contact] - ref_face)
        e_srf = np.abs(face[:, contact] - ref_surface)
        B = 2 * model.n_state + 1
        T0 = 300.0 + 30.0 * rng.standard_normal((B, model.n_state))
        t = _time(_model_step(model, 80.0), T0, steps)
        if growth == 1.0:
            equal[L] = t
        ratio = f"{t / equal[L]:6.2f}" if L in equal else "-"
        d0 = 0.5e3 * model.layer_thickness[0]  # one slice, mm

        def stats(e: np.ndarray) -> str:
            return f"{e.max():5.1f} /{np.sqrt(np.mean(e**2)):5.1f}"

        print(
            f"{L:>3} {growth:6.2f} {d0:6.3f} {stats(e_ref):>12} {stats(e_srf):>12}"
            f" {t:7.3f} {ratio:>6}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300, help="steps timed per case")
    parser.add_argument("--layers", action="store_true", help="graded-layer accuracy and cost")
    args = parser.parse_args()
    with threadpool_limits(limits=1):
        (bench_layers if args.layers else bench)(args.steps)


if __name__ == "__main__":
    main()
