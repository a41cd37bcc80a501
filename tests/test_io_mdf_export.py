"""``estimate --mdf-out``: the estimate as MDF4, read back independently by asammdf."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from asammdf import MDF

from brakethermo.io.mdf_reader import read_mdf
from brakethermo.report.mdf_export import write_estimate_mdf

EPOCH = 1_763_700_000.25


def estimate_frame(n: int = 600, nodes: int = 12) -> pd.DataFrame:
    t = np.arange(n) * 0.1
    cols: dict[str, np.ndarray] = {"time": t, "lap": (t // 20).astype(np.int64)}
    for i in range(1, 5):
        cols[f"spot{i}"] = 400.0 + 10 * i + 50 * np.sin(t / 7)
        cols[f"spot{i}_std"] = 3.0 + 0.1 * i + 0 * t
    cols["contact_avg"] = 420.0 + 40 * np.cos(t / 9)
    cols["contact_avg_std"] = 2.5 + 0 * t
    for k in range(nodes):
        cols[f"node_{k}"] = 380.0 + k + 30 * np.sin(t / 5 + k)
    cols["braking_power"] = 1e5 * np.abs(np.sin(t))
    cols["h"] = 60.0 + 0 * t
    return pd.DataFrame(cols)


def test_mdf_header_takes_the_sessions_date_when_time_is_relative(tmp_path: Path) -> None:
    path = write_estimate_mdf(estimate_frame(), tmp_path / "e.mf4", source="race.mcap",
                              date="2026-05-30")
    with MDF(path) as mdf:
        assert mdf.header.start_time == dt.datetime(2026, 5, 30, tzinfo=dt.UTC)
        assert "2026-05-30" in mdf.header.comment and "time of day unknown" in mdf.header.comment


@pytest.mark.parametrize("epoch", [EPOCH, None], ids=["epoch", "relative"])
def test_mdf_export_round_trip(epoch: float | None, tmp_path: Path) -> None:
    frame = estimate_frame()
    radii = np.linspace(0.1, 0.17, 12)
    path = write_estimate_mdf(frame, tmp_path / "estimate.mf4", node_radii=radii,
                              start_epoch_s=epoch, source="race.mcap")
    with MDF(path) as mdf:  # the reader WinTAX/ATLAS users check with: asammdf itself
        assert mdf.version == "4.10"
        if epoch is not None:
            assert mdf.header.start_time == dt.datetime.fromtimestamp(epoch, tz=dt.UTC)
        spot = mdf.get("BT_spot3")
        assert spot.unit == "degC" and "0.146 m" in spot.comment
        np.testing.assert_array_equal(spot.timestamps, frame["time"].to_numpy())
        np.testing.assert_array_equal(spot.samples, frame["spot3"].to_numpy())
        lower, upper = mdf.get("BT_spot3_lower").samples, mdf.get("BT_spot3_upper").samples
        np.testing.assert_allclose(upper - lower, 2 * frame["spot3_std"].to_numpy())
        node = mdf.get("BT_node_11")
        assert node.unit == "degC" and "0.1700 m" in node.comment
        assert mdf.get("BT_braking_power").unit == "W"
        assert mdf.get("BT_h").unit == "W/(m2 K)"
        np.testing.assert_array_equal(mdf.get("BT_lap").samples, frame["lap"].to_numpy())
    raw = read_mdf(path)  # and our own reader puts it on the source log's clock
    assert raw.metadata["source"] == "race.mcap"
    assert raw.start_epoch_s == (pytest.approx(epoch) if epoch is not None else None)
    assert {c.name for c in raw.channels} >= {"BT_contact_avg", "BT_contact_avg_std"}


def test_estimate_mdf_out_option_writes_beside_the_estimate(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The CLI hook only (the estimate itself is tested in test_pipelines_estimate)."""
    from typer.testing import CliRunner

    from brakethermo.cli import app
    from brakethermo.io import load_session
    from brakethermo.pipelines import estimate as estimate_mod
    from brakethermo.pipelines.estimate import EstimateResult
    from brakethermo.thermal.disc import load_disc

    src = tmp_path / "race.csv"
    src.write_text("time,vFront [km/h]\n0,1\n0.1,2\n")
    frame = estimate_frame()
    result = EstimateResult(
        session=load_session(src), frame=frame, node_radii=np.linspace(0.1, 0.17, 12),
        summary={"run": {"warnings": [], "timings_s": {}, "wall_time_s": 0.0, "h_law": "law"},
                 "laps": []},
        scores=None, open_loop=None, disc=load_disc(), timings={"total_s": 0.0},
    )
    # The command imports the pipeline when it runs (a light CLI start): patch it there.
    monkeypatch.setattr(estimate_mod, "estimate_from_session", lambda *_a, **_k: result)
    out = tmp_path / "out"
    run = CliRunner().invoke(app, ["estimate", str(src), "--out", str(out), "--no-report",
                                   "--mdf-out", "--mcap-out", "--json"])
    assert run.exit_code == 0, run.output
    with MDF(out / "race" / "estimate.mf4") as mdf:
        np.testing.assert_array_equal(mdf.get("BT_contact_avg").samples,
                                      frame["contact_avg"].to_numpy())
    # --mcap-out was batch's only; estimate writes the same MCAP beside
    import json

    from mcap.reader import make_reader

    with (out / "race" / "estimate.mcap").open("rb") as fh:
        spot3 = [json.loads(m.data)["value"] for _, _, m in
                 make_reader(fh).iter_messages(topics=["/brakethermo/spot3"])]
    np.testing.assert_allclose(spot3, frame["spot3"].round(3), atol=1e-9)
