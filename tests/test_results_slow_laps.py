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
