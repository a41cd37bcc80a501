"""Issue 10 targets on bench sessions the p-V fit and the tuning never saw.

The shipped training result comes from training seed 0; the observer settings were tuned
on seeds 1-2. Here: seeds 21-22, closed loop and vehicle-like, written with the real
session writers and read back through the CLI's pipeline.

Measured and asserted: pressures within 0.1 MPa RMS of the validation channels and a
95 % band covering 85-99 % of the validation points, for both observers, and the UKF's
residual no higher than the EKF's (the pedal force as one Gaussian state: with the
literal chi-square w^2 state the UKF's residual was 2-8 times the EKF's). The issue's
target of a UKF residual at least 10 % below the EKF's is NOT met and NOT asserted: on
seeds 11-15 the UKF is 1-6 % better (see README section and
``benchmarks/bench_ebooster_accuracy.py``). The residual check guards against the
chi-square state's bias, not a UKF advantage: on short vehicle sessions of other seeds
(3 and 4, 12 s at 500 Hz) the UKF is 8-11 % worse after brake releases (the force mean
sits deep below zero, see ``brakethermo/models/ebooster.py``).
"""

from __future__ import annotations

from dataclasses import replace

import pytest

from brakethermo.pipelines.ebooster import observe
from brakethermo.results.ebooster import PRESSURES
from brakethermo.sim.ebooster import (
    PRODUCTION_CHANNELS,
    EboosterSimConfig,
    simulate_ebooster,
    write_ebooster_session,
)

CASES = [("closed", 21), ("vehicle", 22)]


@pytest.fixture(scope="module", params=CASES, ids=[f"{s}-{n}" for s, n in CASES])
def summary(request, tmp_path_factory):
    scenario, seed = request.param
    cfg = EboosterSimConfig(scenario, seed=seed, rate_hz=500.0, duration_s=12.0)
    path, _ = write_ebooster_session(simulate_ebooster(cfg),
                                     tmp_path_factory.mktemp("t") / f"{scenario}{seed}.mcap")
    return observe(path).summary


def test_pressures_within_0_1_mpa_rms(summary):
    for observer in ("ukf", "ekf"):
        for state, rmse in summary["pressure_rmse_mpa"][observer].items():
            assert rmse < 0.1, (observer, state, rmse)


def test_95_percent_band_is_honest(summary):
    for observer in ("ukf", "ekf"):
        assert 0.85 <= summary["coverage_95"][observer] <= 0.99, summary["coverage_95"]


def test_ukf_residual_is_not_above_the_ekfs(summary):
    res = summary["residual_rmse_mm"]
    assert 0.0 < res["ukf"] <= res["ekf"] < 0.05, res
    expected = 100.0 * (res["ekf"] - res["ukf"]) / res["ekf"]
    assert summary["improvement_pct"] == pytest.approx(expected)


@pytest.mark.parametrize("scenario, seed, shift", [("open", 23, 0.3), ("vehicle", 24, -0.3)])
def test_band_admits_a_pv_curve_that_moved_since_training(tmp_path, scenario, seed, shift):
    """A session whose p-V curve sits 0.3 mm off the training bench's (seals, fluid): the
    pressures carry the offset (delta cannot tell it from the pedal force), the band says
    so — before the band admitted it, it covered 22 % (open) and 60 % (vehicle)."""
    cfg = EboosterSimConfig(scenario, seed=seed, rate_hz=500.0, duration_s=12.0,
                            pv_shift_mm=shift)
    path, _ = write_ebooster_session(simulate_ebooster(cfg), tmp_path / "s.mcap")
    s = observe(path, with_effect="none").summary  # as a session without the sensor
    for observer in ("ukf", "ekf"):
        assert s["pressure_rmse_mpa"][observer]["p_m"] > 0.05  # the shift is there
        assert 0.85 <= s["coverage_95"][observer] <= 1.0, s["coverage_95"]
    assert s["band"]["pv_shift_sd_mm"] == pytest.approx(0.25)


def test_pv_shift_out_of_range_is_refused():
    from brakethermo.errors import ConfigError

    with pytest.raises(ConfigError, match="pv_shift_mm"):
        simulate_ebooster(EboosterSimConfig("open", pv_shift_mm=3.0))


def test_a_band_the_sessions_own_sensor_refutes_is_said(tmp_path):
    """A curve 0.6 mm off (beyond the 0.25 mm the band admits) left the band covering a
    third of the applied pressures with no warning, and the pooled coverage counted the
    idle samples (both sides near 0) as covered: coverage while braking is reported and a
    low one is said, naming the diagnosis that sizes the shift; a nominal session says
    nothing."""
    cfg = EboosterSimConfig("open", seed=25, rate_hz=500.0, duration_s=12.0, pv_shift_mm=0.6)
    path, _ = write_ebooster_session(simulate_ebooster(cfg), tmp_path / "s.mcap")
    s = observe(path, with_effect="none").summary
    assert s["coverage_95_braking"]["ukf"] < 0.8
    assert any("while the brake is applied" in w and "diagnose --rig ebooster" in w
               for w in s["warnings"]), s["warnings"]
    nominal = EboosterSimConfig("open", seed=25, rate_hz=500.0, duration_s=12.0)
    path, _ = write_ebooster_session(simulate_ebooster(nominal), tmp_path / "n.mcap")
    s = observe(path).summary
    assert s["coverage_95_braking"]["ukf"] > 0.85
    assert not any("while the brake is applied" in w for w in s["warnings"])


def test_by_default_a_session_with_its_sensor_measures_where_its_curve_sits(tmp_path):
    """The default run diagnoses a session that logs the master-cylinder pressure first
    (held-out applies) and carries the shift it finds; the band is then the session's own
    held-out residual about that curve, not the datasheet's 0.25 mm. Without the sensor
    nothing is carried and the band keeps the datasheet's shift."""
    cfg = EboosterSimConfig("open", seed=26, rate_hz=500.0, duration_s=12.0, pv_shift_mm=0.4)
    path, _ = write_ebooster_session(simulate_ebooster(cfg), tmp_path / "s.mcap")
    plain = observe(path, with_effect="none").summary
    s = observe(path).summary
    assert s["with_effect"]["source"].startswith("default")
    assert "pv_shift" in s["with_effect"]["verdict_set"]
    assert s["pressure_rmse_mpa"]["ukf"]["p_m"] < 0.5 * plain["pressure_rmse_mpa"]["ukf"]["p_m"]
    band = s["band"]
    assert band["shift_sd_from"] == "session" and 0.0 < band["heldout_curve_sd_mpa"] < 0.1
    assert 0.0 < band["pv_shift_sd_mm"] < 3 * 0.25 and "in-sample" in s["with_effect"]["in_sample"]
    for observer in ("ukf", "ekf"):
        assert 0.85 <= s["coverage_95_braking"][observer] <= 1.0, s["coverage_95_braking"]
    production = write_ebooster_session(simulate_ebooster(cfg), tmp_path / "p.mcap",
                                        channels=PRODUCTION_CHANNELS)[0]
    s = observe(production).summary
    assert s["with_effect"] is None and s["band"]["pv_shift_sd_mm"] == pytest.approx(0.25)


@pytest.mark.parametrize("fault", ["x10", "offset"])
def test_the_default_does_not_trust_a_pressure_sensor_that_is_off(tmp_path, fault):
    """The default places the curve with the session's own pressure sensor: one read in
    bar as MPa (its channel check flags it) is not used, the band stays the datasheet's
    and nothing is scored against it (its RMSE and a coverage warning sending the user to
    diagnose would mean nothing: new-user test); a sensor 2 MPa off that passes the
    channel check reads so at rest, where a master cylinder holds none: not used either,
    and the coverage warning against it speaks."""
    sim = simulate_ebooster(EboosterSimConfig("open", seed=27, rate_hz=500.0, duration_s=12.0))
    p_m = sim.meas[PRESSURES["p_m"]]
    bad = replace(sim, meas={**sim.meas,
                             PRESSURES["p_m"]: 10.0 * p_m if fault == "x10" else p_m + 2.0})
    path, _ = write_ebooster_session(bad, tmp_path / "s.mcap")
    s = observe(path).summary
    assert s["band"]["pv_shift_sd_mm"] == pytest.approx(0.25)
    assert "suspect" in s["with_effect"]["skipped"] and s["with_effect"]["effects"] == {}
    flagged = any(w.startswith(f"channel '{PRESSURES['p_m']}'") for w in s["warnings"])
    assert flagged is (fault == "x10")
    assert (s["pressure_rmse_mpa"]["ukf"]["p_m"] is None) is flagged
    assert any("while the brake is applied" in w for w in s["warnings"]) is not flagged
    if fault == "offset":
        assert "+2.00 MPa with the screw back at rest" in s["with_effect"]["skipped"]
