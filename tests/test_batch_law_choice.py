"""Issue 12 items 9, 10, 12: batch chooses the h law deliberately, records it, shows progress."""

from __future__ import annotations

import functools
import json
from pathlib import Path

import pytest
from _synth_race import SynthBatchRunner, write_session_parquet

from brakethermo.io.atomic import write_text_atomic
from brakethermo.pipelines import batch as batch_mod
from brakethermo.pipelines.batch import (
    DEFAULT_LAW,
    BatchOptions,
    Phase,
    SessionOutcome,
    choose_law,
    process_session,
    run_batch,
)
from brakethermo.pipelines.batch import session as batch_session


class LawRunner(SynthBatchRunner):
    """Every session notes the law it ran with in its summary, as the pipelines do."""

    def record(self, stage: Path, written: Path | None, given: Path | None) -> None:
        law = written or given
        write_text_atomic(stage / "summary.json",
                          json.dumps({"run": {"h_law": str(law) if law else "shipped"}}))


JOB = functools.partial(process_session, runner=LawRunner())


def _outcome(name: str, date: str, **facts: str) -> SessionOutcome:
    return SessionOutcome(Path(f"/nowhere/{name}.mcap"), name, "ok", kind="multi",
                          h_law_file=f"/out/{name}/h_law.toml", session_date=date,
                          facts={"date": date, **facts})


def test_same_disc_first_then_track_and_vehicle_then_newest():
    laws = [
        _outcome("other_disc_newest", "2026-09-01", disc="cc-380", track="A", vehicle="X"),
        _outcome("same_disc_other_track", "2026-08-01", disc="cc-340-8", track="B",
                 vehicle="X"),
        _outcome("same_disc_same_track_old", "2026-01-01", disc="cc-340-8", track="A",
                 vehicle="Y"),
        _outcome("same_disc_same_track_new", "2026-02-01", disc="cc-340-8", track="A",
                 vehicle="Y"),
    ]
    choice = choose_law({"disc": "cc-340-8", "track": "A", "vehicle": "Y"}, laws)
    assert choice.source == "identified: same_disc_same_track_new"
    assert "same disc cc-340-8" in choice.reason and "same track A" in choice.reason
    assert "same vehicle Y" in choice.reason and "newest of 3" in choice.reason
    other = choose_law({"disc": "cc-340-8", "track": "C"}, laws)
    assert other.source == "identified: same_disc_other_track"  # newest of the same disc


def test_never_another_discs_law_and_it_says_so():
    laws = [_outcome("foreign", "2026-09-01", disc="cc-380", track="A")]
    choice = choose_law({"disc": "cc-340-8", "track": "A"}, laws)
    assert choice.path is None and choice.source == DEFAULT_LAW
    assert "no law identified in this batch for disc cc-340-8" in choice.reason
    assert "foreign (cc-380)" in choice.reason


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    src = tmp_path / "in"
    src.mkdir()
    # Processing order would pick 'z_other_disc' as the most recent law.
    write_session_parquet(src / "a_mugello.parquet", 1, seed=1, multi=True, date="2026-05-01",
                          facts={"track": "mugello"})
    write_session_parquet(src / "b_misano.parquet", 1, seed=2, multi=True, date="2026-05-03",
                          facts={"track": "misano"})
    write_session_parquet(src / "z_other_disc.parquet", 1, seed=3, multi=True,
                          date="2026-06-01", facts={"disc": "cc-380-9", "track": "mugello"})
    write_session_parquet(src / "race_mugello.parquet", 1, seed=4, date="2026-05-04",
                          facts={"track": "mugello"})
    return src


def test_batch_uses_records_and_prints_the_choice(folder, tmp_path):
    out = tmp_path / "out"
    events: list[tuple[str, object]] = []
    result = run_batch(folder, BatchOptions(out=out, reports=False), job=JOB,
                       on_event=lambda k, p: events.append((k, p)))
    race = {o.name: o for o in result.outcomes}["race_mugello"]
    assert race.status == "ok", race.reason
    assert race.h_law_source == "identified: a_mugello"
    assert race.h_law_used == str(out / "a_mugello" / "h_law.toml")
    assert "same track mugello" in race.h_law_reason
    record = json.loads((out / "race_mugello" / batch_mod.MANIFEST).read_text())
    assert record["h_law_used"] == race.h_law_used and record["h_law_reason"] == race.h_law_reason
    summary = json.loads((out / "race_mugello" / "summary.json").read_text())
    assert summary["run"]["h_law"] == race.h_law_used
    assert summary["run"]["h_law_choice"] == race.h_law_reason
    # item 10: a four-spot session's summary names the final law, not the staging folder
    multi = json.loads((out / "a_mugello" / "summary.json").read_text())
    assert multi["run"]["h_law"] == str(out / "a_mugello" / "h_law.toml")
    assert Path(multi["run"]["h_law"]).is_file()
    records = {r["name"]: r for r in result.to_json()["sessions"]}
    assert records["race_mugello"]["h_law_reason"] == race.h_law_reason
    assert records["race_mugello"]["h_law_file"] == race.h_law_used
    # A re-run with nothing changed skips the race (same law chosen again).
    again = run_batch(folder, BatchOptions(out=out, reports=False), job=JOB)
    assert {o.name: o.status for o in again.outcomes}["race_mugello"] == "skipped"


def test_progress_names_session_phase_and_laps(folder, tmp_path, monkeypatch):
    monkeypatch.setattr(batch_session, "PipelineRunner", LawRunner)
    for name in ("b_misano", "z_other_disc"):
        (folder / f"{name}.parquet").unlink()
    phases: list[Phase] = []

    def keep(kind: str, payload: object) -> None:
        if kind == "phase":
            phases.append(payload)  # type: ignore[arg-type]

    # Reports only for the race (rendering is the slow part), then the test session alone.
    (folder / "a_mugello.parquet").rename(tmp_path / "a_mugello.parquet")
    run_batch(folder, BatchOptions(out=tmp_path / "out"), on_event=keep)
    (tmp_path / "a_mugello.parquet").rename(folder / "a_mugello.parquet")
    (folder / "race_mugello.parquet").unlink()
    run_batch(folder, BatchOptions(out=tmp_path / "out", reports=False), on_event=keep)
    race = [p for p in phases if p.name == "race_mugello"]
    assert [p.phase for p in race][:2] == ["reading", "estimating"]
    reports = [(p.done, p.total) for p in race if p.phase == "reports"]
    assert reports and reports[-1][0] == reports[-1][1] >= 1
    assert any(p.phase == "identifying h(V)" for p in phases if p.name == "a_mugello")


def test_cli_progress_and_choice_lines(folder, tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from brakethermo.cli import app

    monkeypatch.setattr(batch_session, "PipelineRunner", LawRunner)
    res = CliRunner().invoke(app, ["batch", str(folder), "--out", str(tmp_path / "o"),
                                   "--no-reports"], env={"COLUMNS": "80"})
    assert res.exit_code == 0, res.output
    text = " ".join(res.output.split())
    assert "race_mugello: h law batch — identified from a_mugello (same disc cc-340-8" in text
    assert max(len(line) for line in res.output.splitlines()) <= 80


def test_an_assumed_disc_and_a_law_of_another_disc_are_said_on_the_console(tmp_path):
    """A CSV without session facts was taken for disc cc-340-8 with no word, the batch
    reporting "same disc cc-340-8" as if known; batch --h-law with a law of another disc
    ran with exit 0, status ok, the mismatch said only inside summary.json."""
    from _synth_race import write_session_csv
    from typer.testing import CliRunner

    from brakethermo.cli import app
    from brakethermo.config import config_dir
    from brakethermo.pipelines.batch.laws import session_facts
    from brakethermo.pipelines.models import DISC_ASSUMED, assumed_disc

    folder = tmp_path / "day"
    folder.mkdir()
    race = write_session_csv(folder / "race_hand.csv", 1, seed=4)
    session = LawRunner().load(race, BatchOptions(out=tmp_path / "o"))
    assert assumed_disc(session).startswith(DISC_ASSUMED)
    assert assumed_disc(session, "cc-340-8") is None
    facts = session_facts(session)
    assert facts["disc"] == "cc-340-8" and facts["disc_assumed"] == "yes"
    laws = [_outcome("test_day", "2026-01-01", disc="cc-340-8")]
    assert "same disc cc-340-8 (assumed: the file's facts name no disc)" in choose_law(
        facts, laws).reason
    assert "assumed" not in choose_law({"disc": "cc-340-8"}, laws).reason

    shipped = config_dir() / "hlaw" / "cc-340-8.toml"
    other = tmp_path / "other_disc_law.toml"
    other.write_text(shipped.read_text().replace('disc = "cc-340-8"', 'disc = "cc-355-9"'))
    res = CliRunner().invoke(app, ["batch", str(folder), "--out", str(tmp_path / "o"),
                                   "--h-law", str(other), "--no-reports"],
                             env={"COLUMNS": "200"})
    assert res.exit_code == 0, res.output
    text = " ".join(res.output.split())
    assert "warning: race_hand: the session's facts name no disc" in text
    # a long temporary path may wrap anywhere (under xdist the console ignores COLUMNS)
    flat = "".join(res.output.split())
    assert "".join(("warning: race_hand: " + str(other) + ": this h law was identified on"
                    " disc 'cc-355-9'").split()) in flat
    res = CliRunner().invoke(app, ["batch", str(folder), "--out", str(tmp_path / "o"),
                                   "--h-law", str(other), "--no-reports", "--json"])
    row = json.loads(res.output)["sessions"][0]
    assert row["status"] == "skipped" and len(row["warnings"]) == 2  # said again
    res = CliRunner().invoke(app, ["estimate", str(race), "--out", str(tmp_path / "e"),
                                   "--no-reports"], env={"COLUMNS": "200"})
    assert res.exit_code == 0, res.output
    assert "warning: the session's facts name no disc: processed as the default disc" \
           " cc-340-8" in " ".join(res.output.split())
