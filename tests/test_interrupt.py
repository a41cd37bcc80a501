"""Ctrl-C during batch: exit 130, one line saying what finished, finished sessions intact,
the interrupted one as before, and the next run resumes."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

CMD = [sys.executable, "-c", "from brakethermo.__main__ import main; main()"]


@pytest.mark.skipif(os.name != "posix", reason="SIGINT semantics of POSIX")
def test_sigint_during_batch_then_resume(sim_test_session, sim_race_session,
                                         tmp_path: Path) -> None:
    folder = tmp_path / "sessions"
    folder.mkdir()
    shutil.copy(sim_race_session[0], folder / "a_race.parquet")
    shutil.copy(sim_race_session[0], folder / "b_race.parquet")
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    proc = subprocess.Popen([*CMD, "batch", str(folder), "--out", str(out), "--no-reports",
                             "--h-law", str(Path(__file__).resolve().parents[1] / "configs"
                                            / "hlaw" / "cc-340-8.toml")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and not list(out.glob("*/batch_manifest.json")):
        time.sleep(0.2)
        if proc.poll() is not None:
            break
    if proc.poll() is not None:
        pytest.skip("the batch finished before it could be interrupted")
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stdout + stderr
    assert "interrupted" in stderr and "Traceback" not in stderr
    assert "Exception ignored" not in stderr
    finished = [p.parent.name for p in out.glob("*/batch_manifest.json")]
    assert finished, "the finished session's outputs are complete"
    for name in finished:
        assert (out / name / "estimate.parquet").is_file()
    assert not list(out.glob(".*stage*")), "no staging folder left behind"
    # the next run resumes: finished sessions are skipped, the rest done
    res = subprocess.run([*CMD, "batch", str(folder), "--out", str(out), "--no-reports",
                          "--h-law", str(Path(__file__).resolve().parents[1] / "configs"
                                         / "hlaw" / "cc-340-8.toml")],
                         capture_output=True, text=True, env=env, timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr
    assert len(list(out.glob("*/batch_manifest.json"))) == 2


@pytest.mark.skipif(os.name != "posix", reason="SIGINT semantics of POSIX")
@pytest.mark.parametrize("fraction", [0.3, 0.7])
def test_sigint_during_estimate_leaves_the_old_results(sim_race_session, tmp_path: Path,
                                                       fraction: float) -> None:
    """Ctrl-C while estimate filters or writes: exit 130, one line, the folder as it was
    (the earlier run's files intact, no staging folder), and a re-run completes. The
    interrupt comes at a fraction of an uninterrupted run's time (a fixed delay landed
    after the end once the filter got faster, while the process was exiting)."""
    race = sim_race_session[0]
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    first = subprocess.run([*CMD, "estimate", str(race), "--out", str(out)],
                           capture_output=True, text=True, env=env, timeout=300)
    assert first.returncode == 0, first.stdout + first.stderr
    # the reference time from a run with the kernels compiled: on a fresh checkout the
    # first compiles them, and a fraction of its time landed after a cached run's end
    t0 = time.monotonic()
    again = subprocess.run([*CMD, "estimate", str(race), "--out", str(out)],
                           capture_output=True, text=True, env=env, timeout=300)
    after_s = fraction * (time.monotonic() - t0)
    assert again.returncode == 0, again.stdout + again.stderr
    folder = out / race.stem
    before = {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}
    proc = subprocess.Popen([*CMD, "estimate", str(race), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    time.sleep(after_s)
    if proc.poll() is not None:
        pytest.skip("the estimate finished before it could be interrupted")
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stdout + stderr
    assert "Traceback" not in stderr and "Exception ignored" not in stderr
    assert len([line for line in stderr.splitlines() if line.strip()]) == 1, stderr
    after = {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}
    assert after == before, "the interrupted run changed the earlier results"
    assert not list(out.rglob(".*stage*")), "no staging folder left behind"
    again = subprocess.run([*CMD, "estimate", str(race), "--out", str(out)],
                           capture_output=True, text=True, env=env, timeout=300)
    assert again.returncode == 0, again.stdout + again.stderr
    assert (folder / "index.html").is_file()


def test_an_interrupt_while_the_cli_imports_is_one_line(monkeypatch, capsys) -> None:
    """Ctrl-C before the commands are loaded (numpy, scipy, numba importing): the
    console script says the same one line and exits 130, no traceback."""
    import types

    from brakethermo.__main__ import main

    class Importing(types.ModuleType):
        def __getattr__(self, name: str) -> None:
            raise KeyboardInterrupt

    monkeypatch.setitem(sys.modules, "brakethermo.cli", Importing("brakethermo.cli"))
    with pytest.raises(SystemExit) as stop:
        main()
    assert stop.value.code == 130
    err = capsys.readouterr().err
    assert err.startswith("interrupted:") and len(err.strip().splitlines()) == 1


@pytest.mark.skipif(os.name != "posix", reason="SIGINT semantics of POSIX")
def test_an_interrupt_during_shutdown_is_ignored(tmp_path: Path) -> None:
    """After the command (its outputs written) the interpreter still tears down; an
    interrupt there raised in the teardown or killed the process (exit -2, once an
    abort). Here the teardown is held open by an exit hook: the interrupt is ignored and
    the process ends with the command's own code, saying nothing more."""
    script = (
        "import atexit, sys, time\n"
        "import brakethermo.cli\n"
        "from brakethermo.__main__ import main\n"
        "atexit.register(time.sleep, 3)\n"
        "print('ready', flush=True)\n"
        "sys.argv = ['brakethermo', '--version']\n"
        "main()\n"
    )
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == "ready"
    time.sleep(1.5)  # --version is printed and the exit hook is sleeping
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 0, stderr
    assert "brakethermo" in stdout and not stderr.strip(), stderr


def test_an_interrupt_after_the_outputs_says_they_are_complete(sim_race_session, tmp_path,
                                                               monkeypatch) -> None:
    """An interrupt between the atomic write and the console table said "nothing of this
    run was written" while the estimate's folder was complete."""
    from typer.testing import CliRunner

    import brakethermo.cli.estimate_cmd as estimate_cmd
    from brakethermo.cli import app

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(estimate_cmd, "_render", interrupted)
    race = sim_race_session[0]
    out = tmp_path / "out"
    res = CliRunner().invoke(app, ["estimate", str(race), "--out", str(out), "--no-report"],
                             env={"COLUMNS": "300"})
    assert res.exit_code == 130, res.output
    assert (out / race.stem / "estimate.parquet").is_file()
    assert "nothing of this run was written" not in res.output
    assert "written 1 output(s)" in res.output and str(out / race.stem) in res.output


def test_the_record_of_outputs_leaves_out_caches_stages_and_nested_pages(tmp_path) -> None:
    from brakethermo.errors import committed_outputs, forget_committed
    from brakethermo.io.atomic import atomic_dir, atomic_entries, write_text_atomic

    forget_committed()
    write_text_atomic(tmp_path / "cache.json", "{}", output=False)  # e.g. the unit memo
    with atomic_entries(tmp_path / "race", ("*",)) as stage:
        write_text_atomic(stage / "summary.json", "{}")  # inside a stage: not yet output
    write_text_atomic(tmp_path / "race" / "index.html", "<html/>")  # inside the folder
    with atomic_dir(tmp_path / "race" / "diagnosis") as d:
        (d / "index.html").write_text("<html/>")
    user = tmp_path / "run.stage.2"  # a user's folder that only looks like a stage
    write_text_atomic(user / "h_law.toml", "x = 1")
    assert committed_outputs() == [tmp_path / "race", user / "h_law.toml"]
