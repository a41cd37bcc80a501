"""Issue 12 items 13-16: what the report says must be true, and said the same way everywhere."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

from brakethermo.io.session import Lap
from brakethermo.report.figures import LapFigures
from brakethermo.report.index import write_batch_index
from brakethermo.report.lap_report import _colour_range, write_session_report
from brakethermo.results.laps import (
    flying_laps,
    lap_label,
    lap_stats,
    lap_summaries,
    round_temp,
    temp_text,
)

WINDOW = (250.0, 850.0)
RADII = np.linspace(0.100, 0.170, 11)
DT = 0.1


def _frame(n_per_lap: int = 300, laps: tuple[int, ...] = (0, 1, 2)) -> pd.DataFrame:
    """An estimate frame whose outer edge overheats while the contact band stays inside."""
    n = n_per_lap * len(laps)
    t = np.arange(n) * DT
    lap = np.repeat(laps, n_per_lap)
    phase = np.sin(np.pi * (np.arange(n) % n_per_lap) / n_per_lap)
    base = 300.0 + 300.0 * phase * (lap >= 1)  # 300..600 degC on the flying laps
    # hotter towards the outer radius; the outer node crosses 850 degC mid-lap
    nodes = base[None, :] + (RADII[:, None] - RADII[0]) / (RADII[-1] - RADII[0]) * (
        300.0 * phase * (lap >= 1))[None, :]
    cols = {"time": t, "lap": lap.astype(np.int64)}
    spot_r = (0.111, 0.130, 0.146, 0.162)
    for i, r in enumerate(spot_r, start=1):
        cols[f"spot{i}"] = np.array([np.interp(r, RADII, nodes[:, k]) for k in range(n)])
        cols[f"spot{i}_std"] = np.full(n, 5.0)
    cols["contact_avg"] = (cols["spot2"] + cols["spot3"] + cols["spot4"]) / 3.0
    cols["contact_avg_std"] = np.full(n, 4.0)
    for k in range(len(RADII)):
        cols[f"node_{k}"] = nodes[k]
    return pd.DataFrame(cols)


def _laps(frame: pd.DataFrame) -> tuple[Lap, ...]:
    out = []
    for lap, g in frame.groupby("lap"):
        out.append(Lap(int(lap), float(g["time"].min()), float(len(g) * DT)))
    return tuple(out)


# ------------------------------------------------------------- item 13: hottest radius
def test_hottest_radius_reveals_what_the_contact_band_hides():
    frame = _frame()
    records = lap_summaries(frame, _laps(frame), WINDOW, RADII)
    lap1 = records[1]
    assert lap1["time_above_window_s"] == 0.0  # contact band inside the whole lap
    hot = lap1["hottest"]
    assert hot["temp_c"] > 850.0 and hot["radius_mm"] == pytest.approx(170.0)
    assert hot["time_above_window_s"] > 0.0
    assert lap1["time_above_window_by_spot_s"]["spot4"] > 0.0
    assert lap1["time_above_window_by_spot_s"]["spot1"] == 0.0
    stats = lap_stats(frame, WINDOW, RADII)
    assert stats.loc[1, "above_s"] == 0.0 and stats.loc[1, "above_hot_s"] == pytest.approx(
        hot["time_above_window_s"])
    assert stats.loc[1, "peak_hot_radius_mm"] == pytest.approx(170.0)
    assert stats.loc[1, "above_spot4_s"] == pytest.approx(
        lap1["time_above_window_by_spot_s"]["spot4"], abs=0.05)
    # the contact band 4 degC wide (1 sigma) never nears 850 degC: sure it stays below
    assert lap1["time_above_window_band_s"] == [0.0, 0.0]
    lo, hi = lap1["time_below_window_band_s"]
    assert lo <= lap1["time_below_window_s"] <= hi


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> tuple[Path, pd.DataFrame]:
    out = tmp_path_factory.mktemp("rep") / "session"
    frame = _frame(200, (0, 1))
    on = frame["lap"] == 1
    frame.loc[on, "spot1"] += 699.46 - frame.loc[on, "spot1"].max()
    (out).mkdir()
    (out / "h_law.png").write_bytes(_png())
    summary = {
        "run": {"measured_spot": 3, "h_law": str(out / "h_law.toml"),
                "h_law_choice": "identified from this session by identify-h"},
        "scores": {
            "measured_spot": 3,
            "table": [{"method": "smoother", "spot1": 9.1, "spot2": 5.2, "spot3": 2.0,
                       "spot4": 6.3, "contact_avg": 4.4},
                      {"method": "single-spot", "spot1": 30.0, "spot2": 20.0, "spot3": 0.0,
                       "spot4": 25.0, "contact_avg": 15.0}],
            "contact_ratio_vs_single_spot": {"smoother": 0.29},
            "peak": {"spot3": {"zones": 7, "zones_total": 8, "mean_abs_pct": 1.5}},
            "coverage95": {"spot1": 0.93, "spot2": 0.96, "spot4": 0.97},
        },
    }
    write_session_report(frame, None, out, node_radii=RADII, summary=summary,
                         back_href="../index.html")
    return out, frame


def _png() -> bytes:
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (4, 4), "white").save(buf, format="png")
    return buf.getvalue()


def test_lap_page_shows_hottest_radius_and_per_spot_time_above(report):
    out, _ = report
    html = (out / "lap_01" / "index.html").read_text()
    assert "Hottest radius" in html and "at 170 mm" in html
    assert re.search(r'class="hot">[0-9]+</span> <small>°C at 170 mm, [1-9][0-9.]* s above', html)
    assert "Above window per spot" in html


# ------------------------------------------------------------- item 14: session page
def test_session_page_says_which_spot_fed_the_filter_and_shows_self_scores(report):
    out, _ = report
    index = (out / "index.html").read_text()
    assert "spot 3 measured (the filter&#39;s input); spots 1, 2, 4 held out" in index or (
        "spot 3 measured (the filter's input); spots 1, 2, 4 held out" in index)
    assert "How well the estimate did" in index and "0.29x" in index
    assert "over 7 of 8 zones" in index and "spot4 97 %" in index
    assert "identified from this session by identify-h" in index
    assert 'alt="the h(V) law and the straights it rests on' in index
    assert '<a href="../index.html">&larr; all sessions</a>' in index
    lap = (out / "lap_01" / "index.html").read_text()
    assert "held out" in lap and 'href="../index.html"' in lap


# ------------------------------------------------------------- item 15: ranges and title
def test_heatmap_scale_follows_the_flying_laps_and_title_promises_nothing_unseen():
    nodes = np.concatenate([np.full(20, -150.0), np.linspace(300.0, 720.0, 5000)])
    lo, hi = _colour_range(nodes)
    assert (lo, hi) == (300.0, 750.0)
    figs = LapFigures(RADII, (0.111, 0.130, 0.146, 0.162), WINDOW, 0.1, 0.17,
                      __import__("brakethermo.report.figures", fromlist=["AxisScales"])
                      .AxisScales((0.0, 900.0), (200.0, 900.0), 300.0, 20.0))
    try:
        title = figs.ax_heatmap.get_title(loc="left")
        assert "dashed contours: window" not in title and "where crossed" in title
    finally:
        figs.close()


def test_heatmap_title_names_only_the_window_marks_the_colour_bar_shows():
    from brakethermo.report.figures import AxisScales

    def title_and_marks(temp_range):
        figs = LapFigures(RADII, (0.111, 0.130, 0.146, 0.162), (250.0, 850.0), 0.1, 0.17,
                          AxisScales((0.0, 900.0), (200.0, 900.0), 300.0, 20.0),
                          temp_range_c=temp_range)
        try:
            cax = figs.fig_heatmap.axes[-1]
            marks = sorted({round(float(line.get_ydata()[0])) for line in cax.lines})
            return figs.ax_heatmap.get_title(loc="left"), marks
        finally:
            figs.close()

    title, marks = title_and_marks((250.0, 760.0))  # the lower edge at the bar's very end
    assert marks == [] and "both edges beyond the colour bar" in title
    assert "marked" not in title
    title, marks = title_and_marks((200.0, 760.0))
    assert marks == [250] and "; 250 °C marked on the colour bar" in title
    title, marks = title_and_marks((0.0, 1000.0))
    assert marks == [250, 850] and "both edges marked on the colour bar" in title
    assert "window 250–850 °C white dashed where crossed" in title


# ------------------------------------------------------------- item 16: one definition each
def test_out_lap_and_lap_counts_have_one_name(report):
    out, frame = report
    assert lap_label(0) == "out-lap" and lap_label(3) == "3"
    assert flying_laps(frame["lap"]) == 1 and flying_laps([0, 1, 2, 2, 3]) == 3
    index = (out / "index.html").read_text()
    assert re.search(r'Laps</div><div class="value">1 <small>\+ out-lap', index)
    assert ">out-lap</a>" in index and "lap 00" not in index
    assert "<h1>session · out-lap</h1>" in (out / "lap_00" / "index.html").read_text()


def test_a_peak_rounds_to_the_same_integer_everywhere(report, tmp_path):
    out, frame = report
    stats = lap_stats(frame, WINDOW, RADII)
    assert stats.loc[1, "peak_spot1"] == pytest.approx(699.46)
    page = (out / "index.html").read_text()
    assert "<td>700</td>" in page and "<td>699</td>" not in page
    summary = lap_summaries(frame, _laps(frame), WINDOW, RADII)
    stored = summary[1]["peak"]["spot1"]["temp_c"]
    assert stored == 699.46 and temp_text(stored) == temp_text(round_temp(stored)) == "700"
    write_batch_index(tmp_path, tmp_path, [{"name": "s", "status": "ok", "kind": "single",
                                            "laps": 2, "peaks_c": {"spot1": round_temp(stored)}}])
    assert "<td>700</td>" in (tmp_path / "index.html").read_text()


@given(st.floats(-100.0, 2000.0, allow_nan=False))
def test_displayed_integer_is_the_same_from_raw_or_stored(x):
    assert temp_text(x) == temp_text(round_temp(x))
    assert abs(int(temp_text(x)) - x) <= 0.55


def test_a_measured_spot_above_the_window_shows_even_if_the_estimate_stays_inside(tmp_path):
    import pyarrow.parquet as pq
    from _synth_race import estimate_frame, write_session_parquet

    from brakethermo.io.load import load_session

    path = write_session_parquet(tmp_path / "hot.parquet", 1, seed=9, multi=True)
    table = pq.read_table(path)
    spot4 = table.column("disc_temp_spot4").to_numpy().copy()
    hot = slice(len(spot4) // 2, len(spot4) // 2 + 40)  # 4 s at 900 degC
    spot4[hot] = 900.0
    i = table.schema.get_field_index("disc_temp_spot4")
    pq.write_table(table.set_column(i, table.schema.field(i), [spot4]), path)
    session = load_session(path)
    est, radii = estimate_frame(session.frame, n_nodes=11)
    for col in [c for c in est.columns if c.startswith(("spot", "node_", "contact"))
                and not c.endswith("_std")]:
        est[col] = est[col].clip(upper=800.0)  # the model keeps it inside
    out = tmp_path / "rep"
    result = write_session_report(est, session, out, node_radii=radii)
    lap = int(session.frame["lap"].to_numpy()[hot.start])
    assert result.laps.loc[lap, "above_hot_s"] == 0.0
    assert result.laps.loc[lap, "meas_above_spot4_s"] == pytest.approx(4.0, abs=0.25)
    page = (out / f"lap_{lap:02d}" / "index.html").read_text()
    assert re.search(r'S4 <span class="hot">[34]\.[0-9] s above, peak 900 °C', page)


def test_a_cut_last_lap_is_marked_partial() -> None:
    """A truncated log's last lap (72 s on a 1:56 track) read as a lap time."""
    from brakethermo.io.session import Lap
    from brakethermo.results.laps import partial_laps

    laps = (Lap(0, 0.0, 150.0), Lap(1, 150.0, 116.0), Lap(2, 266.0, 115.8),
            Lap(3, 381.8, 116.2), Lap(4, 498.0, 72.2))
    assert partial_laps(laps) == {4}
    assert partial_laps(laps[:3]) == set()  # two full flying laps
    assert partial_laps((*laps[:2], Lap(2, 266.0, 63.3))) == {2}  # a log cut in lap 2
    assert partial_laps(laps[:2]) == set()  # one lap alone cannot be judged


def test_contact_band_legend_gives_the_bands_size_and_spot_axis_keeps_the_band():
    """A ±7.6 °C band on the contact plot's 0–900 °C axis is a hairline: the legend says
    its size; the spot plot's axis stopped at the estimate's peak and cut its band."""
    import io
    from dataclasses import replace

    from PIL import Image

    from brakethermo.report.figures import RIGHT, AxisScales, LapData

    figs = LapFigures(RADII, (0.111, 0.130, 0.146, 0.162), WINDOW, 0.1, 0.17,
                      AxisScales((0.0, 900.0), (200.0, 900.0), 300.0, 20.0))
    try:
        n = 50
        t = np.arange(n) * 0.1
        spot = np.full((4, n), 600.0)
        spot[1, 10] = 699.0  # a peak just under 700 °C with a 20 °C band
        std = np.full((4, n), 20.0)
        lap = LapData(t, spot, std, np.full((4, n), np.nan), np.full(n, 600.0),
                      np.full(n, 7.6), np.full((len(RADII), n), 600.0), np.full(n, 200.0),
                      np.zeros(n), np.zeros((0, 2)))
        first = figs.render(lap)["contact"]
        assert figs._band_label.get_text() == "σ ≈ 7.6 °C (median)"
        assert figs.ax_spots.get_ylim()[1] >= 699.0 + 20.0
        # the next lap's page shows its own σ (the legend was in the cached background)
        second = figs.render(replace(lap, contact_std=np.full(n, 3.2)))["contact"]
        legend_part = []
        for png in (first, second):
            img = np.asarray(Image.open(io.BytesIO(png)).convert("L"))
            legend_part.append(img[:, int(img.shape[1] * (RIGHT + 0.01)):])
        assert not np.array_equal(*legend_part)
        # ... and its own course of σ, on a scale that holds it (the band is a hairline)
        np.testing.assert_array_equal(figs.sigma_line.get_ydata(), np.full(n, 3.2))
        assert figs.ax_sigma.get_ylim() == (0.0, 5.0)
        figs.render(replace(lap, contact_std=np.linspace(1.0, 12.0, n)))
        assert figs.ax_sigma.get_ylim() == (0.0, 15.0)
    finally:
        figs.close()
