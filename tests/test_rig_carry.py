"""--with-effect's sources (pipelines/rig_carry.py): what is carried, and bad files."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from brakethermo.errors import ConfigError
from brakethermo.models.rig_effects import BOOSTER_EFFECTS, ROLLER_EFFECTS
from brakethermo.pipelines.rig_carry import carried


def _never() -> dict:
    raise AssertionError("auto was not asked for")


def _diagnosis(tmp_path: Path, name: str, summary) -> str:
    path = tmp_path / f"{name}.json"
    path.write_text(summary if isinstance(summary, str) else json.dumps(summary))
    return str(path)


def test_a_verdict_alone_a_set_and_none(tmp_path: Path) -> None:
    effects = [{"name": "pv_shift", "params": {"shift_mm": 0.3}},
               {"name": "pv_drift", "params": {"shift_mm": 0.2, "drift_mm": 0.1}}]
    alone = {"rig": "ebooster", "verdict": "pv_shift", "verdict_set": ["pv_shift"],
             "effects": effects}
    chosen, fact = carried(_diagnosis(tmp_path, "a", alone), BOOSTER_EFFECTS, "ebooster",
                           _never)
    assert chosen == {"pv_shift": {"shift_mm": 0.3}} and "note" not in fact
    both = {**alone, "verdict_set": ["pv_shift", "pv_drift"]}
    chosen, fact = carried(_diagnosis(tmp_path, "b", both), BOOSTER_EFFECTS, "ebooster",
                           _never)
    assert chosen == {"pv_shift": {"shift_mm": 0.3}} and "pv_drift" in fact["note"]
    none = {**alone, "verdict": "none", "verdict_set": []}
    chosen, fact = carried(_diagnosis(tmp_path, "c", none), BOOSTER_EFFECTS, "ebooster",
                           _never)
    assert chosen == {} and "nothing carried" in fact["note"]
    assert carried("none", BOOSTER_EFFECTS, "ebooster", _never) == ({}, None)
    chosen, fact = carried("auto", ROLLER_EFFECTS, "roller-rig", lambda: {
        "rig": "roller-rig", "verdict": "creep_slope", "verdict_set": ["creep_slope"],
        "effects": [{"name": "creep_slope", "params": {"slope_change": -0.2}}]})
    assert chosen == {"creep_slope": {"slope_change": -0.2}} and fact["source"].startswith("auto")


@pytest.mark.parametrize(("summary", "words"), [
    ("[]", "not a diagnosis.json"),
    ("", "not a readable diagnosis.json"),
    ({"rig": "ebooster", "verdict": "pv_shift", "verdict_set": ["pv_shift"]},
     "not of this rig (roller-rig)"),
    ({"verdict": "none"}, "the diagnosis of a disc session"),
    ({"rig": "roller-rig", "verdict": "creep_slope", "verdict_set": ["creep_slope"]},
     "not an effect of this rig with fitted parameters"),
    ({"rig": "roller-rig", "verdict": "creep_slope", "verdict_set": ["creep_slope"],
      "effects": [{"name": "creep_slope", "params": {"slope_change": "abc"}}]},
     "is not a number"),
    ({"rig": "roller-rig", "verdict": "creep_slope", "verdict_set": ["creep_slope"],
      "effects": [{"name": "creep_slope", "params": {"foo": 1}}]},
     "needs the parameters slope_change"),
])
def test_a_bad_diagnosis_file_is_one_clear_error(tmp_path: Path, summary, words: str) -> None:
    with pytest.raises(ConfigError, match=words.replace("(", r"\(").replace(")", r"\)")):
        carried(_diagnosis(tmp_path, "bad", summary), ROLLER_EFFECTS, "roller-rig", _never)


def test_pairs_only_for_one_parameter_effects() -> None:
    chosen, fact = carried("pv_shift=0.25", BOOSTER_EFFECTS, "ebooster", _never)
    assert chosen == {"pv_shift": {"shift_mm": 0.25}} and fact["source"] == "option"
    for text, words in (("pv_drift=0.1", "NAME=VALUE"), ("pv_shift=inf", "not a number"),
                        ("pv_shift", "NAME=VALUE")):
        with pytest.raises(ConfigError, match=words):
            carried(text, BOOSTER_EFFECTS, "ebooster", _never)
