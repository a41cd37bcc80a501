"""The race's filter: its disc model, how the h law's effects enter it (fixed or online
states), the state space it runs on (full, or its leading POD modes), its UKF, what it
reports beside its state, and the forward pass with the smoother.

The race's decided run (:mod:`brakethermo.pipelines.race_run`) decides the law and the
online effects and calls these; they know nothing of files.
"""

from __future__ import annotations

import hashlib
import threading
import time
from collections import OrderedDict
from concurrent.futures import Future
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from brakethermo.estimation import UnscentedKalmanFilter
from brakethermo.estimation.urts import urts_smooth_windowed
from brakethermo.models.disc import (
    BALANCE_MAX,
    BALANCE_PARAM,
    H_FACTOR_PARAM,
    KZ_PARAM,
    SCALE_PARAM,
    DiscEffects,
    DiscStateSpace,
    RandomWalkParam,
)
from brakethermo.models.reduced import MAX_MODES, ReducedStateSpace, pod_modes, with_directions
from brakethermo.pipelines.inputs import DiscInputs
from brakethermo.pipelines.speculative import cancellable, cancellable_steps
from brakethermo.pipelines.tuning import EstimateTuning
from brakethermo.thermal.disc import DiscSpec
from brakethermo.thermal.model import DiscFEModel
from brakethermo.thermal.power import crown_load

# Temperature states beyond which the filter runs on modes: the default 10 x 4 mesh and
# every finer one; the paper's 10 x 1 model (and a 10 x 2 one) stays full. On the 0.001
# degC basis (31 modes of 40 at the default mesh) a 25-lap race 3.3 -> 2.9 s in process
# and a race that switches k_z on (thin-skin 10 x 6 then) 12.7 -> 7.9 s, beside the full
# filter in the same session; on 30 development races (5 test effects x 3 race effects x
# 2 tracks) the same online decisions, dropped law parts and identify-h selections as the
# full filter, contact band within 0.01 of the single-spot baseline of it in every race
# (mean 0.452 against 0.452). A 0.003 degC basis (28 modes) changed one race's online
# decision (0.72 -> 0.45x) and another's result (0.85 -> 1.21x); a 14-mode one lost
# 0.03-0.07 on discs unlike the test session's.
AUTO_REDUCE_ABOVE = 24
SNAPSHOTS = 2000  # open-loop steps per run the modes are taken from
# The open loop the modes come from covers at most this many steps from the session's
# start (1200 s at the model's 10 Hz: about 10 laps of the Mugello-like track): a race
# repeats its laps, and the open loop of all 25 laps was the largest part of a long
# race's set-up (1.2 s of a k_z race's 15 x 6 filter); on two 25-lap races the estimate
# stayed within 0.004 degC RMS of the one on modes of every lap
SNAPSHOT_SPAN = 12000


def disc_model(
    disc: DiscSpec, tuning: EstimateTuning, weights: tuple[float, float, float] = (1.0, 1.0, 1.0),
    kz_ratio: float = 1.0,
) -> DiscFEModel:
    """The estimation model: radial nodes x graded through-thickness layers."""
    return DiscFEModel(disc, tuning.nodes, tuning.layers, weights=weights, kz_ratio=kz_ratio,
                       layer_growth=tuning.layer_growth)


@dataclass(frozen=True)
class EffectPlan:
    """How the fitted effects of an h law enter the race filter.

    Attributes
    ----------
    fixed : DiscEffects
        μ(T) and sensor lag at their test-session values.
    online : tuple of RandomWalkParam
        Effects one spot can follow: the slipstream h factor (off the brakes) and the
        through-thickness conductivity factor.
    emissivity_ratio : float or None
        ε_disc/ε_set of the pyrometer: readings are converted back to face
        temperatures before filtering.
    facts : dict
        What was done with each effect, for the run facts.
    """

    fixed: DiscEffects
    online: tuple[RandomWalkParam, ...]
    emissivity_ratio: float | None
    facts: dict[str, dict[str, Any]]


def effect_plan(effects: dict[str, dict[str, Any]], tuning: EstimateTuning) -> EffectPlan:
    """Turn ``[effects.<name>]`` tables and the tuning into fixed and online effects.

    The k_z factor and the slipstream h factor are online whenever the tuning says so
    (the default), the crown balance when asked for: they are what one spot can follow
    on a disc the test session never saw; an h law that carries the effect switches
    them on regardless.
    """
    facts: dict[str, dict[str, Any]] = {}
    fixed = DiscEffects()
    online: list[RandomWalkParam] = []
    ratio = None
    tables = dict(effects)
    if tuning.adapt_kz:
        tables.setdefault("thickness_gradient", {})
    if tuning.adapt_slipstream:
        tables.setdefault("slipstream", {})
    if tuning.adapt_balance:
        tables.setdefault("power_distribution", {})
    for name, values in tables.items():
        use = "fixed at the test-session value"
        if name == "friction_temperature":
            fixed = replace(fixed, mu_beta=values.get("beta", 0.0),
                            mu_t_mid_c=values.get("t_mid", 400.0))
        elif name == "sensor_lag":
            fixed = replace(fixed, sensor_tau_s=values.get("tau_s", 0.0))
        elif name == "emissivity_error":
            ratio = values.get("ratio", 1.0)
            use = ("readings corrected with the test-session value; a single pyrometer cannot"
                   " tell its own bias from the disc, so this correction is all there is")
        elif name == "slipstream":
            online.append(RandomWalkParam(H_FACTOR_PARAM, 1.0, tuning.init_sigma_h_factor,
                                          tuning.sigma_h_factor_step, lower=0.3,
                                          off_brake_only=True))
            use = "adapted online: an h factor that moves off the brakes"
        elif name == "thickness_gradient":
            online.append(RandomWalkParam(KZ_PARAM, 1.0, tuning.init_sigma_kz,
                                          tuning.sigma_kz_step, lower=0.05))
            use = ("test-session value, adapted online (a race disc's k_z differs from batch"
                   " to batch)")
        elif name == "power_distribution" and not tuning.adapt_balance:
            use = "in the crown weights of the file"
        elif name == "power_distribution":
            online.append(RandomWalkParam(BALANCE_PARAM, 0.0, tuning.init_sigma_balance,
                                          tuning.sigma_balance_step, lower=-BALANCE_MAX))
            use = ("crown weights of the file, their inner/outer balance adapted online (one"
                   " spot cannot tell it from a k_z change)")
        elif name == "h_speed_knee":
            use = "in the h law of the file"
        facts[name] = {"values": values, "use": use}
    return EffectPlan(fixed, tuple(online), ratio, facts)


def build_state_space(
    model: DiscFEModel, inputs: DiscInputs, h: np.ndarray, tuning: EstimateTuning,
    power_scale: float = 1.0, plan: EffectPlan | None = None, spot_radius: float | None = None,
) -> DiscStateSpace:
    """The estimate filter's state space: nodes (+ braking-power scale, + effects)."""
    params = []
    if tuning.adapt_power:
        scale = RandomWalkParam(
            SCALE_PARAM, power_scale, tuning.init_sigma_scale, tuning.sigma_scale_step,
            lower=0.05,
        )
        params.append(scale)
    plan = plan or effect_plan({}, tuning)
    params.extend(plan.online)
    return DiscStateSpace(
        model, inputs.q_brk, inputs.t_amb, h, params,
        sigma_temp=tuning.sigma_temp, sigma_crown=tuning.sigma_crown,
        effects=plan.fixed, spot_radius=spot_radius,
    )  # fmt: skip


def ukf_for(space: DiscStateSpace | ReducedStateSpace, tuning: EstimateTuning,
            spot_radius: float, cancel: threading.Event | None = None
            ) -> UnscentedKalmanFilter:
    """The UKF of ``space`` fed by the pyrometer at ``spot_radius`` (m); a run that stops
    at its next step (its next compiled span of steps) once ``cancel`` is set."""
    f = space.f if cancel is None else cancellable(space.f, cancel)
    steps = space.compiled_steps()
    if cancel is not None:
        steps = cancellable_steps(steps, cancel)
    return UnscentedKalmanFilter(f, space.Q, np.array([[tuning.sigma_meas**2]]),
                                 H=space.H_measured(spot_radius), alpha=tuning.alpha,
                                 beta=tuning.beta, kappa=tuning.kappa, steps=steps)


def filter_space(ssm: DiscStateSpace, model: DiscFEModel, inputs: DiscInputs, h: np.ndarray,
                  power_scale: float, modes: int | None
                  ) -> tuple[DiscStateSpace | ReducedStateSpace, dict[str, Any]]:
    """The state space the filter runs on: the full one, or its reduced order
    (:mod:`brakethermo.models.reduced`) with the modes of the model's own open loop over
    the session's first laps at a spread of braking-power scales and h factors."""
    count = _mode_count(ssm.n_temp, modes)
    if count is None:
        return ssm, {"kind": "full", "states": ssm.n}
    Phi, error = session_modes(model, inputs, h, power_scale, count)
    span = min(inputs.q_brk.size - 1, SNAPSHOT_SPAN)
    # and the directions the crown-split process noise pushes the field in: the filter's
    # corrections live there, the open loop never goes
    n_pod = Phi.shape[1]
    Phi = with_directions(Phi, ssm.crown_directions())
    reduced = ReducedStateSpace(ssm, Phi)
    return reduced, {
        "kind": "reduced", "modes": reduced.r, "states": reduced.n, "full_states": ssm.n,
        "snapshot_projection_rms_c": error,
        "approximation": "node temperatures on the leading POD modes of the model's own open"
                         f" loop over the session's first {span} steps (power scale 0.7-1.3,"
                         " h x 0.7-1.4, k_z x 0.5-2, crown tilt +-0.5), at most"
                         f" {MAX_MODES}, and the directions the crown-split noise pushes"
                         f" the field in ({reduced.r - n_pod} here); what the modes cannot"
                         " hold is dropped each step"}


def _mode_count(n_temp: int, modes: int | None) -> int | None:
    """At most how many modes the filter on ``n_temp`` temperature states takes (None:
    it runs on the full state), given the ``modes`` option (None: automatic, 0: full)."""
    if modes == 0 or (modes is None and n_temp <= AUTO_REDUCE_ABOVE):
        return None
    return min(modes or MAX_MODES, n_temp)


def warm_modes(model: DiscFEModel, inputs: DiscInputs, h: np.ndarray, power_scale: float,
               modes: int | None) -> None:
    """Compute now the modes :func:`filter_space` would take for ``model`` (arguments as
    there), kept by :func:`session_modes` for the filter that will ask for them."""
    count = _mode_count(model.n_state, modes)
    if count is not None:
        session_modes(model, inputs, h, power_scale, count)


# Modes computed, or being computed, per (model, session, law): the race's decision runs
# its filter variants on the same laps side by side, and most share the model. A race
# asks for at most 3 distinct sets (the law's, the law without its crown, the race's
# final mesh); 8 keep a batch worker's last few races without growing.
_MODES: OrderedDict[str, Future[tuple[np.ndarray, float]]] = OrderedDict()
_MODES_LOCK = threading.Lock()
MODES_KEPT = 8


def session_modes(model: DiscFEModel, inputs: DiscInputs, h: np.ndarray, power_scale: float,
                  max_modes: int) -> tuple[np.ndarray, float]:
    """:func:`open_loop_modes` over the session's first :data:`SNAPSHOT_SPAN` steps,
    computed once per model, inputs, h and power scale and shared: a variant that asks
    while another computes the same waits for its answer (the decision's variants of one
    model, open loops of 8 laps on one core, ran it each).

    Parameters
    ----------
    model : DiscFEModel
    inputs : DiscInputs
    h : ndarray (K,) — W/(m^2 K), the law's h on the session's grid
    power_scale : float — the law's braking-power scale
    max_modes : int — at most this many modes

    Returns
    -------
    Phi : ndarray (n_state, r) — orthonormal modes, read-only (shared between callers).
    error_c : float — degC, RMS projection error of the snapshots.
    """
    K = min(inputs.q_brk.size - 1, SNAPSHOT_SPAN)
    digest = hashlib.blake2b(digest_size=16)
    digest.update(repr((model.fingerprint(), power_scale, max_modes, K)).encode())
    for a in (inputs.q_brk[:K], inputs.t_amb[:K], h[:K]):
        digest.update(np.ascontiguousarray(a, dtype=float).tobytes())
    key = digest.hexdigest()
    mine: Future[tuple[np.ndarray, float]] = Future()
    with _MODES_LOCK:
        known = _MODES.get(key)
        if known is None:
            _MODES[key] = mine
            while len(_MODES) > MODES_KEPT:
                _MODES.popitem(last=False)
        else:
            _MODES.move_to_end(key)
    if known is not None:
        return known.result()
    try:
        Phi, error = open_loop_modes(model, inputs, h, power_scale, max_modes, K)
        Phi.setflags(write=False)
    except BaseException as err:  # Ctrl-C too: a waiter must never wait for ever
        with _MODES_LOCK:
            if _MODES.get(key) is mine:
                del _MODES[key]
        mine.set_exception(err)
        raise
    mine.set_result((Phi, error))
    return Phi, error


def forget_modes() -> None:
    """Empty the modes :func:`session_modes` keeps (a benchmark timing cold runs)."""
    with _MODES_LOCK:
        _MODES.clear()


def open_loop_modes(model: DiscFEModel, inputs: DiscInputs, h: np.ndarray,
                    power_scale: float, max_modes: int, K: int) -> tuple[np.ndarray, float]:
    """The leading POD modes (:func:`~brakethermo.models.reduced.pod_modes`) of the
    model's open loop through the session's first ``K`` steps, at a spread of power
    scales, h factors, k_z factors and crown tilts (arguments as :func:`session_modes`;
    ``K`` in steps)."""
    # (power scale, h factor, k_z factor, inner/outer crown tilt) of each open-loop run
    spread = np.array([(1.0, 1.0, 1.0, 0.0), (0.7, 1.0, 1.0, 0.0), (1.3, 1.0, 1.0, 0.0),
                       (1.0, 0.7, 1.0, 0.0), (1.0, 1.4, 1.0, 0.0), (1.0, 1.0, 0.5, 0.0),
                       (1.0, 1.0, 2.0, 0.0), (1.0, 1.0, 1.0, 0.5), (1.0, 1.0, 1.0, -0.5)])
    edges = model.disc.crown_edges
    loads = np.stack([crown_load(model.radii, edges, model.weights * [1 + b, 1.0, 1 - b])
                      for b in spread[:, 3]])
    n_t = model.n_state
    runs = model.run_readout(
        np.tile(model.initial_state(float(inputs.t_amb[0])), (len(spread), 1)),
        inputs.q_brk[:K, None] * power_scale * spread[:, 0], h[:K, None] * spread[:, 1],
        inputs.t_amb[:K], model.kz_ratio * spread[:, 2], loads[None], np.zeros(K, int),
        np.eye(n_t))
    stride = max(1, K // SNAPSHOTS)
    return pod_modes(runs[::stride].reshape(-1, n_t), max_modes=max_modes)


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
                readout: np.ndarray, smoother: bool, workers: int,
                more: np.ndarray | None = None) -> tuple[Any, ...]:
    """Forward filter (and the smoother): the forward result, the states, the readout and
    its variance (with the rows of ``more`` last: computed in the smoother's pass only
    when it runs, else by the filter), the smoother's windows and the forward pass's
    seconds."""
    t0 = time.perf_counter()
    if smoother:
        # windows bound the gains' memory whatever the mesh and session length; the
        # answer is the whole-session smoother's (estimation.urts)
        run = urts_smooth_windowed(ukf, x0, P0, y[:, None], readout=readout,
                                   smooth_readout=more, workers=workers)
        s = run.smoothed
        return (run.forward, s.x_smooth, s.readout, s.readout_var, len(run.windows),
                run.forward_s)
    rows = readout if more is None else np.vstack([readout, more])
    forward = ukf.run(x0, P0, y[:, None], store="diag", readout=rows)
    return (forward, forward.x_filt, forward.readout, forward.readout_var, 1,
            time.perf_counter() - t0)
