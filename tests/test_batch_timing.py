"""timing-check: each lap timed on its own; the slowest lap decides against the budget."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest
from _synth_race import make_session, race_frame, write_session_parquet
from typer.testing import CliRunner

from brakethermo.io.session import Session
from brakethermo.pipelines import estimate as estimate_mod
from brakethermo.pipelines.timing import session_slice, time_laps


def _slow_on_lap(slow_lap: int, delay_s: float):
    seen: list[tuple[int, ...]] = []

    def estimate(session: Session, *_args) -> None:
        laps = tuple(np.unique(session.frame["lap"]).tolist())
        seen.append(laps)
        time.sleep(delay_s if slow_lap in laps else 0.001)

    return estimate, seen


def test_each_lap_timed_on_its_own() -> None:
    session = make_session(race_frame(4, lap_s=20.0), Path("race.parquet"))
    estimate, seen = _slow_on_lap(2, 0.08)
    report = time_laps(session, estimate, budget_s=1.0, race_laps=25)
    assert seen[1:] == [(0,), (1,), (2,), (3,)]  # after the warm-up, one lap per run
    assert [t.lap for t in report.laps] == [0, 1, 2, 3]
    assert report.worst.lap == 2 and report.worst.wall_s >= 0.08
    assert report.budget_per_lap_s == pytest.approx(0.04)
    assert not report.passed
    assert [t.data_s for t in report.laps] == pytest.approx([20.0] * 4)
    assert time_laps(session, estimate, budget_s=300.0).passed


def test_session_slice_keeps_time_base_and_laps() -> None:
    session = make_session(race_frame(3, lap_s=10.0), Path("race.parquet"))
    part = session_slice(session, 100, 200)
    assert part.frame["time"].iloc[0] == pytest.approx(10.0)
    assert [lap.lap for lap in part.laps] == [1]
    assert len(part.frame) == 100


@pytest.mark.parametrize(("budget", "code"), [(300.0, 0), (0.5, 1)])
def test_cli_exit_code_and_message(tmp_path: Path, monkeypatch, budget: float, code: int) -> None:
    from brakethermo.cli import app

    path = write_session_parquet(tmp_path / "race.parquet", 3)
    estimate, _ = _slow_on_lap(1, 0.06)
    monkeypatch.setattr(estimate_mod, "estimate_from_session", estimate)
    args = ["timing-check", str(path), "--budget-s", str(budget), "--race-laps", "25"]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == code, res.output
    if code:
        assert "lap 1 took" in res.output and "over the budget of 0.02 s/lap" in res.output
    else:
        assert "worst: lap 1" in res.output
    res = CliRunner().invoke(app, [*args, "--json"])
    assert res.exit_code == code
    record = json.loads(res.stdout)
    assert record["worst_lap"] == 1 and [r["lap"] for r in record["laps"]] == [0, 1, 2]
