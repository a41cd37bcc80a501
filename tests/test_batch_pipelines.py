"""batch with the project's real pipelines: identify-h, estimate, scores, reports, MCAP."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from _synth_race import write_session_parquet
from mcap.reader import make_reader

from brakethermo.pipelines.batch import DEFAULT_LAW, MANIFEST, BatchOptions, run_batch
from brakethermo.report.lap_report import read_estimate


@pytest.fixture(scope="module")
def batch_out(tmp_path_factory) -> Path:
    src = tmp_path_factory.mktemp("src")
    write_session_parquet(src / "test.parquet", 1, seed=1, multi=True, date="2026-05-01")
    write_session_parquet(src / "race.parquet", 2, seed=2, date="2026-05-02")
    out = tmp_path_factory.mktemp("out")
    result = run_batch(src, BatchOptions(out=out, mcap_out=True))
    assert [(o.name, o.status, o.reason) for o in result.outcomes] == [
        ("race", "ok", ""),
        ("test", "ok", ""),
    ]
    assert result.outcomes[0].h_law_source == "identified: test"
    return out


def test_outputs_of_both_kinds(batch_out: Path) -> None:
    test, race = batch_out / "test", batch_out / "race"
    for name in ("h_law.toml", "h_samples.parquet", "estimate.parquet", "summary.json"):
        assert (test / name).is_file(), name
    assert not (race / "h_law.toml").exists()
    test_summary = json.loads((test / "summary.json").read_text())
    assert test_summary["scores"] is not None
    # issue 12 item 10: the final law, not the staging folder it was written in
    assert test_summary["run"]["h_law"] == str(test / "h_law.toml")
    race_summary = json.loads((race / "summary.json").read_text())
    assert race_summary["run"]["h_law"] == str(test / "h_law.toml")
    assert race_summary["run"]["h_law_choice"].startswith("identified from test (same disc")
    manifest = json.loads((race / MANIFEST).read_text())
    assert manifest["h_law_source"] == "identified: test" and manifest["laps"] == 1
    assert (race / "lap_01" / "index.html").is_file() and (race / "index.html").is_file()


def test_mcap_export_equals_estimate(batch_out: Path) -> None:
    frame, radii = read_estimate(batch_out / "race" / "estimate.parquet")
    assert radii is not None and len(radii) >= 3
    values, nodes = [], []
    with (batch_out / "race" / "estimate.mcap").open("rb") as fh:
        reader = make_reader(fh)
        channels = {c.topic: c for c in reader.get_summary().channels.values()}
        for _, channel, msg in reader.iter_messages(
            topics=["/brakethermo/spot3", "/brakethermo/disc_nodes"]
        ):
            data = json.loads(msg.data)
            if channel.topic.endswith("spot3"):
                values.append(data["value"])
            else:
                nodes.append(data["temperature"])
    np.testing.assert_allclose(values, frame["spot3"].round(3), atol=1e-9)
    node_cols = [f"node_{k}" for k in range(len(radii))]
    np.testing.assert_allclose(nodes, frame[node_cols].round(2).to_numpy(), atol=1e-9)
    meta_radii = json.loads(channels["/brakethermo/disc_nodes"].metadata["radius_m"])
    np.testing.assert_allclose(meta_radii, radii, rtol=1e-9)


def test_race_only_folder_uses_the_shipped_law(tmp_path: Path) -> None:
    src = tmp_path / "race_only"
    src.mkdir()
    write_session_parquet(src / "race.parquet", 1, seed=4)
    (o,) = run_batch(src, BatchOptions(out=tmp_path / "out", reports=False)).outcomes
    assert o.status == "ok", o.reason
    assert o.h_law_source == DEFAULT_LAW
    summary = json.loads((tmp_path / "out" / "race" / "summary.json").read_text())
    assert summary["run"]["h_law"].endswith("hlaw/cc-340-8.toml")
