"""The channel-table abstraction every reader produces and every pipeline consumes.

A :class:`Session` is one logged session on a uniform time grid ``t = 0, dt, 2 dt, ...``
seconds from the earliest sample of any channel — the 10 Hz grid of OUTPUTS.md for the
disc pipelines, the rig's own rate for the rig pipelines — with canonical channel
names, SI units inside (temperatures in degC, pressures in Pa, speeds in m/s, angular
speeds in rad/s), the lap number of each grid point and the session facts. A channel
logged once (a reference measurement) is a value in :attr:`Session.constants`, not a
time series.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from brakethermo.errors import DataError
from brakethermo.io.kinds import kind_hint
from brakethermo.io.units import si_unit

AIR_RANGE_C = (-40.0, 60.0)  # degC: the air of any session (whatif's scenarios' range too)
KELVIN_C = 273.15

GRID_DT = 0.1  # s, the OUTPUTS.md time base


@dataclass(frozen=True)
class ChannelInfo:
    """Where a canonical channel came from and what resampling did to it.

    Attributes
    ----------
    name : str
        Canonical channel name (``speed``, ``disc_temp_spot3``, ...).
    source : str
        Name of the channel in the file (topic, ``topic.field`` or column).
    unit : str
        Unit string found in the file (the canonical unit when the file gave none).
    si_unit : str
        Unit of the values held in :attr:`Session.frame`.
    rate_hz : float
        Native sample rate (median of the sample spacing), Hz.
    samples : int
        Number of native samples.
    gaps : tuple of (float, float)
        Gaps longer than the bridging limit, as ``(start_s, duration_s)``; the
        10 Hz values inside them are NaN.
    spikes : int
        Isolated spikes rejected (IR temperature channels only).
    """

    name: str
    source: str
    unit: str
    si_unit: str
    rate_hz: float
    samples: int
    gaps: tuple[tuple[float, float], ...] = ()
    spikes: int = 0


@dataclass(frozen=True)
class Lap:
    """One lap: number (0 = out-lap), start time and duration on the session grid, s;
    ``cut_start``: the log began inside a lap (its first beacon numbers lap 2 or later),
    so lap 0 is the fragment of a flying lap, not an out-lap from the pits; ``cut_end``:
    the log ended inside this last lap (no beacon closes it and the bike rode well short
    of a lap's distance in it: an in-lap to the pits)."""

    lap: int
    start_s: float
    duration_s: float
    cut_start: bool = False
    cut_end: bool = False


@dataclass(frozen=True)
class Session:
    """A session resampled to a uniform grid, canonical names, SI units.

    Attributes
    ----------
    path : Path
        The file the session was read from.
    frame : pandas.DataFrame
        Columns ``time`` (float64 s), ``lap`` (int64) and one float64 column per
        canonical channel present, in SI units; NaN inside reported gaps.
    channels : dict of str to ChannelInfo
        One entry per canonical channel in :attr:`frame`.
    laps : tuple of Lap
    metadata : dict of str to str
        Session facts (``vehicle``, ``track``, ``date``, ``disc``, ``ambient_temp_c``...).
    aliases : dict of str to tuple of str
        The names tried for each canonical channel, for error messages.
    available : tuple of str
        Every channel name the file holds (source names), for error messages.
    start_epoch_s : float or None
        Absolute time of grid point 0 when the file carried epoch timestamps.
    warnings : tuple of str
        Things the reader recovered from (a truncated file, bridged gaps...), to show
        the user.
    dt : float
        Grid spacing, s (0.1 on the disc grid).
    constants : dict of str to float
        Canonical channels logged as a single sample (e.g. ``rolling_radius_ref``), SI.
    format : str
        The file format the session was read from (``MCAP``, ``MDF 4.10``, ``CSV``...).
    unusable : dict of str to str
        Canonical channels the file maps but that hold no finite sample (all null, NaN
        or infinite), with what was found; they are neither in :attr:`frame` nor in
        :attr:`constants`, and :meth:`require` names them.
    """

    path: Path
    frame: pd.DataFrame
    channels: dict[str, ChannelInfo]
    laps: tuple[Lap, ...]
    metadata: dict[str, str] = field(default_factory=dict)
    aliases: dict[str, tuple[str, ...]] = field(default_factory=dict)
    available: tuple[str, ...] = ()
    start_epoch_s: float | None = None
    warnings: tuple[str, ...] = ()
    dt: float = GRID_DT
    constants: dict[str, float] = field(default_factory=dict)
    format: str = ""
    unusable: dict[str, str] = field(default_factory=dict)

    @property
    def rate_hz(self) -> float:
        """Grid rate, Hz."""
        return 1.0 / self.dt

    @property
    def time(self) -> np.ndarray:
        """Grid time, s."""
        return self.frame["time"].to_numpy()

    @property
    def lap(self) -> np.ndarray:
        """Lap number of each grid point."""
        return self.frame["lap"].to_numpy()

    def has(self, name: str) -> bool:
        """Whether canonical channel ``name`` is present."""
        return name in self.channels

    def require(self, *names: str) -> None:
        """Raise a :class:`DataError` naming the first missing canonical channel.

        The message lists the aliases that were tried and the channels the file has,
        so the user can fix the alias table (``--aliases FILE``).
        """
        for name in names:
            if name in self.unusable:
                raise DataError(
                    f"{self.unusable[name]}; it cannot carry the computation. Check the"
                    " logger's channel setup or map another channel with --aliases FILE",
                    path=self.path,
                    channel=name,
                )
            if name in self.constants:
                raise DataError(
                    f"holds a single sample ({self.constants[name]:g} {si_unit(name)}) where a"
                    " time series is needed; check the logger's channel setup",
                    path=self.path,
                    channel=name,
                )
            if name not in self.channels:
                tried = ", ".join(self.aliases.get(name, (name,)))
                have = ", ".join(self.available) or "none"
                hint = kind_hint({*self.available, *self.channels}, name)
                advice = "add the file's name for it to an alias table and pass --aliases FILE"
                raise DataError(
                    f"required channel is missing (tried: {tried}); the file has: {have}."
                    + (f"{hint} If the file logs it under another name, {advice}" if hint
                       else f" {advice[0].upper()}{advice[1:]}"),
                    path=self.path,
                    channel=name,
                )

    def constant(self, name: str) -> float | None:
        """Value of a channel logged once, SI; else the mean of its series; else None."""
        if name in self.constants:
            return self.constants[name]
        if name in self.channels:
            v = self.frame[name].to_numpy(dtype=float)
            return float(np.nanmean(v)) if np.isfinite(v).any() else None
        return None

    def values(self, name: str) -> np.ndarray:
        """Values of canonical channel ``name`` on the grid, SI units."""
        self.require(name)
        return self.frame[name].to_numpy(dtype=float)

    def _check_air(self, air_c: float, what: str) -> None:
        """Refuse an air temperature no session is run in (:data:`AIR_RANGE_C`), naming
        the likely unit slip: degC labelled K put a 24 degC day at -249 degC, and the
        diagnosis then named an effect with confidence (review)."""
        lo, hi = AIR_RANGE_C
        if lo <= air_c <= hi:
            return
        hint = ("degC labelled K? set its unit to degC" if lo <= air_c + KELVIN_C <= hi
                else "kelvin labelled degC? set its unit to K" if lo <= air_c - KELVIN_C <= hi
                else "check its unit")
        raise DataError(f"{what} reads {air_c:.0f} °C (median): no session is run in such"
                        f" air ({lo:g} to {hi:g} °C): {hint}, or pass --ambient DEGC",
                        path=self.path)

    def ambient_c(self, override_c: float | None = None) -> np.ndarray:
        """Ambient temperature on the grid, degC.

        From the ``ambient_temp`` channel (gaps filled), else the session's
        ``ambient_temp_c`` fact, else ``override_c``; else a :class:`DataError`.
        """
        n = len(self.frame)
        if override_c is not None:
            return np.full(n, float(override_c))
        if self.has("ambient_temp"):
            amb = pd.Series(self.values("ambient_temp")).ffill().bfill().to_numpy()
            if np.isfinite(amb).all():
                self._check_air(float(np.median(amb)), "channel 'ambient_temp'")
                return amb
        if "ambient_temp_c" in self.metadata:
            try:
                air = float(self.metadata["ambient_temp_c"])
            except ValueError:
                raise DataError(
                    f"session fact ambient_temp_c={self.metadata['ambient_temp_c']!r} is not"
                    " a number; fix it or pass --ambient",
                    path=self.path,
                ) from None
            self._check_air(air, "session fact ambient_temp_c")
            return np.full(n, air)
        raise DataError(
            "no ambient temperature: no 'ambient_temp' channel and no session fact"
            " 'ambient_temp_c'; pass --ambient DEGC",
            path=self.path,
        )
