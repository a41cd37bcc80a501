"""Tuning and calibration files: precedence, validation, custom datasheets."""

from __future__ import annotations

from pathlib import Path

import pytest

from brakethermo.config import config_dir
from brakethermo.errors import ConfigError
from brakethermo.pipelines.estimate import EstimateOptions, calibrated_tuning, estimate_session
from brakethermo.pipelines.models import read_calibration
from brakethermo.pipelines.tuning import load_tuning

SHIPPED_LAW = config_dir() / "hlaw" / "cc-340-8.toml"


def test_a_tuning_file_overrides_only_the_keys_it_sets(tmp_path):
    cal = read_calibration(SHIPPED_LAW)
    user = tmp_path / "t.toml"
    user.write_text("[estimate]\nsigma_meas = 4.0\n")
    tuning = calibrated_tuning(cal, EstimateOptions(tuning=user))
    assert tuning.sigma_meas == 4.0
    assert tuning.sigma_crown == cal.sigma_crown and tuning.layers == cal.layers
    user.write_text("[estimate]\nsigma_crown = 0.3\n")
    assert calibrated_tuning(cal, EstimateOptions(tuning=user)).sigma_crown == 0.3
    explicit = EstimateOptions(tuning=user, sigma_crown=0.07, layers=2, adapt_power=False)
    tuning = calibrated_tuning(cal, explicit)
    assert (tuning.sigma_crown, tuning.layers, tuning.adapt_power) == (0.07, 2, False)


@pytest.mark.parametrize(
    "line",
    ["layers = 9", "layer_growth = 1e6", "sigma_meas = 1e308", "sigma_meas = nan",
     "nodes = 10.7", "layers = true", "nodes = 5", "smoother = 1", "sigma_crown = -1"],
)
def test_bad_tuning_values_are_config_errors(tmp_path, line):
    path = tmp_path / "t.toml"
    path.write_text(f"[estimate]\n{line}\n")
    with pytest.raises(ConfigError, match=r"t\.toml"):
        load_tuning(path)


@pytest.mark.parametrize(
    "line", ["kz_ratio = inf", "layers = 9", "power_scale = 1e6", "band_scale = 0.5",
             "layers = 2.5", "adapt_power = 1"],
)
def test_bad_calibration_values_are_config_errors(tmp_path, line):
    key = line.split(" =")[0]
    text = SHIPPED_LAW.read_text()
    kept = "\n".join(row for row in text.splitlines() if not row.startswith(f"{key} ="))
    path = tmp_path / "h_law.toml"
    path.write_text(kept.replace("[extra]", f"[extra]\n{line}"))
    with pytest.raises(ConfigError, match=key):
        read_calibration(path)


def test_custom_datasheet_file_is_used_throughout(sim_race_session, tmp_path):
    disc = tmp_path / "my-disc.toml"
    text = (config_dir() / "discs" / "cc-340-8.toml").read_text()
    disc.write_text(text.replace('id = "cc-340-8"', 'id = "my-disc"').replace(
        "window_c = [250.0, 850.0]", "window_c = [300.0, 800.0]"))
    res = estimate_session(sim_race_session[0],
                           EstimateOptions(disc=disc, h_law=SHIPPED_LAW, layers=1))
    assert res.disc.id == "my-disc" and res.disc.window_c == (300.0, 800.0)
    assert res.summary["run"]["disc"] == "my-disc"
    assert any("fitted for 4" in w for w in res.summary["run"]["warnings"])


def test_a_run_reads_the_tuning_file_once(sim_race_session, tmp_path, monkeypatch) -> None:
    """The race's decision passes and its filter share one read of the user's file (a
    file edited half-way through a run cannot give its passes two tunings)."""
    import brakethermo.pipelines.tuning as tuning_module
    from brakethermo.pipelines.tuning import TuningFiles, read_tuning

    mine = tmp_path / "mine.toml"
    mine.write_text("[estimate]\nsigma_meas = 4.0\n")
    reads = []
    real = tuning_module.config_file

    def counted(path):
        reads.append(Path(path))
        return real(path)

    monkeypatch.setattr(tuning_module, "config_file", counted)
    files = read_tuning(mine)
    assert isinstance(files, TuningFiles) and read_tuning(files) is files
    assert files.estimate.sigma_meas == 4.0 and files.user_estimate == {"sigma_meas"}
    reads.clear()
    result = estimate_session(sim_race_session[0], EstimateOptions(tuning=mine))
    assert result.summary["run"]["online_choice"].get("scores")  # the decision ran passes
    assert reads.count(mine) == 1
