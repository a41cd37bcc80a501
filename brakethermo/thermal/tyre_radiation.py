"""Heat radiated from the brake disc's inner face toward the front tyre.

Model (stated assumptions):

- the disc's inner face is a flat annulus ``r_int..r_est``; the tyre's sidewall next to
  it is a flat annulus from the rim bead radius to the tyre radius, coaxial and parallel
  to the disc face at an axial distance ``gap`` (the disc sits outboard of the rim
  flange, the sidewall bulges toward it);
- view factors between coaxial parallel annuli are exact for that geometry (the
  disk-to-disk relation, Howell's catalogue C-41, combined by view-factor algebra); the
  rim, spokes and caliper shading the view are ignored, so the figure is an upper
  bound of the direct exchange;
- both surfaces grey and diffuse, exchange ``σ ε_d ε_t A F (T_d⁴ − T_t⁴)`` per ring:
  inter-reflections are neglected, an error of order ``(1 − ε_d)(1 − ε_t) F²``, a few
  per mille for these view factors;
- the carcass temperature is one number (tyre blankets and running keep it near
  60–90 °C); the disc face temperature is taken ring by ring from the model's face
  nodes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SIGMA_SB = 5.670374419e-8  # W/(m^2 K^4)
KELVIN = 273.15


@dataclass(frozen=True)
class TyreView:
    """Geometry and surface facts of the disc–tyre exchange.

    Parameters
    ----------
    rim_radius : float — m
        Bead-seat radius of the rim (17-inch rim: 0.216 m).
    tyre_radius : float — m
        Outer radius of the tyre.
    gap : float — m
        Axial distance from the disc's inner face to the sidewall plane.
    emissivity : float — dimensionless
        Emissivity of the tyre rubber (0.95).
    carcass_c : float — degC
        Temperature of the sidewall.
    """

    rim_radius: float = 0.216
    tyre_radius: float = 0.300
    gap: float = 0.03
    emissivity: float = 0.95
    carcass_c: float = 60.0

    def __post_init__(self) -> None:
        if not (0 < self.rim_radius < self.tyre_radius and self.gap > 0
                and 0 < self.emissivity <= 1 and np.isfinite(self.carcass_c)):
            raise ValueError("tyre view needs 0 < rim radius < tyre radius, gap > 0,"
                             " 0 < emissivity <= 1 and a finite carcass temperature")


def disk_to_disk(r1: np.ndarray | float, r2: float, gap: float) -> np.ndarray:
    """View factor from a disk of radius ``r1`` to a coaxial parallel disk ``r2``, ``gap`` away.

    ``F = (X − sqrt(X² − 4 (r2/r1)²)) / 2``, ``X = 1 + (1 + R2²)/R1²``, ``R = r/gap``.
    """
    r1 = np.asarray(r1, dtype=float)
    R1, R2 = r1 / gap, r2 / gap
    with np.errstate(divide="ignore", invalid="ignore"):
        X = 1.0 + (1.0 + R2**2) / R1**2
        F = 0.5 * (X - np.sqrt(np.maximum(X**2 - 4.0 * (r2 / r1) ** 2, 0.0)))
    return np.where(r1 > 0, F, 0.0)


def annulus_view_factors(edges: np.ndarray, view: TyreView) -> np.ndarray:
    """View factor from each disc ring ``edges[i]..edges[i+1]`` to the sidewall annulus.

    Parameters
    ----------
    edges : ndarray (n + 1,) — m
        Ring boundaries on the disc face, increasing.

    Returns
    -------
    ndarray (n,) — dimensionless
    """
    e = np.asarray(edges, dtype=float)
    # disk of radius r to the annulus a2..b2: F(r, b2) - F(r, a2); then area-weighted
    # differences of disks give the rings (view-factor algebra)
    to_ann = disk_to_disk(e, view.tyre_radius, view.gap) - disk_to_disk(e, view.rim_radius,
                                                                        view.gap)
    area_f = np.pi * e**2 * to_ann
    ring_area = np.pi * np.diff(e**2)
    return np.diff(area_f) / ring_area


def ring_edges(radii: np.ndarray, r_int: float, r_est: float) -> np.ndarray:
    """Ring boundaries around the nodes: midpoints, closed by the disc's rims, m."""
    r = np.asarray(radii, dtype=float)
    return np.concatenate([[r_int], 0.5 * (r[1:] + r[:-1]), [r_est]])


def tyre_heat(face_c: np.ndarray, radii: np.ndarray, r_int: float, r_est: float,
              disc_emissivity: float, view: TyreView) -> np.ndarray:
    """Power radiated from one disc's inner face to the tyre sidewall, W.

    Parameters
    ----------
    face_c : ndarray (..., n) — degC
        Face temperature of each radial node.
    radii : ndarray (n,) — m
        Node radii.
    r_int, r_est : float — m
        Inner and outer radius of the disc ring.
    disc_emissivity : float
    view : TyreView

    Returns
    -------
    ndarray (...,) — W (negative if the tyre were hotter than the disc)
    """
    edges = ring_edges(radii, r_int, r_est)
    area = np.pi * np.diff(edges**2)
    F = annulus_view_factors(edges, view)
    t4 = (np.asarray(face_c, float) + KELVIN) ** 4 - (view.carcass_c + KELVIN) ** 4
    return SIGMA_SB * disc_emissivity * view.emissivity * (t4 * (area * F)).sum(axis=-1)
