"""The session's layout for the diagnosis: lap distance, braking zones and straights, the
lap split into training and held-out laps, and the masks of the phases."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from brakethermo.errors import DataError
from brakethermo.io.session import Session
from brakethermo.models.disc_effects import KNEE, Segments
from brakethermo.pipelines.diagnose._common import MIN_STRAIGHT_S
from brakethermo.pipelines.inputs import DiscInputs
from brakethermo.report.braking_zones import (
    cluster_names,
    detect_zones,
    zone_clusters,
)
from brakethermo.report.braking_zones import lap_distance as track_distance
from brakethermo.results.laps import partial_laps


def lap_distance(inputs: DiscInputs, session: Session) -> np.ndarray:
    """Distance along the lap, m: the ``distance`` channel, else integrated speed."""
    logged = session.values("distance") if session.has("distance") else None
    return track_distance(inputs.lap, inputs.speed, session.dt, logged)


def build_segments(inputs: DiscInputs, zones: np.ndarray, dist: np.ndarray) -> Segments:
    """Braking zones matched across laps by lap distance; straights per lap."""
    K = inputs.speed.size
    starts = zones[:, 0] if zones.size else np.empty(0, int)
    ids, centres = zone_clusters(starts, inputs.lap, dist)
    zone = np.full(K, -1)
    for start, z in zip(starts, ids, strict=True):
        zone[start:] = z  # the zone owns its cycle until the next start
    braking = np.zeros(K, bool)
    for a, b in zones:
        braking[a:b] = True
    straight = np.full(K, -1)
    laps: list[int] = []
    edges = np.diff(np.concatenate(([1], braking.astype(np.int8), [1])))
    run_starts, run_stops = np.flatnonzero(edges == -1), np.flatnonzero(edges == 1)
    for a, b in zip(run_starts, run_stops, strict=True):
        if (b - a) * 0.1 < MIN_STRAIGHT_S and laps:
            straight[a:b] = len(laps) - 1
            continue
        straight[a:b] = len(laps)
        laps.append(int(inputs.lap[a]))
    return Segments(zone=zone, n_zones=len(centres), straight=straight,
                    n_straights=len(laps), straight_lap=np.asarray(laps, int),
                    zone_names=tuple(cluster_names(ids, inputs.lap[starts], len(centres))))


def session_segments(session: Session, inputs: DiscInputs
                     ) -> tuple[np.ndarray, np.ndarray, Segments]:
    """The session's braking zones (``[start, stop)`` rows), lap distance (m) and segments."""
    zones = detect_zones(inputs.time, session.values("brake_pressure_front"))
    dist = lap_distance(inputs, session)
    return zones, dist, build_segments(inputs, zones, dist)


def full_laps(session: Session, inputs: DiscInputs) -> list[int]:
    """The session's whole flying laps (the out-lap and partial laps excluded), by number
    (results.laps.flying_laps counts the flying laps, partial ones included)."""
    present = sorted(int(v) for v in np.unique(inputs.lap) if v >= 1)
    durations = {lap.lap: lap.duration_s for lap in session.laps}
    short = partial_laps(session.laps)
    return [lap for lap in present if durations.get(lap, 0.0) > 0 and lap not in short]


def split_laps(session: Session, inputs: DiscInputs, holdout: Sequence[int] | None
               ) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """Training and held-out flying laps (out-lap and partial last lap excluded)."""
    full = full_laps(session, inputs)
    if len(full) < 2:
        raise DataError(
            f"diagnose needs at least two flying laps to fit on some and check on others; the"
            f" session has {len(full)} (lap_beacon marks laps; the out-lap is lap 0)",
            path=session.path, channel="lap_beacon",
        )
    if holdout:
        bad = [lap for lap in holdout if lap not in full]
        if bad:
            raise DataError(
                f"--holdout-laps {', '.join(map(str, bad))}: not flying laps of this session"
                f" (flying laps: {', '.join(map(str, full))})", path=session.path,
            )
        held = tuple(sorted(holdout))
        train = tuple(lap for lap in full if lap not in held)
        if not train:
            raise DataError("--holdout-laps leaves no lap to fit on", path=session.path)
        return train, held
    return tuple(full[0::2]), tuple(full[1::2])


@dataclass(frozen=True)
class Layout:
    """Masks of the grid used for fitting, scoring and the phase splits."""

    train: np.ndarray  # (K,)
    held: np.ndarray  # (K,)
    braking: np.ndarray  # (K,)
    release: np.ndarray  # (K,) first seconds after a release
    cycles: np.ndarray  # (K,) id of the braking cycle (bootstrap unit), -1 outside


def zone_masks(zones: np.ndarray, K: int, settle: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per step from the ``[start, stop)`` braking zones: braking, release (the ``settle``
    steps after a release, off the brakes) and the braking cycle's id (-1 before the first).
    """
    braking = np.zeros(K, bool)
    release = np.zeros(K, bool)
    cycles = np.full(K, -1)
    for j, (a, b) in enumerate(zones):
        braking[a:b] = True
        release[b: b + settle] = True
        cycles[a:] = j
    return braking, release & ~braking, cycles


def _phase_masks(layout: Layout) -> dict[str, np.ndarray]:
    return {"braking": layout.braking, "cooling": ~layout.braking}


def _fast_straights(layout: Layout, speed: np.ndarray, segments: Segments, v_ref: float
                    ) -> np.ndarray:
    """Held-out straights that pass the knee speed, from the first crossing to the next
    braking, as units (the straight's id, -1 elsewhere)."""
    units = np.full(speed.size, -1)
    st = segments.straight
    for j in np.unique(st[st >= 0]):
        idx = np.flatnonzero((st == j) & layout.held & ~layout.braking)
        above = idx[speed[idx] >= KNEE * v_ref]
        if above.size:
            units[idx[idx >= above[0]]] = j
    return units


# Where an effect's signature lives, as held-out units: the effect registered here is
# also tested on those units (diagnosis.verdict.Signature). An effect not listed is
# tested on whole held-out braking cycles only.
SIGNATURE_UNITS = {
    "h_speed_knee": ("held-out straights above the knee speed, to the next braking",
                     _fast_straights),
}


def signature_units(name: str, layout: Layout, speed: np.ndarray, segments: Segments,
                    v_ref: float) -> tuple[str, np.ndarray] | None:
    """The units (per step, -1 outside) where ``name``'s signature lives, and their words;
    ``None`` for an effect tested on whole cycles only."""
    if name not in SIGNATURE_UNITS:
        return None
    where, units_of = SIGNATURE_UNITS[name]
    return where, units_of(layout, speed, segments, v_ref)
