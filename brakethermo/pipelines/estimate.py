"""``estimate``: disc temperature at every radius from one IR spot (paper §4.2, §5.2–5.3).

State = node temperatures of the layered 1D-FE model (+ the braking-power scale as a
random walk); one spot measured; h from the identified law; an unscented RTS smoother
on top of the UKF, since the work is offline. On a multi-spot session the unmeasured
spots validate the estimate (the paper's Tables 3 and 4).
"""

from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from brakethermo import __version__
from brakethermo.errors import ConfigError, DataError
from brakethermo.io.plausibility import SENSOR_FLOOR_C  # one floor for every command
from brakethermo.io.session import Session
from brakethermo.models.disc import (
    DiscStateSpace,
)
from brakethermo.models.effects import true_from_reading
from brakethermo.models.reduced import (
    MAX_MODES,
    ReducedStateSpace,
)
from brakethermo.pipelines import scoring
from brakethermo.pipelines.checks import check_estimate_result, check_power_scale
from brakethermo.pipelines.crown_band import crown_balance_std
from brakethermo.pipelines.inputs import DiscInputs, disc_inputs, load_timed
from brakethermo.pipelines.models import (
    DiscCalibration,
    calibration_for,
    disc_for,
    other_disc,
)
from brakethermo.pipelines.online_choice import (
    DECISION_LAPS,
    ONLINE_FLAGS,
    OnlineChoice,
    choose_online,
    droppable,
    law_without,
)
from brakethermo.pipelines.outputs import write_json, write_parquet
from brakethermo.pipelines.race_filter import (
    EffectPlan,
    build_state_space,
    disc_model,
    effect_plan,
    filter_space,
    readout_rows,
    run_filter,
    ukf_for,
)
from brakethermo.pipelines.speculative import Speculation
from brakethermo.pipelines.tuning import (
    EstimateTuning,
    TuningSource,
    check_overrides,
    load_tuning,
    read_tuning,
    user_tuning_keys,
)
from brakethermo.report.braking_zones import detect_zones
from brakethermo.results.laps import lap_summaries
from brakethermo.thermal.disc import DiscSpec
from brakethermo.thermal.model import DiscFEModel

SIGMA_MEAS_FLOOR_C = 0.5  # degC: never trust a reading beyond its quantisation


@dataclass(frozen=True)
class EstimateOptions:
    """What the user chose on the command line; ``None`` means the tuning file's value.

    Attributes
    ----------
    spot : int
        Spot (1..4) used as the filter's measurement; 3 is the race sensor.
    h_law : path or DiscCalibration, optional
        ``h_law.toml`` from identify-h (or that file as a command already read it);
        default: the law shipped for the disc.
    disc : str or path, optional
        Datasheet id or file; default: the session's ``disc`` fact, else cc-340-8.
    tuning : path or TuningFiles, optional
        Filter tuning TOML overlaid on ``configs/tuning.toml`` (or those files as a
        command already read them, :func:`~brakethermo.pipelines.tuning.read_tuning`).
    nodes, layers : int, optional
    smoother, adapt_power : bool, optional
    sigma_crown : float, optional
        Crown-split process noise (identify-h's validation sets it per variant).
    adapt_kz, adapt_slipstream, adapt_balance : bool, optional
        Online k_z factor, slipstream h factor and inner/outer crown balance (diagnose
        compares with and without).
    aliases : path, optional
    ambient_c : float, optional — degC
    score : bool
        Score against the unmeasured spots when the session has them.
    workers : int
        Threads re-running smoother windows in parallel (a fine mesh's smoother runs in
        windows to bound its memory; see ``estimation.urts``).
    online_auto : bool
        Let the race decide the online effects whose flag is neither given here nor set
        in the user's tuning file (:mod:`brakethermo.pipelines.online_choice`).
    modes : int, optional
        Reduced-order filter (:mod:`brakethermo.models.reduced`): at most this many
        thermal modes; 0 runs the full-order filter; ``None`` reduces a model of more
        than :data:`AUTO_REDUCE_ABOVE` temperature states and keeps a smaller one full.
    """

    spot: int = 3
    h_law: str | Path | DiscCalibration | None = None
    disc: str | Path | None = None
    tuning: TuningSource = None
    nodes: int | None = None
    layers: int | None = None
    smoother: bool | None = None
    adapt_power: bool | None = None
    sigma_crown: float | None = None
    adapt_kz: bool | None = None
    adapt_slipstream: bool | None = None
    adapt_balance: bool | None = None
    aliases: str | Path | None = None
    ambient_c: float | None = None
    score: bool = True
    workers: int = 1
    online_auto: bool = True
    modes: int | None = None

    def __post_init__(self) -> None:
        check_overrides(self.overrides())
        if self.modes is not None and not 0 <= self.modes <= MAX_MODES:
            raise ConfigError(f"--modes {self.modes}: give 0 (the full filter) or 1 to"
                              f" {MAX_MODES} thermal modes")
        if self.ambient_c is not None and not -60.0 <= self.ambient_c <= 80.0:
            raise ConfigError(
                f"ambient temperature {self.ambient_c} degC must be a finite value between"
                " -60 and 80 degC"
            )

    def overrides(self) -> dict[str, Any]:
        """The tuning values this run sets explicitly."""
        return {
            k: v
            for k, v in (
                ("nodes", self.nodes),
                ("layers", self.layers),
                ("smoother", self.smoother),
                ("adapt_power", self.adapt_power),
                ("sigma_crown", self.sigma_crown),
                ("adapt_kz", self.adapt_kz),
                ("adapt_slipstream", self.adapt_slipstream),
                ("adapt_balance", self.adapt_balance),
            )
            if v is not None
        }


@dataclass
class EstimateResult:
    """Everything ``estimate`` computed for one session.

    Attributes
    ----------
    session : Session
    frame : pandas.DataFrame
        The OUTPUTS.md ``estimate.parquet`` table.
    node_radii : ndarray — m
    summary : dict
        The ``summary.json`` content.
    scores : dict or None
        Tables 3/4, peak errors and coverage on a multi-spot session.
    open_loop : ndarray (K, 4) or None — degC
        The open-loop 1D-FE spot temperatures (for scoring and reports).
    disc : DiscSpec
        The datasheet the estimate was computed with.
    timings : dict of str to float — s
    innovation, innovation_var : ndarray (K,) or None — degC, degC²
        The filter's one-step-ahead innovation of the measured spot and its variance
        (NaN where nothing was measured): what diagnose reads on a single-spot session.
    spread : ndarray (K, 4) or None — degC
        The filter's (smoother's) own 1-sigma at spot1..4, without the pyrometer
        calibration term of the reported band: what readings of the same sensor, which
        share that calibration error, are compared with.
    states : ndarray (K, n) or None
        The smoothed (or filtered) full state: every node of every layer, then the
        online parameters; what ``whatif`` replays.
    state_space : DiscStateSpace or None
        The filter's state space, whose transition the states follow.
    y_measured : ndarray (K,) or None — degC
        The measured spot's readings as the filter used them (NaN at the sensor floor,
        emissivity-corrected when the law says so).
    spot_radius : float or None — m
        Radius of the measured spot.
    """

    session: Session
    frame: pd.DataFrame
    node_radii: np.ndarray
    summary: dict[str, Any]
    scores: dict[str, Any] | None
    open_loop: np.ndarray | None
    disc: DiscSpec
    timings: dict[str, float] = field(default_factory=dict)
    innovation: np.ndarray | None = None
    innovation_var: np.ndarray | None = None
    spread: np.ndarray | None = None
    states: np.ndarray | None = None
    state_space: DiscStateSpace | None = None
    y_measured: np.ndarray | None = None
    spot_radius: float | None = None

    @property
    def stem(self) -> str:
        return self.session.path.stem


def _measurement(inputs: DiscInputs, spot: int, path: Path) -> np.ndarray:
    if spot not in (1, 2, 3, 4):
        raise DataError(f"--spot must be 1..4, got {spot}", path=path)
    if spot not in inputs.measured:
        have = ", ".join(f"spot {s}" for s in inputs.measured)
        raise DataError(
            f"cannot measure spot {spot}: the session logs {have}; choose --spot from those",
            path=path,
        )
    y = inputs.spots[:, spot - 1].copy()
    y[y <= SENSOR_FLOOR_C] = np.nan  # at the pyrometer floor the reading is no information
    if not np.isfinite(y).any():
        raise DataError(
            f"spot {spot} has no reading above the sensor floor ({SENSOR_FLOOR_C:.0f} degC)",
            path=path,
        )
    return y


def _initial_temperature(y: np.ndarray, t_amb: np.ndarray) -> float:
    """First temperature: the first valid reading if it comes in the first 5 s, else ambient."""
    first = np.flatnonzero(np.isfinite(y))
    if first.size and first[0] < 50:
        return max(float(y[first[0]]), float(t_amb[0]))  # never colder than the air
    return float(t_amb[0])


def calibrated_tuning(cal: DiscCalibration, options: EstimateOptions) -> EstimateTuning:
    """The tuning of a run: shipped values < calibration < the user's file < options.

    What identify-h calibrated (crown-split noise, power adaptation, layering) replaces
    the shipped values key by key, unless the user's ``--tuning`` file sets that key;
    command-line options win over everything.
    """
    tuning, _ = load_tuning(options.tuning)
    user = user_tuning_keys(options.tuning, "estimate")
    calibrated: dict[str, Any] = {"sigma_crown": cal.sigma_crown, "adapt_power": cal.adapt_power,
                                  "sigma_temp": cal.sigma_temp}
    if cal.layers is not None and "layers" not in user:
        calibrated["layers"] = cal.layers
        calibrated["layer_growth"] = cal.layer_growth
    tuning = replace(tuning, **{k: v for k, v in calibrated.items()
                                if v is not None and k not in user})
    return replace(tuning, **options.overrides())


def _choice_inputs(options: EstimateOptions, cal: DiscCalibration,
                   calibration: DiscCalibration | None
                   ) -> tuple[tuple[str, ...], tuple[str, ...]] | None:
    """The online effects the race chooses and the law's parts it may drop (None:
    nothing to choose).

    An effect the h law carries is on whatever the race says (identify-h found it on the
    test session); a flag given as an option or in the user's tuning file is forced.
    """
    if not options.online_auto or calibration is not None:
        return None  # identify-h's own validation runs choose their variants themselves
    user = user_tuning_keys(options.tuning, "estimate")
    given = options.overrides()
    candidates = tuple(name for name, flag in ONLINE_FLAGS.items()
                       if flag not in given and flag not in user and name not in cal.effects)
    parts = droppable(cal)
    return (candidates, parts) if candidates or parts else None


def _online_choice(session: Session, options: EstimateOptions, cal: DiscCalibration,
                   tuning: EstimateTuning,
                   chooses: tuple[tuple[str, ...], tuple[str, ...]]) -> OnlineChoice:
    """The race's own choice of the online effects nobody forced (:func:`_choice_inputs`)."""
    candidates, parts = chooses
    choice = choose_online(session, options, candidates, cal, parts)
    forced = {flag: getattr(tuning, flag) for name, flag in ONLINE_FLAGS.items()
              if name not in candidates}
    return OnlineChoice(choice.flags, {**choice.facts, "forced_or_from_law": forced},
                        choice.dropped)


def _race_layering(choice: OnlineChoice, tuning: EstimateTuning, options: EstimateOptions
                   ) -> tuple[EstimateTuning, str | None]:
    """identify-h's thin-skin layering for a race whose disc conducts through the thickness
    worse than the law's (the race chose k_z and learned it lower): heat stays nearer the
    face, and the law's layering, built for its own disc, is too coarse to hold the skin.
    Returns the tuning and what was changed, in words (None: nothing)."""
    row = next((r for r in choice.facts.get("scores", [])
                if r.get("name") == "thickness_gradient"), None)
    user = user_tuning_keys(options.tuning, "estimate")
    if (row is None or "thickness_gradient" not in choice.facts.get("chosen", [])
            or not row.get("learned", 1.0) < 1.0 or options.layers is not None
            or "layers" in user or tuning.layers >= tuning.thin_skin_layers):
        return tuning, None
    said = (f"{tuning.thin_skin_layers} layers (growth {tuning.thin_skin_layer_growth:g})"
            f" instead of the law's {tuning.layers}: the race's k_z came out"
            f" {row['learned']:.2f} of the law's, a thinner thermal skin")
    return replace(tuning, layers=tuning.thin_skin_layers,
                   layer_growth=tuning.thin_skin_layer_growth), said


@dataclass(frozen=True)
class _Run:
    """The race's model, state space and filter (and smoother) pass on a decided law."""

    cal: DiscCalibration
    tuning: EstimateTuning
    y: np.ndarray  # degC, the readings as filtered (emissivity-corrected where the law says)
    h: np.ndarray
    model: DiscFEModel
    plan: EffectPlan
    ssm: DiscStateSpace
    order: dict[str, Any]
    sigma_meas_source: str
    x0: np.ndarray
    forward: Any
    states: np.ndarray
    out: np.ndarray
    out_var: np.ndarray
    windows: int
    filter_s: float
    smoother_s: float
    speculative: bool = False


def _filtered(disc: DiscSpec, inputs: DiscInputs, y: np.ndarray, cal: DiscCalibration,
              tuning: EstimateTuning, options: EstimateOptions,
              cancel: threading.Event | None = None) -> _Run:
    """Build the race's filter for ``cal`` and ``tuning`` and run it (and the smoother)."""
    h = cal.law(inputs.speed)
    model = disc_model(disc, tuning, cal.weights, cal.kz_ratio)
    spot_radius = float(disc.spot_radii[options.spot - 1])
    plan = effect_plan(cal.effects, tuning)
    if plan.emissivity_ratio is not None:
        y = true_from_reading(y, plan.emissivity_ratio)
    tuning, sigma_meas_source = _reading_noise(y, tuning, options)
    ssm = build_state_space(model, inputs, h, tuning, cal.power_scale, plan, spot_radius)
    filt, order = filter_space(ssm, model, inputs, h, cal.power_scale, options.modes)
    readout = readout_rows(filt, np.asarray(disc.spot_radii), tuning.adapt_power)
    x0, P0 = filt.prior(model.initial_state(_initial_temperature(y, inputs.t_amb)),
                        tuning.init_sigma_temp)
    ukf = ukf_for(filt, tuning, spot_radius, cancel)
    t0 = time.perf_counter()
    forward, states, out, out_var, windows, forward_s = run_filter(
        ukf, x0, P0, y, readout, tuning.smoother, options.workers)
    if isinstance(filt, ReducedStateSpace):
        states, x0 = filt.lift(states), filt.lift(x0)  # the full model's nodes, everywhere
    return _Run(cal, tuning, y, h, model, plan, ssm, order, sigma_meas_source, x0, forward,
                states, out, out_var, windows, forward_s,
                time.perf_counter() - t0 - forward_s)


def _decided_run(session: Session, options: EstimateOptions, disc: DiscSpec,
                 inputs: DiscInputs, y: np.ndarray, cal: DiscCalibration,
                 tuning: EstimateTuning, calibration: DiscCalibration | None
                 ) -> tuple[OnlineChoice | None, _Run, float]:
    """The race's online decision and the filter run on what it decided, and when the
    decision ended. On a race longer than the decision's laps, the run for "nothing
    switched on, nothing dropped" starts before the decision on its own thread
    (:mod:`brakethermo.pipelines.speculative`): a 25-lap race that decides so, 8.3 → 6.3–7 s
    in process; one that switches k_z on waits for a decision on one core less."""
    chooses = _choice_inputs(options, cal, calibration)
    guess = null = None
    # a race no longer than the decision's laps has a filter pass as short as one of the
    # decision's: nothing to win there, and the decision would lose a core
    # (and on one core the guess would only queue the decision behind it)
    if (chooses is not None and sum(lap.lap >= 1 for lap in session.laps) > DECISION_LAPS
            and (os.cpu_count() or 1) > 1):
        null = replace(tuning, **{ONLINE_FLAGS[c]: False for c in chooses[0]})
        guess = Speculation(partial(_filtered, disc, inputs, y, cal, null, options))
    try:
        choice = None if chooses is None else _online_choice(session, options, cal, tuning,
                                                             chooses)
    except BaseException:  # a bad session or Ctrl-C: the guess stops with the decision
        if guess is not None:
            guess.abandon()
        raise
    if choice is not None:
        tuning, layering = _race_layering(choice, replace(tuning, **choice.flags), options)
        if layering:
            choice = replace(choice, facts={**choice.facts, "layering": layering})
        for name in choice.dropped:
            cal = law_without(cal, name)
    t_choice = time.perf_counter()
    if guess is not None and choice is not None and tuning == null and not choice.dropped:
        return choice, replace(guess.result(), speculative=True), t_choice
    if guess is not None:
        guess.abandon()
    return choice, _filtered(disc, inputs, y, cal, tuning, options), t_choice


def estimate_from_session(
    session: Session, options: EstimateOptions, calibration: DiscCalibration | None = None
) -> EstimateResult:
    """Run the estimator on a loaded session (see :func:`estimate_session`).

    ``calibration`` replaces the ``h_law.toml`` of ``options`` (identify-h uses it to
    calibrate the bands on its own session).
    """
    t_start = time.perf_counter()
    options = replace(options, tuning=read_tuning(options.tuning))  # once for every pass
    disc = disc_for(session, options.disc)
    inputs = disc_inputs(session, disc, options.ambient_c)
    y = _measurement(inputs, options.spot, session.path)
    cal = calibration or calibration_for(disc, options.h_law)
    tuning = calibrated_tuning(cal, options)
    warnings = [*session.warnings, *inputs.warnings, *_law_warnings(cal, disc, tuning)]
    choice, run, t_choice = _decided_run(session, options, disc, inputs, y, cal, tuning,
                                         calibration)
    cal, tuning, model, x0, forward = run.cal, run.tuning, run.model, run.x0, run.forward
    out, h, spot_radii = run.out, run.h, np.asarray(disc.spot_radii)
    t_done = time.perf_counter()

    std = np.sqrt(np.maximum(run.out_var, 0.0))
    warnings.extend(check_estimate_result(out[:, :5], forward.nis))
    online = {p.name: run.ssm.index[p.name] for p in run.plan.online}
    band = _reported_band(out, std, tuning, model, x0[: model.n_state],
                          inputs.q_brk * cal.power_scale, h, inputs.t_amb, spot_radii,
                          options.spot)
    frame = _estimate_frame(inputs, model, run.states, out, band, tuning, h, online)
    if "power_scale" in frame:
        warnings.extend(check_power_scale(frame["power_scale"].to_numpy(), inputs.q_brk > 0))
    open_loop = scores = None
    if options.score and len(inputs.measured) > 1:
        open_loop, scores = _self_scores(session, inputs, model, cal, x0, h, frame, std,
                                         forward.readout, spot_radii, options.spot,
                                         tuning.smoother)
    t_end = time.perf_counter()
    timings = dict(zip(("setup_s", "filter_s", "smoother_s", "scoring_s", "total_s"),
                       (t_choice - t_start, run.filter_s, run.smoother_s, t_end - t_done,
                        t_end - t_start), strict=True))
    timings["overlapped"] = run.speculative  # the filter ran while the race decided
    mean_nis = float(np.nanmean(forward.nis))
    summary = {
        "session": str(session.path),
        "metadata": session.metadata,
        "laps": lap_summaries(frame, session.laps, disc.window_c, model.radii),
        "run": {
            "brakethermo": __version__,
            "disc": disc.id,
            "window_c": list(disc.window_c),
            **_model_facts(cal, tuning, model),
            "sigma_meas_source": run.sigma_meas_source,
            "smoother_windows": run.windows,
            "filter_order": run.order,
            "workers": options.workers,
            "measured_spot": options.spot,
            "effects": run.plan.facts,
            "online_choice": choice.facts if choice is not None else {
                "rule": "every online effect set by the options or the tuning file"},
            "steps": len(frame),
            "covariance_repairs": forward.n_repairs,
            "log_likelihood": forward.log_likelihood,
            "mean_nis": mean_nis,
            "wall_time_s": timings["total_s"],
            "timings_s": timings,
            "warnings": warnings,
        },
        "scores": scores,
    }
    return EstimateResult(session, frame, model.radii.copy(), summary, scores, open_loop, disc,
                          timings, forward.innovation[:, 0], forward.innovation_var[:, 0],
                          std[:, :4], run.states, run.ssm, run.y,
                          float(spot_radii[options.spot - 1]))


def _reading_noise(y: np.ndarray, tuning: EstimateTuning, options: EstimateOptions
                   ) -> tuple[EstimateTuning, str]:
    """The reading noise of this very sensor, from the signal itself, unless the user's
    tuning file sets it: a fixed guess either starves the filter of the measurement or
    trusts it too much."""
    if "sigma_meas" in user_tuning_keys(options.tuning, "estimate"):
        return tuning, "tuning file"
    noise = max(scoring.reading_noise(y), SIGMA_MEAS_FLOOR_C)
    return (replace(tuning, sigma_meas=noise),
            "measured from the signal (second differences)")


def _model_facts(cal: DiscCalibration, tuning: EstimateTuning, model: DiscFEModel
                 ) -> dict[str, Any]:
    """The run facts of the law, the mesh and the filter settings."""
    return {
        "h_law": cal.source,
        "nodes": tuning.nodes,
        "layers": tuning.layers,
        "layer_growth": tuning.layer_growth,
        "sigma_crown": tuning.sigma_crown,
        "sigma_temp": tuning.sigma_temp,
        "kz_ratio": cal.kz_ratio,
        "power_scale_prior": cal.power_scale,
        "band_scale_check": cal.band_scale,
        "sigma_meas_c": tuning.sigma_meas,
        "ir_calibration_pct": tuning.ir_calibration_pct,
        "crown_balance_sd": tuning.crown_balance_sd,
        "crown_weights": [float(w) for w in model.weights],
        "filter": "UKF (Merwe scaled sigma points)",
        "smoother": tuning.smoother,
        "adapt_power": tuning.adapt_power,
    }


def _self_scores(session: Session, inputs: DiscInputs, model: DiscFEModel,
                 cal: DiscCalibration, x0: np.ndarray, h: np.ndarray, frame: pd.DataFrame,
                 std: np.ndarray, readout: np.ndarray, spot_radii: np.ndarray, spot: int,
                 smoother: bool) -> tuple[np.ndarray, dict[str, Any]]:
    """A multi-spot session scores its estimate at the spots it did not feed the filter:
    the open-loop 1D-FE baseline, Tables 3/4, peaks and coverage, and whether that is in
    sample (the law identified on this very session)."""
    T_ol = model.open_loop(x0[: model.n_state], inputs.q_brk[:-1], h[:-1], inputs.t_amb[:-1],
                           scale=cal.power_scale)
    open_loop = T_ol @ model.spot_matrix(spot_radii).T
    scores = score_estimate(frame, std[:, :4], readout[:, :4], open_loop, inputs, spot,
                            smoother, zones=detect_zones(inputs.time,
                                                         session.values("brake_pressure_front")))
    in_sample = (cal.identified_on is not None
                 and Path(cal.identified_on).name == session.path.name)
    scores["in_sample"] = in_sample
    scores["reference"] = (
        "measured spots — in sample: the h law, crown weights and k_z were identified on"
        " these spots of this very session; score a session the law did not see for a"
        " held-out figure" if in_sample else
        "measured spots (the law was identified on another session: held out)")
    return open_loop, scores


def band_std(out: np.ndarray, std: np.ndarray, tuning: EstimateTuning) -> np.ndarray:
    """1-sigma of the true disc temperature: the filter's spread and the pyrometer's calibration.

    Every reading shares one calibration error (the carbon face's emissivity is known to a
    few hundredths and drifts with glazing and oxidation), so the filter, fed by that one
    sensor, cannot see it; the reported band adds it in quadrature to the spot and
    contact-band readouts, in % of the absolute temperature because an emissivity error
    scales the radiance temperature.

    Parameters
    ----------
    out : ndarray (K, m) — degC
        Readouts; the first five are spot1..4 and the contact-band average.
    std : ndarray (K, m) — degC or the readout's unit
        The filter's (or smoother's) 1-sigma of each readout.
    tuning : EstimateTuning
        ``ir_calibration_pct``, 1-sigma in % of the absolute temperature.
    """
    band = std.copy()
    calib = 0.01 * tuning.ir_calibration_pct * (out[:, :5] + 273.15)
    band[:, :5] = np.hypot(std[:, :5], calib)
    return band


def _law_warnings(cal: DiscCalibration, disc: DiscSpec, tuning: EstimateTuning) -> list[str]:
    """What the h law was made for that this run is not: another disc, another layering."""
    warnings = [w for w in (other_disc(cal, disc),) if w]
    if cal.layers is not None and tuning.layers != cal.layers:
        warnings.append(
            f"the model runs {tuning.layers} layers but the h law's k_z ratio was fitted for"
            f" {cal.layers}; re-run identify-h with the same layering for best accuracy"
        )
    return warnings


def _reported_band(out: np.ndarray, std: np.ndarray, tuning: EstimateTuning,
                   model: DiscFEModel, T0: np.ndarray, q: np.ndarray, h: np.ndarray,
                   t_amb: np.ndarray, spot_radii: np.ndarray, spot: int) -> np.ndarray:
    """The 1-sigma the outputs carry: the filter's, the pyrometer's calibration
    (:func:`band_std`) and what a crown balance unlike the law's would do at the spots
    the filter does not measure (:mod:`brakethermo.pipelines.crown_band`)."""
    band = band_std(out, std, tuning)
    H_spots = model.spot_matrix(spot_radii)
    H = np.vstack([H_spots, H_spots[1:4].mean(axis=0)])
    crown = crown_balance_std(model, T0, q, h, t_amb, H, spot, tuning.crown_balance_sd)
    band[:, :5] = np.hypot(band[:, :5], crown)
    return band


def _estimate_frame(
    inputs: DiscInputs,
    model: DiscFEModel,
    states: np.ndarray,
    out: np.ndarray,
    std: np.ndarray,
    tuning: EstimateTuning,
    h: np.ndarray,
    online: dict[str, int],
) -> pd.DataFrame:
    cols: dict[str, np.ndarray] = {"time": inputs.time, "lap": inputs.lap.astype(np.int64)}
    # A disc is never colder than the air around it: project the estimate onto T >= T_amb
    # (estimate projection of a constrained Kalman filter, Simon & Chia 2002). Without it
    # the smoother, with no reading below the pyrometer floor, can start the disc colder.
    floor = inputs.t_amb
    out = out.copy()
    out[:, :5] = np.fmax(out[:, :5], floor[:, None])
    for i in range(4):
        cols[f"spot{i + 1}"] = out[:, i]
        cols[f"spot{i + 1}_std"] = std[:, i]
    cols["contact_avg"] = out[:, 4]
    cols["contact_avg_std"] = std[:, 4]
    for k, j in enumerate(model.face_index):
        cols[f"node_{k}"] = np.fmax(states[:, j], floor)
    if model.layers > 1:
        mid = model.face_index + model.layers - 1
        for k, j in enumerate(mid):
            cols[f"mid_{k}"] = np.fmax(states[:, j], floor)
    if tuning.adapt_power:
        cols["power_scale"] = out[:, 5]
        cols["power_scale_std"] = std[:, 5]
    for name, j in online.items():  # online effect factors, e.g. kz_factor, h_factor
        cols[name] = states[:, j]
    cols["braking_power"] = inputs.q_brk
    cols["h"] = h
    return pd.DataFrame(cols)


def score_estimate(
    frame: pd.DataFrame,
    std: np.ndarray,
    filtered: np.ndarray,
    open_loop: np.ndarray,
    inputs: DiscInputs,
    spot: int,
    smoothed: bool,
    zones: np.ndarray | None = None,
) -> dict[str, Any]:
    """The paper's Tables 3 and 4 on a multi-spot session, plus peaks and coverage.

    The reference is the measured spots, as in the paper; the band coverage adds each
    reading's own noise, measured from the reading itself. ``std`` (K, 4) is the filter's
    spread without the pyrometer calibration term: the readings share that error.
    """
    ref = inputs.spots.copy()
    ref[ref <= SENSOR_FLOOR_C] = np.nan
    smooth = frame[[f"spot{i}" for i in range(1, 5)]].to_numpy()
    baseline = scoring.single_spot_baseline(ref[:, spot - 1])
    rows = [
        scoring.score_method("smoother" if smoothed else "filter", smooth, ref),
        *([scoring.score_method("filter", filtered, ref)] if smoothed else []),
        scoring.score_method("open-loop 1D-FE", open_loop, ref),
        scoring.score_method("single-spot", baseline, ref),
    ]
    base = rows[-1]
    validation = [i for i in range(1, 5) if i != spot]
    braking = inputs.braking
    return {
        "reference": "measured spots",
        "measured_spot": spot,
        "table": [r.as_dict() for r in rows],
        "contact_ratio_vs_single_spot": {
            r.method: scoring.ratio(r.contact_rmse, base.contact_rmse) for r in rows[:-1]
        },
        "peak": {
            f"spot{i}": scoring.peak_errors(smooth[:, i - 1], ref[:, i - 1], braking, zones=zones)
            for i in range(1, 5)
        },
        "coverage95": {
            f"spot{i}": scoring.coverage(smooth[:, i - 1], std[:, i - 1], ref[:, i - 1],
                                         extra_var=scoring.reading_noise(ref[:, i - 1]) ** 2)
            for i in validation
        },
        # the band estimate.parquet carries (``spot<i>_std``): the filter's spread, the
        # pyrometer's calibration (which these readings share, so it is left out above) and
        # the pads' crown balance
        "coverage95_written_band": {
            f"spot{i}": scoring.coverage(smooth[:, i - 1], frame[f"spot{i}_std"].to_numpy(),
                                         ref[:, i - 1],
                                         extra_var=scoring.reading_noise(ref[:, i - 1]) ** 2)
            for i in validation if f"spot{i}_std" in frame
        },
        "coverage95_band": "the filter's own spread (plus each reading's noise), without the"
                           " pyrometer calibration term the readings share and the crown"
                           " balance term; coverage95_written_band: the band estimate.parquet"
                           " carries",
    }


def estimate_session(path: str | Path, options: EstimateOptions | None = None) -> EstimateResult:
    """Load a session file and estimate its disc temperatures.

    Parameters
    ----------
    path : str or Path
        Session file (MCAP, Parquet or CSV).
    options : EstimateOptions, optional

    Returns
    -------
    EstimateResult
    """
    options = options or EstimateOptions()
    session, read_s = load_timed(path, options.aliases)
    result = estimate_from_session(session, options)
    result.timings["read_s"] = read_s
    result.summary["run"]["timings_s"]["read_s"] = read_s
    result.summary["run"]["wall_time_s"] += read_s
    return result


def write_estimate(
    result: EstimateResult, out_dir: str | Path, *, folder: str | Path | None = None
) -> Path:
    """Write ``<out_dir>/<stem>/estimate.parquet`` and ``summary.json``; return the folder.

    ``folder`` writes there instead (a staging folder that replaces ``<out_dir>/<stem>``).
    """
    folder = Path(folder) if folder is not None else Path(out_dir) / result.stem
    field_meta: dict[str, dict[str, str]] = {"time": {"unit": "s"}}
    for col in result.frame.columns:
        if col.startswith(("spot", "contact_avg", "node_", "mid_")):
            field_meta[col] = {"unit": "degC"}
    for k, r in enumerate(result.node_radii):
        field_meta[f"node_{k}"]["radius_m"] = repr(float(r))
        if f"mid_{k}" in field_meta:
            field_meta[f"mid_{k}"]["radius_m"] = repr(float(r))
    field_meta["braking_power"] = {"unit": "W"}
    field_meta["h"] = {"unit": "W/(m2 K)"}
    write_parquet(folder / "estimate.parquet", result.frame, field_meta,
                  {"brakethermo": __version__, "session": str(result.session.path)})
    write_json(folder / "summary.json", result.summary)
    return folder


def disc_of(result: EstimateResult) -> DiscSpec:
    """The datasheet the result was computed with."""
    return result.disc
