"""Shared fixtures: small simulated sessions, written once per test run."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from pathlib import Path

import pytest

# pint's unit answers are cached per user (io/units.py): tests keep their own, so that a
# run starts from no cache and leaves the user's alone (nor a directory per run in /tmp)
if "BRAKETHERMO_CACHE_DIR" not in os.environ:
    _cache = tempfile.mkdtemp(prefix="brakethermo-cache-")
    os.environ["BRAKETHERMO_CACHE_DIR"] = _cache
    atexit.register(shutil.rmtree, _cache, ignore_errors=True)

from brakethermo.sim.session import SimConfig, simulate, write_simulation

# Seeds used by the tests; the tuning in configs/tuning.toml was set on seeds 500-599.
TEST_SEED = 4242
RACE_SEED = 4243


@pytest.fixture(scope="session")
def sim_test_session(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A 2-lap four-spot test session (MCAP) and its truth file."""
    out = tmp_path_factory.mktemp("sim") / "test_multi.mcap"
    return write_simulation(simulate(SimConfig(laps=2, sensor="multi", seed=TEST_SEED)), out)


@pytest.fixture(scope="session")
def sim_race_session(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A 2-lap four-spot race-like session (Parquet, other seed) and its truth file."""
    out = tmp_path_factory.mktemp("sim") / "race_multi.parquet"
    return write_simulation(simulate(SimConfig(laps=2, sensor="multi", seed=RACE_SEED)), out)


@pytest.fixture(scope="session")
def identified(sim_test_session: tuple[Path, Path], tmp_path_factory: pytest.TempPathFactory):
    """identify-h run once on the simulated test session: (result, h_law.toml path)."""
    from brakethermo.pipelines.identify_h import identify_h, write_identify

    result = identify_h(sim_test_session[0])
    folder = write_identify(result, tmp_path_factory.mktemp("identify"))
    return result, folder / "h_law.toml"
