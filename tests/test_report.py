"""Per-lap reports: braking zones, lap statistics, self-contained HTML, MCAP export."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from _synth_race import estimate_frame, make_session, race_frame, write_estimate_parquet
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from PIL import Image

from brakethermo.report.braking_zones import BAR, ZoneDetection, detect_zones, zone_table
from brakethermo.report.lap_report import read_estimate, write_session_report
from brakethermo.report.mcap_export import write_estimate_mcap
from brakethermo.results.laps import lap_stats

WINDOW = (250.0, 850.0)


@pytest.fixture(scope="module")
def race() -> tuple[pd.DataFrame, pd.DataFrame, np.ndarray]:
    frame = race_frame(3, seed=7)
    est, radii = estimate_frame(frame, n_nodes=17)
    return frame, est, radii


@pytest.fixture(scope="module")
def report(race, tmp_path_factory):
    frame, est, radii = race
    out = tmp_path_factory.mktemp("report") / "race"
    session = make_session(frame, out.parent / "race.mcap")
    return write_session_report(est, session, out, node_radii=radii), out


def test_detect_zones_bridges_and_drops() -> None:
    t = np.arange(100) * 0.1
    p = np.zeros(100)
    p[10:30] = 10 * BAR  # 2 s braking
    p[33:40] = 8 * BAR  # 0.3 s release -> same zone
    p[60:62] = 12 * BAR  # 0.2 s blip -> dropped
    p[80:95] = 5 * BAR
    p[85] = np.nan  # a gap in the pressure log (< bridge) does not split the zone
    zones = detect_zones(t, p, ZoneDetection(on_pa=3 * BAR, bridge_s=0.6, min_duration_s=0.4))
    assert zones.tolist() == [[10, 40], [80, 95]]
    assert detect_zones(t, np.zeros(100)).shape == (0, 2)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0, 20), min_size=2, max_size=300))
def test_detect_zones_properties(bars: list[float]) -> None:
    p = np.asarray(bars) * BAR
    t = np.arange(p.size) * 0.1
    det = ZoneDetection()
    zones = detect_zones(t, p, det)
    # Ordered, disjoint, inside the data, starting and ending on brake application/release.
    assert np.all(zones[:, 0] < zones[:, 1])
    assert np.all(zones[1:, 0] > zones[:-1, 1])
    assert zones.size == 0 or (zones.min() >= 0 and zones.max() <= p.size)
    for a, b in zones:
        assert p[a] > det.on_pa and p[b - 1] > det.on_pa
        assert (b - a) * 0.1 >= det.min_duration_s - 1e-9
    # Every long braking run is covered by a zone.
    covered = np.zeros(p.size, bool)
    for a, b in zones:
        covered[a:b] = True
    run = 0
    for k, on in enumerate(p > det.on_pa):
        run = run + 1 if on else 0
        if run * 0.1 >= det.min_duration_s - 1e-9:
            assert covered[k]


def test_zone_table_matches_the_data(race) -> None:
    frame, est, _ = race
    p = frame["brake_pressure_front"].to_numpy()
    zones = detect_zones(frame["time"].to_numpy(), p)
    table = zone_table(est, frame["speed"].to_numpy(), p, zones, WINDOW)
    assert table.groupby("lap").size().tolist() == [6, 6, 6]
    assert table["zone"].tolist() == [f"B{k}" for k in range(1, 7)] * 3  # no distance: order
    # Zones start at the braking positions of the synthetic lap (lap time, s).
    np.testing.assert_allclose(table["start_s"][:6], [8, 22, 37, 51, 66, 82], atol=0.35)
    assert (table["entry_speed_kmh"] > 280).all() and (table["min_speed_kmh"] < 200).all()
    assert (table["peak_pressure_bar"] > 6).all()
    # Brute force for one zone: its cycle runs to the next zone's start.
    k = 8
    a, b = zones[k, 0], zones[k + 1, 0]
    contact = est["contact_avg"].to_numpy()
    row = table.iloc[k]
    assert row["peak_spot3"] == pytest.approx(est["spot3"].to_numpy()[a:b].max())
    assert row["rise_k"] == pytest.approx(contact[a:b].max() - contact[a])
    assert row["cooling_k"] == pytest.approx(contact[a:b].max() - contact[b])
    assert row["below_s"] + row["inside_s"] + row["above_s"] == pytest.approx((b - a) * 0.1)
    assert row["inside_s"] == pytest.approx(
        np.sum((contact[a:b] >= 250) & (contact[a:b] <= 850)) * 0.1
    )
    assert (table["rise_k"] > 0).all() and (table["cooling_k"] > 0).all()


def test_lap_stats_brute_force(race) -> None:
    _, est, _ = race
    est = est.copy()
    est.loc[est.index[:50], "contact_avg"] = 900.0  # some time above the window
    stats = lap_stats(est, WINDOW)
    for lap, g in est.groupby("lap"):
        c = g["contact_avg"].to_numpy()
        s = stats.loc[lap]
        assert s["lap_time_s"] == pytest.approx(len(g) * 0.1)
        assert s["peak_spot4"] == pytest.approx(g["spot4"].max())
        assert s["peak_spot4_t"] == pytest.approx(
            g["time"].to_numpy()[g["spot4"].argmax()] - g["time"].min()
        )
        assert s["above_s"] == pytest.approx(np.sum(c > 850) * 0.1)
        assert s["below_s"] == pytest.approx(np.sum(c < 250) * 0.1)
        assert s["inside_pct"] == pytest.approx(100 * np.mean((c >= 250) & (c <= 850)))
        band = 1.96 * g["contact_avg_std"].to_numpy()
        assert s["above_band_lo_s"] == pytest.approx(np.sum(c - band > 850) * 0.1)
        assert s["above_band_hi_s"] == pytest.approx(np.sum(c + band > 850) * 0.1)
        assert s["below_band_lo_s"] == pytest.approx(np.sum(c + band < 250) * 0.1)
        assert s["below_band_hi_s"] == pytest.approx(np.sum(c - band < 250) * 0.1)
        assert s["above_band_lo_s"] <= s["above_s"] <= s["above_band_hi_s"]
        assert s["below_band_lo_s"] <= s["below_s"] <= s["below_band_hi_s"]
    assert stats.loc[0, "above_s"] == pytest.approx(5.0)
    assert "above_band_lo_s" not in lap_stats(est.drop(columns="contact_avg_std"), WINDOW)


def test_report_files_and_self_contained_html(report) -> None:
    result, out = report
    assert sorted(p.name for p in out.iterdir()) == [
        "index.html",
        "lap_00",
        "lap_01",
        "lap_02",
        "trend.png",
    ]
    for lap in ("lap_00", "lap_01", "lap_02"):
        names = sorted(p.name for p in (out / lap).iterdir())
        assert names == ["contact.png", "context.png", "heatmap.png", "index.html", "spots.png"]
        with Image.open(out / lap / "heatmap.png") as img:
            assert img.size[0] == 1100
        html = (out / lap / "index.html").read_text()
        assert html.count('src="data:image/png;base64,') == 4
        assert not re.search(r"(src|href)=\"(https?:)?//", html)  # no network needed
        assert html.count("<tr>") == 1 + 6  # header + one row per braking zone
    index = (out / "index.html").read_text()
    for lap in ("lap_00", "lap_01", "lap_02"):
        assert f'href="{lap}/index.html"' in index
    assert 'href="../lap_01/index.html"' in (out / "lap_00" / "index.html").read_text()
    assert set(result.lap_pages) == {0, 1, 2}
    assert result.timings["render_s"] > 0


def test_read_estimate_radii_and_report_from_file(race, tmp_path: Path) -> None:
    _, est, radii = race
    write_estimate_parquet(est, radii, tmp_path / "estimate.parquet")
    back, back_radii = read_estimate(tmp_path / "estimate.parquet")
    np.testing.assert_allclose(back_radii, radii)
    # Without the session (no speed, pressure, measurement) the report still renders.
    result = write_session_report(back, None, tmp_path / "r", node_radii=back_radii)
    assert result.zones.empty and (tmp_path / "r" / "lap_02" / "index.html").is_file()


def test_mcap_export_round_trip(race, tmp_path: Path) -> None:
    _, est, radii = race
    est = est.copy()
    est["power_scale"] = np.linspace(0.9, 1.1, len(est))
    est["braking_power"] = 1.0e4
    for k in range(len(radii)):  # mid-plane temperatures, a second node family
        est[f"mid_{k}"] = est[f"node_{k}"] - 5.0
    est.loc[5, "spot1"] = np.nan  # a gap stays a gap (JSON null)
    path = write_estimate_mcap(
        est,
        tmp_path / "estimate.mcap",
        node_radii=radii,
        start_epoch_s=1_746_000_000.5,
        source="race.mcap",
    )
    got: dict[str, list] = {}
    times: dict[str, list] = {}
    with path.open("rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        assert {c.compression for c in summary.chunk_indexes} == {"zstd"}
        channels = {c.topic: c for c in summary.channels.values()}
        for schema, channel, msg in reader.iter_messages():
            assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
            got.setdefault(channel.topic, []).append(json.loads(msg.data))
            times.setdefault(channel.topic, []).append(msg.log_time)
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert meta["brakethermo"]["source"] == "race.mcap"
    assert channels["/brakethermo/spot3"].metadata["unit"] == "degC"
    assert float(channels["/brakethermo/spot3"].metadata["radius_m"]) == 0.146
    np.testing.assert_allclose(
        json.loads(channels["/brakethermo/disc_nodes"].metadata["radius_m"]), radii
    )
    expected_t = 1_746_000_000_500_000_000 + np.rint(est["time"].to_numpy() * 1e9).astype(np.int64)
    assert times["/brakethermo/spot3"] == expected_t.tolist()
    for col in ("spot1", "spot2", "spot3", "spot4", "contact_avg"):
        msgs = got[f"/brakethermo/{col}"]
        value = np.array([np.nan if m["value"] is None else m["value"] for m in msgs])
        np.testing.assert_allclose(value, est[col].round(3), equal_nan=True, atol=1e-9)
        std = np.array([m["std"] for m in msgs])
        np.testing.assert_allclose(std, est[f"{col}_std"].round(3), atol=1e-9)
        upper = np.array([np.nan if m["upper"] is None else m["upper"] for m in msgs])
        np.testing.assert_allclose(
            upper, (est[col] + est[f"{col}_std"]).round(3), equal_nan=True, atol=1e-9
        )
    assert got["/brakethermo/spot1"][5]["value"] is None
    nodes = np.array([m["temperature"] for m in got["/brakethermo/disc_nodes"]])
    node_cols = [f"node_{k}" for k in range(len(radii))]
    np.testing.assert_allclose(nodes, est[node_cols].round(2).to_numpy(), atol=1e-9)
    mid = np.array([m["temperature"] for m in got["/brakethermo/disc_mid"]])
    np.testing.assert_allclose(mid, (est[node_cols] - 5.0).round(2).to_numpy(), atol=1e-9)
    assert channels["/brakethermo/disc_mid"].metadata["unit"] == "degC"
    assert channels["/brakethermo/braking_power"].metadata["unit"] == "W"
    assert not any(t.startswith("/brakethermo/mid_") for t in channels)
    assert [m["value"] for m in got["/brakethermo/lap"]] == est["lap"].tolist()
    np.testing.assert_allclose(
        [m["value"] for m in got["/brakethermo/power_scale"]],
        est["power_scale"].round(6),
        atol=1e-9,
    )


def test_zones_are_named_by_track_position_on_every_lap() -> None:
    """Three flying laps brake at 300, 900 and 1500 m; lap 2 misses the second zone and
    lap 3 adds a dab at 1200 m: the names stay with the corners (B1, B2, B3 on every
    lap, the dab "B2+"); the out-lap's stops, at no flying lap's zone, are named after
    the zone before them on the track (they were "out B1", "out B2" by their order)."""
    from brakethermo.report.braking_zones import zone_names

    names = zone_names(*_laps_braking_at({
        0: [100.0, 700.0], 1: [300.0, 900.0, 1500.0], 2: [305.0, 1490.0],
        3: [295.0, 905.0, 1200.0, 1510.0]}))
    assert names == ["B0+", "B1+", "B1", "B2", "B3", "B1", "B3", "B1", "B2", "B2+", "B3"]


def _laps_braking_at(laps: dict[int, list[float]], offset: dict[int, float] | None = None
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Zones, lap and lap distance of 2000 m laps braking at the given distances (each
    lap's distance from its first sample; ``offset``: m of the lap before its log began,
    as an out-lap from the pit exit)."""
    offset = offset or {}
    lap, dist, starts = [], [], []
    for n, ds in laps.items():
        skip = int(offset.get(n, 0.0))
        base = len(lap)
        lap += [n] * (2000 - skip)
        dist += list(np.arange(2000.0 - skip))
        starts += [base + int(d) - skip for d in ds]
    zones = np.column_stack([starts, np.array(starts) + 20])
    return zones, np.array(lap), np.array(dist)


def test_out_lap_stops_carry_the_flying_laps_names() -> None:
    """The out-lap brakes where the flying laps do, and once where only some do (the
    "B1+" dab at 600 m): its stops carry those names, from the line or from a pit exit
    450 m down the lap. They were named by their order, "out B1" … "out B4", so from the
    dab on every name was one off (the repro's "out B4" at the flying laps' "B3+")."""
    from brakethermo.report.braking_zones import zone_names

    flying = {1: [300.0, 600.0, 900.0, 1500.0], 2: [300.0, 900.0, 1500.0],
              3: [300.0, 900.0, 1500.0]}
    want_flying = ["B1", "B1+", "B2", "B3"] + ["B1", "B2", "B3"] * 2
    from_line = zone_names(*_laps_braking_at({0: [310.0, 610.0, 900.0, 1490.0], **flying}))
    assert from_line == ["B1", "B1+", "B2", "B3", *want_flying]
    # from the pit exit at 450 m: the out-lap's own distance is 450 m short all lap
    pit = zone_names(*_laps_braking_at({0: [610.0, 900.0, 1490.0], **flying},
                                       offset={0: 450.0}))
    assert pit == ["B1+", "B2", "B3", *want_flying]
