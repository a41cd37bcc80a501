"""The generic report page and the rig output folder: files, escaping, atomic replacement."""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from brakethermo.pipelines.rig_outputs import write_rig_outputs
from brakethermo.report.page import Card, Page, Section, TableBlock


def _page(title: str) -> Page:
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    section = Section("Radius", ["text <b>bold?</b>"], [TableBlock(["a", "b"], [[1, "[/b]"]])],
                      {"radius": fig}, ["note"])
    return Page(title, "bench 3", [Card("radius", "348.1", "mm")], [section])


def test_rig_folder_written_whole_and_escaped(tmp_path: Path) -> None:
    frame = pd.DataFrame({"time": [0.0, 0.005], "radius_mm_320": [320.0, 321.0]})
    folder = write_rig_outputs(tmp_path, "run1", "roller_rig", frame,
                               {"x": np.float64(2.5), "nan": float("nan")},
                               _page("<script>"), {"radius_mm_320": "mm"})
    assert sorted(p.name for p in folder.iterdir()) == [
        "index.html", "radius.png", "roller_rig.parquet", "summary.json"]
    html = (folder / "index.html").read_text()
    assert "<script>" not in html and "&lt;script&gt;" in html
    assert "&lt;b&gt;" in html and 'src="radius.png"' in html
    assert json.loads((folder / "summary.json").read_text()) == {"x": 2.5, "nan": None}
    field = pq.read_schema(folder / "roller_rig.parquet").field("radius_mm_320")
    assert field.metadata == {b"unit": b"mm"}
    # A re-run replaces the folder as a whole: no stale file of the first run stays.
    (folder / "stale.png").write_bytes(b"x")
    write_rig_outputs(tmp_path, "run1", "roller_rig", frame, {}, Page("again"))
    assert not (folder / "stale.png").exists()
    assert not (folder / "radius.png").exists()
