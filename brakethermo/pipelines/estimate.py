"""``estimate``: disc temperature at every radius from one IR spot (paper §4.2, §5.2–5.3).

State = node temperatures of the layered 1D-FE model (+ the braking-power scale as a
random walk); one spot measured; h from the identified law; an unscented RTS smoother
on top of the UKF, since the work is offline. On a multi-spot session the unmeasured
spots validate the estimate (the paper's Tables 3 and 4).

This module is the pipeline's spine: its options, its result, one session from the
measured spot to the summary, and the files it writes. The steps live beside it: the
race's online decision and the filter run on it (:mod:`~brakethermo.pipelines.race_run`),
the table and its band (:mod:`~brakethermo.pipelines.estimate_table`), the scores on a
multi-spot session (:mod:`~brakethermo.pipelines.estimate_scores`) and the run facts of
the summary (:mod:`~brakethermo.pipelines.run_facts`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from brakethermo import __version__
from brakethermo.errors import ConfigError, DataError
from brakethermo.io.plausibility import SENSOR_FLOOR_C  # one floor for every command
from brakethermo.io.session import Session
from brakethermo.models.disc import DiscStateSpace
from brakethermo.models.reduced import MAX_MODES
from brakethermo.pipelines.checks import check_estimate_result, check_power_scale
from brakethermo.pipelines.estimate_scores import self_scores
from brakethermo.pipelines.estimate_table import (
    above_air,
    estimate_frame,
    node_rows_start,
    reported_band,
)
from brakethermo.pipelines.h_factor_found import HFactorFound, h_factor_found, h_factor_warning
from brakethermo.pipelines.inputs import DiscInputs, disc_inputs, load_timed
from brakethermo.pipelines.law_drops import law_part_warnings
from brakethermo.pipelines.models import (
    DiscCalibration,
    assumed_disc,
    calibration_for,
    disc_for,
)
from brakethermo.pipelines.outputs import write_json, write_parquet
from brakethermo.pipelines.race_run import decided_run
from brakethermo.pipelines.run_facts import law_warnings, model_facts
from brakethermo.pipelines.tuning import (
    EstimateTuning,
    TuningSource,
    check_overrides,
    load_tuning,
    read_tuning,
    user_tuning_keys,
)
from brakethermo.results.laps import lap_summaries, whole_flying_laps
from brakethermo.thermal.disc import DiscSpec

if TYPE_CHECKING:
    from brakethermo.pipelines.online_choice import OnlineChoice


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
        in the user's tuning file, and which of the h law's test-session effects hold for
        it (:mod:`brakethermo.pipelines.online_choice`); False: the law as written
        (``estimate --law-as-written``).
    bands : bool
        False: the bands leave out the crown balance's term (an open loop of the model
        beside the filter): for the race's crown-noise trials, whose bands nobody reads
        (:func:`~brakethermo.pipelines.race_run._with_crown_noise`).
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
    bands: bool = True

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
    if cal.nodes is not None and "nodes" not in user:
        calibrated["nodes"] = cal.nodes
    tuning = replace(tuning, **{k: v for k, v in calibrated.items()
                                if v is not None and k not in user})
    return replace(tuning, **options.overrides())


def undecided_warning(choice: OnlineChoice | None) -> list[str]:
    """The warning when the race had too few flying laps to decide its online effects."""
    from brakethermo.pipelines.online_choice import UNDECIDED

    if choice is None or not str(choice.facts.get("rule", "")).startswith(UNDECIDED):
        return []
    return ["fewer than two flying laps: the race could not decide its online effects"
            " (k_z, slipstream) on its own laps and left them off; a lap_beacon channel (or a"
            " distance channel back to 0 at the line) gives the laps"]


def _frame_findings(frame: pd.DataFrame, session: Session, inputs: DiscInputs,
                    choice: OnlineChoice | None, warnings: list[str]) -> HFactorFound | None:
    """The result's own checks (power scale, undecided race, the law's parts dropped)
    appended to ``warnings``, and what the online h factor found, when it ran."""
    if "power_scale" in frame:
        warnings.extend(check_power_scale(frame["power_scale"].to_numpy(), inputs.q_brk > 0))
    warnings.extend(undecided_warning(choice))
    # a law part dropped on the measured spot alone moves the unmeasured ones: said here
    warnings.extend(law_part_warnings(None if choice is None else choice.facts))
    if "h_factor" not in frame:
        return None
    found = h_factor_found(frame["h_factor"].to_numpy(), inputs.braking,
                           frame["lap"].to_numpy(), whole_flying_laps(session.laps),
                           float(session.dt))
    warnings.extend(h_factor_warning(found))
    return found


def _with_found(facts: dict[str, dict[str, Any]], found: HFactorFound | None
                ) -> dict[str, dict[str, Any]]:
    """``run.effects`` with what the online h factor found under ``slipstream.found``."""
    if found is None or "slipstream" not in facts:
        return facts
    return {**facts, "slipstream": {**facts["slipstream"], "found": found.facts()}}


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
    assumed = assumed_disc(session, options.disc)
    warnings = [*session.warnings, *inputs.warnings, *([assumed] if assumed else []),
                *law_warnings(cal, disc, tuning, inputs.speed)]
    choice, run, t_choice = decided_run(session, options, disc, inputs, y, cal, tuning,
                                        calibration)
    cal, tuning, model, x0, forward = run.cal, run.tuning, run.model, run.x0, run.forward
    out, h, spot_radii = run.out, run.h, np.asarray(disc.spot_radii)
    t_done = time.perf_counter()

    std = np.sqrt(np.maximum(run.out_var, 0.0))
    nodes = node_rows_start(out, tuning, model)
    # judged as published (a smoother's transient below a -40 degC air is no unit error)
    warnings.extend(check_estimate_result(above_air(out, inputs.t_amb)[:, :5], forward.nis))
    online = {p.name: run.ssm.index[p.name] for p in run.plan.online}
    band = reported_band(out, std, tuning, run.crown, nodes)
    frame = estimate_frame(inputs, model, run.states, out, band, tuning, h, online,
                           None if nodes is None else band[:, nodes:])
    found = _frame_findings(frame, session, inputs, choice, warnings)
    open_loop = scores = None
    if options.score and len(inputs.measured) > 1:
        open_loop, scores = self_scores(session, inputs, model, cal, x0, h, frame, std,
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
            **model_facts(cal, tuning, model),
            "sigma_meas_source": run.sigma_meas_source,
            "smoother_windows": run.windows,
            "filter_order": run.order,
            "workers": options.workers,
            "measured_spot": options.spot,
            "effects": _with_found(run.plan.facts, found),
            "online_choice": choice.facts if choice is not None else {
                "rule": ("every online effect set by the options or the tuning file"
                         if options.online_auto else
                         "not decided (--law-as-written): the h law as written, the online"
                         " effects as the options and the tuning file set them")},
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
