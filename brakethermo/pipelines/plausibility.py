"""Physics checks of a disc session's inputs and of an estimate, before and after the work.

A unit mislabelled in a logger (a wheel speed in rpm tagged rad/s, a pyrometer in kelvin
tagged °C, a sensor frozen at one value) gives numbers that look like data; these checks
hold each input against the others and the datasheet, and say which channel and which
unit is the likely cause — an error where no estimate can be right, a loud warning
where the session might still be genuine.
"""

from __future__ import annotations

import numpy as np

from brakethermo.errors import DataError
from brakethermo.io.session import Session
from brakethermo.thermal.disc import DiscSpec

RATIO_RANGE = (0.8, 1.25)  # speed / (wheel speed x tyre radius) at free rolling
MIN_SPEED_MPS = 15.0  # m/s: free-rolling samples used for the ratio (above 54 km/h)
RPM_PER_RAD_S = 60.0 / (2.0 * np.pi)
COLD_EXCESS_C = 200.0  # degC above the air: a disc before its first stop is not that hot
STUCK_S = 60.0  # s: a pyrometer that reads one value this long while the disc works
NIS_LOUD = 10.0  # mean NIS of an estimate that says the inputs do not fit the model


def check_wheel_speed(speed: np.ndarray, omega: np.ndarray, q_brk_on: np.ndarray,
                      disc: DiscSpec, session: Session) -> None:
    """Vehicle speed against wheel speed × tyre radius, off the brakes.

    Raises
    ------
    DataError
        The median ratio is far from 1: names the likely unit (rpm, km/h…).
    """
    ok = np.isfinite(speed) & np.isfinite(omega) & (speed > MIN_SPEED_MPS) & ~q_brk_on
    if ok.sum() < 50:
        return
    ratio = float(np.median(speed[ok] / np.maximum(np.abs(omega[ok]), 1e-9)
                            / disc.tyre_rolling_radius))
    lo, hi = RATIO_RANGE
    if lo <= ratio <= hi:
        return
    hint = ""
    if abs(ratio * RPM_PER_RAD_S - 1.0) < 0.2:
        hint = " — it looks like rpm labelled rad/s"
    elif abs(ratio / RPM_PER_RAD_S - 1.0) < 0.2:
        hint = " — it looks like rad/s labelled rpm"
    raise DataError(
        f"reads {1 / ratio:.3g} times the wheel speed that the vehicle speed and the"
        f" {disc.tyre_rolling_radius:g} m tyre radius imply{hint}; fix the channel's unit"
        " (or the speed channel's) in the file or the alias table",
        path=session.path, channel="wheel_speed_front")


def check_pyrometers(spots: np.ndarray, t_amb: np.ndarray, q_brk: np.ndarray,
                     names: list[str], session: Session) -> list[str]:
    """A pyrometer stuck at one value (error) or hot before the first stop (warning).

    Returns
    -------
    list of str — warnings for the run facts.
    """
    warnings: list[str] = []
    dt = session.dt
    on = q_brk > 0.01 * max(float(np.nanmax(q_brk, initial=0.0)), 1.0)
    first = int(np.argmax(on)) if on.any() else spots.shape[0]
    for i, name in enumerate(names):
        y = spots[:, i]
        ok = np.isfinite(y)
        if not ok.any():
            continue
        pre = y[:first][ok[:first]]
        if pre.size >= 10 and np.median(pre) > float(t_amb[0]) + COLD_EXCESS_C:
            warnings.append(
                f"{name} reads {np.median(pre):.0f} °C before the first stop, {t_amb[0]:.0f} °C"
                " air: a session started on a hot disc, or a pyrometer in kelvin labelled °C"
                f" (that would read about {np.median(pre) - 273.15:.0f} °C); check its unit")
        run = _longest_constant(y, ok)
        if run * dt >= STUCK_S and on.sum() * dt >= STUCK_S / 4:
            raise DataError(
                f"reads the same value for {run * dt:.0f} s while the brakes work: a stuck or"
                " frozen pyrometer; check the sensor and its logger channel",
                path=session.path, channel=name)
    return warnings


def _longest_constant(y: np.ndarray, ok: np.ndarray) -> int:
    """Length of the longest run of equal finite readings, in grid steps."""
    same = ok[1:] & ok[:-1] & (np.abs(np.diff(np.where(ok, y, 0.0))) < 1e-9)
    if not same.any():
        return 0
    edges = np.diff(np.concatenate(([0], same.astype(np.int8), [0])))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return int(np.max(stops - starts)) + 1


def estimate_warnings(mean_nis: float, frame_max_c: float, disc: DiscSpec) -> list[str]:
    """Loud warnings of an estimate that cannot be right as it stands."""
    out = []
    if np.isfinite(mean_nis) and mean_nis > NIS_LOUD:
        out.append(
            f"the filter's innovations are {np.sqrt(mean_nis):.1f} times larger than its noise"
            f" settings admit (mean NIS {mean_nis:.1f}, about 1 expected): the inputs do not"
            " fit the disc model — check the units of speed, wheel speed, brake pressure and"
            " the pyrometer before trusting these temperatures")
    if frame_max_c > 1.5 * disc.window_c[1] + 300.0:
        out.append(
            f"the estimate reaches {frame_max_c:.0f} °C, far above the disc's operating window"
            f" ({disc.window_c[0]:g}–{disc.window_c[1]:g} °C): check the brake pressure and"
            " wheel speed units")
    return out
