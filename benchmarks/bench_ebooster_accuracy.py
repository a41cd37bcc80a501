"""Accuracy of `brakethermo ebooster` over unseen seeds: UKF vs EKF, mean and spread.

Simulated bench sessions (``brakethermo.sim.ebooster``) the shipped p-V/disk fit (training
seed 0) and the observer tuning (seeds 1-2) never saw, written with the real session
writers (MCAP) and observed by the pipeline. Per scenario it prints the paper's Table 1
(residual RMSE of both observers, the improvement), the pressure RMSE against the
validation channels and the 95 % band coverage, as mean ± standard deviation over seeds
with min and max.

``--pedal-state chi_square`` runs both observers on the literal chi-square pedal model
(F = F_scale w^2 with w a state) instead of the shipped Gaussian force state.

``--pv-shift 0.35`` moves each session's p-V curve along the stroke (a dead stroke longer
by that many mm than the training bench's: seal and fluid state), as a real booster's
curve moves between sessions.

``--train-offset 1000`` trains on a training session of each seed's own bench (seed +
offset) instead of using the shipped fit, and observes every session twice in one run:
with the process noise the training session chose by held-out likelihood and with the
datasheet's (``q_factor`` 1), side by side.

Run: ``python benchmarks/bench_ebooster_accuracy.py [--seeds 11 12 13 14 15]
[--scenarios open closed vehicle] [--pedal-state force|chi_square] [--pv-shift MM ...]
[--train-offset N]``
"""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from brakethermo.config import config_dir
from brakethermo.io.atomic import write_text_atomic
from brakethermo.pipelines.ebooster import observe, train
from brakethermo.rigs.booster_datasheet import PEDAL_STATES, load_booster
from brakethermo.sim.ebooster import EboosterSimConfig, simulate_ebooster, write_ebooster_session


def _stat(values: list[float], fmt: str) -> str:
    a = np.array(values, dtype=float)
    return (f"{a.mean():{fmt}} ± {a.std(ddof=1) if a.size > 1 else 0.0:{fmt}} "
            f"[{a.min():{fmt}}, {a.max():{fmt}}]")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[11, 12, 13, 14, 15])
    ap.add_argument("--scenarios", nargs="+", default=["open", "closed", "vehicle"])
    ap.add_argument("--pedal-state", choices=PEDAL_STATES, default="force")
    ap.add_argument("--pv-shift", type=float, nargs="+", default=[0.0],
                    help="p-V shift of the observed sessions, mm (one row block each)")
    ap.add_argument("--with-effect", default=None,
                    help="as ebooster's --with-effect ('none': as a session without the"
                         " pressure sensor); default: the command's default")
    ap.add_argument("--train-offset", type=int, default=None,
                    help="train on each seed's bench (seed + N): chosen vs datasheet noise")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        text = (config_dir() / "rigs" / "ebooster.toml").read_text()
        bench = Path(tmp) / "bench.toml"
        bench.write_text(text.replace('pedal_state = "force"',
                                      f'pedal_state = "{args.pedal_state}"'))
        print(f"pedal state: {args.pedal_state}")
        for scenario, shift in ((sc, sh) for sc in args.scenarios for sh in args.pv_shift):
            rows: dict[str, list[float]] = {}
            carried: list[str] = []
            for seed in args.seeds:
                cfg = EboosterSimConfig(scenario, seed=seed, pv_shift_mm=shift)
                path, _ = write_ebooster_session(simulate_ebooster(cfg),
                                                 Path(tmp) / f"{scenario}{seed}.mcap")
                if args.train_offset is None:
                    s = observe(path, bench=bench, with_effect=args.with_effect).summary
                else:
                    fits = _fits(seed + args.train_offset, bench, Path(tmp))
                    s = observe(path, bench=bench, fit_path=fits["chosen"],
                                with_effect=args.with_effect).summary
                    d = observe(path, bench=bench, fit_path=fits["datasheet"],
                                with_effect=args.with_effect).summary
                    rows.setdefault("q_factor chosen", []).append(s["noise_choice"]["q_factor"])
                    for w in ("ukf", "ekf"):
                        rows.setdefault(f"p_m RMSE {w} MPa, datasheet Q", []).append(
                            d["pressure_rmse_mpa"][w]["p_m"])
                        rows.setdefault(f"95% coverage {w} %, datasheet Q", []).append(
                            100 * d["coverage_95"][w])
                for w in ("ukf", "ekf"):
                    rows.setdefault(f"residual RMSE {w} mm", []).append(
                        s["residual_rmse_mm"][w])
                    for state, v in s["pressure_rmse_mpa"][w].items():
                        rows.setdefault(f"{state} RMSE {w} MPa", []).append(v)
                    rows.setdefault(f"95% coverage {w} %", []).append(100 * s["coverage_95"][w])
                    for state, v in s["outside_1sigma"][w].items():
                        rows.setdefault(f"{state} outside 1σ {w} %", []).append(100 * v)
                rows.setdefault("UKF improvement over EKF %", []).append(s["improvement_pct"])
                carried.append((s["with_effect"] or {}).get("verdict") or "none")
            print(f"\n{scenario}, p-V shift {shift:+.2f} mm: seeds {args.seeds}"
                  " (mean ± sd [min, max])")
            for name, values in rows.items():
                fmt = (".4f" if "residual" in name else ".3f" if "MPa" in name
                       else ".2f" if "q_factor" in name else ".1f")
                print(f"  {name:34s} {_stat(values, fmt)}")
            print("  per seed:")
            for name in ("UKF improvement over EKF %", "95% coverage ukf %", "95% coverage ekf %"):
                print(f"    {name:32s} " + " ".join(f"{v:6.1f}" for v in rows[name]))
            print(f"    {'p-V departure carried':32s} " + " ".join(carried))


_FITS: dict[int, dict[str, Path]] = {}


def _fits(train_seed: int, bench: Path, tmp: Path) -> dict[str, Path]:
    """The fit of the bench's training session of ``train_seed``, saved with the noise it
    chose and with the datasheet's (trained once per seed)."""
    if train_seed not in _FITS:
        path, _ = write_ebooster_session(
            simulate_ebooster(EboosterSimConfig("train", seed=train_seed)),
            tmp / f"train{train_seed}.mcap")
        fit = train(path, load_booster(bench))
        _FITS[train_seed] = {}
        for name, f in (("chosen", fit), ("datasheet", replace(fit, q_factor=1.0))):
            _FITS[train_seed][name] = tmp / f"fit{train_seed}_{name}.toml"
            write_text_atomic(_FITS[train_seed][name], f.toml_text())
    return _FITS[train_seed]


if __name__ == "__main__":
    main()
