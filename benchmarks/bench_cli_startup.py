"""CLI start-up: what ``brakethermo --help`` (and so every command) pays before its work.

Each figure is the median wall time of fresh processes (several runs, the machine is
shared). Prints:

1. the bare interpreter (``python -c pass``): the floor no change can go below;
2. ``import brakethermo.cli``: the command modules, Typer, rich, numpy;
3. ``brakethermo --help``: the same plus building and printing the help;
4. ``import brakethermo.cli`` plus every pipeline module: what the CLI paid on every run
   while the command modules imported their pipelines at module level — and the ratio of
   (4) to (2), the start-up saved on ``--help`` and on each command's option parsing.

Usage::

    python benchmarks/bench_cli_startup.py [--runs 9]

Run it with ``PYTHONPATH`` pointing at the tree to measure (the worktree, or an export of
an older commit for the "before" figure).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

FULL = (
    "import importlib, pkgutil, brakethermo.cli, brakethermo.pipelines as p\n"
    "for m in pkgutil.iter_modules(p.__path__):\n"
    "    importlib.import_module(f'brakethermo.pipelines.{m.name}')"
)
CASES = {
    "python -c pass": ["-c", "pass"],
    "import brakethermo.cli": ["-c", "import brakethermo.cli"],
    "brakethermo --help": ["-c", "from brakethermo.__main__ import main; main()", "--help"],
    "cli + every pipeline": ["-c", FULL],
}


def median_wall(args: list[str], runs: int) -> tuple[float, float, float]:
    """Median, min and max wall time (s) of ``runs`` fresh interpreter processes."""
    walls = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, *args], check=True, capture_output=True)
        walls.append(time.perf_counter() - t0)
    return statistics.median(walls), min(walls), max(walls)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=9, help="Processes per case.")
    args = parser.parse_args()
    # One untimed pass fills the bytecode and OS file caches for every case alike.
    for case in CASES.values():
        subprocess.run([sys.executable, *case], check=True, capture_output=True)
    medians = {}
    for name, case in CASES.items():
        med, lo, hi = median_wall(case, args.runs)
        medians[name] = med
        print(f"{name:24s} median {med:6.3f} s  (min {lo:.3f}, max {hi:.3f}, {args.runs} runs)")
    ratio = medians["cli + every pipeline"] / medians["import brakethermo.cli"]
    print(f"ratio cli + every pipeline / import brakethermo.cli: {ratio:.1f}x")


if __name__ == "__main__":
    main()
