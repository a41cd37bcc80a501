"""Race tracks as data: straights and corners with apex speeds (``configs/tracks``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brakethermo.config import config_file, resolve_named
from brakethermo.errors import ConfigError

KMH = 1.0 / 3.6  # m/s per km/h


@dataclass(frozen=True)
class Segment:
    """One piece of track.

    Attributes
    ----------
    kind : str
        ``straight`` or ``corner``.
    length : float — m
    apex_speed : float — m/s, the corner's speed limit (``inf`` on a straight)
    name : str
    """

    kind: str
    length: float
    apex_speed: float
    name: str = ""


@dataclass(frozen=True)
class TrackSpec:
    """A track layout and its pit lane.

    Attributes
    ----------
    name, description : str
    segments : tuple of Segment
        Driven in order; the start/finish line is at the start of the first one.
    pit_speed : float — m/s
        Pit-lane speed limit (the out-lap starts at it).
    pit_lane : float — m
        Distance from the line driven at the pit speed on the out-lap.
    ambient_c : float — degC
        Typical air temperature.
    """

    name: str
    description: str
    segments: tuple[Segment, ...]
    pit_speed: float
    pit_lane: float
    ambient_c: float

    @property
    def length(self) -> float:
        """Lap length, m."""
        return float(sum(s.length for s in self.segments))

    @property
    def corners(self) -> tuple[Segment, ...]:
        return tuple(s for s in self.segments if s.kind == "corner")

    def corner_spans(self) -> np.ndarray:
        """Start and end distance of every corner along the lap, shape (n_corners, 2), m."""
        ends = np.cumsum([s.length for s in self.segments])
        starts = ends - [s.length for s in self.segments]
        return np.array(
            [
                (a, b)
                for a, b, s in zip(starts, ends, self.segments, strict=True)
                if s.kind == "corner"
            ]
        )

    def longest_straight(self) -> tuple[float, float]:
        """Start and end distance of the longest straight, m."""
        ends = np.cumsum([s.length for s in self.segments])
        best = max(
            (s.length, e - s.length, e)
            for s, e in zip(self.segments, ends, strict=True)
            if s.kind == "straight"
        )
        return best[1], best[2]


def load_track(name_or_path: str | Path) -> TrackSpec:
    """Load and validate a track by shipped name (``mugello-like``) or TOML path."""
    path = resolve_named("tracks", name_or_path)
    raw = config_file(path)
    segments = []
    for i, seg in enumerate(raw.tables("segments")):
        kind = seg.string("kind", choices=("straight", "corner"))
        apex = seg.number("apex_kmh", positive=True) * KMH if kind == "corner" else float("inf")
        segments.append(
            Segment(
                kind=kind,
                length=seg.number("length_m", positive=True),
                apex_speed=apex,
                name=seg.string("name", f"{kind}-{i + 1}"),
            )
        )
    spec = TrackSpec(
        name=raw.string("name", path.stem),
        description=raw.string("description", ""),
        segments=tuple(segments),
        pit_speed=raw.number("pit_speed_kmh", positive=True) * KMH,
        pit_lane=raw.number("pit_lane_m", lo=0.0),
        ambient_c=raw.number("ambient_c", lo=-40.0, hi=60.0),
    )
    problems = []
    if not spec.corners or not any(s.kind == "straight" for s in spec.segments):
        problems.append("a track needs at least one straight and one corner")
    if any(s.length <= 0 for s in spec.segments):
        problems.append("every segment needs length_m > 0")
    if any(not 5.0 < s.apex_speed < 120.0 for s in spec.corners):
        problems.append("corner apex_kmh must lie between 18 and 430 km/h")
    if not 0 < spec.pit_speed < 40.0 or not 0 <= spec.pit_lane < spec.length:
        problems.append("pit_speed_kmh must be in (0, 144) and pit_lane_m shorter than a lap")
    if problems:
        raise ConfigError("; ".join(problems), path=path)
    return spec
