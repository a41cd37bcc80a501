"""Unit strings of the logged channels and their conversion to the SI units used inside.

Units are parsed by ``pint`` (any unit it knows: ``km/h``, ``psi``, ``mbar``, ``K``,
``degF``...) after a small registry of logger spellings that pint reads differently or
not at all (``°C``, ``C`` — coulomb to pint —, ``1/min``, ``kph``, ``Nm``, ``-``...).

Inside brakethermo every quantity is SI except temperature, which stays in degC (the
disc datasheet, the operating window and every output are in degC). A conversion is
affine, ``si = scale * value + offset``, taken from pint once per unit string, so degF
and K map onto degC with their offsets right.

pint's answers are kept in the user's cache folder (``BRAKETHERMO_CACHE_DIR`` overrides
it), keyed by pint's version and the tables below: importing pint and building its
registry costs about 0.6 s, more than reading a whole session, and the unit strings a
team's loggers write are few.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import astuple, dataclass
from functools import cache
from importlib.metadata import version
from pathlib import Path
from typing import Any

import numpy as np

from brakethermo.errors import DataError
from brakethermo.io.atomic import write_text_atomic


@dataclass(frozen=True)
class Unit:
    """One accepted unit string.

    Attributes
    ----------
    dimension : str
        Physical quantity (``speed``, ``pressure``, ...), a key of :data:`SI_UNIT`.
    scale : float
        Factor to the SI unit of the dimension.
    offset : float
        Added after scaling (non-zero only for temperatures).
    """

    dimension: str
    scale: float
    offset: float = 0.0


# Dimension -> (unit held inside, its pint spelling, unit strings quoted in messages).
_DIMENSIONS: dict[str, tuple[str, str, str]] = {
    "speed": ("m/s", "m/s", "km/h, m/s, mph, kph"),
    "angular_speed": ("rad/s", "rad/s", "rad/s, rpm, 1/min, deg/s"),
    "pressure": ("Pa", "Pa", "bar, mbar, kPa, MPa, Pa, psi"),
    "temperature": ("degC", "degC", "degC, °C, K, degF, °F"),
    "force": ("N", "N", "N, kN, lbf"),
    "torque": ("N m", "N*m", "N m, Nm, kN m"),
    "length": ("m", "m", "m, mm, cm, km, in"),
    "angle": ("rad", "rad", "rad, deg, °"),
    "current": ("A", "A", "A, mA"),
    "dimensionless": ("-", "dimensionless", "-, 1, %"),
}

# SI unit held inside for each dimension (temperatures in degC, see module docstring).
SI_UNIT: dict[str, str] = {dim: si for dim, (si, _, _) in _DIMENSIONS.items()}

# Logger and export spellings -> pint expression. Exact match first, then the
# case-insensitive table (only spellings with no case-sensitive meaning in SI: ``MPa``
# and ``mPa`` differ, ``KPH`` and ``kph`` do not).
LOGGER_SPELLINGS: dict[str, str] = {
    "°C": "degC",
    "ºC": "degC",
    "℃": "degC",
    "C": "degC",
    "deg C": "degC",
    "°F": "degF",
    "ºF": "degF",
    "℉": "degF",
    "F": "degF",
    "deg F": "degF",
    "°K": "kelvin",
    "1/min": "rpm",
    "min-1": "rpm",
    "min^-1": "rpm",
    "U/min": "rpm",
    "rev/min": "rpm",
    "km/hr": "km/h",
    "km h-1": "km/h",
    "kmh": "km/h",
    "kph": "km/h",
    "kmph": "km/h",
    "Nm": "N*m",
    "N m": "N*m",
    "N.m": "N*m",
    "N·m": "N*m",
    "N-m": "N*m",
    "kNm": "kN*m",
    "kN m": "kN*m",
    "°": "deg",
    "º": "deg",
    "degrees": "deg",
    "°/s": "deg/s",
    "-": "dimensionless",
    "1": "dimensionless",
    "%": "percent",
}
_CASELESS: dict[str, str] = {
    k.casefold(): v
    for k, v in {
        "km/h": "km/h", "kph": "km/h", "kmh": "km/h", "km/hr": "km/h", "mph": "mph",
        "rpm": "rpm", "bar": "bar", "psi": "psi", "degC": "degC", "degF": "degF",
        "deg C": "degC", "deg F": "degF", "deg": "deg", "rad": "rad", "rad/s": "rad/s",
    }.items()
}  # fmt: skip

# Unit a channel is logged in when the file names none (CHANNELS.md §2 tables).
CANONICAL_UNIT: dict[str, str] = {
    "speed": "km/h",
    "wheel_speed_front": "rad/s",
    "brake_pressure_front": "bar",
    "disc_temp_spot1": "degC",
    "disc_temp_spot2": "degC",
    "disc_temp_spot3": "degC",
    "disc_temp_spot4": "degC",
    "disc_temp": "degC",
    "ambient_temp": "degC",
    "distance": "m",
    "lap_beacon": "-",
    "wheel_omega": "rad/s",
    "roller_omega": "rad/s",
    "wheel_torque": "N m",
    "normal_force": "N",
    "roller_torque": "N m",
    "rolling_radius_ref": "mm",
    "pushrod_displacement": "mm",
    "reaction_disk_delta": "mm",
    "master_cylinder_pressure": "MPa",
    "front_circuit_pressure": "MPa",
    "rear_circuit_pressure": "MPa",
    "pedal_force": "N",
    "motor_angle": "rad",
    "motor_current": "A",
    "clamp_force": "kN",
    "vehicle_speed": "m/s",
    "wheel_speed": "rad/s",
    "drag_force": "N",
    "slip_ratio": "-",
    "friction_coefficient": "-",
}

CANONICAL_CHANNELS: tuple[str, ...] = tuple(CANONICAL_UNIT)

_ANGLE_WORDS = ("radian", "degree", "revolution", "turn", "grad", "arcminute", "arcsecond")


@cache
def registry() -> Any:
    """The pint unit registry (built on first use: it costs a fraction of a second)."""
    import pint

    return pint.UnitRegistry(autoconvert_offset_to_baseunit=True)


def _angular(units: Any) -> bool:
    """Whether a pint unit carries an angle (pint counts radians as dimensionless)."""
    names = [n for n in units._units if "Celsius" not in n and "Fahrenheit" not in n]
    return any(word in name for name in names for word in _ANGLE_WORDS)


@cache
def _dimension_keys() -> dict[tuple[Any, bool], str]:
    ureg = registry()
    keys = {}
    for dim, (_, spelling, _) in _DIMENSIONS.items():
        units = ureg.parse_units(spelling)
        keys[(units.dimensionality, _angular(units))] = dim
    return keys


def _memo_path() -> Path:
    """The cache file of pint's answers for this pint and these tables."""
    import platformdirs

    root = os.environ.get("BRAKETHERMO_CACHE_DIR") or platformdirs.user_cache_dir("brakethermo")
    tables = repr((sorted(LOGGER_SPELLINGS.items()), sorted(_CASELESS.items()),
                   sorted(_DIMENSIONS.items()), _ANGLE_WORDS, version("pint")))
    return Path(root) / f"units-{hashlib.sha256(tables.encode()).hexdigest()[:16]}.json"


@cache
def _memo() -> dict[str, Unit | None]:
    """The units pint parsed in earlier runs (empty when there is no readable cache)."""
    try:
        raw = json.loads(_memo_path().read_text(encoding="utf-8"))
        return {k: None if v is None else Unit(str(v[0]), float(v[1]), float(v[2]))
                for k, v in raw.items()}
    except (OSError, ValueError, TypeError, IndexError, KeyError, AttributeError):
        return {}  # absent, unreadable or not ours: pint answers afresh


@cache
def _lookup(key: str) -> Unit | None:
    """A normalised unit string's conversion (``None``: not a unit we hold), from the
    cache of earlier runs or else from pint (then remembered)."""
    memo = _memo()
    if key in memo and (memo[key] is None or memo[key].dimension in SI_UNIT):
        return memo[key]
    unit = _parse(key)
    memo[key] = unit
    try:
        write_text_atomic(_memo_path(), json.dumps(
            {k: None if u is None else astuple(u) for k, u in memo.items()}), output=False)
    except OSError:
        pass  # a read-only home: pint answers again next time, nothing else changes
    return unit


def _parse(key: str) -> Unit | None:
    """Parse a normalised unit string with pint; ``None`` if it is not a unit we hold."""
    spelling = LOGGER_SPELLINGS.get(key) or _CASELESS.get(key.casefold()) or key
    if not spelling or any(c in spelling for c in "[]{}=#"):
        return None  # pint reads "[length]" as a dimension; a logger unit never is one
    ureg = registry()
    try:
        quantity = ureg.Quantity(spelling)
    except Exception:  # pint raises many kinds (undefined, syntax, tokenizer) on junk
        return None
    if not isinstance(quantity, ureg.Quantity) or quantity.magnitude != 1:
        return None  # "10 m", "2": a number is not a unit
    units = quantity.units
    dim = _dimension_keys().get((units.dimensionality, _angular(units)))
    if dim is None:
        return None
    target = _DIMENSIONS[dim][1]
    zero = float(ureg.Quantity(0.0, units).to(target).magnitude)
    # The slope over a wide step: pint's offset arithmetic loses digits over a step of 1.
    scale = (float(ureg.Quantity(1.0e3, units).to(target).magnitude) - zero) / 1.0e3
    return Unit(dim, scale, zero)


def parse_unit(text: str, *, path: object = None, channel: str | None = None,
               expected: str | None = None) -> Unit:
    """Look up a unit string, tolerating surrounding blanks and repeated spaces.

    Parameters
    ----------
    text : str
        Unit string from the file.
    path, channel
        File and channel, for the error message.
    expected : str, optional
        Dimension the channel needs, to quote fitting units in the error message.

    Raises
    ------
    DataError
        The string is not a unit of any dimension brakethermo reads.
    """
    key = " ".join(text.split())
    unit = _lookup(key)
    if unit is None:
        hint = (f"a {expected.replace('_', ' ')} unit such as {_DIMENSIONS[expected][2]}"
                if expected else "a unit such as km/h, rad/s, bar, degC, N, N m, mm, rad, A")
        raise DataError(
            f"unknown unit '{text}'; write {hint} in the file (or the channel's unit field)",
            path=path,
            channel=channel,
        )
    return unit


def dimension_of(canonical: str) -> str:
    """Dimension (``speed``, ``pressure``...) of canonical channel ``canonical``."""
    unit = _lookup(CANONICAL_UNIT[canonical])
    assert unit is not None  # every canonical unit is a known unit (tested)
    return unit.dimension


def si_unit(canonical: str) -> str:
    """SI unit (degC for temperatures) of the values of canonical channel ``canonical``."""
    return SI_UNIT[dimension_of(canonical)]


def _article(dimension: str) -> str:
    """``"an angular speed"``, ``"a pressure"``: a dimension name for a sentence."""
    words = dimension.replace("_", " ")
    return f"{'an' if words[0] in 'aeiou' else 'a'} {words}"


def to_si(
    values: np.ndarray,
    unit_text: str | None,
    canonical: str,
    *,
    path: object = None,
    source: str | None = None,
) -> tuple[np.ndarray, str]:
    """Convert a canonical channel's samples from its file unit to SI.

    Parameters
    ----------
    values : ndarray
        Samples in the file's unit.
    unit_text : str or None
        Unit string from the file; ``None`` or blank means the canonical unit.
    canonical : str
        Canonical channel name, fixing the expected dimension.
    path, source
        File and source channel name, for error messages.

    Returns
    -------
    si : ndarray
        Samples in the SI unit of :func:`si_unit`.
    unit : str
        The unit string actually applied (the canonical one when the file gave none).

    Raises
    ------
    DataError
        Unknown unit, or a unit of the wrong kind for the channel (``bar`` on ``speed``).
    """
    label = source or canonical
    text = unit_text if unit_text and unit_text.strip() else CANONICAL_UNIT[canonical]
    expected = dimension_of(canonical)
    unit = parse_unit(text, path=path, channel=label, expected=expected)
    if unit.dimension != expected:
        raise DataError(
            f"unit '{text}' is {_article(unit.dimension)} unit but '{canonical}' is"
            f" {_article(expected)}; fix the unit in the file or the alias table",
            path=path,
            channel=label,
        )
    if unit.scale == 1.0 and unit.offset == 0.0:
        return values, text
    return values * unit.scale + unit.offset, text


def unit_suffix(unit: str) -> str:
    """`` kN`` after a figure or a heading; nothing for a dimensionless output, ``"-"`` or
    ``""`` (the tyre's μ: "0.083 -" and "before -" read as text)."""
    return "" if unit in ("-", "") else f" {unit}"
