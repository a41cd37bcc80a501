"""What carrying a diagnosed effect into identify-h and estimate buys, against truth.

For each case a four-spot test session and a single-spot race of the same bike are
simulated with one effect strong; identify-h runs on the test session without effects
and with ``--with-effect`` (a named effect, or ``auto`` = the diagnosis's forward
selection); both laws estimate the race. Printed per case: the law's RMS error against
the truth's h over the test session's off-brake samples (relative to its mean), and the
race's contact-band RMSE, bias and 95 % band coverage against the true temperatures.

    python benchmarks/accuracy_with_effects.py                  # both cases, seeds 31001+
    python benchmarks/accuracy_with_effects.py --cases friction_temperature:auto --seeds 2

Targets (issue 8): with a strong μ(T), identify-h with ``auto`` recovers h(V) within
15 % RMS over the speeds the session covers.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from brakethermo.pipelines.estimate import EstimateOptions, estimate_session
from brakethermo.pipelines.identify_h import IdentifyOptions, identify_h, write_identify
from brakethermo.pipelines.truth_score import read_truth
from brakethermo.sim.session import SimConfig, simulate, write_simulation

CASES = ("friction_temperature:auto", "emissivity_error:emissivity_error")
SEED_BASE = 31000  # reporting seeds: not used to develop the effects


def law_error(law, truth) -> float:
    """RMS of the law against the truth's h off the brakes, relative to the mean h."""
    v = truth["speed"].to_numpy() / 3.6
    off = truth["q_brake"].to_numpy() == 0
    h = truth["h"].to_numpy()[off]
    return float(np.sqrt(np.mean((law(v[off]) - h) ** 2)) / np.mean(h))


def race_scores(frame, truth) -> dict[str, float]:
    """Contact-band RMSE, bias (degC) and 95 % coverage against the truth."""
    err = frame["contact_avg"].to_numpy() - truth[["spot2", "spot3", "spot4"]].mean(axis=1)
    std = frame["contact_avg_std"].to_numpy()
    return {"rmse_c": float(np.sqrt(np.mean(err**2))), "bias_c": float(np.mean(err)),
            "coverage": float(np.mean(np.abs(err) <= 1.96 * std))}


def run_case(effect: str, with_effect: str, seed: int, test_laps: int, race_laps: int) -> None:
    strengths = {effect: 1.0}
    with tempfile.TemporaryDirectory(prefix="bench-fx-") as tmp, threadpool_limits(1):
        work = Path(tmp)
        test, test_truth = write_simulation(simulate(SimConfig(
            laps=test_laps, effects=strengths, sensor="multi", seed=seed, bike_seed=seed)),
            work / "test.mcap")
        race, race_truth = write_simulation(simulate(SimConfig(
            laps=race_laps, effects=strengths, sensor="single", seed=seed + 1, bike_seed=seed)),
            work / "race.parquet")
        truth_test, truth_race = read_truth(test_truth), read_truth(race_truth)
        for label, opts in (("no effect", IdentifyOptions(with_effects="none")),
                            (f"--with-effect {with_effect}",
                             IdentifyOptions(with_effects=with_effect))):
            t0 = time.perf_counter()
            ident = identify_h(test, opts)
            wall = time.perf_counter() - t0
            law_path = write_identify(ident, work / label.replace(" ", "_")) / "h_law.toml"
            race_est = estimate_session(race, EstimateOptions(h_law=law_path))
            sc = race_scores(race_est.frame, truth_race)
            fitted = sorted(ident.summary["structure"]["effects"]) if ident.structure else []
            print(f"{effect:22s} seed {seed}  {label:36s} law error "
                  f"{100 * law_error(ident.law, truth_test):5.1f} %  race contact RMSE "
                  f"{sc['rmse_c']:5.1f} C (bias {sc['bias_c']:+5.1f}, coverage "
                  f"{100 * sc['coverage']:3.0f} %)  fitted {fitted}  identify {wall:.0f} s",
                  flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=",".join(CASES),
                    help="effect:with-effect pairs, comma separated")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--test-laps", type=int, default=6)
    ap.add_argument("--race-laps", type=int, default=4)
    args = ap.parse_args()
    for case in args.cases.split(","):
        effect, with_effect = case.split(":")
        for r in range(args.seeds):
            run_case(effect, with_effect, SEED_BASE + 10 * r + 1, args.test_laps,
                     args.race_laps)


if __name__ == "__main__":
    main()
