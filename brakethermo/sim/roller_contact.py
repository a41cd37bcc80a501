"""The roller-rig truth's wheel-roller contact, written apart from the estimator's.

The estimator (:mod:`brakethermo.rigs`) solves Hertz's problem by the ratio of complete
elliptic integrals and takes its creep forces from Kalker's simplified theory
(FASTSIM) and Polach's law. The truth here uses other theories, so that what the
estimator's accuracy is measured against is not its own model:

- **Hertz** by Carlson's symmetric integrals: for the semi-ellipsoidal pressure on the
  ellipse (a, b) the surface gap closes when (Johnson, *Contact Mechanics*, eq. 3.x in
  integral form; Barber, *Contact Mechanics*, ch. 3)
  ``A = N R_D(b^2, 0, a^2) / (2 pi E*)``, ``B = N R_D(a^2, 0, b^2) / (2 pi E*)``,
  solved for (a, b) in log a, log b by MINPACK's hybrid method (``scipy.optimize.root``);
- **strip theory** (Haines and Ollerton, 1963): the ellipse cut into strips along the
  rolling direction, each a 2-D rolling contact solved exactly by Carter (1926),
  ``Q / (mu P) = 1 - (1 - |xi| / xi_c)^2`` with ``xi_c = 2 mu p0(y) / E*``; spin
  enters as a longitudinal creepage varying across the strips, ``xi - phi y``.

Strip theory's small-creep slope is ``(pi^2 / 4) a b E*``, some 15 % under Kalker's
``G a b C11`` on this rig's near-round ellipse, the way measured creep curves fall
under Kalker's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy.optimize import root
from scipy.special import elliprd

from brakethermo.config import load_toml, resolve_named
from brakethermo.errors import ConfigError

N_STRIPS = 48


@dataclass(frozen=True)
class Machine:
    """The datasheet values the truth needs (``configs/rigs/<id>.toml``), SI units."""

    id: str
    wheel_inertia: float
    roller_inertia: float
    roller_radius: float
    wheel_lateral_curvature: float
    roller_lateral_curvature: float
    contact_angle: float
    young: float
    poisson: float
    nominal_load: float
    mu0: float
    motor: tuple[float, float, float, float, float, float, int]  # v_th, r_th, x_th, r2, x2, f, p
    bearings: tuple[float, float, float, float]  # wheel c0, c1, roller c0, c1


def load_machine(name_or_path: str | Path = "roller-rig") -> Machine:
    """Read the rig's datasheet for the truth (ConfigError naming the key)."""
    path = resolve_named("rigs", name_or_path)
    raw = load_toml(path)

    def num(table: str, key: str) -> float:
        value = raw.get(table, {}).get(key) if isinstance(raw.get(table), dict) else None
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise ConfigError(f"[{table}] {key} must be a number, found {value!r}", path=path)
        return float(value)

    m = "roller_motor"
    return Machine(
        id=str(raw.get("id", Path(path).stem)),
        wheel_inertia=num("wheel", "inertia"),
        roller_inertia=num("roller", "inertia"),
        roller_radius=num("roller", "radius"),
        wheel_lateral_curvature=num("wheel", "lateral_curvature"),
        roller_lateral_curvature=num("roller", "lateral_curvature"),
        contact_angle=num("contact", "contact_angle"),
        young=num("contact", "young"),
        poisson=num("contact", "poisson"),
        nominal_load=num("contact", "nominal_load"),
        mu0=num("friction", "mu0"),
        motor=(
            *(num(m, key) for key in ("v_th", "r_th", "x_th", "r2", "x2", "f_rated")),
            int(num(m, "pole_pairs")),
        ),
        bearings=tuple(
            num("bearings", f"{shaft}_{kind}")
            for shaft in ("wheel", "roller")
            for kind in ("coulomb", "viscous")
        ),
    )


def hertz_ellipse(
    normal_force: float, A: float, B: float, e_star: float
) -> tuple[float, float, float]:
    """Semi-axes and peak pressure of Hertz's contact, by Carlson's integrals.

    Parameters
    ----------
    normal_force : float — N.
    A, B : float — curvature sums in the rolling (x) and lateral (y) directions, 1/m.
    e_star : float — contact modulus E*, Pa (1/E* = sum of (1 - nu^2)/E).

    Returns
    -------
    a, b, p0 : float — semi-axes along x and y, m, and peak pressure, Pa.
    """
    if not (normal_force > 0.0 and A > 0.0 and B > 0.0 and e_star > 0.0):
        raise ConfigError(f"contact needs N, A, B, E* > 0 (N={normal_force:g}, A={A:g}, B={B:g})")
    k = normal_force / (2.0 * math.pi * e_star)
    # start from the circle of the mean curvature: R_D(r^2, 0, r^2) = 3 pi / (4 r^3)
    r = (3.0 * math.pi * k / (4.0 * math.sqrt(A * B))) ** (1.0 / 3.0)

    def gap(z: np.ndarray) -> np.ndarray:  # log of the closing condition, in log semi-axes
        a2, b2 = np.exp(2.0 * z)
        return np.log([k * elliprd(b2, 0.0, a2) / A, k * elliprd(a2, 0.0, b2) / B])

    sol = root(gap, np.log([r, r]), method="hybr", options={"xtol": 1e-13})
    if not np.max(np.abs(sol.fun)) < 1e-11:  # MINPACK may stop at round-off, solved
        raise ConfigError(f"Hertz's contact did not solve (A={A:g}, B={B:g}): {sol.message}")
    z = sol.x
    a, b = (float(v) for v in np.exp(z))
    return a, b, 3.0 * normal_force / (2.0 * math.pi * a * b)


def contact_strips(machine: Machine, wheel_radius: float, n: int = N_STRIPS) -> NDArray[np.float64]:
    """The strips of the contact at the nominal load, (3, n): y (m), load share, xi_c / mu.

    The load shares sum to one; at another load N every length and xi_c scale by
    (N / N_ref)^(1/3) (Hertz), which :func:`strip_force` applies.
    """
    A = 0.5 * (1.0 / wheel_radius + 1.0 / machine.roller_radius)
    B = 0.5 * (machine.wheel_lateral_curvature + machine.roller_lateral_curvature)
    e_star = machine.young / (2.0 * (1.0 - machine.poisson**2))  # same steel both sides
    a, b, p0 = hertz_ellipse(machine.nominal_load, A, B, e_star)
    y = b * ((np.arange(n) + 0.5) / n * 2.0 - 1.0)
    shape = 1.0 - (y / b) ** 2
    load = 0.5 * math.pi * p0 * a * shape * (2.0 * b / n)  # Carter strip load P(y) dy, N
    xi_c = 2.0 * p0 * np.sqrt(shape) / e_star
    return np.vstack([y, load / load.sum(), xi_c])


@njit(cache=True, nogil=True)
def strip_force(xi, mu, N, n_ref, spin, strips):  # pragma: no cover - compiled
    """Longitudinal creep force of the strips, N (Carter in each strip).

    Parameters
    ----------
    xi : float — longitudinal creepage, -.
    mu : float — friction coefficient, -.
    N : float — normal load, N.
    n_ref : float — the load ``strips`` were computed at, N.
    spin : float — spin creepage, 1/m.
    strips : (3, n) array — :func:`contact_strips`.
    """
    s = (N / n_ref) ** (1.0 / 3.0)
    total = 0.0
    for j in range(strips.shape[1]):
        u = (xi - spin * strips[0, j] * s) / (mu * strips[2, j] * s)
        g = 1.0 if abs(u) >= 1.0 else 1.0 - (1.0 - abs(u)) ** 2
        total += strips[1, j] * math.copysign(g, u)
    return total * mu * N
