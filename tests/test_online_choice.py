"""The race decides its online effects: k_z on where the race disc differs, not where it
matches; forced flags win; the decision and its evidence are in the run facts."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from brakethermo.pipelines import online_choice
from brakethermo.pipelines.estimate import EstimateOptions, estimate_session
from brakethermo.pipelines.truth_score import read_truth
from brakethermo.sim.session import SimConfig, simulate, write_simulation

SEED = 61101  # not a tuning seed


def _contact_rmse(frame, truth) -> float:
    t = truth[["spot2", "spot3", "spot4"]].mean(axis=1).to_numpy()
    n = min(t.size, len(frame))
    fly = frame["lap"].to_numpy()[:n] >= 1
    return float(np.sqrt(np.mean((frame["contact_avg"].to_numpy()[:n] - t[:n])[fly] ** 2)))


@pytest.fixture(scope="module")
def races(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, Path]]:
    out = tmp_path_factory.mktemp("online")
    return {
        name: write_simulation(simulate(SimConfig(laps=4, sensor="single", seed=SEED,
                                                  effects=eff)), out / f"{name}.parquet")
        for name, eff in (("low_kz", {"thickness_gradient": 1.0}), ("normal", {}),
                          ("slow_pyrometer", {"sensor_lag": 1.0}))
    }


def test_a_disc_of_other_kz_switches_kz_on_and_gains(races) -> None:
    path, truth_path = races["low_kz"]
    auto = estimate_session(path, EstimateOptions(smoother=False))
    choice = auto.summary["run"]["online_choice"]
    assert "thickness_gradient" in choice["chosen"]
    row = next(r for r in choice["scores"] if r["name"] == "thickness_gradient")
    assert row["learned"] < 0.8 and row["shrink_ci95_pct"][0] > 5.0
    # a thinner thermal skin than the law's disc: identify-h's thin-skin layering
    assert choice["layering"].startswith("6 layers")
    assert auto.summary["run"]["layers"] == 6
    # and finer radial nodes: its face follows the pads' flux profile
    assert auto.summary["run"]["nodes"] == 15 and "15 radial nodes" in choice["layering"]
    # too short a race to choose its crown-split noise (test_crown_noise: a long one)
    assert "crown_noise" not in choice
    off = estimate_session(path, EstimateOptions(smoother=False, adapt_kz=False,
                                                 adapt_slipstream=False))
    truth = read_truth(truth_path)
    assert _contact_rmse(auto.frame, truth) < 0.6 * _contact_rmse(off.frame, truth)
    assert "crown_noise" not in off.summary["run"]["online_choice"]


def test_a_matching_disc_is_not_made_worse_and_flags_force(races) -> None:
    path, truth_path = races["normal"]
    truth = read_truth(truth_path)
    auto = estimate_session(path, EstimateOptions(smoother=False))
    off = estimate_session(path, EstimateOptions(smoother=False, adapt_kz=False,
                                                 adapt_slipstream=False))
    assert _contact_rmse(auto.frame, truth) <= 1.1 * _contact_rmse(off.frame, truth) + 0.5
    forced = estimate_session(path, EstimateOptions(smoother=False, adapt_kz=True))
    run = forced.summary["run"]
    assert run["online_choice"]["forced_or_from_law"] == {"adapt_kz": True}
    assert "kz_factor" in forced.frame
    none = estimate_session(path, EstimateOptions(smoother=False, adapt_kz=False,
                                                  adapt_slipstream=False))
    assert "every online effect" in none.summary["run"]["online_choice"]["rule"]


def _law_with_kz(tmp_path: Path, factor: float) -> tuple[Path, float]:
    """The shipped law with its k_z ratio times ``factor``; the file and the new ratio."""
    import re

    shipped = Path(__file__).parents[1] / "configs" / "hlaw" / "cc-340-8.toml"
    text = shipped.read_text()
    kz = float(re.search(r"^kz_ratio = (.*)$", text, re.M).group(1)) * factor
    law = tmp_path / f"kz{factor:g}.toml"
    law.write_text(re.sub(r"^kz_ratio = .*$", f"kz_ratio = {kz!r}", text, flags=re.M))
    return law, kz


def test_a_kz_within_the_laws_own_error_stays_off_one_far_from_it_goes_on(races, tmp_path
                                                                           ) -> None:
    """A law whose k_z is 20 % low (as identify-h's can be): the normal race learns it
    higher and predicts its spot better with it, but that is the law's own k_z error, so
    k_z stays off, and the page says why; a law 4x off is another disc, and k_z goes on."""
    path, _ = races["normal"]
    law, _ = _law_with_kz(tmp_path, 0.8)
    auto = estimate_session(path, EstimateOptions(h_law=law, smoother=False))
    choice = auto.summary["run"]["online_choice"]
    row = next(r for r in choice["scores"] if r["name"] == "thickness_gradient")
    assert 1.0 < row["learned"] < online_choice.KZ_LIKE_LAW[1]
    assert row["shrink_ci95_pct"][0] > online_choice.MIN_SHRINK_PCT  # won, but gated
    assert not row["significant"] and "thickness_gradient" not in choice["chosen"]
    assert row["like_law"].startswith(f"but the race's k_z came out {row['learned']:.2f}")
    far, _ = _law_with_kz(tmp_path, 0.25)
    auto = estimate_session(path, EstimateOptions(h_law=far, smoother=False))
    choice = auto.summary["run"]["online_choice"]
    row = next(r for r in choice["scores"] if r["name"] == "thickness_gradient")
    assert row["learned"] > online_choice.KZ_LIKE_LAW[1] and "like_law" not in row
    assert "thickness_gradient" in choice["chosen"]


def test_a_gated_kz_still_lets_the_laws_mu_t_be_judged_beside_it(races, tmp_path) -> None:
    """A law 20 % low in k_z carrying a μ(T) the race's pads lack: the best combination is
    the law without μ(T) with k_z online, but k_z is like the law's and stays off, so
    μ(T) is judged as the race runs — the law with it against without it, k_z off — and
    dropped; the page's rows say which pair they compare."""
    law, _ = _law_with_kz(tmp_path, 0.8)
    law.write_text(law.read_text() + "\n[effects.friction_temperature]\nbeta = 0.45\n"
                                     "t_mid = 380.0\n")
    path, _ = races["normal"]
    auto = estimate_session(path, EstimateOptions(h_law=law, smoother=False))
    choice = auto.summary["run"]["online_choice"]
    row = next(r for r in choice["scores"] if r["name"] == "thickness_gradient")
    top = next(c for c in row["joint_test"] if c["significant"])
    assert top["name"] == "without friction_temperature + thickness_gradient"
    assert "thickness_gradient" not in choice["chosen"] and not row["significant"]
    assert row["like_law"].startswith("but the race's k_z came out")
    assert row["test"].startswith("k_z online against off, on the law without")
    assert choice["law_effects_dropped"] == ["friction_temperature"]
    (tested,) = choice["law_effects_tested"]
    assert tested["significant"] and tested["must_earn"]
    assert "the law with its friction_temperature against without it" in tested["test"]
    assert "k_z online in both" not in tested["test"]
    assert "kz_factor" not in auto.frame


def test_the_race_judges_the_laws_mu_t_a_lap_ahead(races, tmp_path) -> None:
    """A law carrying a μ(T) far stronger than the race's pads: the race tests the law with
    and without it, each model a whole lap ahead from its own filtered state, and the
    decision and its evidence are in the run facts; without the race's say it is kept."""
    shipped = Path(__file__).parents[1] / "configs" / "hlaw" / "cc-340-8.toml"
    law = tmp_path / "law.toml"
    law.write_text(shipped.read_text()
                   + "\n[effects.friction_temperature]\nbeta = 0.45\nt_mid = 380.0\n")
    path, _ = races["normal"]
    auto = estimate_session(path, EstimateOptions(h_law=law, smoother=False))
    choice = auto.summary["run"]["online_choice"]
    (tested,) = choice["law_effects_tested"]
    assert tested["name"] == "without friction_temperature"
    assert "a whole lap ahead" in tested["test"]
    assert choice["law_effects_dropped"] == (
        ["friction_temperature"] if tested["significant"] else [])
    assert tested["significant"], tested  # μ/μ_nom 0.55..1.45: the race's pads say no
    used = auto.summary["run"]["effects"]
    assert "friction_temperature" not in used
    kept = estimate_session(path, EstimateOptions(h_law=law, smoother=False, online_auto=False))
    assert "friction_temperature" in kept.summary["run"]["effects"]


def test_the_race_judges_the_laws_uneven_crown_before_its_online_states(races, tmp_path) -> None:
    """A law whose pad crown is far more uneven than the race's pads (a test session with
    a pad split): the race tests uniform weights a lap ahead before anything else, drops
    the law's, and then needs no online k_z to explain its measured spot."""
    shipped = Path(__file__).parents[1] / "configs" / "hlaw" / "cc-340-8.toml"
    text = shipped.read_text()
    start = text.index("w = [")
    end = text.index("]", start) + 1
    law = tmp_path / "split.toml"
    law.write_text(text[:start] + "w = [1.6, 0.6, 0.8]" + text[end:])
    path, truth_path = races["normal"]
    auto = estimate_session(path, EstimateOptions(h_law=law, smoother=False))
    choice = auto.summary["run"]["online_choice"]
    crown = next(r for r in choice["law_effects_tested"] if r["name"] == "without crown_weights")
    assert crown["significant"] and choice["law_effects_dropped"] == ["crown_weights"]
    assert "thickness_gradient" not in choice["chosen"]
    # the drop is said where the engineer reads it, with what it moves (it was silent)
    assert crown["said"] in auto.summary["run"]["warnings"]
    assert set(crown["peaks_apart_c"]) == {"spot1", "spot2", "spot3", "spot4"}
    assert "--law-as-written" in crown["said"] and "spot 1 " in crown["said"]
    from brakethermo.report.lap_report import _decisions
    assert crown["said"] in _decisions(auto.summary)
    kept = estimate_session(path, EstimateOptions(h_law=law, smoother=False, online_auto=False))
    truth = read_truth(truth_path)
    assert _contact_rmse(auto.frame, truth) < 0.7 * _contact_rmse(kept.frame, truth)
    plain = estimate_session(path, EstimateOptions(smoother=False))  # the shipped law: usual
    assert not plain.summary["run"]["online_choice"].get("law_effects_tested")


def test_the_race_judges_the_laws_pyrometer_lag_by_its_own_readings(races, tmp_path) -> None:
    """The law's lag is the test session's pyrometer: a race logged by a fast one drops it
    (one-step innovations, before the online states), a race whose sensor is as slow
    keeps it."""
    shipped = Path(__file__).parents[1] / "configs" / "hlaw" / "cc-340-8.toml"
    law = tmp_path / "lag.toml"
    law.write_text(shipped.read_text() + "\n[effects.sensor_lag]\ntau_s = 0.35\n")
    for race, dropped in (("normal", True), ("slow_pyrometer", False)):
        path, _ = races[race]
        auto = estimate_session(path, EstimateOptions(h_law=law, smoother=False))
        choice = auto.summary["run"]["online_choice"]
        row = next(r for r in choice["law_effects_tested"] if r["name"] == "without sensor_lag")
        assert row["test"].startswith("one-step predictive likelihood")
        assert bool(row["significant"]) is dropped, (race, row)
        assert ("sensor_lag" in choice["law_effects_dropped"]) is dropped
        assert ("sensor_lag" in auto.summary["run"]["effects"]) is not dropped


@pytest.mark.parametrize("race", ["normal", "low_kz"])
def test_the_guessed_run_gives_the_sequential_answer(races, monkeypatch, race) -> None:
    """The filter for "nothing switched on" starts before the decision (pipelines/
    speculative.py, here on a 4-lap race by lowering the length it needs): used where the
    race decides so, stopped where it switches k_z on — the numbers the sequential path
    gives either way."""
    import brakethermo.pipelines.race_run as race_run

    path, _ = races[race]
    opts = EstimateOptions(smoother=True)
    sequential = estimate_session(path, opts)
    monkeypatch.setattr(race_run, "DECISION_LAPS", 1)
    guessed = estimate_session(path, opts)
    chose = guessed.summary["run"]["online_choice"]["chosen"]
    assert chose == sequential.summary["run"]["online_choice"]["chosen"]
    assert guessed.summary["run"]["timings_s"]["overlapped"] is (not chose)
    assert bool(chose) is (race == "low_kz")
    np.testing.assert_array_equal(guessed.frame.to_numpy(), sequential.frame.to_numpy())
    assert guessed.summary["laps"] == sequential.summary["laps"]


def test_the_decision_hands_over_the_learned_kz_and_the_thin_skin_modes_are_warmed(
        races, monkeypatch) -> None:
    """The k_z variant runs first and hands what it learned over from its own thread the
    moment it ends (the run stops its guess there); on a disc below the law's the
    thin-skin filter's modes are computed then, once: the filter takes them as kept."""
    import threading

    import brakethermo.pipelines.race_filter as race_filter
    import brakethermo.pipelines.race_run as race_run

    seen: list[tuple[float, bool]] = []
    real = race_run._kz_learned

    def spy(*args: object) -> object:
        hook = real(*args)

        def learned(kz: float) -> None:
            seen.append((kz, threading.current_thread() is not threading.main_thread()))
            hook(kz)

        return learned

    computed: list[tuple[int, bool]] = []
    real_modes = race_filter.open_loop_modes

    def modes(model: object, *args: object) -> object:
        computed.append((model.n_state, threading.current_thread() is threading.main_thread()))
        return real_modes(model, *args)

    monkeypatch.setattr(race_run, "_kz_learned", spy)
    monkeypatch.setattr(race_filter, "open_loop_modes", modes)
    race_filter.forget_modes()
    path, _ = races["low_kz"]
    run = estimate_session(path, EstimateOptions(smoother=False)).summary["run"]
    row = next(r for r in run["online_choice"]["scores"] if r["name"] == "thickness_gradient")
    assert seen == [(row["learned"], True)]
    thin = run["nodes"] * run["layers"]
    # once, and during the decision on its k_z variant's thread, not after it on the main
    assert thin == 90 and [main for n, main in computed if n == thin] == [False]


def _earned_trial(monkeypatch: pytest.MonkeyPatch, written: float, without: float,
                  with_kz: float | None = None):
    """A decision's trial and runs whose lap-ahead predictions miss the readings by the
    given noise levels (°C): the law as written, without its μ(T), and (``with_kz``) each
    with k_z online."""
    from types import SimpleNamespace

    from brakethermo.diagnosis.verdict import VerdictRule

    rng = np.random.default_rng(5)
    lap = np.repeat(np.arange(1, 5), 400)
    cycles = np.arange(lap.size) // 80
    y = 300.0 + 100.0 * np.sin(np.arange(lap.size) / 30.0)
    monkeypatch.setattr(online_choice, "_lap_ahead", lambda run, lap, laps: run.pred)

    def run(sd: float) -> SimpleNamespace:
        pred = y + rng.normal(0.0, sd, y.size)
        frame = pd.DataFrame({s: pred for s in ("spot1", "spot2", "spot3", "spot4")})
        return SimpleNamespace(pred=pred, y_measured=y, frame=frame)

    bare = f"without {online_choice.EARNED}"
    runs = {"reference": run(written), bare: run(without)}
    if with_kz is not None:
        runs["thickness_gradient"] = run(written)
        runs[f"{bare} + thickness_gradient"] = run(with_kz)
    trial = SimpleNamespace(joint=None, later=(online_choice.EARNED,), lap=lap, cycles=cycles,
                            rule=VerdictRule(min_shrink_pct=online_choice.MIN_SHRINK_PCT))
    return trial, runs


@pytest.mark.parametrize(("written", "without", "dropped"),
                         [(2.0, 6.0, False), (6.0, 2.0, True), (4.0, 4.05, True)])
def test_the_laws_mu_t_is_kept_only_where_the_race_earns_it(monkeypatch, written, without,
                                                            dropped) -> None:
    """The burden is on the law's μ(T): kept where the law as written predicts the laps a
    lap ahead clearly better than without it, dropped where it does worse and where the
    two are alike (the data cannot tell: on development races keeping it cost the contact
    band); the row is the law with it against without it, and the page says so."""
    from brakethermo.report.lap_report import _decisions

    trial, runs = _earned_trial(monkeypatch, written, without)
    (row,) = online_choice._later_tests(trial, runs, None, [])
    assert row["name"] == f"without {online_choice.EARNED}" and row["must_earn"]
    assert row["significant"] is dropped
    assert (row["shrink_ci95_pct"][0] > online_choice.MIN_SHRINK_PCT) is not dropped
    assert row["test"].startswith("kept only where the race earns it")
    summary = {"run": {"online_choice": {
        "law_effects_tested": [row],
        "law_effects_dropped": [online_choice.EARNED] if dropped else []}}}
    (line,) = _decisions(summary)
    assert ("dropped" if dropped else "kept") in line and "error with it" in line


@pytest.mark.parametrize(
    ("written", "without", "with_kz", "allowed", "kept", "kz_on"),
    [(6.0, 4.0, 2.0, True, False, True),    # k_z wins on the bare law: on, μ(T) out
     (6.0, 4.0, 4.0, True, False, False),   # nothing beats the bare law
     (6.0, 4.0, 2.0, False, False, False),  # k_z would win but is like the law's
     (2.0, 6.0, 6.0, True, True, False)])   # μ(T) earns it; k_z adds nothing beside it
def test_the_joint_test_judges_each_factor_against_its_counterpart(
        monkeypatch, written, without, with_kz, allowed, kept, kz_on) -> None:
    """k_z and the law's μ(T) as a 2 x 2 against the law without μ(T): each factor must
    beat its own counterpart at the other's final level — μ(T) is kept only where the law
    with it beats without it with k_z as it will run, k_z goes on only where it beats k_z
    off on the law the race will use; the rows say which pair they compare."""
    trial, runs = _earned_trial(monkeypatch, written, without, with_kz=with_kz)
    j = online_choice._joint_test(runs, "thickness_gradient", online_choice.EARNED,
                                  trial.lap, trial.cycles, trial.rule, allowed)
    assert (j.kept, j.kz_on) == (kept, kz_on)
    assert j.gated is (not allowed)
    assert j.effect_row["significant"] is kept
    assert "k_z online in both" not in j.effect_row["test"] or kz_on
    assert j.kz_row["test"].startswith("k_z online against off, on the law "
                                       + ("as written" if kept else "without"))
    bare = f"without {online_choice.EARNED}"
    assert {c["name"] for c in j.combos} == {"reference", "thickness_gradient",
                                            f"{bare} + thickness_gradient"}
    # "reference" read as the law without its parts: each combination says what it is
    variant = {c["name"]: c["variant"] for c in j.combos}
    assert variant["reference"] == "the law as written, with its friction_temperature; k_z off"
    assert variant[f"{bare} + thickness_gradient"] == ("the law without its"
                                                       " friction_temperature; k_z online")


def test_the_guess_run_assumes_mu_t_unearned_and_equals_the_decided_run(tmp_path,
                                                                        monkeypatch) -> None:
    """A race longer than the decision's laps starts the filter on the likeliest outcome
    before the decision ends — no online state, the law's μ(T) unearned — and where the
    race decides so, that run is the result, equal to the run made after the decision."""
    from brakethermo.pipelines import race_run

    shipped = Path(__file__).parents[1] / "configs" / "hlaw" / "cc-340-8.toml"
    law = tmp_path / "law.toml"
    law.write_text(shipped.read_text()
                   + "\n[effects.friction_temperature]\nbeta = 0.45\nt_mid = 380.0\n")
    path, _ = write_simulation(simulate(SimConfig(
        laps=online_choice.DECISION_LAPS + 1, sensor="single", seed=SEED + 7)),
        tmp_path / "long.parquet")
    opts = EstimateOptions(h_law=law, smoother=False)
    monkeypatch.setattr(race_run.os, "cpu_count", lambda: 2)
    guessed = estimate_session(path, opts)
    assert guessed.summary["run"]["online_choice"]["law_effects_dropped"] == [
        online_choice.EARNED]
    assert guessed.summary["run"]["timings_s"]["overlapped"] is True
    monkeypatch.setattr(race_run.os, "cpu_count", lambda: 1)
    after = estimate_session(path, opts)
    assert after.summary["run"]["timings_s"]["overlapped"] is False
    np.testing.assert_allclose(guessed.frame["contact_avg"], after.frame["contact_avg"],
                               rtol=0, atol=1e-9)


def test_law_as_written_keeps_the_laws_mu_t(races, tmp_path) -> None:
    """``estimate --law-as-written``: a user who knows the race's pads share the test
    session's μ(T) keeps it, and nothing is decided; by default the race, which does not
    earn it, drops it."""
    import json

    from typer.testing import CliRunner

    from brakethermo.cli import app

    shipped = Path(__file__).parents[1] / "configs" / "hlaw" / "cc-340-8.toml"
    law = tmp_path / "law.toml"
    law.write_text(shipped.read_text()
                   + "\n[effects.friction_temperature]\nbeta = 0.2\nt_mid = 380.0\n")
    path, _ = races["normal"]
    runs = {}
    for flag in ("--race-decides", "--law-as-written"):
        r = CliRunner().invoke(app, ["estimate", str(path), "--h-law", str(law), "--out",
                                     str(tmp_path / flag), "--no-reports", "--no-smoother",
                                     "--json", flag])
        assert r.exit_code == 0, r.output
        runs[flag] = json.loads(r.stdout)["run"]
    assert "friction_temperature" not in runs["--race-decides"]["effects"]
    assert runs["--race-decides"]["online_choice"]["law_effects_dropped"] == [
        "friction_temperature"]
    assert "friction_temperature" in runs["--law-as-written"]["effects"]
    assert runs["--law-as-written"]["online_choice"]["rule"].startswith(
        "not decided (--law-as-written)")


@pytest.mark.parametrize(("hetero", "kept"), [("without friction_temperature + "
                                               "thickness_gradient", True),
                                              ("reference", False)])
def test_the_joint_test_leaves_kz_off_where_no_configuration_is_consistent(
        monkeypatch, hetero, kept) -> None:
    """Where k_z helps at one μ(T) level only (one of the four runs is better on average
    but not on every braking cycle), no configuration has each factor beating its
    counterpart at the other's level: k_z stays off and μ(T) is judged as the race then
    runs, k_z off (its row saying k_z was left off where it cleared the rule there)."""
    from types import SimpleNamespace

    from brakethermo.diagnosis.verdict import VerdictRule

    rng = np.random.default_rng(9)
    lap = np.repeat(np.arange(1, 5), 400)
    cycles = np.arange(lap.size) // 80
    y = 300.0 + 100.0 * np.sin(np.arange(lap.size) / 30.0)
    monkeypatch.setattr(online_choice, "_lap_ahead", lambda run, lap, laps: run.pred)
    bare = f"without {online_choice.EARNED}"
    var = {bare: 1.0, "reference": 0.7, "thickness_gradient": 0.49,
           f"{bare} + thickness_gradient": 0.7}
    if hetero == "reference":
        var["thickness_gradient"] = 0.49
    # the heterogeneous run: mean variance as listed, but 0.05 and 1.35 cycle by cycle
    spread = np.where(cycles % 2 == 0, 0.05, 1.35) / 0.7
    runs = {n: SimpleNamespace(pred=y + rng.normal(0.0, 1.0, y.size) * 4.0 * np.sqrt(
        v * (spread if n == hetero else 1.0)), y_measured=y) for n, v in var.items()}
    rule = VerdictRule(min_shrink_pct=online_choice.MIN_SHRINK_PCT)
    j = online_choice._joint_test(runs, "thickness_gradient", online_choice.EARNED, lap,
                                  cycles, rule)
    assert (j.kept, j.kz_on, j.gated) == (kept, False, False)
    assert "k_z online in both" not in j.effect_row["test"]
    if j.kz_row["significant"]:
        assert "left off" in j.kz_row["test"]


def test_a_race_too_short_to_decide_drops_the_unearned_mu_t_and_says_so(tmp_path) -> None:
    """One flying lap: nothing can be decided, the law's μ(T) (which a race must earn) is
    left out, and the page says it was not tested."""
    from brakethermo.report.lap_report import _decisions

    shipped = Path(__file__).parents[1] / "configs" / "hlaw" / "cc-340-8.toml"
    law = tmp_path / "law.toml"
    law.write_text(shipped.read_text()
                   + "\n[effects.friction_temperature]\nbeta = 0.2\nt_mid = 380.0\n")
    path, _ = write_simulation(simulate(SimConfig(laps=1, sensor="single", seed=SEED + 3)),
                               tmp_path / "short.parquet")
    res = estimate_session(path, EstimateOptions(h_law=law, smoother=False))
    choice = res.summary["run"]["online_choice"]
    assert choice["law_effects_dropped"] == [online_choice.EARNED]
    assert "friction_temperature" not in res.summary["run"]["effects"]
    (line,) = [s for s in _decisions(res.summary) if s.startswith("the h law's")]
    assert "dropped" in line and "not tested: fewer than two flying laps" in line
    assert "nan" not in line
    (row,) = choice["law_effects_tested"]
    assert row["outcome"] == "dropped" and row["meaning"].startswith("not tested")


@pytest.mark.parametrize(("written", "without", "outcome"),
                         [(6.0, 2.0, "dropped"), (2.0, 6.0, "kept")])
def test_each_law_effect_row_says_its_outcome_and_its_signs_meaning(
        monkeypatch, written, without, outcome) -> None:
    """The earned row is named "without friction_temperature" but compares the law with
    it against without it: -9 % read as "removing μ(T) makes the error 9 % worse" where
    the law's μ(T) had raised it and was dropped. Each row says what it decided and what
    the sign of its figure means; the crown's and the lag's compare the other way."""
    trial, runs = _earned_trial(monkeypatch, written, without)
    (row,) = online_choice._later_tests(trial, runs, None, [])
    dropped = (online_choice.EARNED,) if row["significant"] else ()
    said = online_choice._read_out(row, dropped)
    assert said["outcome"] == outcome and (row["shrink_pct"] < 0) is (outcome == "dropped")
    assert said["meaning"].startswith("shrink_pct: how much the lap-ahead error shrinks with"
                                      " the law's friction_temperature kept against dropped")
    assert {k: said[k] for k in row} == row  # extended, nothing renamed
    crown = online_choice._read_out({"name": f"without {online_choice.CROWN}",
                                     "shrink_pct": 12.0, "significant": True},
                                    (online_choice.CROWN,))
    assert crown["outcome"] == "dropped" and "instead of the law's" in crown["meaning"]
    lag = online_choice._read_out({"name": "without sensor_lag", "shrink_pct": 1.0,
                                   "significant": False}, ())
    assert lag["outcome"] == "kept" and "with the law's sensor_lag dropped" in lag["meaning"]


def test_a_law_part_dropped_or_kept_against_the_spot_is_said_with_its_evidence() -> None:
    """What the race does with the law's parts is said with the shrink and interval it
    measured, how far the unmeasured spots move and how to keep the law; a part kept where
    the measured spot agreed is not said. (A race dropped a law's crown of 0.64, 1.07,
    1.22 on spot 3 alone and the console said nothing: spots 1, 2, 4 ended 26-43 °C off.)"""
    from brakethermo.pipelines.law_drops import said

    crown = {"name": "without crown_weights", "shrink_pct": 16.6,
             "shrink_ci95_pct": [13.8, 19.4], "law": [0.64, 1.07, 1.22],
             "test": "uniform weights against the law's, a lap ahead",
             "peaks_apart_c": {"spot1": -30.0, "spot2": -68.0, "spot3": 1.0, "spot4": 53.0}}
    line = said(crown, True, 3)
    assert line.startswith("the race dropped the h law's pad-crown weights w = 0.64, 1.07,")
    assert "error was -17 % (95 % -19 to -14 %)" in line
    assert "spot 1 -30 °C, spot 2 -68 °C, spot 4 +53 °C" in line and "spot 3 +1" not in line
    assert "inner/outer split" in line and "`estimate --law-as-written`" in line
    # kept though spot 3 leaned to uniform: said; kept where spot 3 agreed: not
    assert said({**crown, "shrink_pct": 3.0, "shrink_ci95_pct": [-1.0, 7.0]}, False,
                3).startswith("the race kept")
    assert said({**crown, "shrink_pct": -3.0}, False, 3) is None
    # the μ(T) row compares the other way (with it against without); untested: said so
    mu = {"name": "without friction_temperature", "must_earn": True, "shrink_pct": -9.0,
          "shrink_ci95_pct": [-12.0, -6.0], "test": "kept only where the race earns it"}
    # μ(T) raised the error 9 %: without it, 9 % less (as the crown's, the drop's side)
    assert "without it spot 3's error was -9 % (95 % -12 to -6 %)" in said(mu, True, 3)
    untested = said({**mu, "shrink_pct": None, "shrink_ci95_pct": [None, None]}, True, 3)
    assert "untested: fewer than two flying laps" in untested


def test_decision_lines_read_a_summary_that_has_been_through_json() -> None:
    """batch renders the page from summary.json, where a missing interval (fewer than two
    units) or a test not run is null: the lines say so instead of failing."""
    from brakethermo.report.lap_report import _decisions

    summary = json.loads(json.dumps({"run": {"online_choice": {
        "chosen": [], "law_effects_dropped": ["friction_temperature"],
        "scores": [{"name": "slipstream", "test": "one-step innovations", "shrink_pct": 12.0,
                    "shrink_ci95_pct": [None, None]}],
        "law_effects_tested": [{"name": "without friction_temperature", "must_earn": True,
                                "test": "not tested: fewer than two flying laps",
                                "shrink_pct": None, "shrink_ci95_pct": [None, None]}]}}}))
    online, law = _decisions(summary)
    assert "left off" in online and "no interval: fewer than two units" in online
    assert "dropped" in law and "not tested" in law and "nan" not in law


def test_an_h_factor_left_off_alone_is_judged_again_on_top_of_kz(tmp_path) -> None:
    """A low-k_z disc that also cools 40 % less than the law says: alone, the online h
    factor tries to stand in for the k_z change and loses (-4 %); on top of k_z it
    corrects the law (an independent generator's low-k_z races: 0.78x the single-spot
    baseline with the h factor left off, 0.24x with it)."""
    path, truth_path = write_simulation(simulate(SimConfig(
        laps=4, sensor="single", seed=4711, effects={"thickness_gradient": 1.0},
        cooling=0.6)), tmp_path / "low_kz_warm.parquet")
    auto = estimate_session(path, EstimateOptions(smoother=False))
    choice = auto.summary["run"]["online_choice"]
    assert choice["chosen"] == ["thickness_gradient", "slipstream"], choice["scores"]
    row = next(r for r in choice["scores"] if r["name"] == "slipstream")
    top = row["on_top"]
    assert top["of"] == ["thickness_gradient"] and top["significant"]
    assert top["shrink_ci95_pct"][0] > 5.0 and row["shrink_pct"] < 0.0  # the test alone
    kz_only = estimate_session(path, EstimateOptions(smoother=False, adapt_kz=True,
                                                     adapt_slipstream=False))
    truth = read_truth(truth_path)
    assert _contact_rmse(auto.frame, truth) < _contact_rmse(kz_only.frame, truth)


def test_a_law_that_carries_kz_still_gives_a_thinner_race_disc_its_thin_skin(races, tmp_path
                                                                            ) -> None:
    """identify-h found the test disc's k_z: the law carries it, online in every race and so
    not a candidate; a race disc well below it still gets the thin-skin mesh (and chooses
    its crown noise there), one like it does not."""
    import re

    shipped = Path(__file__).parents[1] / "configs" / "hlaw" / "cc-340-8.toml"
    text = shipped.read_text()
    kz = float(re.search(r"^kz_ratio = (.*)$", text, re.M).group(1))
    law = tmp_path / "carries_kz.toml"
    law.write_text(text + f"\n[effects.thickness_gradient]\nkz_factor = {kz!r}\n")
    low = estimate_session(races["low_kz"][0], EstimateOptions(h_law=law, smoother=False))
    choice = low.summary["run"]["online_choice"]
    assert "thickness_gradient" not in [r["name"] for r in choice["scores"]]
    assert choice["law_kz_learned"] < online_choice.KZ_LIKE_LAW[0]
    assert f"came out {choice['law_kz_learned']:.2f} of the law's" in choice["layering"]
    assert low.summary["run"]["nodes"] * low.summary["run"]["layers"] == 90
    assert "crown_noise" not in choice  # 4 laps: too short to choose it
    normal = estimate_session(races["normal"][0], EstimateOptions(h_law=law, smoother=False))
    choice = normal.summary["run"]["online_choice"]
    assert online_choice.KZ_LIKE_LAW[0] <= choice["law_kz_learned"] <= online_choice.KZ_LIKE_LAW[1]
    assert "layering" not in choice and "crown_noise" not in choice


@pytest.mark.parametrize(("law_kz", "uniform_kz", "learned", "dropped"), [
    (6.0, 2.0, 0.45, True),    # uniform + k_z far better, at a k_z the race may switch on
    (6.0, 2.0, 0.9, False),    # ... but at a k_z like the law's: the race would leave it off
    (2.0, 2.2, 0.45, False),   # the law's crown with k_z online is as good
])
def test_an_uneven_crown_lost_with_kz_off_is_judged_again_with_kz_online(
        monkeypatch, law_kz, uniform_kz, learned, dropped) -> None:
    """A race disc of lower k_z on other pads: with the law's k_z the uniform crown
    predicts the measured spot worse, with k_z online in both far better; dropped then,
    and k_z goes on with it (the configuration tested)."""
    from types import SimpleNamespace

    from brakethermo.diagnosis.verdict import VerdictRule

    rng = np.random.default_rng(7)
    lap = np.repeat(np.arange(1, 5), 400)
    y = 300.0 + 100.0 * np.sin(np.arange(lap.size) / 30.0)
    monkeypatch.setattr(online_choice, "_lap_ahead", lambda run, lap, laps: run.pred)
    monkeypatch.setattr(online_choice, "_learned", lambda run, param, lap: learned)

    def run(sd: float) -> SimpleNamespace:
        return SimpleNamespace(pred=y + rng.normal(0.0, sd, y.size), y_measured=y)

    runs = {"reference": run(6.0), online_choice.JOINT: run(law_kz),
            online_choice.CROWN_KZ: run(uniform_kz)}
    trial = SimpleNamespace(lap=lap, cycles=np.arange(lap.size) // 80,
                            rule=VerdictRule(min_shrink_pct=online_choice.MIN_SHRINK_PCT))
    row = {"shrink_pct": -100.0, "shrink_ci95_pct": [-120.0, -90.0], "significant": False,
           "test": "uniform weights against the law's, a lap ahead"}
    out = online_choice._crown_with_kz(trial, runs, row)
    assert out["significant"] is dropped and out["with_kz"]["significant"] is dropped
    assert out["with_kz"]["kz_learned"] == learned
    if dropped:
        assert out["test"].startswith("uniform weights against the law's with k_z online")
        assert "with k_z off: -100 %" in out["test"]
        rows = [{"name": online_choice.JOINT, "significant": False}]
        online_choice._on_with_uniform_crown(rows)
        assert rows[0]["significant"] and "uniform crown" in rows[0]["with_uniform_crown"]
    else:
        assert out["shrink_pct"] == -100.0  # the row as tested with k_z off


def test_a_kz_forced_by_the_uniform_crown_has_the_laws_mu_t_judged_at_kz_online(
        monkeypatch) -> None:
    """k_z that goes on with a dropped crown (whatever its own test): the law's μ(T) is
    judged with k_z online in both, the level the race runs, not with k_z off."""
    trial, runs = _earned_trial(monkeypatch, 4.0, 4.0, with_kz=4.0)
    j = online_choice._joint_test(runs, "thickness_gradient", online_choice.EARNED,
                                  trial.lap, trial.cycles, trial.rule, False, forced=True)
    assert j.kz_on and not j.gated
    assert "k_z online in both" in j.effect_row["test"]
    free = online_choice._joint_test(runs, "thickness_gradient", online_choice.EARNED,
                                     trial.lap, trial.cycles, trial.rule, False)
    assert not free.kz_on and "k_z online in both" not in free.effect_row["test"]
