"""Read + resample speed of a race-length MCAP session (issue 2 performance target: < 3 s).

Writes once (cached in the temp directory) a 25-lap, ~2500 s session as a zstd MCAP with
one JSON topic per channel: speed and front wheel speed at 100 Hz, brake pressure at
500 Hz, four IR disc spots at 50 Hz, and the lap beacon. Then times, best of 3:

* decode   — ``read_raw``: file -> native-rate channels (MCAP parsing + JSON numbers);
* load     — ``load_session``: decode + units + Hampel + 10 Hz resampling + laps;

and prints seconds, MB/s of file read, and which stage bounds the total.

Run: ``python benchmarks/bench_io.py``
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
from mcap.writer import CompressionType, Writer

from brakethermo.io import load_session, read_raw

LAPS = 25
LAP_S = 100.0
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


def write_session(path: Path) -> None:
    """Write the benchmark session (about 2.25 M messages)."""
    rng = np.random.default_rng(2)
    duration = LAPS * LAP_S + 5.0
    with path.open("wb") as fh:
        writer = Writer(fh, compression=CompressionType.ZSTD)
        writer.start()
        schema = writer.register_schema(
            name="value", encoding="jsonschema",
            data=b'{"type":"object","properties":{"value":{"type":"number"}}}',
        )
        ids, stamps, payloads = [], [], []
        for name, rate in RATES_HZ.items():
            meta = {"unit": UNITS.get(name, "degC")}
            channel = writer.register_channel(name, "json", schema, meta)
            t = np.arange(0.0, duration, 1.0 / rate)
            ids.append(np.full(t.size, channel))
            stamps.append(np.round(t * 1e9).astype(np.int64))
            payloads.extend(f'{{"value": {v:.3f}}}'.encode() for v in _signal(name, t, rng))
        # A logger writes in time order, the channels interleaved.
        all_ids, all_ns = np.concatenate(ids), np.concatenate(stamps)
        for i in np.argsort(all_ns, kind="stable").tolist():
            log_time = int(all_ns[i])
            writer.add_message(int(all_ids[i]), log_time, payloads[i], log_time)
        beacon = writer.register_channel("lap_beacon", "json", schema, {})
        for lap in range(1, LAPS + 1):
            t_ns = int((5.0 + (lap - 1) * LAP_S) * 1e9)
            writer.add_message(beacon, t_ns, f'{{"value": {lap}}}'.encode(), t_ns)
        facts = {"vehicle": "bench", "track": "synthetic", "disc": "cc-340-8"}
        writer.add_metadata("session", facts)
        writer.finish()


def best_of(fn, repeats: int = 3) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    path = Path(tempfile.gettempdir()) / "brakethermo_bench_io" / "race_2500s_zstd.mcap"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_suffix(".partial")
        start = time.perf_counter()
        write_session(partial)
        partial.replace(path)
        print(f"wrote {path} in {time.perf_counter() - start:.1f} s")
    size_mb = path.stat().st_size / 1e6
    raw = read_raw(path)
    messages = sum(c.t.size for c in raw.channels)
    t_decode = best_of(lambda: read_raw(path))
    t_load = best_of(lambda: load_session(path))
    t_resample = t_load - t_decode
    session = load_session(path)
    print(f"file: {size_mb:.1f} MB, {messages:,} messages, {len(session.laps)} laps, "
          f"{len(session.frame):,} grid points")
    print(f"decode (read_raw)          : {t_decode:6.3f} s  {size_mb / t_decode:7.1f} MB/s  "
          f"{messages / t_decode / 1e6:5.2f} M msg/s")
    print(f"resample etc. (load - read): {t_resample:6.3f} s")
    print(f"read + resample (load)     : {t_load:6.3f} s  {size_mb / t_load:7.1f} MB/s  "
          f"target < 3 s: {'met' if t_load < 3.0 else 'MISSED'}")
    bound = "decode" if t_decode >= t_resample else "resample"
    print(f"bound by: {bound} ({100.0 * max(t_decode, t_resample) / t_load:.0f} % of the total)")

    # A logger that lost power: no summary, no indexes; the record walk recovers 90 %.
    cut = path.with_name("truncated_90pct.mcap")
    cut.write_bytes(path.read_bytes()[: int(path.stat().st_size * 0.9)])
    t_cut = best_of(lambda: load_session(cut), repeats=1)
    print(f"truncated copy (sequential record walk, 1 run): {t_cut:6.3f} s")
    cut.unlink()


if __name__ == "__main__":
    main()
