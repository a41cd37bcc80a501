"""Read + resample speed per file format on the same race-length session.

Writes once (cached in the temp directory) one 25-lap, ~2500 s session in every format
the project can write, each with its own real writer: speed and front wheel speed at
100 Hz, brake pressure at 500 Hz, four IR disc spots at 50 Hz and the lap beacon
(about 2.25 M samples), values rounded to 3 decimals so the text formats hold them
exactly:

* MCAP  — ``mcap`` Writer, zstd chunks, one JSON topic per channel;
* MDF4  — ``asammdf``, one channel group per rate (as a logger writes it);
* Parquet — ``pyarrow``, one wide table on the union of the time stamps;
* CSV   — ``pandas``, the same wide table as text.

AiM XRK is not timed: libxrk reads XRK but nothing writes one.

Then times, best of ``--repeat``, for each format:

* read — ``read_raw``: file -> native-rate channels;
* load — ``load_session``: read + time checks + units + Hampel + 10 Hz resampling + laps;

checks that every format gives the same 10 Hz channels as the MCAP (max |difference|
over the channel's largest |value|, SI units),
and prints each format's load time as a multiple of the MCAP's (target: MDF4 within 2x;
MCAP itself under 3 s).

Run: ``python benchmarks/bench_io.py [--repeat 3]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
from mcap.writer import CompressionType, Writer

from brakethermo.io import load_session, read_raw
from brakethermo.io.writers import Channel, SessionData, write_session

LAPS = 25
LAP_S = 100.0
START_S = 5.0  # first beacon
RATES_HZ = {
    "speed": 100.0,
    "wheel_speed_front": 100.0,
    "brake_pressure_front": 500.0,
    "disc_temp_spot1": 50.0,
    "disc_temp_spot2": 50.0,
    "disc_temp_spot3": 50.0,
    "disc_temp_spot4": 50.0,
}
UNITS = {"speed": "km/h", "wheel_speed_front": "rad/s", "brake_pressure_front": "bar"}
CACHE = Path(tempfile.gettempdir()) / "brakethermo_bench_io"
STEM = "race_2500s_v2"


def _signal(name: str, t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    phase = 2.0 * np.pi * (t % LAP_S) / LAP_S
    speed_kmh = 180.0 + 120.0 * np.sin(3.0 * phase)
    if name == "speed":
        return speed_kmh + rng.normal(0.0, 0.5, t.size)
    if name == "wheel_speed_front":
        return speed_kmh / 3.6 / 0.3 + rng.normal(0.0, 0.2, t.size)
    if name == "brake_pressure_front":
        return np.clip(-12.0 * np.sin(3.0 * phase + 0.3), 0.0, None) + rng.normal(0, 0.05, t.size)
    spot = int(name[-1])
    return 400.0 + 40.0 * spot + 150.0 * np.cos(3.0 * phase) + rng.normal(0.0, 2.0, t.size)


def session_channels() -> dict[str, tuple[np.ndarray, np.ndarray, str]]:
    """name -> (time s on whole 2 ms ticks, value to 3 decimals, unit), beacon included."""
    rng = np.random.default_rng(2)
    ticks_end = round((LAPS * LAP_S + START_S) * 500)
    out = {}
    for name, rate in RATES_HZ.items():
        t = np.arange(0, ticks_end, round(500 / rate)) / 500.0
        out[name] = (t, np.round(_signal(name, t, rng), 3), UNITS.get(name, "degC"))
    tb = START_S + np.arange(LAPS) * LAP_S
    out["lap_beacon"] = (tb, np.arange(1.0, LAPS + 1), "")
    return out


FACTS = {"vehicle": "bench", "track": "synthetic", "disc": "cc-340-8"}


def write_mcap(path: Path, chans: dict[str, tuple[np.ndarray, np.ndarray, str]]) -> None:
    with path.open("wb") as fh:
        writer = Writer(fh, compression=CompressionType.ZSTD)
        writer.start()
        schema = writer.register_schema(
            name="value", encoding="jsonschema",
            data=b'{"type":"object","properties":{"value":{"type":"number"}}}',
        )
        ids, stamps, payloads = [], [], []
        for name, (t, v, unit) in chans.items():
            channel = writer.register_channel(name, "json", schema, {"unit": unit} if unit else {})
            ids.append(np.full(t.size, channel))
            stamps.append(np.round(t * 1e9).astype(np.int64))
            payloads.extend(f'{{"value": {x:.3f}}}'.encode() for x in v)
        # A logger writes in time order, the channels interleaved.
        all_ids, all_ns = np.concatenate(ids), np.concatenate(stamps)
        for i in np.argsort(all_ns, kind="stable").tolist():
            log_time = int(all_ns[i])
            writer.add_message(int(all_ids[i]), log_time, payloads[i], log_time)
        writer.add_metadata("session", FACTS)
        writer.finish()


def write_mdf(path: Path, chans: dict[str, tuple[np.ndarray, np.ndarray, str]]) -> None:
    from asammdf import MDF, Signal

    mdf = MDF(version="4.10")
    by_rate: dict[int, list] = {}
    for name, (t, v, unit) in chans.items():
        by_rate.setdefault(t.size, []).append(Signal(v, t, name=name, unit=unit))
    for signals in by_rate.values():
        mdf.append(signals)
    mdf.save(path, overwrite=True)
    mdf.close()


def write_wide(path: Path, chans: dict[str, tuple[np.ndarray, np.ndarray, str]]) -> None:
    data = SessionData(tuple(Channel(n, u, t, v) for n, (t, v, u) in chans.items()), FACTS)
    if path.suffix == ".parquet":
        write_session(path, data)
        return
    ticks = np.arange(0, round((LAPS * LAP_S + START_S) * 500))
    frame = pd.DataFrame({"time [s]": ticks / 500.0})
    for name, (t, v, unit) in chans.items():
        col = np.full(ticks.size, np.nan)
        col[np.round(t * 500).astype(np.int64)] = v
        frame[f"{name} [{unit}]" if unit else name] = col
    frame.to_csv(path, index=False, float_format="%.3f")


WRITERS: dict[str, tuple[str, Callable[[Path, dict], None]]] = {
    "MCAP": (".mcap", write_mcap),
    "MDF4": (".mf4", write_mdf),
    "Parquet": (".parquet", write_wide),
    "CSV": (".csv", write_wide),
}


def best_of(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def files() -> dict[str, Path]:
    CACHE.mkdir(parents=True, exist_ok=True)
    chans = None
    out = {}
    for fmt, (suffix, writer) in WRITERS.items():
        path = CACHE / f"{STEM}{suffix}"
        if not path.exists():
            chans = chans if chans is not None else session_channels()
            partial = path.with_name(f".partial{suffix}")
            start = time.perf_counter()
            writer(partial, chans)
            partial.replace(path)
            print(f"wrote {path} in {time.perf_counter() - start:.1f} s")
        out[fmt] = path
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="timing repeats (best of)")
    args = parser.parse_args()
    paths = files()
    ref = load_session(paths["MCAP"])
    samples = sum(c.t.size for c in read_raw(paths["MCAP"]).channels)
    print(f"session: {ref.time[-1]:.0f} s, {samples:,} samples, {len(ref.laps)} laps, "
          f"{len(ref.frame):,} grid points at 10 Hz; best of {args.repeat}")
    print(f"{'format':8s} {'MB':>7s} {'read s':>8s} {'load s':>8s} {'x MCAP':>7s} "
          f"{'max rel. diff vs MCAP':>21s}")
    loads: dict[str, float] = {}
    for fmt, path in paths.items():
        t_read = best_of(lambda p=path: read_raw(p), args.repeat)
        t_load = best_of(lambda p=path: load_session(p), args.repeat)
        loads[fmt] = t_load
        session = load_session(path)
        got = session.frame[list(ref.frame.columns)].to_numpy(dtype=float)
        want = ref.frame.to_numpy(dtype=float)
        scale = np.maximum(np.nanmax(np.abs(want), axis=0), 1.0)  # per channel, SI
        diff = float(np.nanmax(np.abs(got - want) / scale))
        print(f"{fmt:8s} {path.stat().st_size / 1e6:7.1f} {t_read:8.3f} {t_load:8.3f} "
              f"{t_load / loads['MCAP']:6.2f}x {diff:21.2e}")
    print("AiM XRK  not timed: no XRK writer exists (libxrk only reads)")
    ratio = loads["MDF4"] / loads["MCAP"]
    print(f"MDF4 load within 2x of MCAP: {'met' if ratio <= 2.0 else 'MISSED'} ({ratio:.2f}x); "
          f"MCAP load under 3 s: {'met' if loads['MCAP'] < 3.0 else 'MISSED'}")


if __name__ == "__main__":
    main()
