"""Physical plausibility of disc-session channels, checked before any model work.

A channel in the wrong unit, scaled, zeroed, negated or stuck reads without error but
gives an answer that cannot be. These checks compare each channel with physics (a
vehicle speed range, a rolling wheel turning at ``v / r``, a cold disc before the first
stop) and raise :class:`~brakethermo.errors.DataError` naming the channel, the likely
cause and the fix; softer findings are returned as warnings.

All inputs are on the session grid in SI units (speeds m/s, angular speed rad/s,
pressure Pa, temperatures degC).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from brakethermo.errors import DataError
from brakethermo.numeric import true_runs

RPM_PER_RAD_S = 60.0 / (2.0 * np.pi)
KMH_PER_M_S = 3.6
MAX_SPEED_M_S = 150.0  # 540 km/h: above any road or race vehicle
MOVING_M_S = 10.0  # speeds above which a wheel is surely rolling
KELVIN_OFFSET = 273.15
PRE_BRAKE_EXCESS_C = 200.0  # a disc before the first stop is not this far above ambient
STUCK_SPAN_S = 60.0  # a pyrometer that does not move for this long is stuck
STUCK_TOLERANCE_C = 0.01
CLIP_RUN_S = 0.5  # s: a pyrometer at exactly its highest value this long is clipped
SENSOR_FLOOR_C = 100.0  # degC: IR pyrometers read nothing useful below this (datasheet floor)
SILENT_START_S = 5.0  # s: a channel empty this long at the start began below its floor
FIRST_READ_EXCESS_C = 150.0  # a disc heating past the floor is first read within this
# degC: no disc reads below this. A disc is never colder than the air around it, no session
# is run in air this cold, and an IR pyrometer reads nothing below its floor (~100 degC); a
# real session's readings all lie near or above the air. Degrees Celsius labelled K lose
# 273.15 and put the floor at about -173 degC, far below it.
LOWEST_DISC_C = -50.0
# s of readings below LOWEST_DISC_C that refuse the channel: a one-sample glitch (which the
# reader's Hampel filter mostly removes) touches at most two grid points (0.2 s), while the
# warm-up past the floor of a hot spot read in degC labelled K lasts 1 s or more
COLD_SPAN_S = 0.5
# share of those readings at one value that makes them a logger's "no reading" code
SENTINEL_SHARE = 0.9


def _finite(values: np.ndarray) -> np.ndarray:
    return values[np.isfinite(values)]


def ratio_cause(ratio: float, speed: str = "speed", wheel: str = "wheel_speed_front",
                radius: str = "the tyre rolling radius of the datasheet") -> str:
    """Name the unit confusion a (wheel speed x radius) / vehicle speed ratio points to.

    Parameters
    ----------
    ratio : float — wheel speed (rad/s) times the radius (m), over the vehicle speed (m/s)
    speed, wheel : str — the two channels' names, for the message
    radius : str — where the radius comes from, for the message
    """
    known = (
        (RPM_PER_RAD_S, f"{wheel} looks like rpm labelled rad/s: set its unit to rpm"),
        (1.0 / RPM_PER_RAD_S, f"{wheel} looks like rad/s labelled rpm: set its unit to rad/s"),
        (KMH_PER_M_S, f"{speed} looks like m/s labelled km/h: set its unit to m/s"),
        (1.0 / KMH_PER_M_S, f"{speed} looks like km/h labelled m/s: set its unit to km/h"),
        (-1.0, "one of the two is logged with the other sign"),
    )
    for value, cause in known:
        if abs(ratio / value - 1.0) < 0.2:
            return cause
    return f"check the units of {speed} and {wheel} and {radius}"


def check_speeds(speed: np.ndarray, omega: np.ndarray | None, tyre_radius: float,
                 path: Path | None = None, sources: dict[str, str] | None = None) -> None:
    """Vehicle speed in a vehicle's range; wheel speed × tyre radius ≈ vehicle speed.

    Parameters
    ----------
    speed : ndarray — m/s
    omega : ndarray or None — rad/s, front wheel speed (None: not logged)
    tyre_radius : float — m, rolling radius of the datasheet
    path : Path, optional — the session file, for the message
    sources : dict, optional — canonical name to the file's channel name
    """
    src = sources or {}
    v = _finite(speed)
    if v.size == 0 or np.max(np.abs(v)) < 1.0:
        raise DataError("never above 1 m/s: the signal is zeroed or missing; "
                        "log the vehicle speed", path=path, channel=src.get("speed", "speed"))
    if np.median(v) < 0.0 and abs(v.min()) > v.max():
        raise DataError("mostly negative: the speed is logged with the other sign; "
                        "negate it in the export", path=path, channel=src.get("speed", "speed"))
    if v.max() > MAX_SPEED_M_S:
        raise DataError(
            f"peaks at {v.max() * KMH_PER_M_S:.0f} km/h, no vehicle's speed: check its unit "
            "(km/h labelled m/s?)", path=path, channel=src.get("speed", "speed"))
    if omega is None:
        return
    name = src.get("wheel_speed_front", "wheel_speed_front")
    moving = np.isfinite(speed) & np.isfinite(omega) & (np.abs(speed) > MOVING_M_S)
    if moving.sum() < 10:
        return
    w = omega[moving]
    if np.max(np.abs(w)) < 1e-6:
        raise DataError("is zero while the vehicle moves: the signal is zeroed; fix the "
                        "export or drop the channel (speed / tyre radius is then used)",
                        path=path, channel=name)
    ratio = float(np.median(w * tyre_radius / speed[moving]))
    if not 0.8 <= ratio <= 1.25:
        raise DataError(
            f"wheel speed × tyre radius ({tyre_radius:.3f} m) is {ratio:.3g}× the vehicle "
            f"speed, expected ≈1: {ratio_cause(ratio)}", path=path, channel=name)


def check_pressure(pressure: np.ndarray, path: Path | None = None,
                   source: str = "brake_pressure_front") -> None:
    """Brake pressure: some braking, not mostly negative.

    Parameters
    ----------
    pressure : ndarray — Pa
    """
    p = _finite(pressure)
    if p.size == 0 or (p.max() < 1e5 and abs(p.min()) < 1e5):
        raise DataError("never above 1 bar: the signal is zeroed (or in a unit 1000× too "
                        "small); the session has no braking to work on",
                        path=path, channel=source)
    if abs(p.min()) > p.max() and np.median(p[np.abs(p) > 1e5]) < 0.0:
        raise DataError("mostly negative: the pressure is logged with the other sign; "
                        "negate it in the export", path=path, channel=source)


def check_pyrometer(temps: np.ndarray, braking: np.ndarray, ambient_c: float,
                    dt: float, path: Path | None = None, source: str = "disc_temp"
                    ) -> list[str]:
    """One IR channel: not negated, not in kelvin labelled degC nor degC labelled K, not
    stuck.

    Parameters
    ----------
    temps : ndarray — degC, on the grid
    braking : ndarray of bool — grid points with the brake applied
    ambient_c : float — degC
    dt : float — s, grid step

    Returns
    -------
    list of str — warnings (a hot disc before the first stop, a late first reading);
    frozen and clipped stretches are :func:`unusable_readings`'s
    """
    t = _finite(temps)
    if t.size == 0:
        return []
    if np.median(t) < -50.0:
        raise DataError(f"reads {np.median(t):.0f} °C typically: the signal is negated or "
                        "in a wrong unit", path=path, channel=source)
    _check_not_celsius_as_kelvin(t, ambient_c, dt, path, source)
    if t.size * dt >= STUCK_SPAN_S and np.ptp(t) <= STUCK_TOLERANCE_C:
        raise DataError(f"constant at {t[0]:.1f} °C for the whole session: the pyrometer is "
                        "stuck or frozen; drop the channel or fix the sensor",
                        path=path, channel=source)
    warnings = _late_start(temps, dt, source)
    first = int(np.argmax(braking)) if braking.any() else temps.size
    before = temps[:first]
    before = before[np.isfinite(before)]
    if before.size and np.median(before) > ambient_c + PRE_BRAKE_EXCESS_C:
        if (abs(np.median(before) - KELVIN_OFFSET - ambient_c) < 30.0
                and np.ptp(before) < 15.0 and before.size * dt >= 10.0):
            # a disc resting at the air's temperature, read in kelvin: steady at air + 273
            # (a hot disc before its first stop cools visibly: that is a genuine session)
            raise DataError(
                f"reads {np.median(before):.0f} °C before the first stop with ambient at"
                f" {ambient_c:.0f} °C: the values look like kelvin labelled degC: set the"
                " unit to K", path=path, channel=source)
        # a session that starts on a hot disc (logger started on track) is genuine
        kelvin = abs(np.median(before) - KELVIN_OFFSET - ambient_c) < 150.0
        warnings.append(
            f"{source}: reads {np.median(before):.0f} °C before the first stop with ambient"
            f" at {ambient_c:.0f} °C: a session started on a hot disc, or "
            + ("the values are kelvin labelled degC (then set the unit to K)" if kelvin
               else "a unit or sensor problem") + "; check the channel if the disc was cold")
    return warnings


def _check_not_celsius_as_kelvin(t: np.ndarray, ambient_c: float, dt: float,
                                 path: Path | None, source: str) -> None:
    """Refuse readings far below the air for longer than a glitch (:data:`LOWEST_DISC_C`,
    :data:`COLD_SPAN_S`): degrees Celsius labelled K, or a sentinel value.

    Parameters
    ----------
    t : ndarray — degC, the channel's finite readings on the grid
    ambient_c : float — degC, the air
    dt : float — s, grid step
    path : Path or None — the session file, for the message
    source : str — the channel's name in the file
    """
    cold = t < LOWEST_DISC_C
    if cold.sum() * dt < COLD_SPAN_S:
        return
    _, counts = np.unique(np.round(t[cold], 2), return_counts=True)  # unit round trips
    if counts.max() >= SENTINEL_SHARE * cold.sum():
        # one value held: a logger's code for "no reading" (-999, -273.15), not a disc;
        # under the floor, it is left out like every reading there (the grid's
        # resampling leaves a few values between it and the readings at each end)
        return
    low = float(np.min(t))
    head = (f"reads down to {low:.0f} °C ({cold.sum() * dt:.1f} s below"
            f" {LOWEST_DISC_C:.0f} °C) with the air at {ambient_c:.0f} °C: no disc is colder"
            " than the air")
    if low + KELVIN_OFFSET >= ambient_c - 30.0:
        # plus 273.15 the lowest reading is at or above the air (a pyrometer's floor or a
        # disc at rest): the values are degC and the file's unit says K
        raise DataError(f"{head}; read as degC they start at {low + KELVIN_OFFSET:.0f} °C"
                        " (°C labelled K?): set the channel's unit to degC",
                        path=path, channel=source)
    raise DataError(f"{head}: a sentinel value or a wrong unit; fix the channel's unit, or"
                    " blank the invalid readings in the export", path=path, channel=source)


def _late_start(temps: np.ndarray, dt: float, source: str) -> list[str]:
    """A pyrometer silent at the start (a cold disc below its floor) is first read near
    its floor as the disc heats past it; a first reading far above says another unit
    (kelvin labelled degC: floor + 273) or a sensor problem."""
    finite = np.isfinite(temps)
    i = int(np.argmax(finite))
    floor = SENSOR_FLOOR_C
    if not finite.any() or i * dt < SILENT_START_S or temps[i] <= floor + FIRST_READ_EXCESS_C:
        return []
    kelvin = abs(temps[i] - KELVIN_OFFSET - floor) < FIRST_READ_EXCESS_C
    return [f"{source}: silent for the first {i * dt:.0f} s, then first reads {temps[i]:.0f}"
            f" °C, where a disc heating past a pyrometer's floor (about {floor:.0f} °C) is"
            " first read near it: "
            + ("the values look like kelvin labelled degC (then set the unit to K)" if kelvin
               else "a unit or sensor problem") + "; check the channel"]


def unusable_readings(temps: np.ndarray, dt: float, source: str
                      ) -> tuple[np.ndarray, list[str]]:
    """Readings that are not the disc, to be left out of every fit, and why.

    - **Frozen**: a span of :data:`STUCK_SPAN_S` or more where the channel does not move.
    - **Clipped**: the channel sits at exactly its highest value for :data:`CLIP_RUN_S`
      or more, in two or more spans: the pyrometer's range ends there and the disc was
      at least that hot (a real peak is reached once, and noise never repeats it).

    Parameters
    ----------
    temps : ndarray — degC, on the grid
    dt : float — s, grid step
    source : str — the channel's name in the file

    Returns
    -------
    mask : ndarray of bool — the readings to leave out
    warnings : list of str — one line per finding
    """
    mask = np.zeros(temps.size, bool)
    warnings: list[str] = []
    flat = np.abs(np.diff(temps)) <= STUCK_TOLERANCE_C
    starts, ends = true_runs(flat).T
    long = (ends - starts) * dt >= STUCK_SPAN_S
    if long.any():
        for a, b in zip(starts[long], ends[long], strict=True):
            mask[a: b + 1] = True
        i = int(np.argmax(np.where(long, ends - starts, -1)))
        warnings.append(
            f"{source}: constant at {temps[starts[i]]:.1f} °C for"
            f" {(ends[i] - starts[i]) * dt:.0f} s from t = {starts[i] * dt:.0f} s (sensor"
            f" frozen?); {int(mask.sum()) * dt:.0f} s of such readings are left out of the"
            " fit")
    finite = np.isfinite(temps)
    if finite.sum() > 1:
        top = float(np.max(temps[finite]))
        at_top = finite & (temps >= top - STUCK_TOLERANCE_C)
        starts, ends = true_runs(at_top).T
        keep = (ends - starts) * dt >= CLIP_RUN_S
        if keep.sum() >= 2:  # then every reading at that value is the range's end
            clipped = at_top
            mask |= clipped
            warnings.append(
                f"{source}: reads exactly {top:.1f} °C, its highest value, for"
                f" {int(clipped.sum()) * dt:.1f} s in {int(keep.sum())} spans: the"
                " pyrometer's range ends there (clipped); those readings are left out of"
                " the fit (the disc was at least that hot) — a pyrometer with a higher"
                " range would read them")
    return mask, warnings
