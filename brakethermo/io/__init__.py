"""Session readers (MCAP, Parquet, CSV), aliases, units, resampling and laps."""

from brakethermo.io.session import GRID_DT, ChannelInfo, Lap, Session

__all__ = ["GRID_DT", "ChannelInfo", "Lap", "Session"]
