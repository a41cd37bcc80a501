"""diagnose on an E-Booster session: the training p-V curve against this session's
pressures, candidates fitted on some apply cycles and scored on the others."""

from __future__ import annotations

import json
from pathlib import Path

import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from brakethermo.cli import app
from brakethermo.errors import DataError
from brakethermo.pipelines.diagnose.rig import diagnose_booster
from brakethermo.sim.ebooster import (
    PRODUCTION_CHANNELS,
    EboosterSimConfig,
    simulate_ebooster,
    write_ebooster_session,
)

runner = CliRunner()


def _session(tmp_path: Path, shift: float, channels=None) -> Path:
    sim = simulate_ebooster(EboosterSimConfig("vehicle", seed=77, rate_hz=500.0,
                                              duration_s=30.0, pv_shift_mm=shift))
    kw = {} if channels is None else {"channels": channels}
    return write_ebooster_session(sim, tmp_path / f"eb_{shift}.mcap", **kw)[0]


def test_a_moved_pv_curve_is_named_and_sized(tmp_path):
    s = diagnose_booster(_session(tmp_path, 0.35)).summary
    assert s["verdict_set"][0] == "pv_shift" and s["verdict_kind"] in ("single", "set")
    shift = next(e for e in s["effects"] if e["name"] == "pv_shift")
    assert shift["params"]["shift_mm"] == pytest.approx(0.35, abs=0.1)
    assert shift["shrink_ci95_pct"][0] > 30.0
    assert s["gap"]["bias"] > 0.05  # the training curve reads high on a longer dead stroke
    assert any("--train" in step for step in s["next_steps"])


def test_the_observer_carries_the_shift_to_a_session_without_the_sensor(tmp_path):
    """ebooster --with-effect DIAGNOSIS.json: the shift the day's bench session showed,
    carried to a session of that day whose pressures the observer never reads."""
    from brakethermo.pipelines.ebooster import observe

    day = diagnose_booster(_session(tmp_path, 0.35)).summary
    (tmp_path / "diagnosis.json").write_text(json.dumps(day))
    other = write_ebooster_session(simulate_ebooster(EboosterSimConfig(
        "vehicle", seed=78, rate_hz=500.0, duration_s=30.0, pv_shift_mm=0.35)),
        tmp_path / "other.mcap")[0]
    plain = observe(other, with_effect="none").summary
    carried = observe(other, with_effect=str(tmp_path / "diagnosis.json")).summary
    assert carried["with_effect"]["effects"] == {
        "pv_shift": next(e["params"] for e in day["effects"] if e["name"] == "pv_shift")}
    rm = [r["pressure_rmse_mpa"]["ukf"]["p_m"] for r in (plain, carried)]
    assert rm[1] < 0.6 * rm[0], rm
    assert carried["coverage_95"]["ukf"] > 0.9
    r = runner.invoke(app, ["ebooster", str(other), "--with-effect", "pv_drift=0.1"])
    assert r.exit_code == 1 and "NAME=VALUE" in r.output and "Traceback" not in r.output
    r = runner.invoke(app, ["ebooster", str(other), "--with-effect", "pv_shift=9"])
    assert r.exit_code == 1 and "outside the range" in r.output, r.output
    production = _session(tmp_path, 0.35, channels=PRODUCTION_CHANNELS)
    r = runner.invoke(app, ["ebooster", str(production), "--with-effect", "auto"])
    assert r.exit_code == 1 and "--with-effect auto" in r.output and "diagnosis.json" in r.output


def test_a_booster_like_its_training_day_gets_none(tmp_path):
    s = diagnose_booster(_session(tmp_path, 0.0)).summary
    assert s["verdict"] == "none" and s["verdict_set"] == []
    # what the candidates would correct is below a pressure sensor's accuracy: said, not named
    assert set(s["negligible"]) >= {"pv_shift", "hysteresis"}
    assert all(e["correction_rms"] < s["negligible_below"] for e in s["effects"])
    # a gap under the floor is no unexplained one: nothing to check on a clean session
    assert not any("none of the candidates" in step for step in s["next_steps"])


def test_a_floor_is_no_knife_edge():
    from brakethermo.pipelines.diagnose.rig import TIE_SHARE, negligible_cut

    assert negligible_cut({"a": 0.20, "b": 0.30}, 0.344) == 0.344  # none passes: the floor
    cut = negligible_cut({"a": 0.3443, "b": 0.325}, 0.3441)  # one passes: the near one too
    assert cut == pytest.approx(TIE_SHARE * 0.3441) and 0.325 >= cut


def test_several_booster_sessions_are_pooled_as_the_contract_says(tmp_path):
    """OUTPUTS.md: diagnose S1 S2 writes each session's folder and DIR/pooled/diagnosis.json;
    a rig session gets the same files (it was refused: 'one session at a time')."""
    shifted = _session(tmp_path, 0.35)
    clean = _session(tmp_path, 0.0)
    out = tmp_path / "pool"
    r = runner.invoke(app, ["diagnose", str(shifted), str(clean), "--out", str(out),
                            "--json"])
    assert r.exit_code == 0, r.output
    pooled = json.loads(r.output)
    assert pooled["output"] == str(out / "pooled" / "diagnosis.json")
    assert (out / shifted.stem / "diagnosis.json").is_file()
    assert (out / clean.stem / "diagnosis.json").is_file()
    assert pooled["rig"] == "ebooster" and len(pooled["sessions"]) == 2
    assert "pv_shift" in pooled["verdict_set"]
    row = next(e for e in pooled["effects"] if e["name"] == "pv_shift")
    assert row["significant_in"] == [shifted.stem]  # seen in one run only, and said
    assert any("pv_shift is significant in" in n for n in pooled["notes"])
    assert set(pooled["per_session"]) == {shifted.stem, clean.stem}
    # the pooled result has a page beside its JSON, linking each session's (it had none)
    html = (out / "pooled" / "index.html").read_text()
    for stem in (shifted.stem, clean.stem):
        assert f'href="../{stem}/diagnosis/index.html"' in html
        assert (out / stem / "diagnosis" / "index.html").is_file()
    assert "pv_shift" in html
    # its carry command names the diagnosis of the run that shows the effect
    carry = next(step for step in pooled["next_steps"] if "--with-effect" in step)
    assert f"{out}/{shifted.stem}/diagnosis.json" in carry and "DIR/" not in carry
    # ... whichever session comes first: the clean one named first used to be the one the
    # carry command (and its --train advice) named
    r = runner.invoke(app, ["diagnose", str(clean), str(shifted), "--out",
                            str(tmp_path / "pool2"), "--json"])
    assert r.exit_code == 0, r.output
    carry = next(step for step in json.loads(r.output)["next_steps"] if "--with-effect" in step)
    assert shifted.name in carry and clean.name not in carry, carry
    # sessions of two rigs in one call: one line, nothing written
    from brakethermo.sim.emb import simulate_emb, write_emb_simulation

    caliper = write_emb_simulation(simulate_emb("nominal", seed=3, duration_s=8),
                                   tmp_path / "c.parquet")[0]
    r = runner.invoke(app, ["diagnose", str(shifted), str(caliper), "--out",
                            str(tmp_path / "mixed")])
    assert r.exit_code == 1 and "one rig" in r.output and "Traceback" not in r.output
    said = " ".join(r.output.split())  # the kinds' words: it read "a emb session of the"
    assert "an EMB caliper rig session, while the others are of an E-Booster rig" in said
    assert not (tmp_path / "mixed" / shifted.stem).exists()


def test_the_cli_finds_the_rig_and_keeps_the_rig_commands_results(tmp_path):
    path = _session(tmp_path, 0.35)
    out = tmp_path / "out"
    r = runner.invoke(app, ["diagnose", str(path), "--out", str(out)])
    assert r.exit_code == 0, r.output
    folder = out / path.stem
    assert (folder / "diagnosis" / "index.html").is_file()
    # the diagnosis page's back link lands on a small index naming the rig's command
    assert 'href="../index.html"' in (folder / "diagnosis" / "index.html").read_text()
    small = (folder / "index.html").read_text()
    assert "brakethermo ebooster" in small and 'href="diagnosis/index.html"' in small
    r = runner.invoke(app, ["ebooster", str(path), "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert json.loads((folder / "diagnosis.json").read_text())["rig"] == "ebooster"
    assert (folder / "diagnosis.parquet").is_file() and (folder / "ebooster.parquet").is_file()
    page = (folder / "index.html").read_text()  # the booster's page, linking the diagnosis
    assert "E-Booster observation" in page and 'href="diagnosis/index.html"' in page
    assert "from the rig" in page and "from the disc" not in page


def test_options_a_rig_session_would_ignore_are_refused(tmp_path):
    """diagnose took a disc's --h-law or --holdout-laps, and --fit beside --train, on a
    rig session without a word, as if they had been used."""
    path = _session(tmp_path, 0.0)
    for extra, words in ((["--holdout-laps", "2"], "--holdout-laps: options of a disc"),
                         (["--h-law", "x.toml"], "--h-law: options of a disc"),
                         (["--train", str(path), "--fit", "f.toml"], "give one of the two")):
        r = runner.invoke(app, ["diagnose", str(path), *extra, "--out", str(tmp_path / "o")])
        assert r.exit_code == 1 and words in r.output.replace("\n", " "), r.output
    r = runner.invoke(app, ["ebooster", str(path), "--train", str(path), "--fit", "f.toml",
                            "--out", str(tmp_path / "o")])
    assert r.exit_code == 1 and "not both" in r.output.replace("\n", " ")


def test_a_production_session_is_refused_in_one_line(tmp_path):
    path = _session(tmp_path, 0.0, channels=PRODUCTION_CHANNELS)
    with pytest.raises(DataError, match="master-cylinder pressure"):
        diagnose_booster(path)
    r = runner.invoke(app, ["diagnose", str(path), "--out", str(tmp_path / "o")])
    assert r.exit_code == 1 and "master-cylinder pressure" in r.output
    assert "Traceback" not in r.output
    r = runner.invoke(app, ["diagnose", str(path), "--rig", "bogus", "--out", str(tmp_path)])
    assert r.exit_code == 2 and "ebooster" in r.output and "tyre" in r.output


@pytest.fixture(scope="module")
def caliper(tmp_path_factory):
    from brakethermo.sim.emb import simulate_emb, write_emb_simulation

    d = tmp_path_factory.mktemp("emb")
    tr = write_emb_simulation(simulate_emb("nominal", seed=7101, duration_s=40), d / "tr.mcap")
    runs = {name: write_emb_simulation(simulate_emb(name, seed=seed, duration_s=40),
                                       d / f"{name}.mcap")[0]
            for name, seed in (("nominal", 7102), ("worn", 7103), ("heating", 7104))}
    return tr[0], runs


@pytest.mark.parametrize("pads, verdict", [("nominal", "none"), ("worn", "gap_shift"),
                                           ("heating", "stiffness_drift")])
def test_the_caliper_diagnosis_names_what_the_pads_did(caliper, pads, verdict):
    """Worn pads move the contact angle (the stiffness curve shifts), heating pads soften
    through the session (the scale drifts); the trained pads are 'none'."""
    from brakethermo.pipelines.diagnose.rig import diagnose_emb

    train_path, runs = caliper
    s = diagnose_emb(runs[pads], train_path=train_path).summary
    assert s["verdict"] == verdict and s["verdict_kind"] in ("single", "none")
    assert s["rig"] == "emb" and s["unit"] == "kN"
    # OUTPUTS.md's diagnose keys: held-out units as laps, consistency a mean NIS with its
    # χ² band (it was only a sentence, and train_laps/heldout_laps were missing)
    assert s["train_laps"] == s["train_units"] and s["heldout_laps"] == s["heldout_units"]
    c = s["consistency"]["per_channel"]["clamp_force"]
    assert c["mean_nis"] > 0 and c["chi2_band"][0] < 1.0 < c["chi2_band"][1] and c["n"] > 0
    assert "mean NIS" in s["consistency"]["summary"]
    assert "no filter runs here" in s["consistency"]["note"]


def test_a_caliper_session_of_a_second_is_estimated_or_refused_in_one_line(caliper,
                                                                           tmp_path):
    """A 1 s session that logs the force sensor: the sensor-lag choice cross-validates on
    2 s blocks and took the max of an empty array (a traceback in both commands)."""
    from brakethermo.sim.emb import simulate_emb, write_emb_simulation

    train_path, _ = caliper
    short = write_emb_simulation(simulate_emb("nominal", seed=7105, duration_s=1),
                                 tmp_path / "short.mcap")[0]
    r = runner.invoke(app, ["clamp-force", str(short), "--train", str(train_path),
                            "--out", str(tmp_path / "o")])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["diagnose", str(short), "--train", str(train_path),
                            "--out", str(tmp_path / "o")])
    assert r.exit_code == 1 and "needs at least 2.5 s" in r.output.replace("\n", " ")
    assert "Traceback" not in r.output


def test_the_cli_finds_the_caliper_and_needs_its_training(caliper, tmp_path):
    train_path, runs = caliper
    r = runner.invoke(app, ["diagnose", str(runs["worn"]), "--out", str(tmp_path)])
    assert r.exit_code == 1 and "--train" in r.output
    r = runner.invoke(app, ["diagnose", str(runs["worn"]), "--train", str(train_path),
                            "--out", str(tmp_path), "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["verdict"] == "gap_shift"


def test_a_tyre_ramp_is_diagnosed_against_the_two_parameter_curve(tmp_path):
    """The simulated tyre is a brush model (sharper, earlier peak than any two-parameter
    curve): found from the channels, Rudd's curve fitted on half of the ramp's blocks,
    the shape named on the other half; a bad --radius is one line."""
    from brakethermo.sim.tyre_rig import simulate_tyre_rig, write_tyre_simulation

    ty = write_tyre_simulation(simulate_tyre_rig(seed=1), tmp_path / "ty.mcap")[0]
    r = runner.invoke(app, ["diagnose", str(ty), "--out", str(tmp_path / "o"), "--json"])
    assert r.exit_code == 0, r.output
    s = json.loads(r.output)
    assert s["rig"] == "tyre" and s["input"]["name"] == "slip"
    assert s["verdict"] == "curve_shape" or "curve_shape" in s["verdict_set"]
    assert s["effects"][0]["shrink_ci95_pct"][0] > 10.0
    assert (tmp_path / "o" / "ty" / "diagnosis" / "index.html").is_file()
    r = runner.invoke(app, ["diagnose", str(ty), "--radius", "nan", "--out", str(tmp_path)])
    assert r.exit_code == 1 and "--radius" in r.output and "Traceback" not in r.output


def test_the_roller_rigs_creep_law_is_diagnosed_against_its_torque_transducer(
        tmp_path, monkeypatch):
    """The simulated rig's contact is strip theory (its slope some 16 % under Kalker's):
    found from the channels, diagnosed against the roller shaft's torque, the creep
    curve's slope named with its size and the datasheet change that carries it."""
    from brakethermo.sim.roller_rig import RollerRigSimConfig, simulate_roller_rig
    from brakethermo.sim.roller_rig import write_roller_rig_simulation as write_rr

    cfg = RollerRigSimConfig(speed_kmh=30, duration_s=120, free_s=20, seed=6, radius_m=0.3416)
    sim = simulate_roller_rig(cfg)
    path = write_rr(sim, tmp_path / "rr.mcap")[0]
    r = runner.invoke(app, ["diagnose", str(path), "--out", str(tmp_path / "o"), "--json"])
    assert r.exit_code == 0, r.output
    s = json.loads(r.output)
    assert s["rig"] == "roller-rig" and s["unit"] == "N" and s["verdict"] == "creep_slope"
    top = s["effects"][0]
    assert top["name"] == "creep_slope" and -0.35 < top["params"]["slope_change"] < -0.05
    assert any("k_a =" in step for step in s["next_steps"])
    assert (tmp_path / "o" / "rr" / "diagnosis" / "index.html").is_file()
    # the rolling-radius filter carries it when given and the radius moves less with the
    # torque under it; from this session's diagnosis, where the slope and a creepage
    # offset stay a set, the verdict (the slope, first of the set) is carried, the set said
    slope = top["params"]["slope_change"]
    import brakethermo.pipelines.diagnose.rig_roller as diag_mod
    import brakethermo.pipelines.roller_rig as rr_mod

    reads: list[str] = []

    def counted(load):
        def wrapper(*args, **kwargs):
            reads.append(str(args[0]))
            return load(*args, **kwargs)
        return wrapper

    for mod in (rr_mod, diag_mod):
        monkeypatch.setattr(mod, "load_session", counted(mod.load_session))
    runs = {}
    for source in ("none", f"creep_slope={slope}", "creep_slope=0.5",
                   str(tmp_path / "o" / "rr" / "diagnosis.json"), "auto"):
        reads.clear()
        r = runner.invoke(app, ["roller-rig", str(path), "--r0", "340", "--with-effect",
                                source, "--out", str(tmp_path / "o"), "--json"])
        assert r.exit_code == 0, r.output
        assert len(reads) == 1, reads  # auto diagnoses the session already read
        runs[source.rsplit("/", 1)[-1]] = json.loads(r.output)
    assert runs["none"]["filter"]["with_effect"] is None
    given = runs[f"creep_slope={slope}"]
    assert given["filter"]["with_effect"]["effects"] == {"creep_slope": top["params"]}
    err = {k: abs(v["naive_vs_ukf"]["ukf_traction_error_mm"]) for k, v in runs.items()}
    assert err[f"creep_slope={slope}"] < 0.6 * err["none"], err
    assert given["filter"]["with_effect"]["kept"] is True
    # a curve that makes the radius move more with the torque is not kept
    wrong = runs["creep_slope=0.5"]["filter"]["with_effect"]
    assert wrong["kept"] is False and "not kept" in wrong["note"]
    assert err["creep_slope=0.5"] == err["none"]
    for key in ("diagnosis.json", "auto"):
        carried = runs[key]["filter"]["with_effect"]
        assert carried["effects"] == {"creep_slope": top["params"]}
        assert carried["kept"] is True and err[key] < 0.6 * err["none"]
        if s["verdict_kind"] == "set":  # the simplest of the set, and the set said
            assert "cannot tell" in carried["note"] and "creep_slope" in carried["note"]
    assert (tmp_path / "o" / "rr" / "diagnosis.json").is_file()  # kept beside the run's
    for bad, words in (("creep_slope=x", "not a number"), ("grip=0.1", "NAME=VALUE"),
                       (str(tmp_path / "nope.json"), "no such file")):
        r = runner.invoke(app, ["roller-rig", str(path), "--with-effect", bad])
        assert r.exit_code == 1 and words in r.output and "Traceback" not in r.output, r.output
    # bad input, one line each: the transducer in kN m labelled N m, no transducer at all
    pq_path = write_rr(sim, tmp_path / "rr.parquet")[0]
    table = pq.read_table(pq_path)
    i = table.schema.get_field_index("roller_torque")
    scaled = table.set_column(i, table.schema.field(i), pc.divide(table.column(i), 1000.0))
    pq.write_table(scaled, tmp_path / "knm.parquet")
    pq.write_table(table.remove_column(i), tmp_path / "none.parquet")
    for name, words in (("knm", "check its unit"), ("none", "no roller torque transducer")):
        r = runner.invoke(app, ["diagnose", str(tmp_path / f"{name}.parquet"), "--out",
                                str(tmp_path / "o")])
        assert r.exit_code == 1 and words in r.output and "roller_torque" in r.output, r.output
        assert "Traceback" not in r.output


def test_a_roller_rig_log_shorter_than_three_averaging_windows_is_refused(tmp_path):
    """A 5 s log, averaged over 4 s windows, named a creep slope 4x the truth's with 89 %
    held-out shrink, and --with-effect auto carried it."""
    from brakethermo.sim.roller_rig import (
        RollerRigSimConfig,
        simulate_roller_rig,
        write_roller_rig_simulation,
    )

    sim = simulate_roller_rig(RollerRigSimConfig(speed_kmh=30, duration_s=5, free_s=1,
                                                 seed=15))
    path = write_roller_rig_simulation(sim, tmp_path / "short.mcap")[0]
    r = runner.invoke(app, ["diagnose", str(path), "--out", str(tmp_path / "o")])
    assert r.exit_code == 1 and "needs at least 12 s" in r.output.replace("\n", " ")
    assert "Traceback" not in r.output


def test_a_gap_no_candidate_explains_is_said_and_bound_fits_are_flagged():
    """A session the reference misses by a pattern none of the candidates has (a
    once-per-second ripple unrelated to the input): 'none' says that the gap is
    unexplained; a fit that ends on a bound of its range is flagged, not named."""
    from types import SimpleNamespace

    import numpy as np

    from brakethermo.models.rig_effects import ROLLER_EFFECTS, RigContext
    from brakethermo.pipelines.diagnose.rig import RigCase, at_bound_words, run_case

    t = np.arange(0.0, 60.0, 0.01)
    x = 0.002 * (1.0 + np.sin(2 * np.pi * t / 4.0))  # 15 creep episodes off rest
    curve = lambda xi: 4e5 * xi  # noqa: E731 - the reference, N
    y = curve(x) + 300.0 * np.sin(2 * np.pi * t * 1.1)
    session = SimpleNamespace(path=Path("ripple.parquet"), time=t, warnings=[])
    case = RigCase("roller-rig", session, dict(ROLLER_EFFECTS),
                   RigContext(x, np.gradient(x, t), t, curve), y, rest=1e-4, floor=25.0,
                   unit="N", input_name="creepage", input_unit="-", reference_text="linear",
                   reference_fit={}, next_step=lambda n, fit: "", cycle="creep episode",
                   phases=("creep rising", "creep falling", "creep steady"))
    s = run_case(case, 0.0).summary
    assert s["verdict"] == "none" and s["units"] == "creep episode"
    assert set(s["gap"]["per_phase"]) == {"creep rising", "creep falling", "creep steady"}
    assert any("none of the candidates" in step and "x the sensor floor" in step
               for step in s["next_steps"]), s["next_steps"]
    slope = ROLLER_EFFECTS["creep_slope"]
    assert "upper edge" in at_bound_words(slope, {"slope_change": 2.0})
    assert "lower edge" in at_bound_words(slope, {"slope_change": -0.8 + 1e-12})
    assert at_bound_words(slope, {"slope_change": 0.3}) == ""
    from brakethermo.models.rig_effects import TYRE_EFFECTS

    lag = TYRE_EFFECTS["relaxation"]  # its bound of 0 is the effect's absence, no edge
    (name,) = lag.params
    assert lag.lower[0] == 0.0 and at_bound_words(lag, {name: 0.0}) == ""
    assert "upper edge" in at_bound_words(lag, {name: lag.upper[0]})


def test_two_clean_booster_sessions_pool_to_none_with_every_row_complete(tmp_path):
    from brakethermo.pipelines.diagnose.rig_pooled import pool_rig

    clean = diagnose_booster(_session(tmp_path, 0.0))
    s = pool_rig([clean, clean])
    assert s["verdict"] == "none" and s["notes"] == []
    for row in s["effects"]:  # under the floor in both: said, with the keys of any row
        assert row["negligible"] and not row["significant"]
        assert {"shrink_pct", "shrink_ci95_pct", "rank", "rmse_before", "rmse_after"} <= set(row)


def test_an_interval_not_drawn_shows_as_a_dash_not_nan():
    """Fewer than two held-out units draw no interval (NaN): the console and the page said
    '+nan … +nan'."""
    from brakethermo.cli.diagnose_cmd import _interval as console
    from brakethermo.report.rig_diagnosis_page import _interval as page

    nan = float("nan")
    assert console(nan, nan) == "–" and page(nan, None).startswith("–")
    assert console(-3.2, 14.6) == "-3 … +15" == page(-3.2, 14.6)


def test_a_pooled_diagnosis_of_another_rig_is_not_replaced(tmp_path):
    """A second pooled diagnose (roller-rig sessions) into the --out of a first (EMB)
    replaced OUT/pooled/diagnosis.json and its page, no word: refused before the work,
    naming both; the same rig's pooled diagnosis is re-run as before."""
    from brakethermo.cli.diagnose_cmd import _pooled_free
    from brakethermo.errors import ConfigError

    (tmp_path / "pooled").mkdir()
    (tmp_path / "pooled" / "diagnosis.json").write_text(json.dumps(
        {"rig": "emb", "sessions": ["a.mcap", "b.mcap", "c.mcap"]}))
    with pytest.raises(ConfigError, match="holds the pooled diagnosis of 3 sessions of an EMB"
                       " caliper rig; this call pools sessions of a roller rig and would"
                       " replace it: give another --out"):
        _pooled_free(tmp_path, "roller-rig")
    _pooled_free(tmp_path, "emb")
    _pooled_free(tmp_path / "elsewhere", "roller-rig")
    # disc sessions pooled over a rig's pooled/ (review: only rig pools were checked), and
    # a rig name no longer known (an AttributeError)
    with pytest.raises(ConfigError, match="3 sessions of an EMB caliper rig; this call pools"
                       " disc sessions"):
        _pooled_free(tmp_path, None)
    (tmp_path / "pooled" / "diagnosis.json").write_text(json.dumps({"rig": "bogus"}))
    with pytest.raises(ConfigError, match="sessions of rig 'bogus'"):
        _pooled_free(tmp_path, None)


def test_the_console_table_says_a_dimensionless_unit_and_the_negligible_rows():
    """The tyre's table read "before -" / "after -"; the booster's rows, all negligible,
    came in the registry's order under "in the verdict's order"."""
    from rich.console import Console

    from brakethermo.cli.diagnose_cmd import _effects_table

    rows = [{"name": n, "rmse_before": 0.083, "rmse_after": a, "shrink_pct": p,
             "shrink_ci95_pct": [p - 5, p + 5], "negligible": neg}
            for n, a, p, neg in (("curve_shape", 0.033, 60.0, False),
                                 ("relaxation", 0.07, 15.0, True))]
    con = Console(width=200, record=True)
    con.print(_effects_table(rows, "-", 3))
    text = " ".join(con.export_text().split())
    assert "before -" not in text and "after -" not in text and "before" in text
    assert "relaxation (negligible)" in text and "negligible ones after" in text


def test_the_rig_page_says_no_dimensionless_unit():
    """The page's mean-bias card and fitted parameters still printed "-" as a unit (review):
    the page's helper gives nothing for a dimensionless output, " MPa" otherwise."""
    from brakethermo.io.units import unit_suffix as _unit_said

    assert _unit_said("-") == "" == _unit_said("")
    assert _unit_said("MPa") == " MPa"


def test_each_candidates_evidence_is_its_own():
    """The roller rig's three candidates showed one sentence, the reference's residual
    ("+172.867 N at low input, +416.021 N at high input" each): each now adds its own."""
    import numpy as np

    from brakethermo.models.rig_effects import RigContext
    from brakethermo.pipelines.diagnose.rig import _evidence

    x = np.linspace(0.0, 1.0, 200)
    ctx = RigContext(x, np.ones_like(x), x, lambda z: z)
    held = np.ones_like(x, dtype=bool)
    res = 100.0 + 300.0 * x
    said = {name: _evidence(name, res, held, ctx, "N", after=res * k)
            for name, k in (("creep_slope", 0.1), ("friction_level", 0.5))}
    assert said["creep_slope"] != said["friction_level"]
    assert "; with creep_slope: model minus sensor +13.693 N" in said["creep_slope"]
    assert " - " not in _evidence("curve_shape", res / 1e3, held, ctx, "-")
