"""What one pyrometer cannot see: the pads' crown balance, admitted in the band.

The h law carries the test session's crown weights; a race's pads share the braking
power between the inner and the outer crown in their own way (bedding, wear, another
set), and that changes the spots away from the measured one while leaving the measured
one nearly as it was. The filter, fed by one spot, cannot learn it (an online crown state
looks like a k_z change there), so the band admits it instead, as the E-Booster's band
admits where its p-V curve sits: the model run open loop through the session with the
inner/outer balance moved by +σ_b and by -σ_b (weights ``w_in e^b``, ``w_out e^-b``,
normalised to eq. 8); half the difference of the two runs *relative to the measured
spot* (the filter pins that one) is taken as a 1-sigma.
"""

from __future__ import annotations

import numpy as np

from brakethermo.thermal.model import DiscFEModel
from brakethermo.thermal.power import crown_load


def crown_sd(weights: np.ndarray, base_sd: float) -> float:
    """1-sigma of the race's crown balance (log of the inner/outer weight ratio): the
    tuning's ``base_sd``, or half the law's own tilt where that is larger — a crown as
    uneven as a test session's pads made it may not be the race's, which may press
    anywhere from it to an even crown (an independent generator's law of 0.40 / 0.97 /
    1.52 on races with even pads: the unmeasured spots 46-102 degC off, their bands
    covering 1-53 %). 0 stays off."""
    w = np.asarray(weights, float)
    if not base_sd > 0.0 or not (np.all(np.isfinite(w)) and w[0] > 0.0 and w[-1] > 0.0):
        return base_sd
    return max(base_sd, 0.5 * abs(float(np.log(w[0] / w[-1]))))


def crown_balance_std(model: DiscFEModel, T0: np.ndarray, q: np.ndarray, h: np.ndarray,
                      t_amb: np.ndarray, H: np.ndarray, spot: int, sigma_b: float,
                      ) -> np.ndarray:
    """1-sigma of each readout that a crown balance unknown to ±``sigma_b`` leaves, degC.

    Parameters
    ----------
    model : DiscFEModel — the estimator's disc model (its crown weights are the law's).
    T0 : ndarray (n_state,) — degC, the initial node temperatures.
    q, h, t_amb : ndarray (K,) — W (scaled braking power), W/(m^2 K), degC per step.
    H : ndarray (m, n_state) — the readouts (the four spots, the contact band).
    spot : int — 1-based measured spot (its row of ``H``; its own term is zero).
    sigma_b : float — 1-sigma of the inner/outer balance, in log of the weights' ratio
        (0.2: the inner crown 22 % harder against the outer 18 % softer).

    Returns
    -------
    ndarray (K, m) — degC
    """
    K, m = q.size, H.shape[0]
    if not sigma_b > 0.0 or not np.all(np.isfinite(model.weights)):
        return np.zeros((K, m))
    w = np.asarray(model.weights, float)
    loads = np.stack([crown_load(model.radii, model.disc.crown_edges,
                                 w * np.array([np.exp(b), 1.0, np.exp(-b)]))
                      for b in (sigma_b, -sigma_b)])[None]
    runs = model.run_readout(np.tile(T0, (2, 1)), np.repeat(q[:-1, None], 2, axis=1),
                             np.repeat(h[:-1, None], 2, axis=1), t_amb[:-1],
                             np.full(2, model.kz_ratio),
                             loads, np.zeros(K - 1, dtype=np.int64), H)
    d = 0.5 * (runs[:, 0] - runs[:, 1])  # (K, m): one sigma of balance, either way
    return np.abs(d - d[:, spot - 1 : spot])  # the filter holds the measured spot
