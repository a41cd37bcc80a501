"""Torque of an induction (asynchronous) motor from its Thevenin equivalent circuit.

Roller-rig paper eq. 1 with the circuit identified at the rated frequency (no-load,
blocked-rotor and stator-resistance tests, Sen 2007). Under open-loop V/f control the
Thevenin voltage and the reactances scale with the supply frequency while the
resistances do not, so the same circuit gives the torque at any frequency.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class InductionMotor:
    """Per-phase Thevenin circuit at the rated frequency (paper Fig. 4).

    Attributes
    ----------
    v_th : float — Thevenin phase voltage at ``f_rated``, V.
    r_th : float — Thevenin resistance, ohm.
    x_th : float — Thevenin reactance at ``f_rated``, ohm.
    r2 : float — rotor resistance referred to the stator R2', ohm.
    x2 : float — rotor leakage reactance X2' at ``f_rated``, ohm.
    f_rated : float — frequency of the circuit test, Hz.
    pole_pairs : int — p; synchronous speed omega_syn = 2 pi f / p, rad/s.
    """

    v_th: float
    r_th: float
    x_th: float
    r2: float
    x2: float
    f_rated: float
    pole_pairs: int

    def synchronous_speed(self, f_hz: ArrayLike) -> Array:
        """omega_syn = 2 pi f / p, rad/s."""
        return 2.0 * np.pi * np.asarray(f_hz, dtype=float) / self.pole_pairs

    def params(self) -> np.ndarray:
        """(v_th, r_th, x_th + x2, r2, f_rated, p) as one float array for compiled code."""
        return np.array(
            [self.v_th, self.r_th, self.x_th + self.x2, self.r2, self.f_rated, self.pole_pairs],
            dtype=float,
        )


def motor_torque(motor: InductionMotor, omega: ArrayLike, f_hz: ArrayLike) -> Array:
    """Shaft torque at rotor speed ``omega`` under V/f supply at ``f_hz`` (paper eq. 1).

    Parameters
    ----------
    motor : InductionMotor
    omega : array_like — rotor angular speed, rad/s.
    f_hz : array_like — supply frequency, Hz (> 0).

    Returns
    -------
    ndarray — N m, positive when motoring (omega < omega_syn), negative when generating
    (braking the roller that the wheel drives faster than synchronous).
    """
    omega = np.asarray(omega, dtype=float)
    f_hz = np.asarray(f_hz, dtype=float)
    ratio = f_hz / motor.f_rated
    w_syn = 2.0 * np.pi * f_hz / motor.pole_pairs
    s = (w_syn - omega) / w_syn  # slip
    v = motor.v_th * ratio  # V/f: the voltage follows the frequency
    x = (motor.x_th + motor.x2) * ratio  # reactances scale with frequency, resistances do not
    # eq. 1 multiplied through by s^2: finite and zero at synchronous speed
    return 3.0 * v * v * motor.r2 * s / (w_syn * ((motor.r_th * s + motor.r2) ** 2 + (x * s) ** 2))


@njit(cache=True, nogil=True)
def motor_torque_scalar(
    omega, f_hz, v_th, r_th, x_sum, r2, f_rated, pole_pairs
):  # pragma: no cover - compiled
    """:func:`motor_torque` for one rotor speed (``params()`` order), compiled."""
    ratio = f_hz / f_rated
    w_syn = 2.0 * math.pi * f_hz / pole_pairs
    s = (w_syn - omega) / w_syn
    v = v_th * ratio
    x = x_sum * ratio
    return 3.0 * v * v * r2 * s / (w_syn * ((r_th * s + r2) ** 2 + (x * s) ** 2))
