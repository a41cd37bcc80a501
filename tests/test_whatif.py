"""`whatif`: replaying the estimate's laps with a change (physics, anchoring, CLI, bad input)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from brakethermo.cli import app
from brakethermo.errors import ConfigError
from brakethermo.pipelines.models import read_calibration
from brakethermo.pipelines.whatif import Scenario, WhatifOptions, whatif_session
from brakethermo.thermal.tyre_radiation import (
    TyreView,
    annulus_view_factors,
    disk_to_disk,
    tyre_heat,
)

CONFIG_HLAW = Path(__file__).resolve().parents[1] / "configs" / "hlaw"
runner = CliRunner()


# ---------------------------------------------------------------- view factors
def test_disk_to_disk_limits() -> None:
    assert disk_to_disk(0.2, 0.2, 1e-5) == pytest.approx(1.0, abs=1e-4)
    assert disk_to_disk(0.2, 0.2, 100.0) == pytest.approx(0.0, abs=1e-5)
    # tabulated case (Incropera Fig. 13.5): r_i = r_j = L gives F = 0.382
    assert disk_to_disk(1.0, 1.0, 1.0) == pytest.approx(0.382, abs=1e-3)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.05, 0.15), st.floats(0.01, 0.05), st.floats(0.16, 0.25),
       st.floats(0.02, 0.1), st.floats(0.005, 0.2))
def test_annulus_reciprocity(a1: float, w1: float, a2: float, w2: float, gap: float) -> None:
    """A1 F12 = A2 F21 for coaxial parallel annuli, computed from either side."""
    b1, b2 = a1 + w1, a2 + w2
    f12 = annulus_view_factors(np.array([a1, b1]), TyreView(a2, b2, gap))[0]
    # the reverse direction: the same algebra with the roles swapped
    to_1 = (disk_to_disk(np.array([a2, b2]), b1, gap) - disk_to_disk(np.array([a2, b2]), a1,
                                                                     gap))
    f21 = np.diff(np.pi * np.array([a2, b2]) ** 2 * to_1)[0] / (np.pi * (b2**2 - a2**2))
    A1, A2 = np.pi * (b1**2 - a1**2), np.pi * (b2**2 - a2**2)
    assert 0.0 <= f12 <= 1.0
    assert A1 * f12 == pytest.approx(A2 * f21, rel=1e-6, abs=1e-12)


def test_tyre_heat_signs_and_scaling() -> None:
    radii = np.linspace(0.1, 0.17, 10)
    view = TyreView(carcass_c=60.0)
    hot = tyre_heat(np.full(10, 600.0), radii, 0.1, 0.17, 0.85, view)
    assert 0.0 < hot < 1000.0  # watts, a fraction of the ~1.6 kW the face radiates
    assert tyre_heat(np.full(10, 60.0), radii, 0.1, 0.17, 0.85, view) == pytest.approx(0.0)
    # a taller sidewall sees more of the disc (the annulus only grows); the exchange
    # vanishes at zero gap, where the radially offset annuli no longer see each other
    taller = tyre_heat(np.full(10, 600.0), radii, 0.1, 0.17, 0.85, TyreView(tyre_radius=0.35))
    assert taller > hot
    assert tyre_heat(np.full(10, 600.0), radii, 0.1, 0.17, 0.85, TyreView(gap=1e-4)) < 0.01 * hot


# ---------------------------------------------------------------- replay
@pytest.fixture(scope="module")
def replayed(sim_race_session: tuple[Path, Path]):
    opts = WhatifOptions(scenarios=(Scenario(), Scenario(cooling=1.3), Scenario(cooling=0.8),
                                    Scenario(ambient_c=40.0), Scenario(heat_share=0.95)),
                         draws=4)
    return whatif_session(sim_race_session[0], opts)


def test_no_change_reproduces_the_estimate(replayed) -> None:
    est = replayed.estimate.frame
    same = replayed.replays[0]
    np.testing.assert_allclose(same.contact, est["contact_avg"], atol=1e-9)
    for i in range(4):
        np.testing.assert_allclose(same.spots[:, i], est[f"spot{i + 1}"], atol=1e-9)
    np.testing.assert_allclose(same.contact_std, est["contact_avg_std"], atol=1e-9)


def test_more_cooling_is_cooler_less_is_hotter_and_hot_air_hotter(replayed) -> None:
    base = replayed.base.contact
    braked = np.flatnonzero(replayed.estimate.frame["braking_power"].to_numpy() > 0)
    after = slice(int(braked[0]) + 50, None)  # once the first stop has heated the disc
    cool, warm, hot_day, more_heat = (r.contact for r in replayed.replays[1:])
    assert np.all(more_heat[after] >= base[after] - 0.5)
    # within a few tenths where the estimate sits at the air temperature (its state may dip
    # below the air there, and more cooling relaxes it towards the air faster)
    assert np.all(cool[after] <= base[after] + 0.5)
    assert np.all(warm[after] >= base[after] - 0.5)
    assert np.mean(cool[after] - base[after]) < -5.0
    assert np.mean(hot_day[after] - base[after]) > 2.0
    # the scenario's band admits the change's own uncertainty
    assert np.all(replayed.replays[1].contact_std >= replayed.base.contact_std - 1e-9)


def test_summary_and_frame_follow_outputs_md(replayed) -> None:
    f: pd.DataFrame = replayed.frame
    for col in ("time", "lap", "base_contact_avg", "base_spot1", "base_spot4", "contact_avg",
                "contact_avg_std", "spot1", "spot4", "tyre_heat_w", "mu_rel",
                "contact_avg_2", "spot3_4", "tyre_heat_w_4", "mu_rel_4"):
        assert col in f, col
    assert np.isfinite(f.to_numpy(float)).all()
    s = replayed.summary
    assert [x["label"] for x in s["scenarios"]][1] == "cooling x1.3"
    for row in s["laps"]:
        for key in ("base", "cooling x1.3"):
            assert set(row[key]) >= {"time_in_window_pct", "time_above_s", "peak_contact_c",
                                     "hottest_radius_c", "tyre_heat_kj", "mu_rel_min"}
            assert row[key]["hottest_radius_c"] >= row[key]["peak_contact_c"] - 1e-6
    assert s["laps"][-1]["cooling x1.3"]["tyre_heat_kj"] < s["laps"][-1]["base"]["tyre_heat_kj"]


def test_summary_holds_its_own_evidence_and_says_the_shipped_law(replayed) -> None:
    """The μ assumption pointed to "run.online_choice in the estimate's summary.json",
    which whatif never writes; without --h-law the shipped law was used silently (estimate
    warns of it)."""
    run = replayed.summary["run"]
    assert run["online_choice"] == replayed.estimate.summary["run"]["online_choice"]
    assert run["online_choice"]  # the race decided: its evidence is here
    assert not any("estimate's summary.json" in a for a in replayed.summary["assumptions"])
    assert run["h_law_choice"].startswith("shipped default for disc cc-340-8")
    # the bytes of the law read, so a page can tell two spellings of one file apart
    assert run["h_law_sha256"] == replayed.estimate.summary["run"]["h_law_sha256"]
    assert len(run["h_law_sha256"]) == 64
    assert run["warnings"][0].startswith("no h law of this bike (no --h-law)")


# ---------------------------------------------------------------- CLI and bad input
def test_cli_writes_parquet_summary_and_page(sim_race_session, tmp_path: Path) -> None:
    r = runner.invoke(app, ["whatif", str(sim_race_session[0]), "--cooling", "1.2",
                            "--draws", "2", "--out", str(tmp_path), "--json"])
    assert r.exit_code == 0, r.output
    summ = json.loads(r.output)
    folder = tmp_path / sim_race_session[0].stem
    assert (folder / "whatif.parquet").is_file()
    assert (folder / "whatif" / "index.html").is_file()
    assert (folder / "whatif" / "contact.png").stat().st_size > 10_000
    assert summ["scenarios"][0]["cooling"] == 1.2
    assert summ["run"]["h_law_choice"].startswith("shipped default")  # no --h-law given
    assert "no h law" in " ".join(summ["run"]["warnings"])
    r = runner.invoke(app, ["whatif", str(sim_race_session[0]), "--cooling", "1.2",
                            "--scenario", "cooling=1.3,ambient=35", "--draws", "0",
                            "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert "warning: no h law of this bike" in " ".join(r.output.split())
    page = (folder / "whatif" / "index.html").read_text(encoding="utf-8")
    assert "cooling x1.2 | cooling x1.3, ambient 35 °C" in page
    assert "spread of 0 replays" not in page and "no spread over the h law" in page
    # the law identify-h wrote for this session beside its outputs, as estimate takes it
    # (whatif took the shipped law and said "no h law of this bike", review)
    law = folder / "h_law.toml"
    law.write_text((CONFIG_HLAW / "cc-340-8.toml").read_text(encoding="utf-8").replace(
        'session = "sample_sessions/mugello_test_multi.mcap"',
        f'session = "{sim_race_session[0].name}"'))
    r = runner.invoke(app, ["whatif", str(sim_race_session[0]), "--cooling", "1.2",
                            "--draws", "0", "--out", str(tmp_path), "--json"])
    assert r.exit_code == 0, r.output
    run = json.loads(r.output)["run"]
    assert run["h_law_choice"].startswith("identified from this session")
    assert Path(run["h_law"]) == law and not any("no h law" in w for w in run["warnings"])


@pytest.mark.parametrize("args, needle, code", [
    (["--cooling", "0"], "cooling", 2),
    (["--cooling", "-1"], "cooling", 2),
    (["--cooling", "nan"], "cooling", 2),
    (["--cooling", "inf"], "cooling", 2),
    (["--disc", "no-such-disc"], "no-such-disc", 1),
    (["--ambient", "400"], "ambient", 2),
    (["--scenario", "cooling=fast"], "not a number", 2),
    (["--scenario", "duct=2"], "KEY one of", 2),
    (["--pads", "2"], "pads", 2),
    (["--tyre-temp", "900", "--cooling", "1.2"], "tyre-temp", 2),
    ([], "at least one change", 2),
    (["--cooling", "1.2", "--scenario", "cooling=1.2"], "given twice", 2),
    (["--scenario", "cooling=0"], "--scenario 'cooling=0': cooling=0: the factor", 2),
    (["--scenario", "ambient=35,pads=7"], "pads=7: give the share", 2),
])
def test_bad_options_one_line(sim_race_session, tmp_path: Path, args: list[str],
                              needle: str, code: int) -> None:
    """A value out of an option's range is a usage error (exit 2, as Typer's own checks),
    and so are no change and one change given twice (were exit 1); a scenario's value is
    named as typed (was '--cooling 0.0' for --scenario cooling=0); a datasheet that does
    not exist is a config problem (exit 1)."""
    r = runner.invoke(app, ["whatif", str(sim_race_session[0]), *args, "--draws", "0",
                            "--out", str(tmp_path)])
    assert r.exit_code == code, r.output
    assert needle in r.output and "Traceback" not in r.output


def test_law_of_another_disc_is_refused(sim_race_session, tmp_path: Path) -> None:
    law = tmp_path / "other.toml"
    shipped = Path(__file__).resolve().parents[1] / "configs" / "hlaw" / "cc-340-8.toml"
    text = shipped.read_text()
    assert 'disc = "cc-340-8"' in text
    law.write_text(text.replace('disc = "cc-340-8"', 'disc = "cc-355-9"'))
    r = runner.invoke(app, ["whatif", str(sim_race_session[0]), "--h-law", str(law),
                            "--cooling", "1.2", "--draws", "0", "--out", str(tmp_path)])
    assert r.exit_code == 1 and "cc-355-9" in r.output and "Traceback" not in r.output


def test_law_h_rel_sigma_is_a_checked_calibration_value(tmp_path: Path) -> None:
    shipped = Path(__file__).resolve().parents[1] / "configs" / "hlaw" / "cc-340-8.toml"
    text = shipped.read_text()
    assert "[extra]" in text and "h_rel_sigma" not in text
    good, bad = tmp_path / "good.toml", tmp_path / "bad.toml"
    good.write_text(text.replace("[extra]", "[extra]\nh_rel_sigma = 0.12", 1))
    bad.write_text(text.replace("[extra]", "[extra]\nh_rel_sigma = 3.0", 1))
    assert read_calibration(good).h_rel_sigma == 0.12
    assert read_calibration(shipped).h_rel_sigma is None
    with pytest.raises(ConfigError, match="h_rel_sigma"):
        read_calibration(bad)


def test_session_without_the_estimate_channels(tmp_path: Path) -> None:
    bad = tmp_path / "speed_only.csv"
    t = np.arange(0, 60, 0.1)
    pd.DataFrame({"time": t, "speed [km/h]": 100 + 0 * t}).to_csv(bad, index=False)
    r = runner.invoke(app, ["whatif", str(bad), "--cooling", "1.2", "--out", str(tmp_path)])
    assert r.exit_code == 1 and "Traceback" not in r.output


def test_scenario_rejects_zero_cooling_directly() -> None:
    with pytest.raises(ConfigError):
        Scenario(cooling=0.0)


def test_page_renders_in_a_browser(sim_race_session, tmp_path: Path) -> None:
    """The whatif page loads offline in headless Chromium, its PNGs decode, no errors."""
    from test_report_browser import CHROMIUM, render_offline, screenshots

    if CHROMIUM is None:
        pytest.skip("chromium is not installed (apt-get install -y chromium)")
    r = runner.invoke(app, ["whatif", str(sim_race_session[0]), "--cooling", "1.2",
                            "--ambient", "35", "--draws", "2", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    shots = screenshots(tmp_path)
    page = tmp_path / sim_race_session[0].stem / "whatif" / "index.html"
    assert render_offline([("whatif", page)], shots) == []
    assert (shots / "whatif.png").stat().st_size > 50_000


def test_simulator_replays_the_same_drive_with_a_change() -> None:
    """Same seed with more cooling / hotter air: same speed, cooler / hotter disc."""
    from brakethermo.sim.session import SimConfig, simulate

    base = simulate(SimConfig(laps=1, sensor="single", seed=77, nr=12, nz=3))
    cool = simulate(SimConfig(laps=1, sensor="single", seed=77, nr=12, nz=3, cooling=1.3))
    hot = simulate(SimConfig(laps=1, sensor="single", seed=77, nr=12, nz=3, ambient_c=45.0))
    tb, tc, th = (r.truth.to_pandas() for r in (base, cool, hot))
    n = min(len(tb), len(tc), len(th))
    np.testing.assert_allclose(tc["speed"][:n], tb["speed"][:n], rtol=0, atol=2.0)
    late = slice(n // 2, n)
    assert (tc["contact_avg"][late] < tb["contact_avg"][late]).mean() > 0.95
    assert th["contact_avg"][late].mean() > tb["contact_avg"][late].mean()
    assert th["ambient"].mean() == pytest.approx(45.0, abs=0.5)


def test_a_change_given_twice_is_refused_and_mu_source_is_said() -> None:
    """Two equal scenarios shared one key of the summary (one overwrote the other); the
    page said "the law carries no identified μ(T)" where the race had dropped the law's."""
    from types import SimpleNamespace

    from brakethermo.pipelines.whatif import _mu_assumption

    with pytest.raises(ConfigError, match="twice"):
        WhatifOptions(scenarios=(Scenario(cooling=1.2), Scenario(cooling=1.2)))

    def est(beta: bool, dropped: list[str]) -> SimpleNamespace:
        return SimpleNamespace(
            state_space=SimpleNamespace(effects=SimpleNamespace(mu_beta=beta)),
            summary={"run": {"online_choice": {"law_effects_dropped": dropped}}})

    assert "from the identified μ(T)" in _mu_assumption(est(True, []))
    assert "dropped it" in _mu_assumption(est(False, ["friction_temperature"]))
    assert "carries no identified" in _mu_assumption(est(False, []))


def test_charts_keep_scenarios_apart_and_the_legend_off_the_bars() -> None:
    """Colours repeated after 7 scenarios and the legend sat on the bars; with --draws 0
    the page spoke of "the spread of 0 replays"; the title joined scenario labels with
    the commas that also join a combined scenario's changes."""
    import matplotlib.pyplot as plt

    from brakethermo.report.whatif_page import TITLE_SEP, _band_text, lap_figure, scenario_style

    styles = [scenario_style(j) for j in range(12)]
    assert len(set(styles)) == 12 and len({c for c, _, _ in styles}) == 12
    assert scenario_style(0) != scenario_style(12)  # past the palette: another line style
    labels = [f"cooling x{1 + j / 10:g}" for j in range(9)]
    figs = {"peak_contact_c": 600.0, "peak_contact_band95_c": 5.0, "time_in_window_pct": 50.0,
            "tyre_heat_kj": 10.0, "mu_rel_min": 1.0, "hottest_radius_c": 620.0}
    laps = [{"lap": n, "base": figs, **{lab: figs for lab in labels}} for n in (1, 2)]
    fig = lap_figure(laps, labels, (350.0, 750.0), mu_varies=False)
    fig.canvas.draw()
    (legend,) = fig.legends
    box = legend.get_window_extent()
    for ax in fig.axes:
        assert not box.overlaps(ax.get_window_extent()), "the legend covers a panel"
    plt.close(fig)
    run = {"draws": 0, "h_rel_sigma": 0.08, "model_error_pct": 10.0}
    assert "spread of 0" not in _band_text(run) and "no spread" in _band_text(run)
    assert "spread of 12 replays" in _band_text({**run, "draws": 12})
    assert "," not in TITLE_SEP
