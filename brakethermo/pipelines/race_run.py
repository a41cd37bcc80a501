"""The race's decided run: its online decision, and the filter (and smoother) pass on the
law and tuning that decision leaves.

The race chooses the online effects nobody forced and the parts of the h law it drops
(:mod:`brakethermo.pipelines.online_choice`); a race that switched k_z on at a factor
below the law's (under 0.67, the decision's gate), or learned one that low on a law that
carries its k_z, gets identify-h's thin-skin layering, and chooses its crown-split noise
there (:mod:`brakethermo.pipelines.crown_noise`); the filter is built and run on the
outcome (:mod:`brakethermo.pipelines.race_filter`), the reading noise measured from the
measured spot itself. On a long race the run for
"nothing switched on, nothing dropped" starts before the decision, on a guess
(:mod:`brakethermo.pipelines.speculative`). The estimate pipeline
(:mod:`brakethermo.pipelines.estimate`) turns the run into its table and scores.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from contextlib import suppress
from dataclasses import dataclass, replace
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np

from brakethermo.io.session import Session
from brakethermo.models.disc import DiscStateSpace
from brakethermo.models.effects import true_from_reading
from brakethermo.models.reduced import ReducedStateSpace
from brakethermo.pipelines import crown_noise, scoring
from brakethermo.pipelines.estimate_table import crown_term
from brakethermo.pipelines.inputs import DiscInputs
from brakethermo.pipelines.models import DiscCalibration
from brakethermo.pipelines.online_choice import (
    CROWN,
    DECISION_LAPS,
    EARNED,
    JOINT,
    ONLINE_FLAGS,
    OnlineChoice,
    choose_online,
    droppable,
    kz_allowed,
    law_without,
    thin_skin_learned,
)
from brakethermo.pipelines.race_filter import (
    EffectPlan,
    build_state_space,
    disc_model,
    effect_plan,
    filter_space,
    readout_rows,
    run_filter,
    ukf_for,
    warm_modes,
)
from brakethermo.pipelines.speculative import Speculation, core
from brakethermo.pipelines.tuning import EstimateTuning, user_tuning_keys
from brakethermo.thermal.disc import DiscSpec
from brakethermo.thermal.model import DiscFEModel

if TYPE_CHECKING:
    from brakethermo.pipelines.estimate import EstimateOptions

SIGMA_MEAS_FLOOR_C = 0.5  # degC: never trust a reading beyond its quantisation


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
                   chooses: tuple[tuple[str, ...], tuple[str, ...]],
                   on_learned: Callable[[float], None] | None = None) -> OnlineChoice:
    """The race's own choice of the online effects nobody forced (:func:`_choice_inputs`);
    ``on_learned`` as :func:`choose_online`'s."""
    candidates, parts = chooses
    choice = choose_online(session, options, candidates, cal, parts, on_learned)
    forced = {flag: getattr(tuning, flag) for name, flag in ONLINE_FLAGS.items()
              if name not in candidates}
    return OnlineChoice(choice.flags, {**choice.facts, "forced_or_from_law": forced},
                        choice.dropped)


def _race_layering(choice: OnlineChoice, tuning: EstimateTuning, options: EstimateOptions
                   ) -> tuple[EstimateTuning, str | None]:
    """identify-h's thin-skin layering, on finer radial nodes, for a race whose disc
    conducts through the thickness worse than the law's (the race chose k_z and learned
    it lower, or learned it below 0.67 on a law that carries it,
    :func:`~brakethermo.pipelines.online_choice.thin_skin_learned`): heat stays nearer
    the face, and the law's layering, built for its own disc, is too coarse to hold the
    skin; a face that thin follows the radial profile of the pads' flux, which 10 nodes
    smear (8 development races, 10 -> 15 nodes: 0.66 -> 0.58 of the single-spot
    baseline, 7 better; 20 nodes no better than 15).
    Returns the tuning and what was changed, in words (None: nothing)."""
    learned = thin_skin_learned(choice)
    if learned is None:
        return tuning, None
    thin, said = thin_skin(tuning, options)
    if not said:
        return tuning, None
    return thin, (
        f"{' and '.join(said)}: the race's k_z came out {learned:.2f} of the law's,"
        " a thinner thermal skin")


def thin_skin(tuning: EstimateTuning, options: EstimateOptions
              ) -> tuple[EstimateTuning, list[str]]:
    """``tuning`` with the thin-skin layers and radial nodes where neither the options
    nor the user's tuning file set them (:func:`_race_layering`), and what changed, in
    words (empty: nothing)."""
    user = user_tuning_keys(options.tuning, "estimate")
    change: dict[str, Any] = {}
    said = []
    if (options.layers is None and "layers" not in user
            and tuning.layers < tuning.thin_skin_layers):
        change.update(layers=tuning.thin_skin_layers,
                      layer_growth=tuning.thin_skin_layer_growth)
        said.append(f"{tuning.thin_skin_layers} layers (growth"
                    f" {tuning.thin_skin_layer_growth:g}) instead of the law's {tuning.layers}")
    if (options.nodes is None and "nodes" not in user
            and tuning.nodes < tuning.thin_skin_nodes):
        change["nodes"] = tuning.thin_skin_nodes
        said.append(f"{tuning.thin_skin_nodes} radial nodes instead of {tuning.nodes}")
    return (replace(tuning, **change) if change else tuning), said


@dataclass(frozen=True)
class RaceRun:
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
    crown: np.ndarray  # degC, the band's crown term (estimate_table.crown_term)
    speculative: bool = False


def _initial_temperature(y: np.ndarray, t_amb: np.ndarray) -> float:
    """First temperature: the first valid reading if it comes in the first 5 s, else ambient."""
    first = np.flatnonzero(np.isfinite(y))
    if first.size and first[0] < 50:
        return max(float(y[first[0]]), float(t_amb[0]))  # never colder than the air
    return float(t_amb[0])


def _reading_noise(y: np.ndarray, tuning: EstimateTuning, options: EstimateOptions,
                   per_reading: int, steady: np.ndarray) -> tuple[EstimateTuning, str]:
    """The reading noise of this very sensor, from the signal itself, unless the user's
    tuning file sets it: a fixed guess either starves the filter of the measurement or
    trusts it too much. A pyrometer slower than the grid spreads each reading over
    ``per_reading`` grid points: the filter's noise is sqrt(per_reading) times the
    reading's, so that those points together weigh as the one reading they are."""
    if "sigma_meas" in user_tuning_keys(options.tuning, "estimate"):
        return tuning, "tuning file"
    noise = max(scoring.reading_noise(y, per_reading, steady), SIGMA_MEAS_FLOOR_C)
    if per_reading == 1:
        return (replace(tuning, sigma_meas=noise),
                "measured from the signal (second differences)")
    return (replace(tuning, sigma_meas=noise * np.sqrt(per_reading)),
            f"measured from the signal at its own rate (second differences, {noise:.2f} °C),"
            f" times sqrt({per_reading}): each reading spans {per_reading} grid points")


def _readings(y: np.ndarray, plan: EffectPlan) -> np.ndarray:
    """The readings as the filter takes them: emissivity-corrected where the law says."""
    return y if plan.emissivity_ratio is None else true_from_reading(y, plan.emissivity_ratio)


def _filtered(disc: DiscSpec, inputs: DiscInputs, y: np.ndarray, cal: DiscCalibration,
              tuning: EstimateTuning, options: EstimateOptions,
              cancel: threading.Event | None = None, sigma_meas: float | None = None
              ) -> RaceRun:
    """Build the race's filter for ``cal`` and ``tuning`` and run it (and the smoother);
    ``sigma_meas`` (degC): the reading noise of a run over the race's first laps only,
    the whole race's (else measured from ``y``)."""
    h = cal.law(inputs.speed)
    model = disc_model(disc, tuning, cal.weights, cal.kz_ratio)
    spot_radius = float(disc.spot_radii[options.spot - 1])
    plan = effect_plan(cal.effects, tuning)
    y = _readings(y, plan)
    if sigma_meas is None:
        tuning, sigma_meas_source = _reading_noise(y, tuning, options,
                                                   inputs.per_reading[options.spot - 1],
                                                   inputs.steady)
    else:
        tuning, sigma_meas_source = replace(tuning, sigma_meas=sigma_meas), "the race's"
    ssm = build_state_space(model, inputs, h, tuning, cal.power_scale, plan, spot_radius)
    filt, order = filter_space(ssm, model, inputs, h, cal.power_scale, options.modes)
    readout = readout_rows(filt, np.asarray(disc.spot_radii), tuning.adapt_power)
    x0, P0 = filt.prior(model.initial_state(_initial_temperature(y, inputs.t_amb)),
                        tuning.init_sigma_temp)
    ukf = ukf_for(filt, tuning, spot_radius, cancel)
    reduced = isinstance(filt, ReducedStateSpace)
    x0_full = filt.lift(x0) if reduced else x0  # the full model's nodes, everywhere
    # the face nodes' bands (the hottest radius's) where a smoother runs, in its pass
    # only: the decision's filter-only variants do without them
    nodes = filt.H(model.radii) if tuning.smoother else None
    crown_args = (model, x0_full[: model.n_state], inputs.q_brk * cal.power_scale, h,
                  inputs.t_amb, np.asarray(disc.spot_radii), options.spot, tuning,
                  nodes is not None)
    # the band's crown term is an open loop of the model on the inputs alone: beside a
    # smoother's pass, on the core it leaves (the README's k_z race, 15 x 6 nodes:
    # 0.4 s); the decision's filter-only passes fill the cores already
    pool = (ThreadPoolExecutor(1, "brakethermo-crown") if tuning.smoother and options.bands
            else None)
    crown = None if pool is None else pool.submit(crown_term, *crown_args)
    t0 = time.perf_counter()
    try:
        forward, states, out, out_var, windows, forward_s = run_filter(
            ukf, x0, P0, y, readout, tuning.smoother, options.workers, nodes)
        smoother_s = time.perf_counter() - t0 - forward_s
        if not options.bands:  # a pass whose bands nobody reads: no crown term
            crown_std = np.zeros((inputs.q_brk.size, 5 + (0 if nodes is None else
                                                         nodes.shape[0])))
        else:
            crown_std = crown_term(*crown_args) if crown is None else crown.result()
    finally:
        if pool is not None:  # abandoned or interrupted: nobody waits for the band's term
            pool.shutdown(wait=False, cancel_futures=True)
    if reduced:
        states = filt.lift(states)
    return RaceRun(cal, tuning, y, h, model, plan, ssm, order, sigma_meas_source, x0_full,
                   forward, states, out, out_var, windows, forward_s, smoother_s, crown_std)


def _kz_learned(disc: DiscSpec, inputs: DiscInputs, cal: DiscCalibration,
                tuning: EstimateTuning, options: EstimateOptions, parts: tuple[str, ...],
                guess: Speculation[RaceRun] | None) -> Callable[[float], None]:
    """What the race does the moment its decision learns k_z (``on_learned`` of
    :func:`choose_online`, a factor of the law's): a factor the race may switch on
    (:func:`kz_allowed`) makes the guess of nothing switched on unlikely, so it stops and
    the decision's next variant takes its core; one below the law's makes the thin-skin
    mesh likely (:func:`_race_layering`), so that filter's modes are computed there and
    then instead of after the decision. Neither changes a number: the guess is only a
    head start, and the filter takes the modes
    :func:`~brakethermo.pipelines.race_filter.session_modes` keeps when its model, law and
    inputs are these (the README's k_z race: its filter starts 0.6-1.2 s earlier)."""
    thin, said = thin_skin(tuning, options)
    # a crown the race may drop is in the modes' model, and not known yet
    warm = bool(said) and CROWN not in parts

    def learned(kz: float) -> None:
        if not kz_allowed(kz):
            return
        if guess is not None:
            guess.abandon()
        if warm and kz < 1.0:
            model = disc_model(disc, thin, cal.weights, cal.kz_ratio)
            # a head start only: the filter that needs these modes computes them again
            # (and raises there) if this fails
            with suppress(Exception):
                warm_modes(model, inputs, cal.law(inputs.speed), cal.power_scale,
                           options.modes)

    return learned


def decided_run(session: Session, options: EstimateOptions, disc: DiscSpec,
                inputs: DiscInputs, y: np.ndarray, cal: DiscCalibration,
                tuning: EstimateTuning, calibration: DiscCalibration | None
                ) -> tuple[OnlineChoice | None, RaceRun, float]:
    """The race's online decision and the filter run on what it decided, and when the
    decision ended. On a race longer than the decision's laps, the run for "nothing
    switched on, the law's μ(T) unearned" starts before the decision on its own thread
    (:mod:`brakethermo.pipelines.speculative`): a 25-lap race that decides so, 8.3 → 6.3–7 s
    in process; one whose decision learns a k_z it may switch on stops the guess then, and
    computes the thin-skin filter's modes beside the decision (:func:`_kz_learned`). A
    race on a thinner skin then chooses its crown-split noise beside its filter
    (:func:`_with_crown_noise`)."""
    chooses = _choice_inputs(options, cal, calibration)
    guess = null = None
    # what the race most often decides: no online state, the law's μ(T) not earned
    unearned = (EARNED,) if chooses is not None and EARNED in chooses[1] else ()
    # a race no longer than the decision's laps has a filter pass as short as one of the
    # decision's: nothing to win there, and the decision would lose a core
    # (and on one core the guess would only queue the decision behind it)
    flying = sum(lap.lap >= 1 for lap in session.laps)
    if chooses is not None and flying > DECISION_LAPS and (os.cpu_count() or 1) > 1:
        null = replace(tuning, **{ONLINE_FLAGS[c]: False for c in chooses[0]})
        bare = law_without(cal, EARNED) if unearned else cal
        guess = Speculation(partial(_filtered, disc, inputs, y, bare, null, options))
    try:
        choice = None if chooses is None else _online_choice(
            session, options, cal, tuning, chooses,
            _kz_learned(disc, inputs, cal, tuning, options, chooses[1], guess))
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
    noise_free = crown_noise.free(choice, options, flying)
    if (guess is not None and not guess.abandoned and choice is not None and tuning == null
            and choice.dropped == unearned and not noise_free):
        return choice, replace(guess.result(), speculative=True), t_choice
    if guess is not None:
        guess.abandon()
    if noise_free:
        choice, run = _with_crown_noise(session, options, disc, inputs, y, cal, tuning, choice)
        return choice, run, t_choice
    return choice, _filtered(disc, inputs, y, cal, tuning, options), t_choice


def _with_crown_noise(session: Session, options: EstimateOptions, disc: DiscSpec,
                      inputs: DiscInputs, y: np.ndarray, cal: DiscCalibration,
                      tuning: EstimateTuning, choice: OnlineChoice
                      ) -> tuple[OnlineChoice, RaceRun]:
    """The race's filter at the law's crown-split noise and, beside it on the core it
    leaves, the decision's laps at lower ones (:mod:`~brakethermo.pipelines.crown_noise`);
    the race's filter again at the noise its likelihood chose, where not the law's."""
    t0 = time.perf_counter()
    part = crown_noise.decision_part(session)
    sigma = tuning.sigma_crown
    noise = _reading_noise(_readings(y, effect_plan(cal.effects, tuning)), tuning, options,
                           inputs.per_reading[options.spot - 1], inputs.steady)[0].sigma_meas
    trial, stop = replace(tuning, smoother=False), threading.Event()
    quiet = replace(options, bands=False)  # nobody reads a trial's bands

    def run(steps: int, sigma_crown: float) -> crown_noise.Innovations:
        with core():
            r = _filtered(disc, inputs.head(steps), y[:steps], cal,
                          replace(trial, sigma_crown=sigma_crown), quiet, stop, noise)
        return crown_noise.Innovations(r.forward.innovation[:, 0],
                                       r.forward.innovation_var[:, 0])

    with ThreadPoolExecutor(1, "brakethermo-crown-noise") as pool:
        tried = pool.submit(crown_noise.trials, len(part.frame), sigma, run)
        try:
            race = _filtered(disc, inputs, y, cal, tuning, options)
        except BaseException:  # a bad race or Ctrl-C: the trials stop with it
            stop.set()
            raise
        law = crown_noise.Innovations(race.forward.innovation[:, 0],
                                      race.forward.innovation_var[:, 0])
        online = [*choice.facts["chosen"], *(["the law's k_z"] if JOINT in cal.effects else [])]
        fact = crown_noise.judge(part, law, tried.result(), sigma, online)
    if fact["changed"]:
        race = _filtered(disc, inputs, y, cal, replace(tuning, sigma_crown=fact["chosen"]),
                         options)
    fact["seconds"] = time.perf_counter() - t0  # the race's filter (both, when re-run) within
    return replace(choice, facts={**choice.facts, "crown_noise": fact}), race
