"""Compile every command's kernels once, at install, so a first run costs what later ones do.

numba compiles a kernel the first time it is called and caches the machine code beside
its source (``__pycache__``). Without this module a fresh install paid that on its first
run of each command: the roller-rig's first run took 3.9x a later one. The editable
install's build hook (``hatch_build.py``) runs this module, which runs each command on
small simulated sessions, so every kernel is compiled for the argument types the
commands give it (read-only arrays from the readers, float32 stores, ...), not for a
list that would drift from the code. The disc and the rig commands run side by side.
The sessions and outputs go to a temporary folder and are removed; what stays is
numba's cache (and the per-user cache of unit conversions the readers keep anyway).
An interrupt stops both streams.

    python -m brakethermo.cli.warmup          # both streams, as the build hook runs it
    python -m brakethermo.cli.warmup rigs     # one stream, in this process
"""

from __future__ import annotations

import contextlib
import io
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import click

from brakethermo.errors import EXIT_INTERRUPTED

# Each stream: the commands of one family, in order (later ones read earlier outputs).
# Sessions are as short as each command accepts, so compiling dominates.
STREAMS: dict[str, tuple[tuple[str, ...], ...]] = {
    "disc": (
        ("simulate", "--track", "tight-like", "--laps", "3", "--seed", "1", "--out", "test.mcap"),
        ("simulate", "--track", "tight-like", "--laps", "2", "--sensor", "single", "--seed", "2",
         "--out", "race.parquet"),
        ("identify-h", "test.mcap", "--out", "out"),
        ("estimate", "race.parquet", "--h-law", "out/test/h_law.toml", "--out", "out"),
        ("diagnose", "test.mcap", "--out", "out"),
        ("whatif", "race.parquet", "--h-law", "out/test/h_law.toml", "--cooling", "1.2",
         "--out", "out"),
    ),
    "rigs": (
        ("simulate", "--rig", "roller-rig", "--set", "duration_s=20", "--set", "free_s=5",
         "--seed", "3", "--out", "rr.mcap"),
        ("roller-rig", "rr.mcap", "--out", "out"),
        ("simulate", "--rig", "ebooster", "--set", "scenario=train", "--set", "duration_s=20",
         "--seed", "4", "--out", "train.mcap"),
        ("simulate", "--rig", "ebooster", "--set", "scenario=vehicle", "--set", "duration_s=20",
         "--seed", "5", "--out", "veh.mcap"),
        ("ebooster", "veh.mcap", "--train", "train.mcap", "--out", "out"),
        ("simulate", "--rig", "emb", "--set", "duration_s=10", "--seed", "6", "--out",
         "emb_train.mcap"),
        ("simulate", "--rig", "emb", "--set", "duration_s=10", "--seed", "7", "--out", "emb.mcap"),
        ("clamp-force", "emb.mcap", "--train", "emb_train.mcap", "--out", "out"),
        ("simulate", "--rig", "tyre", "--seed", "8", "--out", "tyre.mcap"),
        ("mu-slip", "tyre.mcap", "--out", "out"),
    ),
}
TIMEOUT_S = 900.0  # s: a stream still compiling after this is left to the first run


def run_stream(name: str) -> list[str]:
    """Run stream ``name`` in this process, in a temporary folder; the commands that failed.

    A failure is reported, not raised: a kernel not compiled here compiles on first use.
    """
    from brakethermo.cli import app

    failed: list[str] = []
    here = Path.cwd()
    with tempfile.TemporaryDirectory(prefix="brakethermo-warmup-") as tmp:
        os.chdir(tmp)
        try:
            for args in STREAMS[name]:
                out = io.StringIO()
                try:
                    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
                        code = app(list(args), standalone_mode=False)
                except click.Abort:  # the CLI's own word for an interrupt
                    raise KeyboardInterrupt from None
                except (Exception, SystemExit) as exc:  # reported, never fatal: see above
                    code = f"{type(exc).__name__}: {exc}"
                if code == EXIT_INTERRUPTED:
                    raise KeyboardInterrupt
                if code not in (None, 0):
                    failed.append(f"{' '.join(args[:2])}: {code}")
        finally:
            os.chdir(here)
    return failed


def main(argv: list[str]) -> int:
    """Both streams as child processes (or the one named in ``argv``, in this process)."""
    try:
        return _run(argv)
    except KeyboardInterrupt:
        print("brakethermo: warm-up interrupted; each command compiles what is missing on"
              " first use", file=sys.stderr)
        return EXIT_INTERRUPTED


def _run(argv: list[str]) -> int:
    if argv:
        failed = run_stream(argv[0])
        for line in failed:
            print(f"warm-up {argv[0]}: {line}", file=sys.stderr)
        return 1 if failed else 0
    t0 = time.perf_counter()
    children = {name: subprocess.Popen([sys.executable, "-m", __spec__.name, name])
                for name in STREAMS}
    codes: dict[str, int | str] = {}
    try:
        for name, child in children.items():
            try:
                codes[name] = child.wait(timeout=max(TIMEOUT_S - (time.perf_counter() - t0),
                                                     1.0))
            except subprocess.TimeoutExpired:
                codes[name] = "timed out"
    finally:  # an interrupt or a timeout ends every stream, not only this process
        for child in children.values():
            if child.poll() is None:
                child.kill()
                child.wait()
    print(f"brakethermo: kernels compiled in {time.perf_counter() - t0:.0f} s"
          + "".join(f"; {n} stream: {c}" for n, c in codes.items() if c != 0), file=sys.stderr)
    return 0 if all(c == 0 for c in codes.values()) else 1


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
