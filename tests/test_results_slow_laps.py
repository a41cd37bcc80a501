"""Slow laps (in-laps, cool-down laps) are told from flying laps, and the page says so."""

from brakethermo.io.session import Lap
from brakethermo.report.diagnose_report import _slow_text
from brakethermo.results.laps import slow_laps


def _laps(durations: list[float]) -> tuple[Lap, ...]:
    start, out = 0.0, []
    for n, d in enumerate(durations):
        out.append(Lap(n, start, d))
        start += d
    return tuple(out)


def test_an_in_lap_is_slow_and_the_flying_laps_are_not():
    laps = _laps([150.0, 105.0, 104.0, 106.0, 105.0, 170.0])
    assert set(slow_laps(laps)) == {5}
    assert slow_laps(laps)[5] == 170.0 / 105.0
    assert slow_laps(_laps([150.0, 105.0, 104.0, 106.0])) == {}  # the out-lap is no lap here


def test_two_laps_cannot_tell_a_slow_one():
    assert slow_laps(_laps([150.0, 105.0, 170.0])) == {}


def test_the_page_says_which_laps_are_slow():
    assert _slow_text({"slow_laps": {}}) == ""
    text = _slow_text({"slow_laps": {"7": 1.43}})
    assert text.startswith(" Lap 7 took 1.43 x the typical lap time") and "no flying lap" in text
    two = _slow_text({"slow_laps": {"6": 1.3, "7": 1.43}})
    assert two.startswith(" Laps 6, 7 took 1.30, 1.43 x") and "no flying laps" in two


def test_the_reference_section_warns_of_a_flat_reference_law() -> None:
    """diagnose ft_a ft_b: the page said "Fitted: h_a = 104, h_b = 2.8e-06" and nothing
    flagged the law at its bound; the law check and any other bound are said in red."""
    from brakethermo.report.diagnose_report import _reference_section

    check = {"text": "h(V) law implausible for forced convection: exponent b = 2.8e-06"}
    test = {"train_laps": [2, 4], "heldout_laps": [3, 5], "slow_laps": {},
            "reference": {"contains": ["x"], "fitted": {"h_a": 104.0, "h_b": 2.8e-06},
                          "law_check": check,
                          "at_bounds": {"reference.b": 2.8e-06, "reference.w1": 0.05}}}
    notes = _reference_section(test).notes
    assert notes[0].startswith("Fitted: h_a = 104")
    assert notes[1] == "WARNING: " + check["text"]
    assert "reference.w1 = 0.05" in notes[2] and "reference.b" not in notes[2]
    # an exponent at its upper bound (3) is no flat law: the law check says nothing of it,
    # the bound note does (review: it was dropped with the lower one)
    test["reference"] |= {"law_check": None, "at_bounds": {"reference.b": 3.0}}
    notes = _reference_section(test).notes
    assert any("reference.b = 3" in n for n in notes)


def test_the_reference_section_says_what_a_single_spot_race_fits() -> None:
    """A single-spot race's page read "Fitted on laps ; every 'after' figure ... laps 1, 2,
    3, 4, 5, which no fit saw" and "Fitted: " with nothing after it: nothing is fitted
    offline there."""
    from brakethermo.report.diagnose_report import _reference_section

    race = {"train_laps": [], "heldout_laps": [1, 2, 3, 4, 5], "slow_laps": {},
            "reference": {"contains": ["the race estimator"], "fitted": {}}}
    section = _reference_section(race)
    text = " ".join(section.paragraphs)
    assert "Fitted on laps ;" not in text and "Nothing is fitted offline" in text
    assert "laps 1, 2, 3, 4, 5" in text and section.notes == []
