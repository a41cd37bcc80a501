"""Every float option of every command refuses nan and inf with one line, no traceback,
before any work (the options are found from the commands' signatures, so a new option
is checked without being listed here)."""

from __future__ import annotations

import typing
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from brakethermo.cli import app

# what each command needs besides the option under test to get as far as its checks
BASE = {
    "clamp-force": ["s.mcap", "--train", "t.mcap", "--out", "o"],
    "inspect": ["s.parquet"],
    "timing-check": ["s.parquet"],
}
DEFAULT = ["s.parquet", "--out", "o"]


def _float_options() -> Iterator[tuple[str, str]]:
    for info in app.registered_commands:
        fn = info.callback
        assert fn is not None
        name = info.name or fn.__name__.replace("_", "-")
        for pname, hint in typing.get_type_hints(fn, include_extras=True).items():
            annotated = typing.get_origin(hint) is typing.Annotated
            base, meta = (typing.get_args(hint)[0], typing.get_args(hint)[1:]) if annotated \
                else (hint, ())
            kinds = {base, *typing.get_args(base)}
            if float not in kinds and not any(float in typing.get_args(k) for k in kinds):
                continue
            decls = [d for m in meta for d in (getattr(m, "param_decls", None) or ())]
            flag = next((d.split("/")[0] for d in decls if d.startswith("--")),
                        "--" + pname.replace("_", "-"))
            yield name, flag


OPTIONS = sorted(set(_float_options()))


def test_the_walk_finds_the_float_options() -> None:
    assert ("whatif", "--cooling") in OPTIONS and ("estimate", "--ambient") in OPTIONS
    assert len(OPTIONS) >= 12


@pytest.mark.parametrize(("command", "flag"), OPTIONS)
@pytest.mark.parametrize("bad", ["nan", "inf", "-inf"])
def test_nan_and_inf_are_refused(command: str, flag: str, bad: str, tmp_path: Path,
                                 monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(app, [command, f"{flag}={bad}", *BASE.get(command, DEFAULT)])
    assert res.exit_code in (1, 2), res.output
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    assert "Traceback" not in res.output
    text = res.output.lower()
    assert bad.lstrip("-") in text or flag in text or "finite" in text, res.output
