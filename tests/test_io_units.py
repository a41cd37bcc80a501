"""Unit conversion to SI and the alias tables."""

from __future__ import annotations

import json
import os
import tomllib
from pathlib import Path

import numpy as np
import pytest

from brakethermo.config import config_dir
from brakethermo.errors import ConfigError, DataError
from brakethermo.io.aliases import default_aliases, load_aliases, resolve
from brakethermo.io.units import CANONICAL_CHANNELS, CANONICAL_UNIT, si_unit, to_si

# (canonical channel, unit string, value in that unit, expected SI value), every §4 unit.
CASES = [
    ("speed", "km/h", 36.0, 10.0),
    ("speed", "m/s", 10.0, 10.0),
    ("speed", "mph", 100.0, 44.704),
    ("wheel_speed_front", "rad/s", 3.0, 3.0),
    ("wheel_speed_front", "rpm", 60.0, 2.0 * np.pi),
    ("brake_pressure_front", "bar", 2.0, 2.0e5),
    ("brake_pressure_front", "kPa", 2.0, 2.0e3),
    ("brake_pressure_front", "MPa", 2.0, 2.0e6),
    ("brake_pressure_front", "Pa", 2.0, 2.0),
    ("brake_pressure_front", "psi", 1.0, 6894.757293168),
    ("disc_temp_spot3", "degC", 500.0, 500.0),
    ("disc_temp_spot3", "K", 773.15, 500.0),
    ("disc_temp_spot3", "degF", 932.0, 500.0),
    ("disc_temp_spot3", "degF", -40.0, -40.0),
    ("normal_force", "N", 5.0, 5.0),
    ("clamp_force", "kN", 5.0, 5000.0),
    ("wheel_torque", "N m", 7.0, 7.0),
    ("distance", "m", 12.0, 12.0),
    ("rolling_radius_ref", "mm", 450.0, 0.45),
    ("motor_angle", "rad", 1.0, 1.0),
    ("motor_angle", "deg", 180.0, np.pi),
    ("motor_current", "A", 3.0, 3.0),
]

# Logger and export spellings (the registry in front of pint), with their SI values.
SPELLINGS = [
    ("disc_temp_spot3", "°C", 500.0, 500.0),
    ("disc_temp_spot3", "C", 500.0, 500.0),  # coulomb to pint; degC in every logger
    ("disc_temp_spot3", "°F", 932.0, 500.0),
    ("disc_temp_spot3", "F", -40.0, -40.0),
    ("disc_temp_spot3", "K", 0.0, -273.15),
    ("ambient_temp", "degF", 32.0, 0.0),
    ("wheel_speed_front", "1/min", 60.0, 2.0 * np.pi),  # pint alone: 1/60 Hz, not 2π/60
    ("wheel_speed_front", "U/min", 60.0, 2.0 * np.pi),
    ("wheel_speed_front", "deg/s", 180.0, np.pi),
    ("speed", "km/hr", 36.0, 10.0),
    ("speed", "kph", 36.0, 10.0),
    ("speed", "KPH", 36.0, 10.0),
    ("speed", "kmh", 36.0, 10.0),
    ("speed", "knot", 1.0, 1852.0 / 3600.0),  # anything pint knows
    ("brake_pressure_front", "mbar", 1000.0, 1.0e5),
    ("brake_pressure_front", "psi", 14.5038, 14.5038 * 6894.757293168),
    ("wheel_torque", "Nm", 7.0, 7.0),
    ("wheel_torque", "N·m", 7.0, 7.0),
    ("rolling_radius_ref", "cm", 30.0, 0.3),
    ("rolling_radius_ref", "in", 10.0, 0.254),
    ("motor_angle", "°", 90.0, np.pi / 2),
    ("slip_ratio", "%", 12.0, 0.12),
    ("clamp_force", "lbf", 1.0, 4.4482216152605),
]


@pytest.mark.parametrize(("canonical", "unit", "value", "si"), CASES + SPELLINGS)
def test_every_unit_converts_to_si(canonical: str, unit: str, value: float, si: float) -> None:
    out, applied = to_si(np.array([value]), unit, canonical)
    assert applied == unit
    np.testing.assert_allclose(out, [si], rtol=1e-12, atol=1e-9)


def test_missing_unit_means_canonical_unit() -> None:
    out, applied = to_si(np.array([1.5]), None, "master_cylinder_pressure")
    assert applied == "MPa" and out[0] == pytest.approx(1.5e6)
    out, applied = to_si(np.array([360.0]), "  ", "speed")
    assert applied == "km/h" and out[0] == pytest.approx(100.0)


def test_unknown_unit_names_file_and_channel() -> None:
    with pytest.raises(DataError, match=r"^s\.mcap: channel 'vFront': unknown unit 'bananas'"):
        to_si(np.ones(2), "bananas", "speed", path="s.mcap", source="vFront")


def test_every_canonical_channel_has_an_si_unit() -> None:
    assert {si_unit(c) for c in CANONICAL_CHANNELS} <= {
        "m/s", "rad/s", "Pa", "degC", "N", "N m", "m", "rad", "A", "-"}
    assert si_unit("disc_temp") == "degC" and si_unit("clamp_force") == "N"


def test_shipped_alias_table_covers_every_canonical_channel() -> None:
    raw = tomllib.loads((config_dir() / "channels.toml").read_text())["aliases"]
    assert set(raw) == set(CANONICAL_UNIT)
    table = default_aliases()
    for canonical, names in table.items():
        assert canonical in names


@pytest.mark.parametrize(("source", "canonical"), [
    ("vFront", "speed"), ("pBrakeF", "brake_pressure_front"), ("TDiscFL_3", "disc_temp_spot3"),
    ("disc_temp.spot3", "disc_temp_spot3"), ("nWheelF", "wheel_speed_front"),
    ("VFRONT", "speed"),
])
def test_team_names_resolve(source: str, canonical: str) -> None:
    assert resolve(default_aliases(), [source, "unrelated"]) == {canonical: source}


def test_alias_order_and_exact_match_preferred() -> None:
    table = {"speed": ("speed", "vFront")}
    assert resolve(table, ["vFront", "speed"]) == {"speed": "speed"}
    assert resolve(table, ["SPEED", "vFront"]) == {"speed": "vFront"}


def test_user_aliases_extend_defaults(tmp_path: Path) -> None:
    path = tmp_path / "team.toml"
    path.write_text('[aliases]\ndisc_temp = "IR_FL_mid"\nwheel_omega = ["enc_w"]\n')
    table = load_aliases(path)
    assert table["disc_temp"][0] == "IR_FL_mid" and "TDiscFL" in table["disc_temp"]
    assert table["wheel_omega"][0] == "enc_w"
    assert table["speed"] == default_aliases()["speed"]


@pytest.mark.parametrize("text", [
    "aliases = 3\n",
    "[other]\nx = 1\n",
    '[aliases]\nspeed = {a = "b"}\n',
    '[aliases]\nspeed = [""]\n',
    '[aliases]\nnot_a_channel = ["x"]\n',
    "[aliases\n",
])
def test_bad_alias_files(tmp_path: Path, text: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=str(path)):
        load_aliases(path)


def test_missing_alias_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not found"):
        load_aliases(tmp_path / "none.toml")


@pytest.mark.parametrize("unit", ["Hz", "10 m", "2", "[km/h]", "V", "", "km/h/h/h"])
def test_not_a_unit_of_the_channel(unit: str) -> None:
    with pytest.raises(DataError, match="channel 'vFront'"):
        to_si(np.ones(1), unit or "blorps", "speed", path="s.csv", source="vFront")


def test_angle_and_dimensionless_are_told_apart() -> None:
    with pytest.raises(DataError, match="angle unit but 'slip_ratio' is a dimensionless"):
        to_si(np.ones(1), "deg", "slip_ratio")
    with pytest.raises(DataError, match="dimensionless unit but 'motor_angle' is an angle"):
        to_si(np.ones(1), "%", "motor_angle")


def test_pint_answers_are_remembered_across_runs(tmp_path: Path) -> None:
    """A second process converts the units of the first without importing pint, to the
    same numbers; a damaged cache file is ignored; an unwritable cache folder costs
    nothing but the speed."""
    import subprocess
    import sys

    probe = ("import sys, json; from brakethermo.io.units import parse_unit as p;"
             " print(json.dumps([[u.dimension, u.scale, u.offset] for u in"
             " (p('km/h'), p('psi'), p('degF'), p('1/min'))] + ['pint' in sys.modules]))")
    env = {**os.environ, "BRAKETHERMO_CACHE_DIR": str(tmp_path / "cache")}

    def run() -> list:
        out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True,
                             text=True, check=True)
        return json.loads(out.stdout)

    first, second = run(), run()
    assert first[-1] is True and second[-1] is False
    assert first[:-1] == second[:-1]
    assert first[0] == ["speed", pytest.approx(1 / 3.6), 0.0]
    for f in (tmp_path / "cache").glob("units-*.json"):
        f.write_text("{not json")
    assert run() == first  # pint again, same answers
    blocker = tmp_path / "a_file"  # a cache folder that cannot be made (even by root)
    blocker.write_text("")
    env["BRAKETHERMO_CACHE_DIR"] = str(blocker / "cache")
    assert run() == first
