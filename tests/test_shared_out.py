"""The README's commands in one --out: each keeps every file the others promised, and
every link of the pages resolves (issue: "Nothing an engineer saves is lost")."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

from typer.testing import CliRunner

from brakethermo.cli import app

runner = CliRunner()


def _ok(args: list[str]) -> None:
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output


def _links_resolve(page: Path) -> None:
    html = page.read_text()
    for href in re.findall(r'(?:href|src)="([^"#:]+)"', html):
        assert (page.parent / href).exists(), f"{page}: broken link {href}"


def test_commands_sharing_an_out_keep_each_others_files(sim_test_session, sim_race_session,
                                                        tmp_path: Path) -> None:
    out = tmp_path / "out"
    test = tmp_path / "test_multi.mcap"
    shutil.copy(sim_test_session[0], test)
    race = sim_race_session[0]
    _ok(["diagnose", str(test), "--out", str(out), "--effects", "sensor_lag", "--json"])
    _ok(["identify-h", str(test), "--out", str(out), "--json"])
    law = out / test.stem / "h_law.toml"
    _ok(["estimate", str(race), "--h-law", str(law), "--out", str(out), "--json"])
    _ok(["whatif", str(race), "--h-law", str(law), "--cooling", "1.2", "--draws", "0",
         "--out", str(out), "--json"])
    _ok(["estimate", str(test), "--out", str(out), "--json"])  # four-spot: scores itself
    _ok(["estimate", str(race), "--h-law", str(law), "--out", str(out), "--no-report",
         "--json"])
    promised = {
        test.stem: ["diagnosis.json", "diagnosis.parquet", "diagnosis/index.html",
                    "h_law.toml", "h_samples.parquet", "h_law.png", "estimate.parquet",
                    "summary.json", "index.html"],
        race.stem: ["estimate.parquet", "summary.json", "whatif.parquet",
                    "whatif/index.html", "whatif/summary.json"],
    }
    for stem, names in promised.items():
        for name in names:
            assert (out / stem / name).exists(), f"{stem}/{name} lost"
    # the no-report re-run removed its own stale report; a small index links what is left
    assert not list((out / race.stem).glob("lap_*"))
    small = (out / race.stem / "index.html").read_text()
    assert "whatif/index.html" in small and "lap_" not in small
    assert "diagnosis/index.html" in (out / test.stem / "index.html").read_text()
    for page in out.rglob("index.html"):
        _links_resolve(page)
    # batch over the same out keeps the diagnosis and the what-if
    folder = tmp_path / "sessions"
    folder.mkdir()
    shutil.copy(test, folder / test.name)
    res = runner.invoke(app, ["batch", str(folder), "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert (out / test.stem / "diagnosis.json").exists()
    assert (out / test.stem / "diagnosis" / "index.html").exists()
    # batch diagnoses a four-spot session itself (identify-h's effect selection did) and
    # its index links the verdict
    tried = json.loads((out / test.stem / "diagnosis.json").read_text())["run"]["effects_tried"]
    assert len(tried) == 7
    assert f"{test.stem}/diagnosis/index.html" in (out / "index.html").read_text()
    for page in out.rglob("index.html"):
        _links_resolve(page)
