"""A race on a thinner skin chooses its crown-split noise by its own one-step predictive
likelihood: a lower noise only where it predicts the readings clearly better, never one
that sends the filter astray, never over the user's."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from brakethermo.pipelines import crown_noise
from brakethermo.pipelines.estimate import EstimateOptions
from brakethermo.pipelines.online_choice import OnlineChoice


def _part(laps: int = 4, per_lap: int = 400) -> SimpleNamespace:
    """The decision's laps: braking every 80 grid points."""
    n = laps * per_lap
    time = np.arange(n) * 0.1
    pressure = np.where(np.arange(n) % 80 < 15, 2.0e6, 0.0)
    frame = pd.DataFrame({"lap": np.repeat(np.arange(1, laps + 1), per_lap), "time": time})
    return SimpleNamespace(frame=frame, time=time, values=lambda name: pressure)


def _innovations(rng: np.random.Generator, n: int, sd: float, claimed: float
                 ) -> crown_noise.Innovations:
    """Innovations of spread ``sd`` a filter claims to be ``claimed`` (degC)."""
    return crown_noise.Innovations(rng.normal(0.0, sd, n), np.full(n, claimed**2))


@pytest.mark.parametrize(("sd", "claimed", "kept"), [
    (1.0, 1.0, True),     # sharper and right: the lower noise is kept
    (1.2, 1.6, False),    # as good as the law's: the law's stays
    (25.0, 1.0, False),   # a noise too low for the race: the filter went astray
])
def test_a_lower_noise_is_kept_only_where_it_predicts_clearly_better(sd, claimed, kept
                                                                     ) -> None:
    rng = np.random.default_rng(3)
    part = _part()
    n = len(part.frame)
    law = _innovations(rng, n + 500, 1.2, 1.6)  # the whole race's filter: longer
    tried = {f: _innovations(rng, n, sd, claimed) for f in crown_noise.FACTORS}
    fact = crown_noise.judge(part, law, tried, 0.4, ["thickness_gradient"])
    assert fact["changed"] is kept
    best = max(fact["tests"], key=lambda r: r["loglik_gain_per_reading"])
    assert fact["chosen"] == (best["sigma_crown"] if kept else 0.4)
    assert [r["significant"] for r in fact["tests"]] == [kept] * len(crown_noise.FACTORS)
    assert "flying laps 1, 2, 3, 4" in fact["test"]


def _choice(learned: float, chosen: bool = True) -> OnlineChoice:
    row = {"name": "thickness_gradient", "learned": learned, "significant": chosen}
    return OnlineChoice({"adapt_kz": chosen}, {
        "scores": [row], "chosen": ["thickness_gradient"] if chosen else []})


def test_only_a_thinner_skin_with_a_noise_nobody_set_chooses(tmp_path) -> None:
    assert crown_noise.free(_choice(0.5), EstimateOptions(), 8)
    assert not crown_noise.free(_choice(1.4), EstimateOptions(), 8)  # a thicker skin
    assert not crown_noise.free(_choice(0.5, chosen=False), EstimateOptions(), 8)
    assert not crown_noise.free(None, EstimateOptions(), 8)
    assert not crown_noise.free(_choice(0.5), EstimateOptions(), 7)  # a short race
    assert not crown_noise.free(_choice(0.5), EstimateOptions(sigma_crown=0.3), 8)
    user = tmp_path / "tuning.toml"
    user.write_text("[estimate]\nsigma_crown = 0.3\n")
    assert not crown_noise.free(_choice(0.5), EstimateOptions(tuning=user), 8)


def test_the_page_says_which_noise_the_race_kept_and_the_evidence() -> None:
    from brakethermo.report.lap_report import _decisions

    fact = {"law": 0.4, "chosen": 0.2, "changed": True, "test": "the law's against lower",
            "tests": [{"factor": 0.5, "sigma_crown": 0.2, "loglik_gain_per_reading": 0.064,
                       "loglik_gain_ci95": [0.045, 0.083], "significant": True},
                      {"factor": 0.25, "sigma_crown": 0.1, "loglik_gain_per_reading": -15.3,
                       "loglik_gain_ci95": [-17.4, -13.2], "significant": False}]}
    (line,) = [x for x in _decisions({"run": {"online_choice": {"crown_noise": fact}}})
               if x.startswith("crown-split noise")]
    assert "lowered to 0.2 from the law's 0.4" in line
    assert "0.2: +0.064 nats per reading (95 % +0.045 to +0.083)" in line
    assert "0.1: -15.300" in line
    kept = _decisions({"run": {"online_choice": {"crown_noise": {**fact, "changed": False,
                                                                 "chosen": 0.4}}}})
    assert any("the law's 0.4 kept" in x for x in kept)


def test_a_noise_whose_filter_breaks_down_loses_and_is_said() -> None:
    from brakethermo.errors import DataError
    from brakethermo.report.lap_report import _decisions

    rng = np.random.default_rng(4)
    part = _part()
    n = len(part.frame)

    def run(steps: int, noise: float) -> crown_noise.Innovations:
        if noise < 0.15:
            raise DataError("race.parquet: the filter's covariance broke down at step 812")
        return _innovations(rng, steps, 1.0, 1.0)

    tried = crown_noise.trials(n, 0.4, run)
    assert isinstance(tried[0.25], str) and "step 812" in tried[0.25]
    fact = crown_noise.judge(part, _innovations(rng, n, 1.2, 1.6), tried, 0.4, ["k_z"])
    lost = next(r for r in fact["tests"] if r["factor"] == 0.25)
    assert not lost["significant"] and "step 812" in lost["failed"]
    assert fact["chosen"] == pytest.approx(0.2)  # the half that ran and won
    line = next(x for x in _decisions({"run": {"online_choice": {"crown_noise": fact}}})
                if x.startswith("crown-split noise"))
    assert "0.1: the filter failed there (race.parquet" in line


def test_a_long_race_on_a_thinner_skin_runs_on_the_noise_it_chose(tmp_path) -> None:
    """End to end: a 9-lap race on a low-k_z disc switches k_z on below the law's, tries
    the lower noises over its decision laps and runs on the one it kept."""
    from brakethermo.pipelines.estimate import estimate_session
    from brakethermo.sim.session import SimConfig, simulate, write_simulation

    path, _ = write_simulation(simulate(SimConfig(
        laps=9, sensor="single", seed=61123, effects={"thickness_gradient": 1.0})),
        tmp_path / "race.parquet")
    run = estimate_session(path, EstimateOptions(smoother=False)).summary["run"]
    noise = run["online_choice"]["crown_noise"]
    assert [r["factor"] for r in noise["tests"]] == list(crown_noise.FACTORS)
    assert run["sigma_crown"] == noise["chosen"]
    assert noise["changed"] is (noise["chosen"] != noise["law"])
    assert "flying laps 1, 2, 3, 4, 5, 6, 7, 8" in noise["test"] and noise["seconds"] > 0
