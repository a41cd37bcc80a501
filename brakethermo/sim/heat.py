"""Heat exchange laws of the truth model: h(V), mu(T), pad-crown power distribution."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class HLaw:
    """True convection law of the disc face, W/(m^2 K).

    ``h(V) = h0 + a * V^n`` (V in m/s), times ``1 + g * x^2`` with
    ``x = (V - V_k) / (V_ref - V_k)`` above the knee ``V_k = knee_frac * V_ref``
    (effect ``h_speed_knee``, gain g). The rims see ``inner_factor`` and
    ``outer_factor`` times the face value.
    """

    h0: float = 25.0
    a: float = 4.0
    n: float = 0.8
    knee_frac: float = 0.8
    inner_factor: float = 0.6
    outer_factor: float = 1.3

    def face(self, v: np.ndarray, v_ref: float, knee_gain: float) -> np.ndarray:
        """Face h at speed ``v`` (m/s), W/(m^2 K)."""
        v = np.maximum(np.asarray(v, dtype=float), 0.0)
        v_k = self.knee_frac * v_ref
        x = np.maximum(v - v_k, 0.0) / (v_ref - v_k)
        return (self.h0 + self.a * v**self.n) * (1.0 + knee_gain * x * x)

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


@dataclass(frozen=True)
class MuLaw:
    """Friction coefficient over its nominal value against rubbed-face temperature.

    ``mu/mu_nom = 1 + amplitude * tanh((T - t_mid) / t_width)``; carbon grips more hot.
    """

    amplitude: float
    t_mid: float = 450.0
    t_width: float = 250.0

    def ratio(self, t_face: np.ndarray) -> np.ndarray:
        return 1.0 + self.amplitude * np.tanh((np.asarray(t_face) - self.t_mid) / self.t_width)


def crown_overlap(r_edges: np.ndarray, crown_edges: np.ndarray) -> np.ndarray:
    """Share of each radial cell's face area lying in each pad crown, shape (nr, 3)."""
    lo = np.maximum(r_edges[:-1, None], crown_edges[None, :-1])
    hi = np.minimum(r_edges[1:, None], crown_edges[None, 1:])
    overlap = np.pi * np.maximum(hi * hi - lo * lo, 0.0) * (hi > lo)
    return overlap / (np.pi * np.diff(r_edges**2))[:, None]


def crown_weights(
    corner_of_event: np.ndarray,
    n_corners: int,
    base_concentration: float,
    event_concentration: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """Pad-crown power weights w_1..w_3 (sum 1) of every braking event, shape (n_events, 3).

    Each corner has its own base distribution (how the rider loads the pads there),
    and every braking scatters around it.
    """
    base = rng.dirichlet(np.full(3, base_concentration), size=n_corners)
    alpha = event_concentration * base[corner_of_event]
    return np.array([rng.dirichlet(a) for a in alpha]).reshape(-1, 3)
