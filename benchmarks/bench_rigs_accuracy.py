"""Accuracy of ``clamp-force`` and ``mu-slip`` over several seeds of our rig simulators.

Seeds from 20000 on: never used while developing the estimators (development used
seeds below 1000, the tests 6000-8200). Every session goes through the real writers
(MCAP) and the pipeline functions the commands call.

clamp-force, per seed s: train on a 60 s nominal session, estimate an unseen 60 s
nominal session (RMSE of every estimator against the true clamp force, which is not
the lagged, noisy sensor); re-train on 20 s of a worn-pad session and estimate an
unseen worn session (with and without re-training); estimate an unseen 60 s session
whose pads heat from 40 to 390 °C (paper KF vs adaptive KF).

mu-slip, per seed and tyre (Burckhardt dry asphalt, Magic Formula book defaults):
peak μ error (%) and peak slip error of the reported peak, of the EKF and of the
converged LM fit of the two-parameter curve; and the paper's own case (40 points,
σ 0.04): share of seeds whose final EKF estimate is within 1σ in both parameters.

Run: ``python benchmarks/bench_rigs_accuracy.py [--seeds 8] [--stress]``
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from brakethermo.models.clamp_force import estimate, fusion_check, train
from brakethermo.models.mu_slip import rudd_ekf
from brakethermo.numeric import rmse
from brakethermo.pipelines import clamp_force as cf
from brakethermo.pipelines import mu_slip as ms
from brakethermo.results.clamp_force import estimator_series
from brakethermo.rigs.tyre import rudd_mu
from brakethermo.sim.emb import EmbCaliper, simulate_emb, write_emb_simulation
from brakethermo.sim.tyre_rig import simulate_tyre_rig, write_tyre_simulation

BASE = 20000
TS = 1e-3  # s, the simulated caliper's logging period
Z95 = 1.959963984540054


def _line(name: str, v: list[float], unit: str = "") -> str:
    a = np.asarray(v, float)
    return (
        f"  {name:44s} {a.mean():8.3f} ± {a.std(ddof=1) if a.size > 1 else 0.0:6.3f}"
        f"  [{a.min():.3f}, {a.max():.3f}] {unit}"
    )


def _covered(est, truth_kn: np.ndarray) -> float:
    """Share of samples, %, where the reported KF's 95 % band holds the true force."""
    return 100.0 * float(np.mean(np.abs(est.kf / 1e3 - truth_kn) <= Z95 * est.kf_std / 1e3))


def clamp(seeds: int, d: Path) -> None:
    rows: dict[str, list[float]] = {}
    for i in range(seeds):
        s = BASE + 10 * i

        def sim(name: str, seed: int, dur: float, tag: str):
            res = simulate_emb(name, seed=seed, duration_s=dur)
            path, _ = write_emb_simulation(res, d / f"{tag}_{seed}.mcap")
            return path, res.truth.column("clamp_force").to_numpy()

        tr, _ = sim("nominal", s, 60, "train")
        ev, t_ev = sim("nominal", s + 1, 60, "eval")
        wt, _ = sim("worn", s + 2, 20, "worn20")
        wv, t_wv = sim("worn", s + 3, 60, "worn")
        hv, t_hv = sim("heating", s + 4, 60, "hot")
        nom = cf.clamp_force(ev, tr)
        for k, v in estimator_series(nom.est).items():
            rows.setdefault(f"nominal {k} (kN)", []).append(rmse(v / 1e3, t_ev))
        rows.setdefault("nominal KF 95 % band coverage (%)", []).append(_covered(nom.est, t_ev))
        kf, ds = rows["nominal kf (kN)"][-1], rows["nominal stiffness (kN)"][-1]
        rows.setdefault("nominal KF below stiffness (%)", []).append(100 * (1 - kf / ds))
        rows.setdefault("nominal KF / ML fusion", []).append(
            kf / rows["nominal ml_fusion (kN)"][-1]
        )
        rows.setdefault("KF fell back to an input or ML (share of seeds)", []).append(
            float(nom.est.kf_source != "kf"))
        worn = cf.clamp_force(wv, tr, retrain_path=wt)
        stale = rmse(worn.est.kf / 1e3, t_wv)
        fresh = rmse(worn.est_retrained.kf / 1e3, t_wv)
        rows.setdefault("worn KF not re-trained (kN)", []).append(stale)
        rows.setdefault("worn KF re-trained on 20 s (kN)", []).append(fresh)
        rows.setdefault("worn KF not re-trained, coverage (%)", []).append(
            _covered(worn.est, t_wv))
        rows.setdefault("worn KF not re-trained, noise scale", []).append(
            worn.est.kf_noise_scale)
        rows.setdefault("worn KF re-trained, coverage (%)", []).append(
            _covered(worn.est_retrained, t_wv))
        rows.setdefault("worn re-trained / nominal KF", []).append(fresh / kf)
        rows.setdefault("worn torque balance not re-trained (kN)", []).append(
            rmse(worn.est.torque_balance / 1e3, t_wv))
        hot = cf.clamp_force(hv, tr)
        rows.setdefault("heating KF (kN)", []).append(rmse(hot.est.kf / 1e3, t_hv))
        rows.setdefault("heating KF coverage (%)", []).append(_covered(hot.est, t_hv))
        rows.setdefault("heating torque balance (kN)", []).append(
            rmse(hot.est.torque_balance / 1e3, t_hv))
        rows.setdefault("heating adaptive KF (kN)", []).append(rmse(hot.est.adaptive / 1e3, t_hv))
        rows.setdefault("heating final stiffness factor", []).append(
            float(hot.est.stiffness_factor[-1])
        )
    print(f"clamp-force over {seeds} seeds (mean ± std [min, max]):")
    for k, v in rows.items():
        print(_line(k, v))


# Calipers the estimator's models do not describe (``--stress``): what the held-out
# choice of the filter's Q and the fallback do against the paper's fixed Q.
STRESS = {
    "hysteresis 4x (0.12, full at 0.5 rad/s)": EmbCaliper(hysteresis=0.12, omega_h=0.5),
    "viscoelastic branches 2.5-4x": EmbCaliper(visco=((0.3, 0.05), (0.2, 1.5))),
    "slow applies (0.4 s holds, 20 rad/s loop)": EmbCaliper(ref_period_s=0.4, omega_n=20.0),
    "force sensor lag 2 ms (trained on it)": EmbCaliper(force_lag_s=0.002),
    "force sensor lag 5 ms (trained on it)": EmbCaliper(force_lag_s=0.005),
}


def stress(seeds: int) -> None:
    print(f"clamp-force on calipers the models do not describe, {seeds} seeds each: KF RMSE"
          " kN against the true force (95 % coverage), held-out Q vs the paper's Q")
    for name, cal in STRESS.items():
        rows: dict[str, list[float]] = {}
        for i in range(seeds):
            s = BASE + 3000 + 10 * i
            tr = simulate_emb("nominal", seed=s, duration_s=60, caliper=cal)
            th, cur, F = (_channel(tr, c) for c in ("motor_angle", "motor_current",
                                                    "clamp_force"))
            F = F * 1e3
            lag = cf.choose_sensor_lag(th, cur, F, TS)
            models = train(th, cur, F, TS, sensor_lag_s=lag.lag_s, eq7=lag.eq7)
            check = fusion_check(th, cur, F, TS, sensor_lag_s=lag.lag_s)
            ev = simulate_emb("nominal", seed=s + 1, duration_s=60, caliper=cal)
            th2, cur2 = _channel(ev, "motor_angle"), _channel(ev, "motor_current")
            truth = ev.truth.column("clamp_force").to_numpy()
            for tag, e in (("held-out", estimate(models, th2, cur2, TS, check=check)),
                           ("paper Q", estimate(models, th2, cur2, TS, q_scale=1.0))):
                rows.setdefault(f"{tag} KF", []).append(rmse(e.kf / 1e3, truth))
                rows.setdefault(f"{tag} coverage %", []).append(_covered(e, truth))
            rows.setdefault("ML fusion", []).append(rmse(e.ml_fusion / 1e3, truth))
            rows.setdefault("stiffness", []).append(rmse(e.stiffness / 1e3, truth))
            rows.setdefault("Q factor", []).append(check.q_scale if check else 1.0)
            rows.setdefault("sensor lag ms", []).append(lag.lag_s * 1e3)
        print(f" {name}: " + ", ".join(f"{k} {np.mean(v):.3f}" for k, v in rows.items()))


def _channel(sim, name: str) -> np.ndarray:
    return next(c.value for c in sim.session.channels if c.name == name)


def mu(seeds: int, d: Path) -> None:
    print(f"mu-slip over {seeds} seeds per tyre (mean ± std [min, max]):")
    for tyre in ("dry", "wet"):
        rows: dict[str, list[float]] = {}
        picks: list[str] = []
        for i in range(seeds):
            sim = simulate_tyre_rig(tyre, seed=BASE + 100 + i)
            path, _ = write_tyre_simulation(sim, d / f"{tyre}_{i}.mcap")
            summ = ms.summary(ms.mu_slip(path))
            mu_t, s_t = sim.peak
            picks.append(summ["peak"]["model"])
            for lab, est in (
                ("reported", (summ["peak"]["mu"], summ["peak"]["slip"])),
                ("EKF", (summ["ekf"]["mu_peak"], summ["ekf"]["slip_peak"])),
                (
                    "LM converged",
                    (summ["lm_converged"]["mu_peak"], summ["lm_converged"]["slip_peak"]),
                ),
            ):
                rows.setdefault(f"{lab} peak μ error (%)", []).append(100 * (est[0] / mu_t - 1))
                rows.setdefault(f"{lab} peak slip error (–)", []).append(est[1] - s_t)
        print(
            f" {tyre}: true peak μ {sim.peak[0]:.4f} at slip {sim.peak[1]:.4f};"
            f" family picked: {', '.join(sorted(set(picks)))} ({picks.count(picks[0])}/{seeds}"
            f" {picks[0]})"
        )
        for k, v in rows.items():
            print(_line(k, v))
    inside, maha = 0, []
    n = 10 * seeds
    for i in range(n):
        rng = np.random.default_rng(BASE + 500 + i)
        s = (np.arange(1, 41) / 40.0) ** 2
        y = rudd_mu(s, 0.35, 0.15) + rng.normal(0.0, 0.04, 40)
        r = rudd_ekf(s, y, 0.04, np.array([0.6, 0.2]), np.diag([0.5**2, 0.1**2]))
        e = r.x_filt[-1] - [0.35, 0.15]
        inside += bool((np.abs(e) < np.sqrt(r.var_filt[-1])).all())
        maha.append(float(np.sqrt(e @ np.linalg.solve(r.P_filt[-1], e))))
    print(
        f" paper case (μp 0.35, sp 0.15, σ 0.04, 40 points), {n} seeds: final EKF within 1σ"
        f" in both parameters on {inside}/{n}; Mahalanobis distance < 1 on"
        f" {sum(m < 1 for m in maha)}/{n}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--stress", action="store_true",
                    help="clamp-force on calipers the models do not describe, only")
    args = ap.parse_args()
    if args.stress:
        stress(args.seeds)
        return
    with tempfile.TemporaryDirectory() as tmp:
        mu(args.seeds, Path(tmp))
        clamp(args.seeds, Path(tmp))


if __name__ == "__main__":
    main()
