"""Rig sessions with a sensor zeroed, frozen, negated or in the wrong unit: each rig
command refuses an input it cannot use with one line naming the channel, keeps a
channel that only scores with a warning, and never exits 0 with a number that cannot be."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from brakethermo.cli import app

RUNNER = CliRunner()
SIMS = {
    "ebt": ["--rig", "ebooster", "--set", "scenario=train", "--seed", "8"],
    "ebv": ["--rig", "ebooster", "--set", "scenario=vehicle", "--set", "duration_s=30",
            "--seed", "7"],
    "embt": ["--rig", "emb", "--set", "duration_s=30", "--seed", "1"],
    "emb": ["--rig", "emb", "--set", "duration_s=30", "--set", "sensor=false", "--seed", "2"],
    "ty": ["--rig", "tyre", "--seed", "4"],
    "rr": ["--rig", "roller-rig", "--set", "duration_s=80", "--seed", "7"],
}


@pytest.fixture(scope="module")
def sessions(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("rigs")
    paths = {}
    for name, args in SIMS.items():
        res = RUNNER.invoke(app, ["simulate", *args, "--out", str(out / f"{name}.parquet")])
        assert res.exit_code == 0, res.output
        paths[name] = out / f"{name}.parquet"
    return paths


def _mutate(src: Path, column: str, how: str, out: Path) -> Path:
    table = pq.read_table(src)
    v = table.column(column).to_numpy(zero_copy_only=False).astype(float)
    v = {"zero": np.zeros_like(v), "negate": -v, "x1000": v * 1000.0, "x4": v * 4.0,
         "div1000": v / 1000.0, "stuck": np.full_like(v, float(np.nanmedian(v)))}[how]
    field = table.schema.field(column)
    table = table.set_column(table.column_names.index(column), field, pa.array(v))
    path = out / f"{src.stem}_{column}_{how}.parquet"
    pq.write_table(table, path)
    return path


def _command(rig: str, session: Path, s: dict[str, Path], out: Path) -> list[str]:
    return {
        "ebooster": ["ebooster", str(session), "--train", str(s["ebt"])],
        "clamp-force": ["clamp-force", str(session), "--train", str(s["embt"])],
        "mu-slip": ["mu-slip", str(session)],
        "roller-rig": ["roller-rig", str(session), "--r0", "340"],
    }[rig] + ["--out", str(out), "--json"]


def _finite(o: object) -> bool:
    if isinstance(o, dict):
        return all(_finite(v) for v in o.values())
    if isinstance(o, list):
        return all(_finite(v) for v in o)
    return not (isinstance(o, float) and not math.isfinite(o))


# (rig, session, channel, mutation, expected: "refused" or "warned")
CASES = [
    ("ebooster", "ebv", "pushrod_displacement", "stuck", "refused"),
    ("ebooster", "ebv", "pushrod_displacement", "x1000", "refused"),
    ("ebooster", "ebv", "master_cylinder_pressure", "zero", "warned"),
    ("ebooster", "ebv", "pedal_force", "negate", "warned"),
    ("ebooster", "ebv", "reaction_disk_delta", "negate", "refused"),  # vs the disk fit
    ("clamp-force", "emb", "motor_current", "x1000", "refused"),
    ("clamp-force", "emb", "motor_current", "negate", "refused"),
    ("clamp-force", "emb", "motor_angle", "negate", "refused"),
    ("clamp-force", "emb", "motor_current", "stuck", "refused"),
    ("clamp-force", "embt", "clamp_force", "div1000", "warned"),  # kN labelled N, scoring
    ("mu-slip", "ty", "drag_force", "zero", "refused"),
    ("mu-slip", "ty", "drag_force", "negate", "refused"),
    ("mu-slip", "ty", "drag_force", "x1000", "refused"),
    ("mu-slip", "ty", "normal_force", "x1000", "refused"),
    ("roller-rig", "rr", "wheel_omega", "stuck", "refused"),
    ("roller-rig", "rr", "roller_torque", "x1000", "warned"),
]


@pytest.mark.parametrize(("rig", "src", "channel", "how", "expected"), CASES,
                         ids=[f"{c[0]}-{c[2]}-{c[3]}" for c in CASES])
def test_rig_mutation(rig: str, src: str, channel: str, how: str, expected: str,
                      sessions: dict[str, Path], tmp_path: Path) -> None:
    bad = _mutate(sessions[src], channel, how, tmp_path)
    res = RUNNER.invoke(app, _command(rig, bad, sessions, tmp_path / "out"))
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    assert "Traceback" not in res.output
    if expected == "refused":
        assert res.exit_code == 1, res.output
        assert channel in res.output or "μ" in res.output, res.output
        assert len(res.output.strip().splitlines()) <= 3  # one message (wrapped at most)
    else:
        assert res.exit_code == 0, res.output
        summary = json.loads(res.stdout[res.stdout.index("{"):])
        assert _finite(summary)
        assert any(channel in w for w in summary["warnings"]), summary["warnings"]


def test_a_training_force_a_thousand_times_too_small_is_refused(sessions: dict[str, Path],
                                                               tmp_path: Path) -> None:
    """A training sensor in kN labelled N trained every force 1000x too small, exit 0."""
    train = _mutate(sessions["embt"], "clamp_force", "div1000", tmp_path)
    res = RUNNER.invoke(app, ["clamp-force", str(sessions["emb"]), "--train", str(train),
                              "--out", str(tmp_path / "out")])
    assert res.exit_code == 1, res.output
    text = " ".join(res.output.split())
    assert train.name in text and "clamp_force" in text and "unit" in text, res.output


def test_clean_rig_sessions_pass_without_warnings(sessions: dict[str, Path],
                                                  tmp_path: Path) -> None:
    for rig, src in (("ebooster", "ebv"), ("clamp-force", "emb"), ("mu-slip", "ty")):
        res = RUNNER.invoke(app, _command(rig, sessions[src], sessions, tmp_path / rig))
        assert res.exit_code == 0, res.output
        summary = json.loads(res.stdout[res.stdout.index("{"):])
        assert not summary.get("warnings"), summary.get("warnings")


# (command, the other rig's session it is handed, the command the message must name)
WRONG_RIG = [
    ("roller-rig", "embt", "brakethermo clamp-force"),
    ("clamp-force", "ebv", "brakethermo ebooster"),
    ("ebooster", "rr", "brakethermo roller-rig"),
    ("mu-slip", "ebv", "brakethermo ebooster"),
]


@pytest.mark.parametrize(("rig", "src", "reads"), WRONG_RIG, ids=[c[0] for c in WRONG_RIG])
def test_a_session_of_another_rig_is_refused_naming_the_command_that_reads_it(
        rig: str, src: str, reads: str, sessions: dict[str, Path], tmp_path: Path) -> None:
    res = RUNNER.invoke(app, _command(rig, sessions[src], sessions, tmp_path / "out"))
    assert res.exit_code == 1, res.output
    assert "Traceback" not in res.output
    text = " ".join(res.output.split())
    assert f"{reads} reads it" in text, res.output
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").rglob("*.json"))


def test_kind_hint_only_for_a_session_of_another_kind() -> None:
    from brakethermo.io.kinds import kind_hint, session_kind

    emb = ("motor_angle", "motor_current", "clamp_force")
    assert session_kind(emb) == "emb"
    assert session_kind(("speed", "disc_temp")) == "disc"
    assert session_kind(("speed",)) is None
    assert "clamp-force" in kind_hint(emb, "wheel_omega")
    assert kind_hint(("motor_angle", "motor_current"), "clamp_force") == ""  # its own channel
    assert kind_hint(("speed", "disc_temp"), "brake_pressure_front") == ""
    assert "estimate" in kind_hint(("speed", "disc_temp"), "pushrod_displacement")


def test_a_booster_session_far_beyond_the_observers_noise_is_warned(
        sessions: dict[str, Path], tmp_path: Path) -> None:
    """A delta four times too large (a wrong unit or gain) made the observers' mean NIS
    about 8.8 and widened their bands by its root, exit 0 and no warning (new-user test)."""
    bad = _mutate(sessions["ebv"], "reaction_disk_delta", "x4", tmp_path)
    res = RUNNER.invoke(app, _command("ebooster", bad, sessions, tmp_path / "out"))
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout[res.stdout.index("{"):])
    assert summary["noise_scale"]["ukf"] > 3.0
    said = [w for w in summary["warnings"] if "beyond noise" in w]
    assert len(said) == 1, summary["warnings"]
    text = said[0]
    assert f"{summary['noise_scale']['ukf']:.1f} (UKF)" in text
    assert "reaction_disk_delta" in text and "reversed sign" in text and "sqrt" in text
    assert bad.name in text and sessions["ebt"].name in text


@pytest.mark.parametrize("channel", ["motor_current", "motor_angle"])
def test_a_reversed_channel_is_blamed_on_the_file_that_has_it(
        channel: str, sessions: dict[str, Path], tmp_path: Path) -> None:
    """A training session's current negated was refused naming the untouched estimation
    file ("flip the channel", new-user test): the training's channels are checked against
    its own sensor, and a reversal found on the estimation session names both files."""
    train = _mutate(sessions["embt"], channel, "negate", tmp_path)
    res = RUNNER.invoke(app, ["clamp-force", str(sessions["emb"]), "--train", str(train),
                              "--out", str(tmp_path / "out")])
    text = " ".join(res.output.split())
    assert res.exit_code == 1, text
    assert train.name in text and channel in text and "reversed in this file" in text, text
    assert sessions["emb"].name not in text, text
    bad = _mutate(sessions["emb"], channel, "negate", tmp_path)
    res = RUNNER.invoke(app, ["clamp-force", str(bad), "--train", str(sessions["embt"]),
                              "--out", str(tmp_path / "out")])
    text = " ".join(res.output.split())
    assert res.exit_code == 1, text
    assert bad.name in text and sessions["embt"].name in text and channel in text, text


def test_a_caliper_that_clamps_rarely_is_not_a_thousand_times_too_small() -> None:
    """The check compares the held peak, not the 99.5th percentile: one 0.25 s apply of
    8 kN in 60 s at 1 kHz read as 36 N and was called a unit slip (review)."""
    from brakethermo.pipelines.rig_checks import Expect, _fault

    rng = np.random.default_rng(0)
    v = 20.0 + rng.normal(0.0, 5.0, 60_000)
    v[30_000:30_250] = 8000.0
    e = Expect("clamp_force", "N", 1e5, positive=True, least=200.0)
    assert _fault(v, e) is None
    assert "less than any use" in (_fault(v / 1000.0, e) or "")


def test_a_pressure_sensor_its_check_warned_about_scores_nothing(sessions: dict[str, Path],
                                                                 tmp_path: Path) -> None:
    """A p_m sensor in bar labelled MPa printed a p_m RMSE of 45.8 MPa beside a warning
    that the figures mean nothing (new-user test): the channel now scores nothing."""
    bad = _mutate(sessions["ebv"], "master_cylinder_pressure", "x1000", tmp_path)
    res = RUNNER.invoke(app, _command("ebooster", bad, sessions, tmp_path / "out"))
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout[res.stdout.index("{"):])
    assert all(summary["pressure_rmse_mpa"][w]["p_m"] is None for w in ("ukf", "ekf"))
    assert any("master_cylinder_pressure" in w for w in summary["warnings"])
    assert not any("--with-effect auto" in w for w in summary["warnings"])
