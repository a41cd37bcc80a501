"""What a simulated session leaves behind: the channels its logger wrote and the truth.

The logged channels are the realised run seen through the sensors — each on its own
jittered logger clock, with noise, the pressure sensor's offset and gain, and the IR
pyrometer's lag, lens and emissivity setting on the patch-averaged face. The truth is
what really happened, on the 10 Hz grid (:data:`TRUTH_DT`), as an Arrow table whose
metadata carries the run's parameters. Only scoring reads the truth; the estimator sees
the channels.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pyarrow as pa

from brakethermo.io.writers import Channel
from brakethermo.sim.brake_chain import BrakeChain
from brakethermo.sim.effects import Effects
from brakethermo.sim.ride_and_heat import KMH, ThermalRun
from brakethermo.sim.sensors import (
    IRSensor,
    LoggerRates,
    finish_ir,
    first_order_lag,
    noisy,
    pyrometer_reading,
    sample_clock,
)
from brakethermo.sim.vehicle import RiderRun
from brakethermo.thermal.disc import BAR, DiscSpec

TRUTH_DT = 0.1  # s, the OUTPUTS.md grid


def _logged_channels(
    sensor: str,
    disc: DiscSpec,
    ride: RiderRun,
    eff: Effects,
    chain: BrakeChain,
    ir: IRSensor,
    t_thermal: np.ndarray,
    spots_face: np.ndarray,
    p_line_bar: np.ndarray,
    omega: np.ndarray,
    t_amb500: np.ndarray,
    duration: float,
    rng: np.random.Generator,
) -> tuple[Channel, ...]:
    """The channels the logger wrote: the realised ``ride`` seen through the sensors, each
    on its own jittered clock over ``duration`` (s)."""
    rates = LoggerRates()
    t500 = ride.time

    def clock(rate: float) -> np.ndarray:
        return sample_clock(rate, duration, rates.jitter_s, rng)

    out: list[Channel] = []
    # One 50 Hz logger task samples speed, wheel speed and distance together.
    ts = clock(rates.speed)
    out.append(
        Channel("speed", "km/h", ts, noisy(np.interp(ts, t500, ride.v) * KMH, 0.15, 0.01, rng), 2)
    )
    out.append(
        Channel(
            "wheel_speed_front", "rad/s", ts, noisy(np.interp(ts, t500, omega), 0.05, 0.01, rng), 2
        )
    )
    out.append(
        Channel(
            "distance",
            "m",
            ts,
            np.round(ride.lap_distance[np.floor(ts * ride.rate).astype(int)], 1),
            1,
        )
    )
    ts = clock(rates.pressure)
    p_bar = chain.logged_pressure_bar(np.interp(ts, t500, p_line_bar), rng)
    out.append(Channel("brake_pressure_front", "bar", ts, np.round(p_bar, 2), 2))

    # IR: the patch-averaged face seen through the sensor's lag, lens and emissivity setting.
    lagged = first_order_lag(spots_face, t_thermal[1] - t_thermal[0], eff.ir_lag_s)
    shown = pyrometer_reading(lagged, disc.emissivity * eff.lens_transmission, eff.emissivity_set)
    ts = clock(ir.rate)
    spots = [finish_ir(np.interp(ts, t_thermal, shown[:, i]), ir, rng) for i in range(4)]
    if sensor == "multi":
        out += [Channel(f"disc_temp_spot{i + 1}", "degC", ts, spots[i], 1) for i in range(4)]
    else:
        out.append(Channel("disc_temp", "degC", ts, spots[2], 1))

    ts = clock(rates.ambient)
    out.append(
        Channel("ambient_temp", "degC", ts, noisy(np.interp(ts, t500, t_amb500), 0.05, 0.1, rng), 1)
    )
    beacons = ride.beacon_times
    out.append(
        Channel("lap_beacon", "", np.round(beacons, 6), np.arange(beacons.size, dtype=float), 0)
    )
    return tuple(out)


def _truth_frame(dt: float, thermal: ThermalRun, ride: RiderRun, d: dict[str, np.ndarray],
                 disc: DiscSpec, spots_face: np.ndarray, spots_mid: np.ndarray,
                 p_line: np.ndarray, torque: np.ndarray, mu500: np.ndarray,
                 t_amb500: np.ndarray, rate: float) -> pd.DataFrame:
    """The truth on the 10 Hz grid (float32 but for the time); ``dt`` (s) is the thermal
    step of ``thermal``."""
    stride = round(TRUTH_DT / dt)
    g = slice(0, None, stride)
    t_grid = thermal.time[g]
    i500 = np.round(t_grid * rate).astype(int)
    lap_grid = np.searchsorted(ride.beacon_times, t_grid + 1e-9, side="right") - 1
    truth = {
        "time": t_grid,
        "lap": lap_grid.astype(np.int64),
        "speed": ride.v[i500] * KMH,
    }
    for i in range(4):
        truth[f"spot{i + 1}"] = spots_face[g, i]
    truth["contact_avg"] = spots_face[g, 1:].mean(axis=1)
    for i in range(4):
        truth[f"spot{i + 1}_mid"] = spots_mid[g, i]
    truth["disc_mean"] = thermal.t_mean[g]
    truth["h"] = d["h"][i500]
    truth["q_brake"] = d["q"][i500]
    truth["q_brake_nominal"] = disc.braking_power(p_line * BAR, d["omega"])[i500]
    truth["mu_ratio"] = mu500[i500]
    truth["p_line_bar"] = p_line[i500]
    truth["brake_torque"] = torque[i500]
    for c_ in range(3):
        truth[f"w{c_ + 1}"] = d["w"][i500, c_]
    truth["slipstream"] = d["slip_on"][i500]
    truth["ambient"] = t_amb500[i500]

    df = pd.DataFrame(truth)
    # Truth values in float32 (0.1 mK at 1000 degC) keep the shipped files small.
    floats = [c for c in df.columns if c != "time" and df[c].dtype == np.float64]
    df[floats] = df[floats].astype(np.float32)
    return df


def _truth_table(truth: pd.DataFrame, params: dict[str, object]) -> pa.Table:
    """The truth frame as an Arrow table with the run's parameters in its metadata."""
    table = pa.Table.from_pandas(truth, preserve_index=False)
    return table.replace_schema_metadata({"brakethermo_truth": json.dumps(params, sort_keys=True)})
