"""batch: failure isolation, idempotence, atomic outputs, worker processes and Dask.

The science is a synthetic runner (real readers, a heat-balance estimate frame), so
these tests exercise the orchestration, the writers and the reports independently of
the estimation pipelines.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np
import pytest
from _synth_race import (
    SynthBatchRunner,
    write_session_csv,
    write_session_parquet,
)
from typer.testing import CliRunner

from brakethermo.config import config_dir
from brakethermo.errors import EXIT_BATCH_PARTIAL
from brakethermo.io.atomic import write_text_atomic
from brakethermo.pipelines import batch as batch_mod
from brakethermo.pipelines.batch import (
    MANIFEST,
    BatchOptions,
    discover_sessions,
    output_names,
    process_session,
    run_batch,
)
from brakethermo.pipelines.batch import scheduling as batch_scheduling
from brakethermo.pipelines.batch import session as batch_session
from brakethermo.pipelines.batch import tasks as batch_tasks


class SynthRunner(SynthBatchRunner):
    """A session without spots of its own notes the law it was given in law_used.txt."""

    def record(self, stage: Path, written: Path | None, given: Path | None) -> None:
        if written is None:
            write_text_atomic(stage / "law_used.txt", str(given))


JOB = functools.partial(process_session, runner=SynthRunner())


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    src = tmp_path / "download"
    (src / "day1").mkdir(parents=True)
    write_session_parquet(
        src / "day1" / "test_am.parquet", 1, seed=1, multi=True, date="2026-05-01"
    )
    write_session_parquet(src / "test_pm.parquet", 1, seed=2, multi=True, date="2026-05-02")
    write_session_parquet(src / "race.parquet", 2, seed=3)
    write_session_csv(src / "day1" / "fp1.csv", 1, seed=4)
    # Simulator truth beside a session: never an input.
    write_session_parquet(src / "race.truth.parquet", 1, seed=5)
    # A logger that lost power mid-write, and a file that is not a session at all.
    good = (src / "race.parquet").read_bytes()
    (src / "truncated.parquet").write_bytes(good[: len(good) // 3])
    (src / "garbage.mcap").write_bytes(b"\x89MCAP0\r\n" + bytes(range(256)) * 4)
    return src


def _options(tmp_path: Path, **kw) -> BatchOptions:
    return BatchOptions(out=tmp_path / "out", **kw)


def test_discovery_skips_truth_and_hidden(folder: Path) -> None:
    (folder / ".cache").mkdir()
    write_session_csv(folder / ".cache" / "old.csv", 1)
    names = [p.name for p in discover_sessions(folder)]
    assert names == [
        "fp1.csv",
        "test_am.parquet",
        "garbage.mcap",
        "race.parquet",
        "test_pm.parquet",
        "truncated.parquet",
    ]


def test_output_names_are_unique(tmp_path: Path) -> None:
    files = [
        tmp_path / "a" / "s.csv",
        tmp_path / "b" / "s.csv",
        tmp_path / "a" / "s.mcap",
        tmp_path / "t.csv",
    ]
    names = output_names(files, tmp_path)
    assert names == ["a__s_csv", "b__s", "a__s_mcap", "t"]
    # case-only differences and a stem that equals another's suffixed name
    same = [tmp_path / "s.mcap", tmp_path / "s.MCAP", tmp_path / "s.csv",
            tmp_path / "s_mcap.mcap"]
    names = output_names(same, tmp_path)
    assert len({n.casefold() for n in names}) == 4, names


def test_out_that_is_or_holds_the_input_is_refused(tmp_path: Path) -> None:
    from brakethermo.cli import app

    (tmp_path / "in").mkdir()
    for args in ([str(tmp_path / "in"), "--out", str(tmp_path / "in")],
                 [str(tmp_path / "in"), "--out", str(tmp_path)]):
        res = CliRunner().invoke(app, ["batch", *args])
        assert res.exit_code == 1 and "--out" in res.output, res.output
        assert "Traceback" not in res.output


def test_failures_isolated_and_rerun_skips(folder: Path, tmp_path: Path) -> None:
    from brakethermo.errors import committed_outputs, forget_committed

    options = _options(tmp_path)
    events: list[str] = []
    forget_committed()
    result = run_batch(folder, options, job=JOB, on_event=lambda k, p: events.append(k))
    by_name = {o.name: o for o in result.outcomes}
    # sessions written in worker processes are recorded by the batch (what an interrupt
    # after them reports), each folder once, its pages counted with it
    recorded = committed_outputs()
    assert {options.out / n for n in ("test_am", "test_pm", "race", "fp1")} <= set(recorded)
    assert not any(p.parent.name in by_name for p in recorded)
    assert set(by_name) == {"test_am", "test_pm", "race", "fp1", "truncated", "garbage"}
    assert result.exit_code == EXIT_BATCH_PARTIAL
    assert {o.name for o in result.failed} == {"truncated", "garbage"}
    for o in result.failed:
        assert str(o.path) in o.reason and "internal error" not in o.reason
    assert events[0] == "start" and events.count("done") == 6
    out = options.out
    for name in ("test_am", "test_pm", "race", "fp1"):
        assert by_name[name].status == "ok"
        assert (out / name / "index.html").is_file()
        assert (out / name / "lap_00" / "index.html").is_file()
        assert (out / name / MANIFEST).is_file()
    assert (out / "race" / "lap_01" / "spots.png").is_file()
    # Multi-spot sessions are identified first; race sessions use the most recent law.
    assert by_name["test_pm"].kind == "multi" and by_name["race"].kind == "single"
    assert by_name["race"].h_law_source == "identified: test_pm"
    assert (out / "race" / "law_used.txt").read_text() == str(out / "test_pm" / "h_law.toml")
    assert by_name["race"].laps == 1 and by_name["race"].peaks["spot3"] > 200
    assert not (out / "truncated").exists()
    index = (out / "index.html").read_text()
    assert 'href="race/index.html"' in index and 'href="truncated' not in index
    assert by_name["truncated"].reason.split(":")[-1].strip()[:20] in index

    again = run_batch(folder, options, job=JOB)
    assert {o.name: o.status for o in again.outcomes} == {
        "test_am": "skipped",
        "test_pm": "skipped",
        "race": "skipped",
        "fp1": "skipped",
        "truncated": "failed",
        "garbage": "failed",
    }
    assert again.exit_code == EXIT_BATCH_PARTIAL
    assert {o.name: o.laps for o in again.outcomes}["race"] == 1

    # A changed input is re-processed; the others stay skipped.
    write_session_csv(folder / "day1" / "fp1.csv", 1, seed=9)
    third = {o.name: o.status for o in run_batch(folder, options, job=JOB).outcomes}
    assert third["fp1"] == "ok" and third["race"] == "skipped"
    forced = run_batch(folder, _options(tmp_path, force=True), job=JOB)
    assert {o.status for o in forced.outcomes} == {"ok", "failed"}


def test_outputs_replaced_since_are_redone_and_earlier_sessions_kept(
        folder: Path, tmp_path: Path) -> None:
    """A session whose results another command replaced since the batch (an estimate
    with another law into the same --out) is redone, not reported "up to date" with the
    manifest's numbers; a batch of another folder into the same --out keeps the first
    batch's sessions on the index."""
    options = _options(tmp_path)
    run_batch(folder, options, job=JOB)
    est = options.out / "race" / "estimate.parquet"
    est.write_bytes(est.read_bytes() + b"\0")  # as another command's rewrite would
    again = {o.name: o.status for o in run_batch(folder, options, job=JOB).outcomes}
    assert again["race"] == "ok" and again["fp1"] == "skipped", again
    import shutil

    shutil.rmtree(options.out / "fp1" / "lap_00")
    (options.out / "fp1" / "index.html").unlink()  # estimate --no-report's leftovers
    assert {o.name: o.status for o in run_batch(folder, options, job=JOB).outcomes
            }["fp1"] == "ok"

    other = tmp_path / "day2"
    other.mkdir()
    write_session_parquet(other / "quali.parquet", 1, seed=7)
    run_batch(other, options, job=JOB)
    index = (options.out / "index.html").read_text()
    assert 'href="quali/index.html"' in index
    for name in ("race", "fp1", "test_am"):
        assert f'href="{name}/index.html"' in index, name
    assert "earlier batch" in index


def test_the_batch_page_follows_commands_run_into_its_folder(folder: Path, tmp_path: Path
                                                             ) -> None:
    """`estimate … --out OUT` into a batch's session folder left OUT/index.html showing
    the batch's peaks and law for results no longer the batch's; a later batch with
    --no-reports left the page without its sessions."""
    from brakethermo.pipelines.batch.index import refresh_batch_index

    options = _options(tmp_path)
    run_batch(folder, options, job=JOB)
    index = options.out / "index.html"
    assert "replaced by another command" not in index.read_text()
    est = options.out / "race" / "estimate.parquet"
    est.write_bytes(est.read_bytes() + b"\0")  # as another command's rewrite would
    assert refresh_batch_index(options.out) == index
    page = index.read_text()
    assert page.count("replaced by another command since") == 1
    # the row said "up to date" above "its results were replaced … since"
    race_row = page[page.index('href="race/index.html"'):].split("</tr>")[0]
    assert ">replaced<br>" in race_row and "up to date" not in race_row
    assert 'href="race/index.html"' in page and 'href="fp1/index.html"' in page
    assert refresh_batch_index(tmp_path) is None  # no batch there: nothing written
    assert not (tmp_path / "index.html").exists()

    other = tmp_path / "day2"
    other.mkdir()
    write_session_parquet(other / "quali.parquet", 1, seed=7)
    run_batch(other, _options(tmp_path, reports=False), job=JOB)
    assert "quali" in index.read_text()


def test_a_row_whose_law_was_rewritten_is_stale_not_up_to_date(folder: Path,
                                                                tmp_path: Path) -> None:
    """identify-h into a batch's test-session folder rewrote the law a race was estimated
    with; the race's row still said "up to date" (the manifest records the law's bytes)."""
    from brakethermo.pipelines.batch.index import refresh_batch_index

    options = _options(tmp_path)
    outcomes = {o.name: o for o in run_batch(folder, options, job=JOB).outcomes}
    race = outcomes["race"]
    assert race.h_law_used is not None
    law = Path(race.h_law_used)
    assert refresh_batch_index(options.out) is not None
    assert "stale" not in (options.out / "index.html").read_text()
    law.write_text(law.read_text() + "\n# identified again\n")
    page = refresh_batch_index(options.out).read_text()  # type: ignore[union-attr]
    row = page[page.index('href="race/index.html"'):].split("</tr>")[0]
    assert ">stale<br>" in row and "up to date" not in row, row
    assert "was rewritten since" in row and law.parent.name in row


def test_pages_later_commands_wrote_into_out_are_linked(folder: Path, tmp_path: Path
                                                       ) -> None:
    """`diagnose a b --out OUT` into a batch's --out wrote OUT/pooled/ and OUT/<b>/ (a
    session the batch never read); the index linked neither, even after a re-batch."""
    from brakethermo.pipelines.batch.index import refresh_batch_index

    options = _options(tmp_path)
    run_batch(folder, options, job=JOB)
    pooled, other = options.out / "pooled", options.out / "ft_b" / "diagnosis"
    for page in (pooled, other):
        page.mkdir(parents=True)
        (page / "index.html").write_text("<html></html>")
    (pooled / "diagnosis.json").write_text("{}")
    (options.out / ".stage-x").mkdir()  # a staging folder is no page
    for page in (refresh_batch_index(options.out).read_text(),  # type: ignore[union-attr]
                 (run_batch(folder, options, job=JOB), options.out / "index.html")[1]
                 .read_text()):
        assert 'href="pooled/index.html">pooled diagnosis</a>' in page
        assert 'href="ft_b/diagnosis/index.html">diagnosis</a>' in page
        assert ".stage-x" not in page
        assert page.count('href="race/index.html"') == 1  # a session stays in its row


def test_another_session_of_a_name_in_out_fails_alone(folder: Path, tmp_path: Path) -> None:
    """A second day's race.parquet batched into the first day's --out replaced the first
    race's results with no word (estimate and the other commands refuse it): that session
    fails, naming both files, and the others are run."""
    options = _options(tmp_path)
    run_batch(folder, options, job=JOB)
    before = (options.out / "race" / "estimate.parquet").read_bytes()
    day2 = tmp_path / "day2"
    day2.mkdir()
    write_session_parquet(day2 / "race.parquet", 2, seed=9)
    write_session_parquet(day2 / "quali.parquet", 1, seed=7)
    result = run_batch(day2, options, job=JOB)
    status = {o.name: o for o in result.outcomes}
    assert status["quali"].status == "ok" and status["race"].status == "failed"
    assert result.exit_code == EXIT_BATCH_PARTIAL
    reason = status["race"].reason
    assert str(folder / "race.parquet") in reason and "another --out" in reason, reason
    assert (options.out / "race" / "estimate.parquet").read_bytes() == before
    # the same file again (the first day's folder re-run) is its own session: no refusal
    assert {o.name: o.status for o in run_batch(folder, options, job=JOB).outcomes
            }["race"] == "skipped"


def test_a_rig_log_in_the_folder_is_listed_not_failed(tmp_path: Path) -> None:
    """A test day's folder with a caliper log beside the disc sessions: the log was
    counted as a failed disc session (exit 3)."""
    from brakethermo.sim.emb import simulate_emb, write_emb_simulation

    src = tmp_path / "day"
    src.mkdir()
    write_session_parquet(src / "race.parquet", 1, seed=3)
    write_emb_simulation(simulate_emb("nominal", seed=7, duration_s=3), src / "emb.mcap")
    result = run_batch(src, _options(tmp_path), job=JOB)
    status = {o.name: (o.status, o.reason) for o in result.outcomes}
    assert status["race"][0] == "ok" and status["emb"][0] == "rig session"
    assert "brakethermo clamp-force reads it" in status["emb"][1]
    # its kind is the rig's (the table listed it as a "single"-spot disc session)
    assert {o.name: o.kind for o in result.outcomes}["emb"] == "emb"
    assert result.exit_code == 0 and "rig session" in (tmp_path / "out" / "index.html"
                                                        ).read_text()


def test_given_h_law_used_and_part_of_the_key(folder: Path, tmp_path: Path) -> None:
    law = tmp_path / "law.toml"
    shipped = (config_dir() / "hlaw" / "cc-340-8.toml").read_text()
    law.write_text(shipped)
    options = _options(tmp_path, h_law=law, reports=False)
    first = {o.name: o for o in run_batch(folder, options, job=JOB).outcomes}
    assert first["race"].h_law_source == "given"
    assert (options.out / "race" / "law_used.txt").read_text() == str(law)
    law.write_text(shipped + "# edited\n")
    second = {o.name: o.status for o in run_batch(folder, options, job=JOB).outcomes}
    assert second["race"] == "ok" and second["test_am"] == "skipped"


def test_default_law_without_multi_spot_sessions(tmp_path: Path) -> None:
    src = tmp_path / "race_only"
    src.mkdir()
    write_session_parquet(src / "race.parquet", 1)
    (o,) = run_batch(src, _options(tmp_path), job=JOB).outcomes
    assert o.status == "ok" and o.h_law_source == batch_mod.DEFAULT_LAW


def test_interrupted_write_leaves_old_report(folder: Path, tmp_path: Path, monkeypatch) -> None:
    options = _options(tmp_path)
    run_batch(folder, options, job=JOB)
    race = options.out / "race"
    before = {p.relative_to(race): p.read_bytes() for p in race.rglob("*") if p.is_file()}

    from brakethermo.report import lap_report

    def broken_report(estimate, session, out_dir, **kw):
        (Path(out_dir) / "lap_00").mkdir(parents=True, exist_ok=True)
        (Path(out_dir) / "lap_00" / "index.html").write_text("<html>half")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(lap_report, "write_session_report", broken_report)
    result = run_batch(folder, _options(tmp_path, force=True), job=JOB)
    race_outcome = next(o for o in result.outcomes if o.name == "race")
    assert race_outcome.status == "failed" and "No space left" in race_outcome.reason
    after = {p.relative_to(race): p.read_bytes() for p in race.rglob("*") if p.is_file()}
    assert after == before
    assert not [p for p in options.out.iterdir() if p.name.startswith(".")]


def _on_worker_job(task):
    """JOB, marking outcomes computed on a Dask worker."""
    from distributed import get_worker

    outcome = JOB(task)
    try:
        get_worker()
    except ValueError:
        return outcome
    outcome.timings["on_dask_worker"] = 1.0
    return outcome


def test_dask_local_cluster_matches_serial(folder: Path, tmp_path: Path, monkeypatch) -> None:
    distributed = pytest.importorskip("distributed")

    def cluster():
        return distributed.LocalCluster(
            n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None
        )

    with cluster() as c:
        options = _options(tmp_path, scheduler=c.scheduler_address)
        result = run_batch(folder, options, job=_on_worker_job)
    # The scheduler can also come from the environment, as on a cluster login node.
    with cluster() as c:
        monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", c.scheduler_address)
        env_run = run_batch(folder, _options(tmp_path / "env", reports=False), job=_on_worker_job)
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS")
    assert [o.status for o in env_run.outcomes] == [o.status for o in result.outcomes]
    for o in (*result.outcomes, *env_run.outcomes):
        assert o.status == "failed" or o.timings["on_dask_worker"] == 1.0
    statuses = {o.name: o.status for o in result.outcomes}
    assert statuses == {
        "test_am": "ok",
        "test_pm": "ok",
        "race": "ok",
        "fp1": "ok",
        "truncated": "failed",
        "garbage": "failed",
    }
    assert next(o for o in result.outcomes if o.name == "race").h_law_source == (
        "identified: test_pm"
    )
    serial = _options(tmp_path / "serial")
    run_batch(folder, serial, job=JOB)
    race_d = json.loads((options.out / "race" / MANIFEST).read_text())
    race_s = json.loads((serial.out / "race" / MANIFEST).read_text())
    assert race_d["peaks_c"] == race_s["peaks_c"]


def test_worker_processes(tmp_path: Path) -> None:
    src = tmp_path / "two"
    src.mkdir()
    write_session_parquet(src / "a.parquet", 1, seed=1)
    write_session_parquet(src / "b.parquet", 1, seed=2, multi=True)
    (src / "c.csv").write_text("time,speed [wibble/fortnight]\n0,1\n")
    result = run_batch(src, _options(tmp_path, workers=2), job=JOB)
    assert [o.status for o in result.outcomes] == ["ok", "ok", "failed"]
    assert "wibble" in result.outcomes[2].reason
    assert result.outcomes[0].h_law_source == "identified: b"


def test_unreachable_scheduler_is_a_user_error(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr(batch_scheduling, "SCHEDULER_TIMEOUT_S", 1.0)
    src = tmp_path / "s"
    src.mkdir()
    write_session_parquet(src / "race.parquet", 1)
    from brakethermo.errors import ConfigError

    with pytest.raises(ConfigError, match="Dask scheduler"):
        run_batch(src, _options(tmp_path, scheduler="tcp://127.0.0.1:9"), job=JOB)


def test_cli_exit_code_table_and_json(folder: Path, tmp_path: Path, monkeypatch) -> None:
    from brakethermo.cli import app

    monkeypatch.setattr(batch_session, "PipelineRunner", SynthRunner)
    out = tmp_path / "cli_out"
    res = CliRunner().invoke(app, ["batch", str(folder), "--out", str(out), "--mcap-out"])
    assert res.exit_code == EXIT_BATCH_PARTIAL, res.output
    assert "truncated" in res.output and "failed" in res.output
    assert (out / "race" / "estimate.mcap").is_file()
    res = CliRunner().invoke(app, ["batch", str(folder), "--out", str(out), "--mcap-out", "--json"])
    assert res.exit_code == EXIT_BATCH_PARTIAL
    summary = json.loads(res.stdout)
    statuses = {s["name"]: s["status"] for s in summary["sessions"]}
    assert statuses["race"] == "skipped" and statuses["garbage"] == "failed"
    assert np.isclose(sum(1 for s in summary["sessions"] if s["status"] == "failed"), 2)


def test_output_key_covers_options_and_shipped_configs(tmp_path: Path, monkeypatch) -> None:
    shipped = tmp_path / "configs"
    (shipped / "hlaw").mkdir(parents=True)
    (shipped / "hlaw" / "cc-340-8.toml").write_text("a = 1\n")
    monkeypatch.setattr(batch_tasks, "config_dir", lambda: shipped)
    base = BatchOptions(out=tmp_path)
    key = base.output_key()
    assert key == BatchOptions(out=tmp_path / "elsewhere", workers=4, force=True).output_key()
    assert key != BatchOptions(out=tmp_path, nodes=21).output_key()
    assert key != BatchOptions(out=tmp_path, mcap_out=True).output_key()
    (shipped / "hlaw" / "cc-340-8.toml").write_text("a = 2\n")
    assert base.output_key() != key


def test_folders_not_read_are_said(tmp_path):
    """A sub-folder that cannot be read and a link to a folder are named, not skipped
    silently; the sessions found elsewhere still run."""
    import os

    root = tmp_path / "sessions"
    (root / "locked").mkdir(parents=True)
    (root / "elsewhere").mkdir()
    os.symlink(root / "elsewhere", root / "link")
    os.symlink(tmp_path / "gone.mcap", root / "race.mcap")  # a link whose target is gone
    os.chmod(root / "locked", 0)
    try:
        notes: list[str] = []
        assert discover_sessions(root, not_read=notes) == []
        assert any("link" in n and "not followed" in n for n in notes)
        assert any("race.mcap" in n and "does not exist" in n for n in notes)
        if os.geteuid() != 0:  # root reads any folder
            assert any("locked" in n and "cannot be read" in n for n in notes)
    finally:
        os.chmod(root / "locked", 0o755)


def test_a_folder_without_sessions_is_an_error(tmp_path: Path) -> None:
    """`batch emptydir` said "no session files" and exited 0, as if all were done."""
    from brakethermo.cli import app

    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("pit board")
    res = CliRunner().invoke(app, ["batch", str(tmp_path / "empty"), "--out",
                                   str(tmp_path / "o")])
    assert res.exit_code == 1 and "no session files" in res.output, res.output
    assert "Traceback" not in res.output


def test_an_interrupt_says_which_sessions_finished(tmp_path: Path) -> None:
    """Ctrl-C after two of four sessions: the message names those two as finished (the
    outcomes reached the batch only when every session was done, so it said none)."""
    from brakethermo.errors import Interrupted
    from brakethermo.pipelines.batch.tasks import SessionOutcome

    folder = tmp_path / "in"
    folder.mkdir()
    for name in ("a", "b", "c", "d"):
        (folder / f"{name}.parquet").write_bytes(name.encode())
    calls: list[str] = []

    def job(task):
        calls.append(task.name)
        if len(calls) > 2:
            raise KeyboardInterrupt
        return SessionOutcome(task.path, task.name, "ok", kind="single")

    options = BatchOptions(out=tmp_path / "out", reports=False, workers=1,
                           h_law=config_dir() / "hlaw" / "cc-340-8.toml")
    with pytest.raises(Interrupted) as info:
        run_batch(folder, options, job=job)
    said = str(info.value)
    assert f"2 of 4 sessions finished ({calls[0]}, {calls[1]})" in said, said
    assert calls[2] in said.split("not done:")[1]


def test_a_refused_folder_or_effect_is_one_line_alone(tmp_path: Path) -> None:
    """The progress bar drew (or left a blank line) before the error's one line."""
    from brakethermo.cli import app

    res = CliRunner().invoke(app, ["batch", str(tmp_path / "missing"), "--out",
                                   str(tmp_path / "o")])
    assert res.exit_code == 1
    assert res.output.strip().splitlines() == res.output.splitlines(), res.output
    assert len(res.output.splitlines()) == 1 and "is not a folder" in res.output
    (tmp_path / "s.mcap").write_bytes(b"")
    res = CliRunner().invoke(app, ["diagnose", str(tmp_path / "s.mcap"), "--effects",
                                   "frictoin_temperature", "--out", str(tmp_path / "o")])
    assert res.exit_code == 1 and res.output.splitlines()[0].startswith("error:"), res.output


def test_a_later_batch_keeps_the_earlier_batchs_rig_rows_and_links_only_its_own(tmp_path):
    """`batch batchdir --out o` then `batch batch3 --out o` dropped batchdir's rig rows
    from o/index.html and batch_index.json (README: the index keeps earlier batches'
    sessions); a failed row, or a rig row whose folder holds another file's results,
    linked those results and their verdict; an index of rig logs read "Disc temperature
    reports"."""
    from brakethermo.cli import app as cli
    from brakethermo.report.index import write_batch_index
    from brakethermo.sim.tyre_rig import simulate_tyre_rig, write_tyre_simulation

    for folder, stem, seed in (("a", "ty1", 1), ("b", "ty2", 2)):
        (tmp_path / folder).mkdir()
        write_tyre_simulation(simulate_tyre_rig(seed=seed), tmp_path / folder / f"{stem}.mcap")
    out = tmp_path / "out"
    for folder in ("a", "b"):
        res = CliRunner().invoke(cli, ["batch", str(tmp_path / folder), "--out", str(out)])
        assert res.exit_code == 0, res.output
    rows = json.loads((out / "batch_index.json").read_text())["sessions"]
    assert [r["name"] for r in rows] == ["ty2", "ty1"]
    assert "disc" not in rows[0]["facts"]  # it read the default disc's cc-340-8
    assert "disc_assumed" not in rows[0]["facts"]  # nor "a disc was assumed" (review)
    assert rows[1]["reason"].startswith(f"from an earlier batch of {tmp_path / 'a'}")
    page = (out / "index.html").read_text()
    assert "ty1" in page and "Rig session reports" in page
    assert "Disc temperature reports" not in page
    # a folder of that stem holding another file's results and verdict
    (out / "rr" / "diagnosis").mkdir(parents=True)
    other = tmp_path / "other" / "rr.mcap"
    other.parent.mkdir()
    other.write_bytes(b"x")
    for name in ("index.html", "diagnosis/index.html"):
        (out / "rr" / name).write_text("<html></html>")
    (out / "rr" / "diagnosis.json").write_text(json.dumps(
        {"session": str(other), "verdict": "creep_slope"}))
    mine = tmp_path / "b" / "rr.mcap"
    mine.write_bytes(b"y")
    for status in ("failed", "rig session"):
        write_batch_index(out, tmp_path / "b", [{"name": "rr", "status": status,
                                                 "file": str(mine), "reason": "r"}])
        page = (out / "index.html").read_text()
        assert 'href="rr/index.html"' not in page and "creep_slope" not in page, status
    write_batch_index(out, tmp_path / "b", [{"name": "rr", "status": "rig session",
                                             "file": str(other), "reason": "r"}])
    page = (out / "index.html").read_text()
    assert 'href="rr/index.html"' in page and "creep_slope" in page
