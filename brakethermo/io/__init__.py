"""Session readers (MCAP, Parquet, CSV, ASAM MDF, AiM XRK), aliases, units, resampling, laps."""

from brakethermo.io.load import load_session, read_raw
from brakethermo.io.session import GRID_DT, ChannelInfo, Lap, Session

__all__ = ["GRID_DT", "ChannelInfo", "Lap", "Session", "load_session", "read_raw"]
