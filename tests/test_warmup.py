"""The install-time compile (brakethermo/cli/warmup.py): its commands are the CLI's, and a
command that fails is reported, never raised (a kernel not compiled then compiles later)."""

from __future__ import annotations

import pytest

from brakethermo.cli import app, warmup


def test_every_stream_command_is_a_cli_command() -> None:
    names = {c.name for c in app.registered_commands}
    used = {args[0] for stream in warmup.STREAMS.values() for args in stream}
    assert used <= names, f"warm-up runs commands the CLI lacks: {used - names}"
    assert {"estimate", "identify-h", "diagnose", "whatif", "roller-rig", "ebooster",
            "clamp-force", "mu-slip"} <= used


def test_a_failing_command_is_reported_not_raised(monkeypatch: pytest.MonkeyPatch,
                                                   tmp_path) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(warmup.STREAMS, "probe", (
        ("estimate", "missing.mcap", "--out", "out"),
        ("inspect", "--help"),
    ))
    failed = warmup.run_stream("probe")
    assert len(failed) == 1 and failed[0].startswith("estimate missing.mcap")
    assert warmup.main(["probe"]) == 1
    assert tmp_path.exists() and not (tmp_path / "out").exists()


def test_an_interrupt_stops_the_stream(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    import brakethermo.cli as cli

    ran: list[str] = []

    def fake_app(args, standalone_mode=True):
        ran.append(args[0])
        return 130  # what the CLI returns for Ctrl-C

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(cli, "app", fake_app)
    monkeypatch.setitem(warmup.STREAMS, "probe", (("estimate", "x"), ("diagnose", "y")))
    with pytest.raises(KeyboardInterrupt):
        warmup.run_stream("probe")
    assert ran == ["estimate"]
    assert warmup.main(["probe"]) == 130
