"""Issue 12 item 6: every TOML the tool reads fails the same way — file, key, expected, found."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brakethermo.config import ConfigTable, config_dir, load_toml
from brakethermo.errors import ConfigError
from brakethermo.io.aliases import load_aliases
from brakethermo.pipelines.models import read_calibration
from brakethermo.pipelines.tuning import load_tuning
from brakethermo.sim.track import load_track
from brakethermo.thermal.disc import load_disc

SHIPPED = {
    "tuning": (config_dir() / "tuning.toml", load_tuning),
    "h_law": (config_dir() / "hlaw" / "cc-340-8.toml", read_calibration),
    "aliases": (config_dir() / "channels.toml", load_aliases),
    "disc": (config_dir() / "discs" / "cc-340-8.toml", load_disc),
    "track": (config_dir() / "tracks" / "mugello-like.toml", load_track),
}
SCHEMA_MESSAGE = re.compile(r"^(?P<file>\S+): key '(?P<key>[^']+)': expected .+, found .+$")


def _copy(tmp_path: Path, kind: str) -> tuple[Path, Callable]:
    src, loader = SHIPPED[kind]
    path = tmp_path / f"{kind}.toml"
    path.write_text(src.read_text())
    return path, loader


def _replace_line(path: Path, key: str, value: str) -> None:
    lines = path.read_text().splitlines()
    hit = [i for i, row in enumerate(lines) if re.match(rf"\s*{re.escape(key)}\s*=", row)]
    assert hit, f"{key} not in {path.name}"
    lines[hit[0]] = f"{key} = {value}"
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("kind", sorted(SHIPPED))
def test_shipped_files_pass_the_schema(kind):
    src, loader = SHIPPED[kind]
    loader(src)


@pytest.mark.parametrize("kind", sorted(SHIPPED))
@pytest.mark.parametrize(
    ("payload", "words"),
    [
        (b"nodes = 1\n\xe9\xe8 = 2\n", "is not UTF-8 text (byte 0xe9 on line 2); save it as UTF-8"),
        ("[x]\na = 1\n".encode("utf-16"), "is UTF-16 text; save it as UTF-8"),
        (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "is a binary file, not TOML text"),
        (b"a = [\n", "invalid TOML"),
    ],
)
def test_unreadable_files_name_file_and_fix(tmp_path, kind, payload, words):
    path = tmp_path / f"{kind}.toml"
    path.write_bytes(payload)
    with pytest.raises(ConfigError) as info:
        SHIPPED[kind][1](path)
    assert str(info.value).startswith(f"{path}: ") and words in str(info.value)


# (file kind, key as in the file, replacement, dotted key in the message, expected, found)
CASES = [
    ("tuning", "nodes", "nan", "estimate.nodes", "a whole number between 10 and 400", "nan"),
    ("tuning", "nodes", "inf", "estimate.nodes", "a whole number", "inf"),
    ("tuning", "layers", "{ a = 1 }", "estimate.layers", "a whole number", "a table"),
    ("tuning", "smoother", "1", "estimate.smoother", "true or false", "1"),
    ("tuning", "sigma_meas", "[5.0]", "estimate.sigma_meas", "a finite number", "[5.0]"),
    ("h_law", "knee", "nan", "knee", "a finite number > 0", "nan"),
    ("h_law", "a", "{ x = 1 }", "power.a", "a finite number >= 0", "a table"),
    ("h_law", "layers", "inf", "extra.layers", "a whole number between 1 and 8", "inf"),
    ("h_law", "layers", "2.5", "extra.layers", "a whole number", "2.5"),
    ("h_law", "w", "3", "weights.w", "a list of 3 finite numbers", "3"),
    ("aliases", "speed", "{ a = 1 }", "aliases.speed", "a list of non-empty texts", "a table"),
    ("aliases", "speed", "7", "aliases.speed", "a list of non-empty texts", "7"),
    ("disc", "r_int", "nan", "geometry.r_int", "a finite number > 0", "nan"),
    ("disc", "r_int", "{ v = 0.1 }", "geometry.r_int", "a finite number > 0", "a table"),
    ("disc", "spot_radii", "0.1", "geometry.spot_radii", "a list of 4", "0.1"),
    ("disc", "c_value", '[700.0, "x"]', "material.c_value[1]", "finite numbers > 0",
     "the text 'x'"),
    ("disc", "window_c", "[850.0, 250.0]", "operation.window_c", "low < high",
     "[850.0, 250.0]"),
    ("disc", "emissivity", "inf", "material.emissivity", "> 0 <= 1", "inf"),
    ("track", "ambient_c", "nan", "ambient_c", "a finite number between -40 and 60", "nan"),
    ("track", "pit_speed_kmh", "[60]", "pit_speed_kmh", "a finite number > 0", "[60]"),
]  # fmt: skip


@pytest.mark.parametrize(("kind", "key", "value", "dotted", "expected", "found"), CASES)
def test_every_field_gives_file_key_expected_found(tmp_path, kind, key, value, dotted, expected,
                                                   found):
    path, loader = _copy(tmp_path, kind)
    _replace_line(path, key, value)
    with pytest.raises(ConfigError) as info:
        loader(path)
    message = str(info.value)
    m = SCHEMA_MESSAGE.match(message)
    assert m, message
    assert m["file"] == str(path) and m["key"] == dotted
    assert expected in message.split(": expected ")[1] and message.endswith(f"found {found}")


def test_scalar_where_a_table_is_expected(tmp_path):
    path, _ = _copy(tmp_path, "tuning")
    path.write_text("estimate = 3\n")
    with pytest.raises(ConfigError, match=r"key 'estimate': expected a table, found 3$"):
        load_tuning(path)
    path.write_text("[aliases]\n")
    path.write_text("aliases = 1\n")
    with pytest.raises(ConfigError, match=r"key 'aliases': expected a table, found 1$"):
        load_aliases(path)
    path.write_text("segments = 4\npit_speed_kmh = 60\npit_lane_m = 1\nambient_c = 20\n")
    with pytest.raises(ConfigError, match=r"key 'segments': expected a non-empty array"):
        load_track(path)


def test_a_folder_or_huge_file_is_refused_before_reading(tmp_path):
    with pytest.raises(ConfigError, match="is a folder"):
        load_toml(tmp_path)
    big = tmp_path / "big.toml"
    big.write_bytes(b"# " + b"x" * (5 << 20))
    with pytest.raises(ConfigError, match="larger than"):
        load_toml(big)


def test_a_bom_is_accepted(tmp_path):
    path = tmp_path / "t.toml"
    path.write_bytes(b"\xef\xbb\xbf[estimate]\nnodes = 12\n")
    assert load_tuning(path)[0].nodes == 12


@settings(max_examples=60, deadline=None)
@given(
    value=st.one_of(
        st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6),
        st.booleans(), st.text(max_size=5), st.lists(st.integers(0, 3), max_size=3),
        st.dictionaries(st.sampled_from("ab"), st.integers(0, 3), max_size=2),
    ),
)
def test_any_value_either_passes_the_bounds_or_names_the_key(value):
    """Property: an integer field accepts exactly the whole numbers in range, else says why."""
    table = ConfigTable({"nodes": value}, Path("t.toml"), "estimate")
    whole = (
        not isinstance(value, bool) and isinstance(value, int | float)
        and value == value and abs(value) != float("inf") and value == int(value)
        and 10 <= value <= 400
    )
    if whole:
        assert table.integer("nodes", lo=10, hi=400) == int(value)
    else:
        with pytest.raises(ConfigError, match=r"^t\.toml: key 'estimate\.nodes': expected a whole"):
            table.integer("nodes", lo=10, hi=400)
