"""Physically plausible synthetic race sessions and estimate frames for report/batch tests.

A lap is a sequence of straights and braking zones; each spot's temperature follows a
first-order heat balance (heating proportional to braking power p·ω, Newton cooling
to ambient) with gains rising towards the outer radius, so the frame has the shape of
a real estimate: peaks a second after release, cooling on straights, outer spots hotter.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
from scipy.signal import lfilter

from brakethermo.io.atomic import write_text_atomic
from brakethermo.io.load import load_session
from brakethermo.io.session import ChannelInfo, Lap, Session
from brakethermo.pipelines.batch import BatchOptions, RunOutput, is_multi_spot

DT = 0.1
SPOT_RADII = (0.111, 0.130, 0.146, 0.162)


def race_frame(n_laps: int = 3, lap_s: float = 96.0, seed: int = 0) -> pd.DataFrame:
    """Session-like frame: ``time``, ``lap``, ``speed`` (m/s), ``brake_pressure_front`` (Pa),
    ``wheel_speed_front`` (rad/s), ``disc_temp`` (degC, spot 3 with noise)."""
    rng = np.random.default_rng(seed)
    n_lap = round(lap_s / DT)
    t_lap = np.arange(n_lap) * DT
    # Six braking zones per lap at fixed lap positions, different depths.
    starts = np.array([8.0, 22.0, 37.0, 51.0, 66.0, 82.0])
    lengths = np.array([3.6, 2.2, 3.0, 1.6, 2.8, 2.0])
    peaks_bar = np.array([13.0, 9.0, 12.0, 7.0, 11.0, 9.5])
    p_lap = np.zeros(n_lap)
    v_lap = np.full(n_lap, 300.0)
    for s, ln, pk in zip(starts, lengths, peaks_bar, strict=True):
        m = (t_lap >= s) & (t_lap < s + ln)
        x = (t_lap[m] - s) / ln
        p_lap[m] = pk * np.sin(np.pi * np.clip(x * 1.2, 0, 1)) ** 0.5
        v_lap[m] = 300.0 - (300.0 - 90.0 - 20 * pk / 13) * x
        after = (t_lap >= s + ln) & (t_lap < s + ln + 7.0)
        v_lap[after] = np.minimum(v_lap[after], 90.0 + 30.0 * (t_lap[after] - s - ln))
    n = n_laps * n_lap
    time = np.arange(n) * DT
    pressure = np.tile(p_lap, n_laps) * (1 + 0.03 * rng.standard_normal(n)).clip(0.9, 1.1)
    speed_kmh = np.tile(v_lap, n_laps)
    speed = speed_kmh / 3.6
    omega = speed / 0.3
    lap = np.repeat(np.arange(n_laps), n_lap)
    frame = pd.DataFrame(
        {
            "time": time,
            "lap": lap.astype(np.int64),
            "speed": speed,
            "brake_pressure_front": pressure * 1e5,
            "wheel_speed_front": omega,
        }
    )
    spots = spot_temperatures(frame)
    frame["disc_temp"] = spots[2] + rng.normal(0.0, 12.0, n)
    return frame


def spot_temperatures(frame: pd.DataFrame, ambient_c: float = 25.0) -> np.ndarray:
    """Four spot temperatures (4, n), degC, from a first-order heat balance."""
    q = (
        0.9
        * 40.0
        * frame["brake_pressure_front"].to_numpy()
        / 1e5
        * frame["wheel_speed_front"].to_numpy()
    )  # W
    out = []
    for gain, tau in ((0.0008, 50.0), (0.00135, 42.0), (0.0016, 38.0), (0.00175, 36.0)):
        a = 1.0 - DT / tau
        # T[k+1] - Tamb = a (T[k] - Tamb) + DT·gain·Q[k]
        out.append(ambient_c + lfilter([0.0, DT * gain], [1.0, -a], q))
    return np.array(out)


def estimate_frame(
    session_frame: pd.DataFrame, n_nodes: int = 21
) -> tuple[pd.DataFrame, np.ndarray]:
    """Estimate frame of OUTPUTS.md with node radii, consistent with the session."""
    spots = spot_temperatures(session_frame)
    n = spots.shape[1]
    std = np.stack([np.full(n, s) for s in (22.0, 14.0, 6.0, 16.0)])
    radii = np.linspace(0.100, 0.170, n_nodes)
    nodes = np.array([np.interp(r, SPOT_RADII, spots[:, k]) for k in range(n) for r in radii])
    nodes = nodes.reshape(n, n_nodes).T
    est = pd.DataFrame({"time": session_frame["time"], "lap": session_frame["lap"]})
    for i in range(4):
        est[f"spot{i + 1}"] = spots[i]
        est[f"spot{i + 1}_std"] = std[i]
    est["contact_avg"] = spots[1:].mean(axis=0)
    est["contact_avg_std"] = np.sqrt((std[1:] ** 2).sum(axis=0)) / 3
    for k in range(n_nodes):
        est[f"node_{k}"] = nodes[k]
    return est, radii


def make_session(
    frame: pd.DataFrame, path: Path, metadata: dict[str, str] | None = None
) -> Session:
    """A :class:`Session` around a synthetic frame."""
    units = {
        "speed": "m/s",
        "brake_pressure_front": "Pa",
        "wheel_speed_front": "rad/s",
        "disc_temp": "degC",
    }
    channels = {
        c: ChannelInfo(c, c, u, u, 10.0, len(frame)) for c, u in units.items() if c in frame
    }
    laps = tuple(
        Lap(int(k), float(g["time"].min()), float(len(g) * DT)) for k, g in frame.groupby("lap")
    )
    return Session(
        path=Path(path),
        frame=frame,
        channels=channels,
        laps=laps,
        metadata=metadata
        or {
            "vehicle": "demo bike",
            "track": "demo ring",
            "date": "2026-05-01",
            "disc": "cc-340-8",
            "ambient_temp_c": "25",
        },
    )


def write_estimate_parquet(est: pd.DataFrame, radii: np.ndarray, path: Path) -> None:
    """Write an estimate frame the way OUTPUTS.md lays it out (radius in field metadata)."""
    table = pa.Table.from_pandas(est, preserve_index=False)
    fields = [
        f.with_metadata({"radius_m": str(radii[int(f.name[5:])])})
        if f.name.startswith("node_")
        else f
        for f in table.schema
    ]
    pq.write_table(table.cast(pa.schema(fields)), path)


UNITS = {
    "speed": "m/s",
    "brake_pressure_front": "Pa",
    "wheel_speed_front": "rad/s",
    "disc_temp": "degC",
    "lap_beacon": "",
}


def session_file_frame(n_laps: int, seed: int, multi: bool) -> pd.DataFrame:
    """Wide logger table (``time``, channels, ``lap_beacon``) of a synthetic session."""
    frame = race_frame(n_laps, seed=seed)
    beacon = np.full(len(frame), np.nan)
    first = np.flatnonzero(np.diff(frame["lap"].to_numpy(), prepend=-1) != 0)[1:]
    beacon[first] = frame["lap"].to_numpy()[first]
    out = frame.drop(columns=["lap"]).assign(lap_beacon=beacon)
    if multi:
        rng = np.random.default_rng(seed + 100)
        spots = spot_temperatures(frame)
        out = out.drop(columns=["disc_temp"])
        for i in range(4):
            out[f"disc_temp_spot{i + 1}"] = spots[i] + rng.normal(0.0, 8.0, len(out))
    return out


def write_session_parquet(
    path: Path, n_laps: int = 2, seed: int = 0, multi: bool = False, date: str = "2026-05-01",
    facts: dict[str, str] | None = None,
) -> Path:
    """A session Parquet file as a logger export would write it (CHANNELS.md).

    ``facts`` overrides the session facts (``track``, ``vehicle``, ``disc``...).
    """
    out = session_file_frame(n_laps, seed, multi)
    table = pa.Table.from_pandas(out, preserve_index=False)
    fields = [
        f.with_metadata({"unit": UNITS.get(f.name, "degC")}) if f.name != "time" else f
        for f in table.schema
    ]
    meta = {
        "session": json.dumps(
            {
                "vehicle": "demo bike",
                "track": "demo ring",
                "date": date,
                "disc": "cc-340-8",
                "ambient_temp_c": "25",
                **(facts or {}),
            }
        )
    }
    pq.write_table(table.cast(pa.schema(fields)).replace_schema_metadata(meta), path)
    return path


def write_session_csv(path: Path, n_laps: int = 2, seed: int = 0) -> Path:
    """A single-spot session as a CSV export (``name [unit]`` headers)."""
    out = session_file_frame(n_laps, seed, multi=False)
    out["ambient_temp"] = 25.0
    units = {**UNITS, "ambient_temp": "degC"}
    out.columns = ["time", *(f"{c} [{units[c]}]" if units[c] else c for c in out.columns[1:])]
    out.to_csv(path, index=False)
    return path


class SynthBatchRunner:
    """A batch runner: the real reader, a synthetic heat-balance estimate; a multi-spot
    session writes an h law. Subclasses say how a session records the law it ran with."""

    def load(self, path: Path, options: BatchOptions) -> Session:
        return load_session(path, aliases=options.aliases)

    def run(
        self, session: Session, stage: Path, options: BatchOptions, h_law: Path | None
    ) -> RunOutput:
        t = time.perf_counter()
        est, radii = estimate_frame(session.frame, n_nodes=options.nodes or 11)
        write_estimate_parquet(est, radii, stage / "estimate.parquet")
        law = None
        if is_multi_spot(session):
            law = stage / "h_law.toml"
            write_text_atomic(law, f'source = "{session.path.name}"\n')
        self.record(stage, law, h_law)
        return RunOutput(est, radii, law, {"estimate_s": time.perf_counter() - t})

    def record(self, stage: Path, written: Path | None, given: Path | None) -> None:
        """Note in ``stage`` the h law the session ran with: the one it wrote (``written``),
        else the ``given`` one (None: the shipped law)."""
        raise NotImplementedError
