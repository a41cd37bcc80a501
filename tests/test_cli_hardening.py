"""Issue 12 items 7, 11 and 17: option checks, the output place, estimate's folder, CLI spelling."""

from __future__ import annotations

import json
import os
import re
import stat
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from _synth_race import write_session_parquet
from typer.testing import CliRunner

from brakethermo.cli import app
from brakethermo.config import config_dir
from brakethermo.errors import ConfigError
from brakethermo.io.atomic import atomic_dir, clean_stale_stages
from brakethermo.io.load import load_session
from brakethermo.pipelines import output_dir as output_dir_mod
from brakethermo.pipelines.estimate import EstimateOptions
from brakethermo.pipelines.output_dir import check_output_dir, check_output_file
from brakethermo.report.braking_zones import detect_zones

SHIPPED_LAW = config_dir() / "hlaw" / "cc-340-8.toml"
COMMANDS = ("estimate", "identify-h", "batch", "timing-check", "simulate")


def _invoke(*args: str):
    return CliRunner().invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def multi_session(tmp_path_factory) -> Path:
    """A one-lap four-spot session (fast to estimate)."""
    return write_session_parquet(tmp_path_factory.mktemp("s") / "t4.parquet", 1, seed=7,
                                 multi=True)


# ------------------------------------------------------------------ option checks (item 7)
@pytest.mark.parametrize(
    ("args", "words"),
    [
        (("timing-check", "x.parquet", "--budget-s", "0"), "must be a finite number > 0"),
        (("timing-check", "x.parquet", "--budget-s", "nan"), "must be a finite number > 0"),
        (("timing-check", "x.parquet", "--nodes", "100000"), "less than or equal to 400"),
        (("estimate", "x.parquet", "--nodes", "100000"), "less than or equal to 400"),
        (("batch", ".", "--nodes", "401"), "less than or equal to 400"),
        (("identify-h", "x.parquet", "--nodes", "100000"), "less than or equal to 400"),
        (("estimate", "x.parquet", "--ambient", "nan"), "is not an air temperature"),
        (("identify-h", "x.parquet", "--ambient", "inf"), "is not an air temperature"),
        (("simulate", "--out", "s.mcap", "--laps", "100000"), "less than or equal to 200"),
    ],
)
def test_bad_option_values_are_usage_errors_before_any_work(args, words):
    res = _invoke(*args)
    assert res.exit_code == 2, res.output
    assert words in re.sub(r"\s*│\s*", " ", res.output)
    assert "Traceback" not in res.output


@pytest.mark.parametrize(("value", "words"), [
    ("bogus", "unknown effect(s) bogus"), ("none,sensor_lag", "'none' stands alone")])
def test_a_bad_with_effect_is_said_before_the_work(multi_session, tmp_path, value, words):
    res = _invoke("identify-h", multi_session, "--with-effect", value, "--out", tmp_path)
    said = res.output.replace("\n", " ")
    assert res.exit_code == 1 and words in said and "'auto'" in said, res.output
    assert not (tmp_path / multi_session.stem).exists()


def test_the_pipeline_options_keep_the_same_limits():
    with pytest.raises(ConfigError, match="nodes = 100000 must be between 10 and 400"):
        EstimateOptions(nodes=100000)
    with pytest.raises(ConfigError, match="ambient temperature nan"):
        EstimateOptions(ambient_c=float("nan"))


@pytest.mark.parametrize("command", ["estimate", "identify-h", "batch"])
def test_out_that_is_a_file_fails_first(tmp_path, multi_session, command):
    out = tmp_path / "out"
    out.write_text("not a folder")
    target = multi_session.parent if command == "batch" else multi_session
    res = _invoke(command, target, "--out", out)
    assert res.exit_code == 1, res.output
    assert f"{out}: is a file, but --out needs a folder" in res.output.replace("\n", "")
    assert out.read_text() == "not a folder"


@pytest.mark.parametrize("command", [("ebooster",), ("clamp-force", "--train", "x"), ("mu-slip",),
                                     ("roller-rig",), ("diagnose", "--rig", "tyre")])
def test_a_rig_commands_out_that_is_a_file_fails_first(tmp_path, multi_session, command):
    """The rig commands checked --out only when writing: a NotADirectoryError traceback
    after all the work."""
    out = tmp_path / "out"
    out.write_text("not a folder")
    res = _invoke(command[0], multi_session, *(multi_session if a == "x" else a
                                               for a in command[1:]), "--out", out)
    assert res.exit_code == 1, res.output
    assert f"{out}: is a file, but --out needs a folder" in res.output.replace("\n", "")
    assert "Traceback" not in res.output and out.read_text() == "not a folder"


@pytest.mark.parametrize("command", [("estimate", "--no-reports"), ("mu-slip",)])
def test_a_folder_of_another_session_of_that_name_is_refused_first(tmp_path, multi_session,
                                                                    command):
    """A roller-rig A/day1.mcap and a tyre B/day1.mcap into one --out: the second command
    replaced the first's summary.json, page and PNGs and left its parquet orphaned."""
    folder = tmp_path / "out" / multi_session.stem
    folder.mkdir(parents=True)
    (folder / "roller_rig.parquet").write_bytes(b"kept")
    (folder / "summary.json").write_text(json.dumps({"session": "/rig/A/t4.mcap"}))
    res = _invoke(command[0], multi_session, *command[1:], "--out", tmp_path / "out")
    assert res.exit_code == 1, res.output
    said = res.output.replace("\n", "")
    assert "holds the roller-rig results of /rig/A/t4.mcap" in said and "--out" in said
    assert json.loads((folder / "summary.json").read_text())["session"] == "/rig/A/t4.mcap"


def test_another_file_of_the_same_name_is_refused_before_the_work(tmp_path, multi_session):
    """estimate A/x then whatif, identify-h, diagnose or estimate B/x into one --out mixed
    the two sessions' results on one page (or replaced A's) with exit 0."""
    a = tmp_path / "A" / "x.parquet"
    a.parent.mkdir()
    a.write_bytes(multi_session.read_bytes())
    (tmp_path / "B").mkdir()
    b = write_session_parquet(tmp_path / "B" / "x.parquet", 1, seed=8, multi=True)
    out = tmp_path / "out"
    assert _invoke("estimate", a, "--out", out, "--no-reports").exit_code == 0
    for args in (("whatif", b, "--cooling", "1.2"), ("identify-h", b), ("diagnose", b),
                 ("estimate", b)):
        res = _invoke(*args, "--out", out)
        said = res.output.replace("\n", "")
        assert res.exit_code == 1 and f"holds the results of {a}" in said, res.output
    assert _invoke("estimate", a, "--out", out, "--no-reports").exit_code == 0  # itself


def test_out_below_a_file_and_read_only_folders(tmp_path, monkeypatch):
    (tmp_path / "f").write_text("x")
    with pytest.raises(ConfigError, match=r"is a file \(inside .*f/sub\)"):
        check_output_dir(tmp_path / "f" / "sub")
    locked = tmp_path / "locked"
    locked.mkdir()
    # Root ignores permission bits; ask os.access the way a normal user's run would.
    monkeypatch.setattr(output_dir_mod, "_writable", lambda p: p != locked)
    with pytest.raises(ConfigError, match="locked: is not writable"):
        check_output_dir(locked / "new")
    with pytest.raises(ConfigError, match="is a folder, but --out needs a file name"):
        check_output_file(tmp_path)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder_really_refused(tmp_path):
    locked = tmp_path / "ro"
    locked.mkdir()
    locked.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        with pytest.raises(ConfigError, match="not writable"):
            check_output_dir(locked)
    finally:
        locked.chmod(stat.S_IRWXU)


def test_broken_h_law_or_aliases_in_batch_is_the_users_error(tmp_path, multi_session):
    bad_law = tmp_path / "law.toml"
    bad_law.write_text(SHIPPED_LAW.read_text().replace("knee = 0.8", "knee = nan"))
    bad_aliases = tmp_path / "aliases.toml"
    bad_aliases.write_bytes(b"\xff\xfe[aliases]")
    for option, path, words in (("--h-law", bad_law, "key 'knee'"),
                                ("--aliases", bad_aliases, "UTF-16")):
        out = tmp_path / f"out{option}"
        res = _invoke("batch", multi_session.parent, "--out", out, option, path)
        assert res.exit_code == 1, res.output
        assert words in res.output and str(path) in res.output.replace("\n", "")
        assert not any(p.is_dir() for p in out.glob("*")), "no session was processed"


# --------------------------------------------------- estimate's folder and the h law (7, 11)
def test_estimate_replaces_its_folder_keeps_identify_outputs_and_uses_own_law(
    tmp_path, multi_session
):
    out = tmp_path / "out"
    folder = out / multi_session.stem
    (folder / "lap_09").mkdir(parents=True)
    (folder / "lap_09" / "index.html").write_text("stale")
    (folder / "trend.png").write_bytes(b"stale")
    # identify-h's law for this very session, beside it in --out
    own = folder / "h_law.toml"
    shipped = SHIPPED_LAW.read_text()
    own.write_text(re.sub(r'(?m)^session = .*$', f'session = "{multi_session}"', shipped))
    res = _invoke("estimate", multi_session, "--out", out, "--no-reports", "--json")
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout)
    assert not (folder / "lap_09").exists() and not (folder / "trend.png").exists()
    assert own.is_file() and summary["run"]["h_law"] == str(own)
    assert "identified from this session" in summary["run"]["h_law_choice"]
    assert oct(folder.stat().st_mode & 0o777) != oct(0o700)
    # item 15: the disc is never estimated colder than the air (25 degC in this session)
    frame = pd.read_parquet(folder / "estimate.parquet")
    temps = frame[[c for c in frame.columns if c.startswith(("node_", "mid_", "spot"))
                   and not c.endswith("_std")]]
    assert temps.min().min() >= 25.0 - 1e-9
    # item 16: the scores count the braking zones the report shows
    session = load_session(multi_session)
    zones = detect_zones(session.time, session.values("brake_pressure_front"))
    assert summary["scores"]["peak"]["spot3"]["zones_total"] == len(zones)
    # A law identified from another session with the same stem is not this session's.
    own.write_text(re.sub(r'(?m)^session = .*$', 'session = "/elsewhere/t4.parquet.old"',
                          shipped))
    res = _invoke("estimate", multi_session, "--out", out, "--no-report")
    assert res.exit_code == 0, res.output
    text = " ".join(res.output.split())
    assert "h law:" in text and "shipped default for disc cc-340-8" in text
    assert "no h law of this bike" in text and "pass --h-law" in text  # said, not silent
    assert not (folder / "index.html").exists(), "--no-report (old spelling) still works"


def test_stale_stages_of_killed_runs_are_cleaned(tmp_path):
    target = tmp_path / "session"
    host = __import__("socket").gethostname().replace(".", "-")
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    stale = tmp_path / f".session.stage.{host}.{dead}.abc"
    aside = tmp_path / f".session.old.{host}.{dead}.def"
    live = tmp_path / f".session.stage.{host}.{os.getpid()}.ghi"
    for d in (stale, aside, live):
        d.mkdir()
    with atomic_dir(target) as stage:
        (stage / "x").write_text("1")
    assert not stale.exists() and not aside.exists() and live.exists()
    assert (target / "x").read_text() == "1"
    assert stat.S_IMODE(target.stat().st_mode) == 0o777 & ~_umask()
    assert clean_stale_stages(target) == []


def test_an_interrupted_run_removes_its_own_stages_only(tmp_path):
    """What an interrupt left mid-removal goes; another live run's stage stays."""
    from brakethermo.io.atomic import remove_own_stages

    host = __import__("socket").gethostname().replace(".", "-")
    own = tmp_path / f".a_race.stage.{host}.{os.getpid()}.abc"
    aside = tmp_path / f".a_race.old.{host}.{os.getpid()}.def"
    other = tmp_path / f".b_race.stage.{host}.{os.getppid()}.ghi"
    for d in (own, aside, other):
        d.mkdir()
    (own / "estimate.parquet").write_text("half")
    assert sorted(remove_own_stages(tmp_path)) == sorted([own, aside])
    assert not own.exists() and not aside.exists() and other.exists()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# ---------------------------------------------------------------- CLI consistency (item 17)
@pytest.mark.parametrize("command", COMMANDS)
def test_help_fits_80_columns_and_shows_flags_as_flags(command):
    text = CliRunner().invoke(app, [command, "--help"], env={"COLUMNS": "80"}).output
    assert max(len(line) for line in text.splitlines()) <= 80
    assert "<bool>" not in text and "--json " in text


def test_spelling_and_defaults_are_the_same_everywhere():
    for command in ("estimate", "batch"):
        text = CliRunner().invoke(app, [command, "--help"], env={"COLUMNS": "200"}).output
        assert "--no-reports" in text and "--no-report " not in text
        assert "--out" in text and "[default: out]" in " ".join(text.split())


@pytest.mark.parametrize(("args", "needle", "code"), [
    (("--rig", "tyre", "--effects", "sensor_lag"), "not read for --rig tyre", 1),
    # a --set the session does not take is a usage error, exit 2 as Typer's own (a key it
    # does not know exited 1, new-user test), naming what it takes
    (("--rig", "tyre", "--set", "seed=5"), "give the seed with --seed", 2),
    (("--rig", "roller-rig", "--set", "foo=1"), "KEY one of duration_s, free_s", 2),
    (("--rig", "roller-rig", "--set", "traction=bogus"), "expected true or false", 2),
    (("--set", "foo=1"), "a disc session takes cooling, ambient_c", 2),
    # outside the simulator's range: usage too, as the rigs' (exited 1, new-user test)
    (("--set", "cooling=0"), "--set cooling=0: cooling must be a finite factor", 2),
    (("--set", "cooling=nan"), "--set cooling=nan: cooling must be", 2),
    (("--set", "ambient_c=200"), "--set ambient_c=200: ambient_c must be an air", 2),
    # an unknown rig was a KeyError traceback (exit 1)
    (("--rig", "foo"), "unknown rig; simulated rigs: ebooster, emb, roller-rig, tyre", 2),
    (("--rig", "roller_rig"), "did you mean 'roller-rig'?", 2),
    (("--rig", "Tyre"), "did you mean 'tyre'?", 2),
    # the roller rig's ranges exited 1 (checked while simulating)
    (("--rig", "roller-rig", "--set", "speed_kmh=500"), "speed_kmh=500.0 out of range", 2),
    (("--rig", "roller-rig", "--set", "radius_m=5"), "radius_m=5.0 out of range", 2),
    (("--rig", "roller-rig", "--set", "torque_max=-100"), "torque_max=-100.0 out of", 2),
    (("--rig", "roller-rig", "--set", "duration_s=0.5"), "duration_s=0.5 out of range", 2),
    (("--rig", "roller-rig", "--set", "rate_hz=0"), "rate_hz=0.0 out of range", 2),
    (("--rig", "roller-rig", "--set", "free_s=1000"), "free_s=1000.0 out of range", 2),
    # a tyre session shorter than its ramp was written at the ramp's length (6.9 s)
    (("--rig", "tyre", "--set", "duration_s=1"), "give duration_s of at least 6.9", 2),
    (("--format", "mcap"), "--format mcap for a file named .parquet", 1),
    (("--grouped",), "--grouped is an MCAP layout", 1),
])
def test_simulate_options_that_would_be_ignored_are_refused(tmp_path, args, needle,
                                                            code) -> None:
    """Each of these used to run with exit 0 and do something else than asked (the seed
    of --set won over --seed, an MCAP file named .parquet the readers then refused)."""
    from brakethermo.cli import app

    laps = () if "--rig" in args else ("--laps", "1")
    res = CliRunner().invoke(app, ["simulate", *laps, *args,
                                   "--out", str(tmp_path / "s.parquet")])
    assert res.exit_code == code and needle in " ".join(res.output.split()), res.output
    assert not (tmp_path / "s.parquet").exists()


def test_a_tyre_session_is_as_long_as_asked(tmp_path) -> None:
    """duration_s=1 wrote a 6.8 s file; a duration the ramp allows is honoured."""
    import pyarrow.parquet as pq

    res = CliRunner().invoke(app, ["simulate", "--rig", "tyre", "--set", "duration_s=8",
                                   "--out", str(tmp_path / "t.parquet")])
    assert res.exit_code == 0, res.output
    time = pq.read_table(tmp_path / "t.truth.parquet").column("time").to_numpy()
    assert time[-1] == pytest.approx(8.0, abs=0.002)


def test_diagnose_an_unknown_rig_is_a_usage_error(tmp_path) -> None:
    """diagnose --rig foo exited 1, as if the session were wrong."""
    res = _invoke("diagnose", tmp_path / "rr.mcap", "--rig", "foo", "--out", tmp_path / "o")
    assert res.exit_code == 2 and "diagnose reads rig sessions of" in res.output, res.output


def test_a_write_interrupted_leaves_no_empty_folder_and_keeps_an_old_one(tmp_path):
    """An interrupted batch left an empty OUT/<session>/ for every session it had not
    finished; a folder that held results before keeps them."""
    from brakethermo.io.atomic import atomic_entries

    new = tmp_path / "race_a"
    with pytest.raises(KeyboardInterrupt), atomic_entries(new, ("*.json",)) as stage:
        (stage / "summary.json").write_text("{}")
        raise KeyboardInterrupt
    assert not new.exists()
    old = tmp_path / "race_b"
    old.mkdir()
    (old / "summary.json").write_text('{"old": 1}')
    with pytest.raises(KeyboardInterrupt), atomic_entries(old, ("*.json",)) as stage:
        (stage / "summary.json").write_text("{}")
        raise KeyboardInterrupt
    assert (old / "summary.json").read_text() == '{"old": 1}'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["race_b"]  # no stage left
