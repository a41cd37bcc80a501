"""Every number shown in two places is the same number: the estimate's lap times and
peaks in the console table, summary.json and the session page (issue: "pages that say
only what is true")."""

from __future__ import annotations

import json
import re
from pathlib import Path

from typer.testing import CliRunner

from brakethermo.cli import app
from brakethermo.results.laps import lap_time_text, temp_text

runner = CliRunner()


def test_console_json_and_page_show_the_same_laps(sim_race_session, tmp_path: Path) -> None:
    race = sim_race_session[0]
    out = tmp_path / "out"
    res = runner.invoke(app, ["estimate", str(race), "--out", str(out)],
                        env={"COLUMNS": "200"})
    assert res.exit_code == 0, res.output
    folder = out / race.stem
    summary = json.loads((folder / "summary.json").read_text())
    page = (folder / "index.html").read_text()
    console_rows = {t[0]: t[1:6] for t in (line.split() for line in res.output.splitlines())
                    if len(t) > 6 and re.fullmatch(r"\d+:\d\d\.\d{3}", t[1])}
    page_rows = {m[1]: [m[2], *m[3:7]] for m in re.findall(
        r'<td><a href="lap_\d+/index.html">([^<]+)</a></td><td>([^<]+)</td>\s*'
        r"<td>([^<]+)</td><td>([^<]+)</td><td>([^<]+)</td><td>([^<]+)</td>", page)
        for m in [(None, *m)]}
    assert summary["laps"]
    for lap in summary["laps"]:
        expected = [lap_time_text(lap["lap_time_s"]),
                    *(temp_text(lap["peak"].get(f"spot{i}", {}).get("temp_c"))
                      for i in range(1, 5))]
        assert console_rows[lap["label"]] == expected, (lap["label"], console_rows)
        assert page_rows[lap["label"]] == expected, (lap["label"], page_rows)
