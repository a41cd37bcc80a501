"""diagnose end to end: a withheld effect is named, the gap shrinks on held-out laps,
the OUTPUTS.md files and page exist, bad input is one clear message."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from brakethermo.cli import app
from brakethermo.models.effects import EFFECT_NAMES
from brakethermo.sim.session import SimConfig, simulate, write_simulation

DIAGNOSE_SEED = 4301  # not a tuning seed (those are 500-599)


@pytest.fixture(scope="module")
def lag_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("diag") / "lag.mcap"
    cfg = SimConfig(track="tight-like", laps=3, sensor="multi", seed=DIAGNOSE_SEED,
                    effects=("sensor_lag",))
    return write_simulation(simulate(cfg), out)[0]


@pytest.fixture(scope="module")
def diagnosed(lag_session: Path, tmp_path_factory: pytest.TempPathFactory
              ) -> tuple[dict, Path]:
    out = tmp_path_factory.mktemp("out")
    result = CliRunner().invoke(app, [
        "diagnose", str(lag_session), "--out", str(out), "--json",
        "--effects", "sensor_lag,emissivity_error,friction_temperature,h_speed_knee",
    ])
    assert result.exit_code == 0, result.output
    return json.loads(result.output), out / lag_session.stem


def test_withheld_sensor_lag_is_named_and_the_gap_shrinks(diagnosed: tuple[dict, Path]) -> None:
    summary, _ = diagnosed
    assert summary["verdict"] == "sensor_lag"
    top = summary["effects"][0]
    assert top["name"] == "sensor_lag" and top["rank"] == 1
    assert top["rmse_after"] < 0.8 * top["rmse_before"]
    assert top["shrink_ci95_pct"][0] > 10.0
    # The simulator's strong lag is 0.35 s; the fit also takes up the sharper face peaks
    # of the reference model's thin face layer, so it lands above that.
    assert 0.2 < top["params"]["tau_s"] < 1.0
    assert summary["combined"]["effects"][0] == "sensor_lag"
    assert set(summary["heldout_laps"]).isdisjoint(summary["train_laps"])
    assert 0 not in summary["heldout_laps"] + summary["train_laps"]


def test_report_page_renders_in_a_browser(diagnosed: tuple[dict, Path], tmp_path: Path
                                          ) -> None:
    """The diagnosis page loads offline in headless Chromium, its PNGs decode, no errors."""
    from test_report_browser import CHROMIUM, render_offline, screenshots

    if CHROMIUM is None:
        pytest.skip("chromium is not installed (apt-get install -y chromium)")
    _, folder = diagnosed
    shots = screenshots(tmp_path)
    problems = render_offline([("diagnosis", folder / "diagnosis" / "index.html")], shots)
    assert problems == []
    assert (shots / "diagnosis.png").stat().st_size > 50_000


def test_outputs_contract(diagnosed: tuple[dict, Path]) -> None:
    summary, folder = diagnosed
    for key in ("gap", "where", "effects", "verdict", "reference", "train_laps",
                "heldout_laps", "consistency"):
        assert key in summary
    assert set(summary["gap"]["per_spot"]) == {"spot1", "spot2", "spot3", "spot4"}
    assert set(summary["gap"]["per_phase"]) == {"braking", "cooling"}
    for e in summary["effects"]:
        assert e["name"] in EFFECT_NAMES
        assert {"rmse_before", "rmse_after", "shrink_pct", "params", "evidence"} <= set(e)
        assert np.isclose(e["shrink_pct"], 100 * (1 - e["rmse_after"] / e["rmse_before"]))
    for spot in summary["consistency"]["per_spot"].values():
        lo, hi = spot["chi2_band"]
        assert lo < 1.0 < hi
    on_disk = json.loads((folder / "diagnosis.json").read_text())
    assert on_disk["verdict"] == summary["verdict"]
    page = (folder / "diagnosis" / "index.html").read_text()
    assert "The reference model" in page and "sensor_lag" in page
    assert {p.name for p in (folder / "diagnosis").glob("*.png")} == {
        "nis.png", "residual_map.png", "effects.png", "heldout_lap.png"}


def test_bad_input_is_one_clear_message(lag_session: Path, tmp_path: Path) -> None:
    runner = CliRunner()
    cases = [
        (["--effects", "warp_drive"], "unknown effect"),
        (["--holdout-laps", "9"], "not flying laps"),
        (["--holdout-laps", "x"], "give lap numbers"),
    ]
    for extra, message in cases:
        result = runner.invoke(app, ["diagnose", str(lag_session), "--out", str(tmp_path),
                                     *extra])
        assert result.exit_code == 1, result.output
        assert message in result.output and "Traceback" not in result.output
    spot1_only = tmp_path / "spot1.csv"
    spot1_only.write_text("time [s],speed [km/h],brake_pressure_front [bar],"
                          "disc_temp_spot1 [degC]\n"
                          + "".join(f"{t / 10},100,20,300\n" for t in range(50)))
    result = runner.invoke(app, ["diagnose", str(spot1_only), "--out", str(tmp_path),
                                 "--ambient", "20"])
    assert result.exit_code == 1 and "race sensor" in result.output
    # an h law whose effect table misses a parameter: refused as estimate refuses it
    # (diagnose read only its a, b and weights and went on)
    from brakethermo.io.load import load_session
    from brakethermo.pipelines.models import disc_for, shipped_h_law

    law = tmp_path / "law.toml"
    law.write_text(shipped_h_law(disc_for(load_session(lag_session))).read_text()
                   + "\n[effects.sensor_lag]\n")
    result = runner.invoke(app, ["diagnose", str(lag_session), "--out", str(tmp_path),
                                 "--h-law", str(law)])
    assert result.exit_code == 1 and "effects.sensor_lag.tau_s" in result.output


def test_single_spot_race_gives_what_one_spot_can(tmp_path: Path) -> None:
    cfg = SimConfig(track="tight-like", laps=2, sensor="single", seed=DIAGNOSE_SEED + 1)
    race = write_simulation(simulate(cfg), tmp_path / "race.parquet")[0]
    result = CliRunner().invoke(app, ["diagnose", str(race), "--out", str(tmp_path / "o"),
                                      "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output)
    assert summary["mode"].startswith("single-spot")
    online = {"thickness_gradient", "slipstream", "power_distribution"}
    assert {e["name"] for e in summary["effects"]} == online
    blind = {e["name"] for e in summary["not_identifiable_from_one_spot"]}
    assert blind == set(EFFECT_NAMES) - online
    assert list(summary["consistency"]["per_spot"]) == ["spot3"]
    assert summary["verdict"] in ("none", *online)
    assert (tmp_path / "o" / "race" / "diagnosis" / "index.html").is_file()
    # judged against the shipped law, it says so (an independent generator's race was
    # called "slipstream" from the shipped law's mismatch, its next step without a law)
    assert any("no --h-law" in w for w in summary["warnings"])
    from brakethermo.io import load_session
    from brakethermo.pipelines.diagnose import DiagnoseOptions, diagnose_session

    law = Path(__file__).resolve().parents[1] / "configs" / "hlaw" / "cc-340-8.toml"
    given = diagnose_session(load_session(race), DiagnoseOptions(h_law=law))
    assert given.summary["warnings"] == []
    assert len(given.evidence) == 3
    assert all(f"--h-law {law} --adapt-" in e.next_step for e in given.evidence)


def test_verdict_keys_sizes_zone_names_and_next_steps(diagnosed: tuple[dict, Path]) -> None:
    summary, _ = diagnosed
    assert summary["verdict_set"][0] == summary["verdict"]
    assert summary["verdict_kind"] in ("single", "set") and summary["next_steps"]
    assert len(summary["verdict_set"]) == 1 or summary["verdict_kind"] == "set"
    lag = next(e for e in summary["effects"] if e["name"] == "sensor_lag")
    assert lag["size"]["tau_s"] == pytest.approx(lag["params"]["tau_s"])
    assert "s" in lag["size_text"] and lag["separate_by"]
    if summary["verdict_kind"] == "single":
        assert "--with-effect sensor_lag" in summary["next_steps"][0]
    for cell in summary["where"]["ranked_cells"]:
        assert cell["zone"] is None or cell["zone"].startswith("B")
    top_speed = max(float(b["band_kmh"].split("-")[1]) for b in summary["where"]["by_speed_band"])
    assert top_speed < 400.0  # bands end at the session's top speed, not 1000 km/h


def test_pooled_sessions_and_pooling_bad_input(lag_session: Path, tmp_path: Path) -> None:
    import pyarrow.parquet as pq

    cfg = SimConfig(track="tight-like", laps=2, sensor="multi", seed=DIAGNOSE_SEED + 2,
                    effects=("sensor_lag",))
    second = write_simulation(simulate(cfg), tmp_path / "lag2.parquet")[0]
    runner = CliRunner()
    args = ["--effects", "sensor_lag,thickness_gradient"]
    result = runner.invoke(app, ["diagnose", str(lag_session), str(second), "--out",
                                 str(tmp_path / "o"), "--json", *args])
    assert result.exit_code == 0, result.output
    pooled = json.loads(result.output)
    for key in ("sessions", "gap", "where", "effects", "verdict", "verdict_set", "next_steps",
                "reference", "train_laps", "heldout_laps", "consistency", "per_session"):
        assert key in pooled, key
    assert len(pooled["sessions"]) == 2 and pooled["verdict"] == "sensor_lag"
    # the keys of a session's diagnosis.json (OUTPUTS.md: "same keys"), pooled
    assert set(pooled["gap"]["per_spot"]) == {"spot1", "spot2", "spot3", "spot4"}
    assert set(pooled["gap"]["per_phase"]) == {"braking", "cooling"}
    for spot in pooled["consistency"]["per_spot"].values():
        lo, hi = spot["chi2_band"]
        assert lo < 1.0 < hi and spot["n"] > 0
    for e in pooled["effects"]:
        assert {"rmse_before", "rmse_after", "shrink_pct", "params", "evidence"} <= set(e)
        assert np.isclose(e["shrink_pct"], 100 * (1 - e["rmse_after"] / e["rmse_before"]))
        assert set(e["params_per_session"]) == {lag_session.stem, "lag2"}
    lag = next(e for e in pooled["effects"] if e["name"] == "sensor_lag")
    taus = [p["tau_s"] for p in lag["params_per_session"].values()]
    assert lag["params"]["tau_s"] == pytest.approx(np.median(taus))
    assert (tmp_path / "o" / "pooled" / "diagnosis.json").is_file()
    assert (tmp_path / "o" / "lag2" / "diagnosis.json").is_file()
    html = (tmp_path / "o" / "pooled" / "index.html").read_text()
    for stem in (lag_session.stem, "lag2"):
        assert f'href="../{stem}/diagnosis/index.html"' in html
        assert (tmp_path / "o" / stem / "diagnosis" / "index.html").is_file()
    # another disc in the same call
    table = pq.read_table(second)
    meta = dict(table.schema.metadata)
    facts = json.loads(meta[b"session"])
    facts["disc"] = "cc-355-9"
    meta[b"session"] = json.dumps(facts).encode()
    other = tmp_path / "other_disc.parquet"
    pq.write_table(table.replace_schema_metadata(meta), other)
    result = runner.invoke(app, ["diagnose", str(lag_session), str(other), "--out",
                                 str(tmp_path / "o"), *args])
    assert result.exit_code == 1 and "one disc" in result.output
    assert "Traceback" not in result.output
    # a single-spot race cannot be pooled with four-spot sessions
    race = write_simulation(simulate(SimConfig(track="tight-like", laps=2, sensor="single",
                                               seed=DIAGNOSE_SEED + 3)),
                            tmp_path / "race.parquet")[0]
    result = runner.invoke(app, ["diagnose", str(lag_session), str(race), "--out",
                                 str(tmp_path / "o"), *args])
    assert result.exit_code == 1 and "four-spot" in result.output


def test_a_pooled_next_step_carries_the_effect_from_the_session_that_shows_it() -> None:
    """The first session named had its law identified with an effect it did not show
    (new-user test: identify-h ft_test --with-effect thickness_gradient, where kz_test
    showed it)."""
    from brakethermo.pipelines.diagnose.pooled import leading

    rows = [{"significant": False, "shrink_ci95_pct": [-0.1, 2.1]},
            {"significant": True, "shrink_ci95_pct": [20.0, 31.0]},
            {"significant": True, "shrink_ci95_pct": [9.0, 14.0]}]
    assert leading(rows) == 1
    assert leading([{"significant": False, "shrink_ci95_pct": [float("nan")] * 2},
                    {"significant": False, "shrink_ci95_pct": [1.0, 4.0]}]) == 1


def test_pooling_refuses_a_session_twice_or_two_of_one_name(tmp_path) -> None:
    """Two files of one name shared OUT/<name>/ (one diagnosis lost, exit 0); one file
    given twice counted its evidence twice and narrowed the interval."""
    from brakethermo.errors import ConfigError
    from brakethermo.pipelines.diagnose._common import filled
    from brakethermo.pipelines.diagnose.sessions import diagnose_many

    a, b = tmp_path / "kz.mcap", tmp_path / "day2" / "kz.mcap"
    with pytest.raises(ConfigError, match="given twice"):
        diagnose_many([a, a])
    with pytest.raises(ConfigError, match="share the name 'kz'"):
        diagnose_many([a, b])
    summary = {"next_steps": ["brakethermo identify-h s.mcap --out OUT"],
               "effects": [{"next_step": "ebooster X --with-effect DIR/<stem>/diagnosis.json"}]}
    done = filled(summary, {"--out OUT": "--out 'my out'",
                            "DIR/<stem>/diagnosis.json": "o/s/diagnosis.json"})
    assert done["next_steps"] == ["brakethermo identify-h s.mcap --out 'my out'"]
    assert done["effects"][0]["next_step"].endswith("--with-effect o/s/diagnosis.json")


def test_pooling_refuses_a_session_named_pooled(tmp_path) -> None:
    """A session of stem 'pooled' had its diagnosis.json replaced by the pooled one (exit
    0): refused in one line, exit 1, before any session is read; alone it is no pool."""
    from typer.testing import CliRunner

    from brakethermo.cli import app
    from brakethermo.errors import ConfigError
    from brakethermo.pipelines.diagnose.sessions import distinct_sessions

    a, b = tmp_path / "ft_a.mcap", tmp_path / "px" / "Pooled.mcap"
    with pytest.raises(ConfigError, match="where the pooled diagnosis"):
        distinct_sessions([a, b])
    distinct_sessions([b])  # one session: no pooled folder is written
    res = CliRunner().invoke(app, ["diagnose", str(a), str(b), "--out", str(tmp_path / "o")])
    assert res.exit_code == 1
    assert "where the pooled diagnosis" in res.output
    assert len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "o" / "pooled").exists()


def test_forward_selection_does_not_add_an_effect_its_combined_fit_leaves_at_a_bound():
    """The combined model brought in a wrong emissivity at its bound behind the verdict
    (independent generator, pyrometer-lag session) and identify-h carried it."""
    import numpy as np

    from brakethermo.pipelines.diagnose._common import Candidate
    from brakethermo.pipelines.diagnose.four_spot import _forward_selection

    def cand(*names):
        c = Candidate(",".join(names), names, np.zeros(1), np.zeros((1, 4)), (1,), 0.0)
        c.scores = {"rmse_after": 1.0, "shrink_pct": 30.0, "significant": True}
        return c

    first, edge, fine = cand("thickness_gradient"), cand("emissivity_error"), cand("sensor_lag")

    def fit(effects, start):
        return cand(*effects)

    def describe(c, pred):
        return {"rmse_after": 0.9, "shrink_pct": 12.0, "significant": True}

    def at_bound(c):
        return "ratio = 0.6" if "emissivity_error" in c.effects else ""

    out = _forward_selection([first, edge, fine], fit, describe, at_bound)
    assert out["effects"] == ["thickness_gradient", "sensor_lag"]


def test_pooled_params_give_a_median_of_vectors_or_say_why_not() -> None:
    """Pooled ``params`` was ``{}`` for list-valued effects (46 and 47 slipstream
    straights, 9 and 10 braking zones), though OUTPUTS.md promises the runs' median: lists
    of one length get the element-wise median, others ``params_not_pooled`` with why."""
    from brakethermo.pipelines.diagnose.pooled import _median_params, _unpooled_params

    same = [{"zone_balance": [0.1, 0.3], "beta": 0.2}, {"zone_balance": [0.3, 0.5], "beta": 0.4}]
    assert _median_params(same) == {"zone_balance": [0.2, 0.4], "beta": pytest.approx(0.3)}
    assert _unpooled_params(same) == {}
    ragged = [{"straight_factor": [1.0, 1.1]}, {"straight_factor": [1.0, 1.2, 0.9]}]
    assert _median_params(ragged) == {}
    assert "different counts in the runs (2, 3)" in _unpooled_params(ragged)["straight_factor"]


def test_an_empty_effect_list_is_a_usage_error(tmp_path: Path) -> None:
    """``diagnose --effects ''`` quietly ran all seven effects."""
    res = CliRunner().invoke(app, ["diagnose", str(tmp_path / "none.parquet"), "--effects",
                                   "", "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "empty list of effects" in " ".join(res.output.split())
