"""The race's filter: the state space it runs on (full, or its leading POD modes), its
UKF, what it reports beside its state, and the forward pass with the smoother.

The estimate pipeline (:mod:`brakethermo.pipelines.estimate`) builds the disc model and
its state space for a decided h law and calls these; they know nothing of files.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np

from brakethermo.estimation import UnscentedKalmanFilter
from brakethermo.estimation.urts import urts_smooth_windowed
from brakethermo.models.disc import SCALE_PARAM, DiscStateSpace
from brakethermo.models.reduced import MAX_MODES, ReducedStateSpace, pod_modes, with_directions
from brakethermo.pipelines.inputs import DiscInputs
from brakethermo.pipelines.speculative import cancellable
from brakethermo.pipelines.tuning import EstimateTuning
from brakethermo.thermal.model import DiscFEModel
from brakethermo.thermal.power import crown_load

AUTO_REDUCE_ABOVE = 64  # temperature states beyond which the filter runs on modes
SNAPSHOTS = 2000  # open-loop steps per run the modes are taken from


def ukf_for(space: DiscStateSpace | ReducedStateSpace, tuning: EstimateTuning,
            spot_radius: float, cancel: threading.Event | None = None
            ) -> UnscentedKalmanFilter:
    """The UKF of ``space`` fed by the pyrometer at ``spot_radius`` (m); a run that stops
    at its next step once ``cancel`` is set."""
    f = space.f if cancel is None else cancellable(space.f, cancel)
    return UnscentedKalmanFilter(f, space.Q, np.array([[tuning.sigma_meas**2]]),
                                 H=space.H_measured(spot_radius), alpha=tuning.alpha,
                                 beta=tuning.beta, kappa=tuning.kappa)


def filter_space(ssm: DiscStateSpace, model: DiscFEModel, inputs: DiscInputs, h: np.ndarray,
                  power_scale: float, modes: int | None
                  ) -> tuple[DiscStateSpace | ReducedStateSpace, dict[str, Any]]:
    """The state space the filter runs on: the full one, or its reduced order
    (:mod:`brakethermo.models.reduced`) with the modes of the model's own open loop over
    this session at a spread of braking-power scales and h factors."""
    n_t = ssm.n_temp
    if modes == 0 or (modes is None and n_t <= AUTO_REDUCE_ABOVE):
        return ssm, {"kind": "full", "states": ssm.n}
    # (power scale, h factor, k_z factor, inner/outer crown tilt) of each open-loop run
    spread = np.array([(1.0, 1.0, 1.0, 0.0), (0.7, 1.0, 1.0, 0.0), (1.3, 1.0, 1.0, 0.0),
                       (1.0, 0.7, 1.0, 0.0), (1.0, 1.4, 1.0, 0.0), (1.0, 1.0, 0.5, 0.0),
                       (1.0, 1.0, 2.0, 0.0), (1.0, 1.0, 1.0, 0.5), (1.0, 1.0, 1.0, -0.5)])
    B, K = len(spread), inputs.q_brk.size - 1
    edges = model.disc.crown_edges
    loads = np.stack([crown_load(model.radii, edges, model.weights * [1 + b, 1.0, 1 - b])
                      for b in spread[:, 3]])
    runs = model.run_readout(
        np.tile(model.initial_state(float(inputs.t_amb[0])), (B, 1)),
        inputs.q_brk[:-1, None] * power_scale * spread[:, 0], h[:-1, None] * spread[:, 1],
        inputs.t_amb[:-1], model.kz_ratio * spread[:, 2], loads[None], np.zeros(K, int),
        np.eye(n_t))
    stride = max(1, K // SNAPSHOTS)
    Phi, error = pod_modes(runs[::stride].reshape(-1, n_t),
                           max_modes=min(modes or MAX_MODES, n_t))
    # and the directions the crown-split process noise pushes the field in: the filter's
    # corrections live there, the open loop never goes
    Phi = with_directions(Phi, ssm.crown_directions())
    reduced = ReducedStateSpace(ssm, Phi)
    return reduced, {
        "kind": "reduced", "modes": reduced.r, "states": reduced.n, "full_states": ssm.n,
        "snapshot_projection_rms_c": error,
        "approximation": "node temperatures on the leading POD modes of the model's own open"
                         " loop over this session (power scale 0.7-1.3, h x 0.7-1.4, k_z x"
                         " 0.5-2, crown tilt +-0.5); what the modes cannot hold is dropped"
                         " each step"}


def readout_rows(ssm: DiscStateSpace | ReducedStateSpace, spot_radii: np.ndarray,
             adapt_power: bool) -> np.ndarray:
    """What the filter reports beside its state: the four spots, the contact band (the
    mean of spots 2-4) and, when it is a state, the braking-power scale."""
    H_spots = ssm.H(spot_radii)
    readout = np.vstack([H_spots, H_spots[1:4].mean(axis=0, keepdims=True)])
    if adapt_power:
        readout = np.vstack([readout, ssm.selector(SCALE_PARAM)])
    return readout


def run_filter(ukf: UnscentedKalmanFilter, x0: np.ndarray, P0: np.ndarray, y: np.ndarray,
                readout: np.ndarray, smoother: bool, workers: int) -> tuple[Any, ...]:
    """Forward filter (and the smoother): the forward result, the states, the readout and
    its variance, the smoother's windows and the forward pass's seconds."""
    t0 = time.perf_counter()
    if smoother:
        # windows bound the gains' memory whatever the mesh and session length; the
        # answer is the whole-session smoother's (estimation.urts)
        run = urts_smooth_windowed(ukf, x0, P0, y[:, None], readout=readout, workers=workers)
        s = run.smoothed
        return (run.forward, s.x_smooth, s.readout, s.readout_var, len(run.windows),
                run.forward_s)
    forward = ukf.run(x0, P0, y[:, None], store="diag", readout=readout)
    return (forward, forward.x_filt, forward.readout, forward.readout_var, 1,
            time.perf_counter() - t0)
