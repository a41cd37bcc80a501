"""The session index's links to the pages other commands wrote beside it."""

from __future__ import annotations

import json
from pathlib import Path

from brakethermo.report.session_links import page_links, refresh_page_links


def _summary(path: Path, law: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"run": {"h_law": law}}))


def test_links_what_exists_and_marks_a_whatif_of_another_law(tmp_path: Path) -> None:
    """A what-if replayed on the shipped law stayed linked, unmarked, after an estimate
    with another law replaced the estimate it was anchored to."""
    folder = tmp_path / "race"
    _summary(folder / "summary.json", "/laws/test_day/h_law.toml")
    assert page_links(folder) == ""
    _summary(folder / "whatif" / "summary.json", "/laws/test_day/h_law.toml")
    (folder / "whatif" / "index.html").write_text("<html></html>")
    assert page_links(folder).endswith("</a>")  # same law: a plain link
    _summary(folder / "summary.json", "/configs/hlaw/cc-340-8.toml")
    links = page_links(folder)
    assert 'href="whatif/index.html"' in links and "cc-340-8.toml" in links
    assert "run whatif again" in links
    index = refresh_page_links(folder)  # no lap reports: a small index holds the links
    assert index is not None and "run whatif again" in index.read_text()
    assert 'href="diagnosis/index.html"' not in index.read_text()
