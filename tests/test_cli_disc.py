"""The identify-h and estimate commands as a user runs them: files, JSON, exit codes."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from brakethermo.cli import app

runner = CliRunner()


def test_estimate_json_and_files(sim_race_session, identified, tmp_path):
    res = runner.invoke(app, ["estimate", str(sim_race_session[0]), "--h-law",
                              str(identified[1]), "--out", str(tmp_path), "--json"])
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout)
    assert summary["run"]["measured_spot"] == 3
    assert (tmp_path / "race_multi" / "estimate.parquet").is_file()
    assert (tmp_path / "race_multi" / "lap_01" / "index.html").is_file()
    assert (tmp_path / "race_multi" / "index.html").is_file()
    assert summary["scores"]["table"][0]["method"] == "smoother"


def test_estimate_rich_output_prints_tables(sim_race_session, identified, tmp_path):
    res = runner.invoke(app, ["estimate", str(sim_race_session[0]), "--h-law",
                              str(identified[1]), "--out", str(tmp_path), "--no-smoother",
                              "--no-report"])
    assert res.exit_code == 0, res.output
    assert not (tmp_path / "race_multi" / "lap_01").exists()
    assert "disc °C per lap" in res.output and "single-spot" in res.output
    assert "h law: " in res.output and "given with --h-law" in res.output


def test_online_effects_can_be_switched_off(sim_race_session, identified, tmp_path):
    import pyarrow.parquet as pq

    res = runner.invoke(app, ["estimate", str(sim_race_session[0]), "--h-law",
                              str(identified[1]), "--out", str(tmp_path), "--no-smoother",
                              "--no-report", "--no-adapt-kz", "--adapt-balance", "--json"])
    assert res.exit_code == 0, res.output
    run = json.loads(res.stdout)["run"]
    effects = run["effects"]
    assert "thickness_gradient" not in effects
    assert "adapted online" in effects["power_distribution"]["use"]
    # slipstream, not forced, was left to the race: its decision is in the run facts
    slip = run["online_choice"]["chosen"]
    assert ("slipstream" in effects) == ("slipstream" in slip)
    assert run["online_choice"]["forced_or_from_law"] == {"adapt_kz": False}
    columns = pq.read_schema(tmp_path / "race_multi" / "estimate.parquet").names
    assert "kz_factor" not in columns and "crown_balance" in columns
    assert ("h_factor" in columns) == ("slipstream" in slip)


def test_bad_h_law_file_is_one_line_exit_1(sim_race_session, tmp_path):
    bad = tmp_path / "h_law.toml"
    bad.write_text("knee = 'x'\n")
    res = runner.invoke(app, ["estimate", str(sim_race_session[0]), "--h-law", str(bad),
                              "--out", str(tmp_path)])
    assert res.exit_code == 1
    assert "h_law.toml" in res.output and "Traceback" not in res.output


def test_missing_channel_names_aliases_and_channels(tmp_path):
    csv = tmp_path / "no_pressure.csv"
    csv.write_text("time,speed [km/h],disc_temp [degC]\n0,100,300\n0.1,101,301\n0.2,102,302\n")
    res = runner.invoke(app, ["estimate", str(csv), "--out", str(tmp_path)])
    assert res.exit_code == 1
    assert "brake_pressure_front" in res.output and "Traceback" not in res.output


def test_identify_rejects_single_spot_session(tmp_path):
    csv = tmp_path / "single.csv"
    csv.write_text("time,speed [km/h],brake_pressure_front [bar],disc_temp [degC]\n"
                   + "".join(f"{i / 10},{100 + i},20,{300 + i}\n" for i in range(50)))
    res = runner.invoke(app, ["identify-h", str(csv), "--out", str(tmp_path), "--ambient", "20"])
    assert res.exit_code == 1 and "four-spot" in res.output


def test_usage_error_is_exit_2(tmp_path):
    res = runner.invoke(app, ["estimate", str(tmp_path / "x.mcap"), "--spot", "7"])
    assert res.exit_code == 2
