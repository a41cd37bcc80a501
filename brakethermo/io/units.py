"""Unit strings of CHANNELS.md §4 and their conversion to the SI units used inside.

Inside brakethermo every quantity is SI except temperature, which stays in degC (the
disc datasheet, the operating window and every output are in degC). A conversion is
affine, ``si = scale * value + offset``, so degF and K map onto degC exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brakethermo.errors import DataError


@dataclass(frozen=True)
class Unit:
    """One accepted unit string.

    Attributes
    ----------
    dimension : str
        Physical quantity (``speed``, ``pressure``, ...).
    scale : float
        Factor to the SI unit of the dimension.
    offset : float
        Added after scaling (non-zero only for temperatures).
    """

    dimension: str
    scale: float
    offset: float = 0.0


# SI unit held inside for each dimension (temperatures in degC, see module docstring).
SI_UNIT: dict[str, str] = {
    "speed": "m/s",
    "angular_speed": "rad/s",
    "pressure": "Pa",
    "temperature": "degC",
    "force": "N",
    "torque": "N m",
    "length": "m",
    "angle": "rad",
    "current": "A",
    "dimensionless": "-",
}

_KMH = 1.0 / 3.6
_MPH = 0.44704
_RPM = 2.0 * np.pi / 60.0
_PSI = 6894.757293168
_DEG = np.pi / 180.0

UNITS: dict[str, Unit] = {
    "km/h": Unit("speed", _KMH),
    "kmh": Unit("speed", _KMH),
    "kph": Unit("speed", _KMH),
    "m/s": Unit("speed", 1.0),
    "mph": Unit("speed", _MPH),
    "rad/s": Unit("angular_speed", 1.0),
    "rpm": Unit("angular_speed", _RPM),
    "1/min": Unit("angular_speed", _RPM),
    "deg/s": Unit("angular_speed", _DEG),
    "bar": Unit("pressure", 1.0e5),
    "mbar": Unit("pressure", 1.0e2),
    "Pa": Unit("pressure", 1.0),
    "kPa": Unit("pressure", 1.0e3),
    "MPa": Unit("pressure", 1.0e6),
    "psi": Unit("pressure", _PSI),
    "degC": Unit("temperature", 1.0),
    "°C": Unit("temperature", 1.0),
    "C": Unit("temperature", 1.0),
    "K": Unit("temperature", 1.0, -273.15),
    "degF": Unit("temperature", 5.0 / 9.0, -32.0 * 5.0 / 9.0),
    "°F": Unit("temperature", 5.0 / 9.0, -32.0 * 5.0 / 9.0),
    "F": Unit("temperature", 5.0 / 9.0, -32.0 * 5.0 / 9.0),
    "N": Unit("force", 1.0),
    "kN": Unit("force", 1.0e3),
    "N m": Unit("torque", 1.0),
    "Nm": Unit("torque", 1.0),
    "N*m": Unit("torque", 1.0),
    "N.m": Unit("torque", 1.0),
    "N·m": Unit("torque", 1.0),
    "m": Unit("length", 1.0),
    "cm": Unit("length", 1.0e-2),
    "mm": Unit("length", 1.0e-3),
    "km": Unit("length", 1.0e3),
    "rad": Unit("angle", 1.0),
    "deg": Unit("angle", _DEG),
    "°": Unit("angle", _DEG),
    "A": Unit("current", 1.0),
    "mA": Unit("current", 1.0e-3),
    "-": Unit("dimensionless", 1.0),
    "1": Unit("dimensionless", 1.0),
    "%": Unit("dimensionless", 1.0e-2),
}

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
}

CANONICAL_CHANNELS: tuple[str, ...] = tuple(CANONICAL_UNIT)


def parse_unit(text: str, *, path: object = None, channel: str | None = None) -> Unit:
    """Look up a unit string, tolerating surrounding blanks and repeated spaces.

    Raises
    ------
    DataError
        The string is not an accepted unit; the message names file and channel.
    """
    key = " ".join(text.split())
    unit = UNITS.get(key)
    if unit is None:
        accepted = ", ".join(sorted(UNITS, key=str.lower))
        raise DataError(
            f"unknown unit '{text}'; accepted units are: {accepted}", path=path, channel=channel
        )
    return unit


def si_unit(canonical: str) -> str:
    """SI unit (degC for temperatures) of the values of canonical channel ``canonical``."""
    return SI_UNIT[UNITS[CANONICAL_UNIT[canonical]].dimension]


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
    unit = parse_unit(text, path=path, channel=label)
    expected = UNITS[CANONICAL_UNIT[canonical]].dimension
    if unit.dimension != expected:
        raise DataError(
            f"unit '{text}' is a {unit.dimension.replace('_', ' ')} unit but '{canonical}' is a"
            f" {expected.replace('_', ' ')}; fix the unit in the file or the alias table",
            path=path,
            channel=label,
        )
    if unit.scale == 1.0 and unit.offset == 0.0:
        return values, text
    return values * unit.scale + unit.offset, text
