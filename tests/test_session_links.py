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


def test_an_estimate_beside_a_batch_keeps_the_back_link(sim_race_session, tmp_path: Path
                                                         ) -> None:
    """`estimate … --out OUT` into a batch's folder dropped the session page's
    "← all sessions" link while the batch index still listed the session."""
    from typer.testing import CliRunner

    from brakethermo.cli import app
    from brakethermo.report.index import BATCH_MARK

    race = sim_race_session[0]
    for kind in ("none", "other site", "batch"):
        out = tmp_path / kind.replace(" ", "_")
        out.mkdir()
        if kind == "other site":
            (out / "index.html").write_text("<html>the team's own pages</html>")
        if kind == "batch":
            (out / "index.html").write_text(f"<html><head>{BATCH_MARK}</head></html>")
        res = CliRunner().invoke(app, ["estimate", str(race), "--out", str(out)])
        assert res.exit_code == 0, res.output
        page = (out / race.stem / "index.html").read_text()
        assert ('href="../index.html"' in page) is (kind == "batch"), kind


def test_refreshing_a_folder_without_a_batch_page_loads_no_report_stack(tmp_path) -> None:
    """An estimate that writes no page refreshes its folder's links without importing
    the batch package (and with it the report stack, matplotlib): checked in a fresh
    interpreter, this test process has long imported everything."""
    import subprocess
    import sys

    folder = tmp_path / "race"
    folder.mkdir()
    probe = ("import sys; from brakethermo.pipelines.output_dir import refresh_indexes;"
             f" refresh_indexes({str(folder)!r});"
             " print(sorted(m for m in sys.modules if m.startswith(('matplotlib',"
             " 'brakethermo.pipelines.batch', 'brakethermo.report.index'))))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "[]"


def test_the_small_index_names_the_option_that_exists(tmp_path: Path) -> None:
    """The index written without lap reports said "without --no-report"; the option is
    --no-reports (the old spelling is a hidden alias)."""
    from typer.testing import CliRunner

    from brakethermo.cli import app

    folder = tmp_path / "race"
    _summary(folder / "whatif" / "summary.json", "/laws/h_law.toml")
    (folder / "whatif" / "index.html").write_text("<html></html>")
    text = refresh_page_links(folder).read_text()
    assert "without --no-reports for them" in text
    assert "--no-reports" in CliRunner().invoke(app, ["estimate", "--help"]).output


def test_a_whatif_on_the_same_law_by_another_path_is_not_stale(tmp_path: Path,
                                                                monkeypatch) -> None:
    """The batch records its law relative to its working folder, whatif --h-law as typed
    (absolute): the page said "made with the h law h_law.toml; the estimate here now uses
    h_law.toml: run whatif again" of one file. A law that really differs is named so the
    two can be told apart, and a law file rewritten since is said to be."""
    monkeypatch.chdir(tmp_path)
    law_a, law_b = tmp_path / "o" / "ft_a" / "h_law.toml", tmp_path / "o" / "ft_b" / "h_law.toml"
    for law, text in ((law_a, "a"), (law_b, "b")):
        law.parent.mkdir(parents=True)
        law.write_text(text)
    folder = tmp_path / "o" / "race"
    (folder / "whatif").mkdir(parents=True)
    (folder / "whatif" / "index.html").write_text("<html></html>")
    _summary(folder / "summary.json", "o/ft_a/h_law.toml")  # as the batch wrote it
    _summary(folder / "whatif" / "summary.json", str(law_a))  # as whatif was given it
    assert "run whatif again" not in page_links(folder)
    _summary(folder / "whatif" / "summary.json", str(law_b))
    links = page_links(folder)
    assert "made with the h law ft_b/h_law.toml" in links
    assert "now uses ft_a/h_law.toml" in links

    def run(law: Path, sha: str) -> dict:
        return {"run": {"h_law": str(law), "h_law_sha256": sha}}

    # recorded bytes decide: one file under two spellings, or one file rewritten since
    (folder / "summary.json").write_text(json.dumps(run(Path("o/ft_a/h_law.toml"), "1" * 64)))
    (folder / "whatif" / "summary.json").write_text(json.dumps(run(law_a, "1" * 64)))
    assert "run whatif again" not in page_links(folder)
    (folder / "whatif" / "summary.json").write_text(json.dumps(run(law_a, "2" * 64)))
    links = page_links(folder)
    assert f"read the h law {law_a} with other contents" in links
    assert "rewritten between them" in links
