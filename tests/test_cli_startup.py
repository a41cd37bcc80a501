"""The CLI starts light: importing it, and every command's ``--help``, load no pipeline.

Each command imports its pipeline (scipy, pandas, matplotlib, numba kernels, pyarrow)
when it runs, so ``brakethermo --help`` and option errors answer at once. Checked in a
fresh interpreter: this test process has long imported everything.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import pytest

from brakethermo.sim.rigs import RIG_SIMULATORS, rig_settings

HEAVY_ROOTS = ("matplotlib", "scipy", "numba", "pandas", "pyarrow", "mcap", "asammdf", "filterpy")
# brakethermo packages that are only reached through a pipeline or a reader.
HEAVY_PACKAGES = ("brakethermo.estimation", "brakethermo.io", "brakethermo.report",
                  "brakethermo.thermal", "brakethermo.rigs")
# Light modules the option help reads its ranges and names from (stdlib + numpy only).
LIGHT = {"brakethermo.pipelines", "brakethermo.pipelines.tuning", "brakethermo.models",
         "brakethermo.models.effects", "brakethermo.sim", "brakethermo.sim.effects",
         "brakethermo.sim.rigs"}

PROBE = """
import json, sys
{setup}
print(json.dumps(sorted(sys.modules)))
"""

HELP_ALL = """
from typer.testing import CliRunner
from brakethermo.cli import app
runner = CliRunner()
for args in (["--help"], *([c.name, "--help"] for c in app.registered_commands)):
    res = runner.invoke(app, args)
    assert res.exit_code == 0, (args, res.output)
"""


def _loaded(setup: str) -> list[str]:
    proc = subprocess.run([sys.executable, "-c", PROBE.format(setup=setup)],
                          capture_output=True, text=True, check=False, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def _heavy(modules: list[str]) -> list[str]:
    def heavy(m: str) -> bool:
        if m.split(".")[0] in HEAVY_ROOTS:
            return True
        if any(m == p or m.startswith(p + ".") for p in HEAVY_PACKAGES):
            return True
        return m.startswith(("brakethermo.pipelines", "brakethermo.models",
                             "brakethermo.sim")) and m not in LIGHT

    return [m for m in modules if heavy(m)]


@pytest.mark.parametrize("setup", ["import brakethermo.cli", HELP_ALL],
                         ids=["import", "every-help"])
def test_cli_loads_no_pipeline(setup: str) -> None:
    modules = _loaded(setup)
    assert "brakethermo.cli.estimate_cmd" in modules  # the probe really loaded the commands
    assert _heavy(modules) == []


def test_the_probe_sees_a_heavy_import() -> None:
    """The check above can fail: a pipeline import is caught."""
    heavy = _heavy(_loaded("import brakethermo.cli, brakethermo.pipelines.roller_rig"))
    assert "brakethermo.pipelines.roller_rig" in heavy and "scipy" in heavy


@pytest.mark.parametrize("rig", sorted(RIG_SIMULATORS))
def test_rig_registry_resolves_each_config_on_demand(rig: str) -> None:
    cls = RIG_SIMULATORS[rig].config
    assert dataclasses.is_dataclass(cls) and cls.__module__ == RIG_SIMULATORS[rig].module
    assert isinstance(cls(**rig_settings(rig, [], seed=3)), cls)


def test_the_help_names_every_format_the_readers_take() -> None:
    from brakethermo.cli._options import SESSION_FORMATS
    from brakethermo.io.formats import SUFFIXES

    assert all(s in SESSION_FORMATS for s in SUFFIXES), SESSION_FORMATS
