"""Sensor models: jittered sample clocks, IR pyrometer spots, logger channels."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.signal import lfilter, lfilter_zi

KELVIN = 273.15


@dataclass(frozen=True)
class IRSensor:
    """Multi-spot IR pyrometer.

    Attributes
    ----------
    patch_radius : float — m, radius of the spot seen on the face
    noise_c : float — degC, 1-sigma white noise
    quantum_c : float — degC, output resolution
    floor_c : float — degC; below it the pyrometer is out of range and gives no
        sample (missing in MCAP, null in Parquet, empty in CSV)
    rate : float — Hz
    """

    patch_radius: float = 0.0025
    noise_c: float = 3.5
    quantum_c: float = 0.5
    floor_c: float = 100.0
    rate: float = 20.0

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


@dataclass(frozen=True)
class LoggerRates:
    """Sample rates of the logged channels, Hz, and the clock jitter, s."""

    speed: float = 50.0  # also wheel speed and distance (one logger task)
    pressure: float = 100.0
    ambient: float = 1.0
    jitter_s: float = 2e-4

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def sample_clock(
    rate: float, duration: float, jitter: float, rng: np.random.Generator
) -> np.ndarray:
    """Sample times of a channel: nominal ``k / rate`` plus clipped Gaussian jitter,
    inside ``[0, duration]``, on the logger's 0.1 ms tick, strictly increasing."""
    nominal = np.arange(int(np.floor(duration * rate)) + 1) / rate
    t = nominal + np.clip(rng.normal(0.0, jitter, nominal.size), -2.5 * jitter, 2.5 * jitter)
    t[0] = 0.0
    return np.round(np.clip(t, 0.0, duration), 4)


def patch_matrix(r_nodes: np.ndarray, spot_radii: np.ndarray, patch_radius: float) -> np.ndarray:
    """Weights mapping a face profile at ``r_nodes`` to spot-patch averages, (n_spots, n_r).

    A circular patch of radius ``patch_radius`` centred at each spot radius: the
    weight of a radial strip is its chord length; the profile is linear between nodes.
    """
    x, wq = np.polynomial.legendre.leggauss(16)
    chord = np.sqrt(1.0 - x * x) * wq
    chord /= chord.sum()
    eye = np.eye(r_nodes.size)
    W = np.zeros((spot_radii.size, r_nodes.size))
    for i, rs in enumerate(spot_radii):
        for xq, cq in zip(x, chord, strict=True):
            W[i] += cq * np.array([np.interp(rs + patch_radius * xq, r_nodes, e) for e in eye])
    return W


def first_order_lag(u: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """First-order lag ``tau y' + y = u`` on a uniform grid (columns are signals),
    exact for an input linear between samples, starting at rest on ``u[0]``."""
    if tau <= 0:
        return u.copy()
    alpha = np.exp(-dt / tau)
    beta = tau / dt * (1.0 - alpha)
    b, a = [1.0 - beta, beta - alpha], [1.0, -alpha]
    zi = lfilter_zi(b, a)[:, None] * np.atleast_1d(u[0])[None, :]
    y, _ = lfilter(b, a, u.reshape(u.shape[0], -1), axis=0, zi=zi)
    return y.reshape(u.shape)


def pyrometer_reading(
    t_true_c: np.ndarray, emissivity_true: float, emissivity_set: float
) -> np.ndarray:
    """Temperature shown by a total-radiation pyrometer set to ``emissivity_set``, degC.

    It sees ``eps_true sigma T^4`` and inverts it with ``eps_set``:
    ``T_read = T (eps_true / eps_set)^(1/4)`` in kelvin, so a too-high setting reads
    low, by more the hotter the disc.
    """
    return (t_true_c + KELVIN) * (emissivity_true / emissivity_set) ** 0.25 - KELVIN


def finish_ir(reading: np.ndarray, sensor: IRSensor, rng: np.random.Generator) -> np.ndarray:
    """Noise, quantisation and the range floor (NaN = no sample) on a reading, degC."""
    noisy = reading + rng.normal(0.0, sensor.noise_c, reading.shape)
    out = np.round(noisy / sensor.quantum_c) * sensor.quantum_c
    out[out < sensor.floor_c] = np.nan
    return out


def noisy(value: np.ndarray, sigma: float, quantum: float, rng: np.random.Generator) -> np.ndarray:
    """Gaussian noise and quantisation of a logged channel."""
    return np.round((value + rng.normal(0.0, sigma, value.shape)) / quantum) * quantum
