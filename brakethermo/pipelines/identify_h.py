"""``identify-h``: the disc convection law h(V) from a four-spot test session (§4.1, §5.1).

1. Joint UKF + unscented RTS smoother on the fine 51-node model, state
   ``[T_1..T_N, h]`` with h a Gaussian random walk (eq. 48–50) and all four spots
   measured by linear interpolation (eq. 53).
2. The law h(V) — power law below the knee, cubic above, joined continuously — fitted
   on off-brake samples only, weighted by the posterior variance of h.
3. Beyond the paper, which tuned the crown weights by hand (§5.3): the mean pad-crown
   weights w_1..w_3, the through-thickness conductivity ratio of the layered estimation
   model and the mean braking-power scale, fitted by least squares of the open-loop
   estimation model against the four spots, with h from the fitted law.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from brakethermo import __version__
from brakethermo.errors import DataError
from brakethermo.estimation import UnscentedKalmanFilter, urts_smooth
from brakethermo.io.atomic import write_text_atomic
from brakethermo.io.session import GRID_DT, Session
from brakethermo.models.disc import H_PARAM, DiscStateSpace, RandomWalkParam
from brakethermo.models.effects import parse_effects
from brakethermo.numeric import rmse
from brakethermo.pipelines import scoring
from brakethermo.pipelines.estimate import (
    SENSOR_FLOOR_C,
    EstimateOptions,
    estimate_from_session,
)
from brakethermo.pipelines.h_evidence import law_level, straight_factors
from brakethermo.pipelines.inputs import (
    MULTI_SPOT,
    DiscInputs,
    disc_inputs,
    load_timed,
)
from brakethermo.pipelines.models import DiscCalibration, assumed_disc, disc_for, shipped_h_law
from brakethermo.pipelines.outputs import write_json, write_parquet
from brakethermo.pipelines.race_filter import disc_model
from brakethermo.pipelines.tuning import (
    EstimateTuning,
    IdentifyTuning,
    TuningSource,
    load_tuning,
    read_tuning,
)
from brakethermo.thermal.disc import DiscSpec, kz_scales
from brakethermo.thermal.hlaw import HLaw, read_h_law
from brakethermo.thermal.hlaw_check import B_LAW_CHECKED, law_speed_check
from brakethermo.thermal.model import DiscFEModel
from brakethermo.thermal.power import normalise_weights

AFTER_BRAKE_S = 2.0  # s after release still excluded from the fit: the face is settling
MIN_ABOVE_KNEE_S = 20.0  # s of running above the knee needed to fit the upper branch
H_MIN = 1.0  # W/(m² K), floor the model sees for a sigma point's h


@dataclass(frozen=True)
class IdentifyOptions:
    """Command-line choices; ``None`` means the tuning file's value."""

    disc: str | Path | None = None
    tuning: TuningSource = None
    nodes: int | None = None
    aliases: str | Path | None = None
    ambient_c: float | None = None
    fit_structure: bool = True
    with_effects: str | None = "auto"


@dataclass(frozen=True)
class StructureFit:
    """Mean crown weights, through-thickness ratio and power scale of the estimation model.

    Attributes
    ----------
    weights : tuple of 3 float — normalised to eq. 8
    kz_ratio : float — k_z / k(T)
    power_scale : float — mean braking power relative to the datasheet formula
    nodes, layers : int — the estimation model they were fitted for
    rmse_c : dict of str to float — degC, open-loop RMSE per spot after the fit
    rmse_uniform_c : dict of str to float — degC, with uniform weights, kz_ratio 1, scale 1
    """

    weights: tuple[float, float, float]
    kz_ratio: float
    power_scale: float
    nodes: int
    layers: int
    rmse_c: dict[str, float]
    rmse_uniform_c: dict[str, float]
    effects: dict[str, dict[str, Any]] = field(default_factory=dict)
    at_bounds: dict[tuple[str, str], float] = field(default_factory=dict)  # (effect, param)
    # of at_bounds, the effects' forms stretched (ExtendedDisc.at_bounds): what selection
    # drops; a straight or zone at its bound, or a lag the fit found none of, is only said
    stretched: dict[tuple[str, str], float] = field(default_factory=dict)

    def facts(self) -> dict[str, Any]:
        """``structure`` of identify.json."""
        return {
            "weights": list(self.weights),
            "kz_ratio": self.kz_ratio,
            "power_scale": self.power_scale,
            "nodes": self.nodes,
            "layers": self.layers,
            "open_loop_rmse_c": self.rmse_c,
            "open_loop_rmse_uniform_c": self.rmse_uniform_c,
            "effects": self.effects,
            "at_bounds": {f"{e}.{p}": v for (e, p), v in self.at_bounds.items()},
        }


@dataclass
class IdentifyResult:
    """What identify-h found for one session."""

    session: Session
    law: HLaw
    law_ukf: HLaw | None
    calibration: DiscCalibration
    samples: pd.DataFrame
    structure: StructureFit | None
    fit_mask: np.ndarray
    summary: dict[str, Any]
    timings: dict[str, float] = field(default_factory=dict)
    straights: pd.DataFrame | None = None  # per straight, h under the layered model
    diagnosis: Any = None  # the effect selection's DiagnoseResult (batch writes it)

    @property
    def stem(self) -> str:
        return self.session.path.stem


def fit_inputs(session: Session, disc: str | Path | None = None,
               ambient_c: float | None = None) -> tuple[DiscSpec, DiscInputs, np.ndarray]:
    """What identify-h fits on a test session: its disc, the model's inputs and the four
    spots' readings (NaN below the sensor's floor), degC, shape (K, 4).

    Parameters
    ----------
    session : Session
    disc : str or path, optional — datasheet id or file; default: the session's fact.
    ambient_c : float, optional — degC, overrides the logged air temperature.

    Raises
    ------
    DataError
        The session does not log the four-spot sensor.
    """
    spec = disc_for(session, disc)
    inputs = disc_inputs(session, spec, ambient_c)
    return spec, inputs, _measurements(inputs, session.path)


def _measurements(inputs: DiscInputs, path: Path) -> np.ndarray:
    if not inputs.is_multi_spot:
        raise DataError(
            "identify-h needs a test session with the four-spot sensor "
            f"({', '.join(MULTI_SPOT)}); this one logs spot(s) "
            f"{', '.join(map(str, inputs.measured))} only",
            path=path,
        )
    y = inputs.spots.copy()
    y[y <= SENSOR_FLOOR_C] = np.nan
    return y


def _initial_profile(radii: np.ndarray, spot_radii: np.ndarray, y: np.ndarray,
                     t_amb: float) -> np.ndarray:
    """Node temperatures interpolated from the first readings (ambient if there are none)."""
    first = y[: int(5.0 / GRID_DT)]
    vals = np.array([col[np.isfinite(col)][0] if np.isfinite(col).any() else np.nan
                     for col in first.T])
    ok = np.isfinite(vals)
    if not ok.any():
        return np.full(radii.size, t_amb)
    return np.interp(radii, spot_radii[ok], vals[ok])


def off_brake_mask(braking: np.ndarray, after_s: float = AFTER_BRAKE_S) -> np.ndarray:
    """Grid points off the brakes and at least ``after_s`` past the last release."""
    pad = round(after_s / GRID_DT)
    recent = np.convolve(braking.astype(float), np.ones(pad + 1), mode="full")[: braking.size]
    return recent == 0


def identify_h_samples(
    inputs: DiscInputs, y: np.ndarray, disc: DiscSpec, tuning: IdentifyTuning
) -> tuple[np.ndarray, np.ndarray, Any]:
    """Posterior mean and std of h on the grid (joint UKF + smoother, eq. 48–53)."""
    model = DiscFEModel(disc, tuning.nodes, tuning.layers)
    h_param = RandomWalkParam(H_PARAM, tuning.h_init, tuning.h_init_sigma, tuning.h_step, H_MIN)
    ssm = DiscStateSpace(
        model, inputs.q_brk, inputs.t_amb, None, [h_param],
        sigma_temp=tuning.sigma_temp, sigma_crown=tuning.sigma_crown,
    )  # fmt: skip
    spot_radii = np.asarray(disc.spot_radii)
    T0 = _initial_profile(model.radii, spot_radii, y, float(inputs.t_amb[0]))
    x0, P0 = ssm.prior(np.repeat(T0, model.layers), tuning.init_sigma_temp)
    ukf = UnscentedKalmanFilter(
        ssm.f, ssm.Q, np.eye(4) * tuning.sigma_meas**2, H=ssm.H(spot_radii),
        alpha=tuning.alpha, beta=tuning.beta, kappa=tuning.kappa, steps=ssm.compiled_steps(),
    )  # fmt: skip
    sel = ssm.selector(H_PARAM)
    forward = ukf.run(x0, P0, y, store="smoother", readout=sel)
    smoothed = urts_smooth(forward, store="diag", readout=sel)
    return smoothed.readout[:, 0], np.sqrt(np.maximum(smoothed.readout_var[:, 0], 0.0)), forward


def _spot_rmse(pred: np.ndarray, y: np.ndarray) -> dict[str, float]:
    err = pred - y
    return {f"spot{i + 1}": rmse(err[:, i]) for i in range(4)}


def _structure_start(law0: HLaw) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Start and bounds of :func:`fit_structure`'s parameters (its docstring), the start
    from the UKF law ``law0`` and the neutral structure, inside the bounds."""
    slope = law0.a * law0.b * law0.knee ** (law0.b - 1.0)  # power-law slope at the knee
    p0 = np.array([np.log(max(law0.a, 1.0)), law0.b, max(slope, 0.0), 0.0, 0.0, 0.0, 0.0, 0.0])
    # c_1, c_2 >= 0: h does not fall with speed above the knee (the tyre exposes more disc)
    lo = np.array([np.log(1.0), 0.0, 0.0, 0.0, *np.log([0.05, 0.05, 0.02, 0.5])])
    hi = np.array([np.log(2000.0), 3.0, np.inf, np.inf, *np.log([20.0, 20.0, 5.0, 2.0])])
    p0 = np.clip(p0, lo + 1e-6, hi - 1e-6)
    return p0, lo, hi


def _batched_residual(run_many: Callable[[np.ndarray], np.ndarray], y: np.ndarray,
                      ok: np.ndarray, hi: np.ndarray
                      ) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """The residual (degC, finite readings ``ok`` of ``y``) at a parameter vector and its
    forward-difference Jacobian, from ``run_many``'s spot temperatures; ``hi``: the upper
    bounds the differences stay under.

    The residual and its Jacobian come from ONE batched model pass (the point and its
    perturbation in each parameter as batch members), cached for the pair of calls
    least_squares makes at each accepted point.
    """
    cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def evaluate(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = p.tobytes()
        if key not in cache:
            step = 1e-3 * np.maximum(1.0, np.abs(p))
            step = np.where(p + step > hi, -step, step)  # stay inside the bounds
            res = (run_many(np.vstack([p, p + np.diag(step)])) - y[None])[:, ok]
            cache.clear()
            cache[key] = (res[0], ((res[1:] - res[0]) / step[:, None]).T)
        return cache[key]

    return evaluate


def fit_structure(
    inputs: DiscInputs, y: np.ndarray, disc: DiscSpec, law0: HLaw, est: EstimateTuning
) -> tuple[HLaw, StructureFit]:
    """Refine h(V) jointly with the estimation model's structure (output error).

    Parameters are the law's ``log a, b, c_1, c_2``, the crown weights ``log w_1, log
    w_2`` (``w_3`` fixed, renormalised to eq. 8), ``log kz_ratio`` and ``log scale``;
    the residual is the open-loop layered model minus the four measured spots over the
    whole session (robust soft-L1 loss). Starting from the UKF law ``law0``, this removes
    what the one-layer identification model folds into h after every braking. The cubic
    term is held at zero here: a session has too few samples above the knee to pin four
    coefficients there, and a free cubic swings between them. With less than
    :data:`MIN_ABOVE_KNEE_S` above the knee the upper branch is not fitted at all: it
    continues the power law along its tangent (as :meth:`HLaw.fit` does).
    """
    spot_radii = np.asarray(disc.spot_radii)
    v = inputs.speed[:-1]
    q, t_amb = inputs.q_brk[:-1], inputs.t_amb[:-1]
    model = disc_model(disc, est)
    basis = model.crown_basis()  # load = w @ basis for weights meeting eq. 8
    H = model.spot_matrix(spot_radii)
    T0 = np.repeat(_initial_profile(model.radii, spot_radii, y, float(inputs.t_amb[0])),
                   est.layers)
    ok = np.isfinite(y)

    upper_branch = np.count_nonzero(v >= law0.knee * law0.v_ref) * GRID_DT >= MIN_ABOVE_KNEE_S

    def unpack(p: np.ndarray) -> tuple[HLaw, np.ndarray, float, float]:
        a = float(np.exp(p[0]))
        tangent = a * p[1] * law0.knee ** (p[1] - 1.0)
        c = (p[2], p[3], 0.0) if upper_branch else (tangent, 0.0, 0.0)
        law = HLaw(v_ref=law0.v_ref, a=a, b=p[1], c=c, knee=law0.knee)
        w = normalise_weights(np.exp([p[4], p[5], 0.0]), disc.crown_edges)
        return law, w, float(np.exp(p[6])), float(np.exp(p[7]))

    def run_many(P: np.ndarray) -> np.ndarray:
        """Open-loop spot temperatures (B, K, 4) for B parameter vectors in one pass."""
        laws, ws, kzs, scales = zip(*(unpack(p) for p in P), strict=True)
        h = np.stack([law(v) for law in laws])
        load = np.stack(ws) @ basis
        out = model.run_readout(np.tile(T0, (len(P), 1)), q[:, None] * np.asarray(scales),
                                h.T, t_amb, np.asarray(kzs), load[None],
                                np.zeros(q.size, int), H)
        return out.transpose(1, 0, 2)

    def run(p: np.ndarray) -> np.ndarray:
        return run_many(p[None, :])[0]

    p0, lo, hi = _structure_start(law0)
    # without an upper branch c_1, c_2 enter nothing: left free, their Jacobian columns
    # are the batch's rounding noise, which x_scale="jac" turns into huge scales, and the
    # fit's path (it stops after 30 evaluations) then hangs on that noise
    free = np.ones(p0.size, bool)
    free[2:4] = upper_branch

    def with_fixed(X: np.ndarray) -> np.ndarray:
        P = np.tile(p0, (len(X), 1))
        P[:, free] = X
        return P

    evaluate = _batched_residual(lambda X: run_many(with_fixed(X)), y, ok, hi[free])
    sol = least_squares(lambda p: evaluate(p)[0], p0[free], jac=lambda p: evaluate(p)[1],
                        bounds=(lo[free], hi[free]), x_scale="jac", loss="soft_l1",
                        f_scale=20.0, ftol=1e-4, xtol=1e-4, max_nfev=30)
    p = with_fixed(sol.x[None])[0]
    law, w, kz, scale = unpack(p)
    at_bounds = _structure_at_bounds(p, lo, hi)
    uniform = np.array([*p0[:4], 0.0, 0.0, 0.0, 0.0])
    return law, StructureFit(
        weights=(float(w[0]), float(w[1]), float(w[2])),
        kz_ratio=kz,
        power_scale=scale,
        nodes=est.nodes,
        layers=est.layers,
        rmse_c=_spot_rmse(run(p), y),
        rmse_uniform_c=_spot_rmse(run(uniform), y),
        at_bounds=at_bounds,
    )


def _structure_at_bounds(p: np.ndarray, lo: np.ndarray, hi: np.ndarray
                         ) -> dict[tuple[str, str], float]:
    """:func:`fit_structure`'s crown weights, k_z ratio and power scale (log-fitted, from
    index 4 of ``p``) at a bound of their range ``lo``..``hi``, within 1 % of it in the
    fitted space (a bounded fit stops near its bound); the exponent b is judged by
    :func:`_law_check`, with what a flat law means."""
    span = hi[4:] - lo[4:]
    edge = (p[4:] <= lo[4:] + 1e-2 * span) | (p[4:] >= hi[4:] - 1e-2 * span)
    return {("reference", n): float(np.exp(x)) for n, x, e
            in zip(("w1", "w2", "kz_ratio", "scale"), p[4:], edge, strict=True) if e}


def _law_with_knee(a: float, b: float, gain: float, v_ref: float, knee: float) -> HLaw:
    """The power-cubic law closest to ``a x^b (1 + g u²)`` above the knee (u as in
    :func:`effects.knee_factor`), continuous at the knee, fitted on ``x`` up to 1.15."""
    x = np.linspace(knee, 1.15, 60)
    u_k = (x - knee) / (1.0 - knee)
    target = a * x**b * (1.0 + gain * u_k**2)
    u = x - knee
    c0 = a * knee**b
    c, *_ = np.linalg.lstsq(np.column_stack([u, u**2, u**3]), target - c0, rcond=None)
    return HLaw(v_ref=v_ref, a=a, b=b, c=(float(c[0]), float(c[1]), float(c[2])), knee=knee)


# Effects the structure fit always fits (the k_z ratio; the knee gain where the session
# runs above the knee): whether selected or not, they stay in the law.
STRUCTURE_EFFECTS = ("thickness_gradient", "h_speed_knee")


def fit_with_effects(
    session: Session, inputs: DiscInputs, y: np.ndarray, disc: DiscSpec, law0: HLaw,
    est: EstimateTuning, effects: tuple[str, ...], max_nfev: int = 30,
) -> tuple[HLaw, StructureFit]:
    """The structure fit of :func:`fit_structure` with registered effects fitted jointly.

    One parameter vector of :class:`~brakethermo.models.disc_effects.ExtendedDisc` on
    the estimation model (its through-thickness factor is the k_z ratio): h(V) with the
    knee gain when the session runs long enough above the knee, the mean crown weights,
    the power scale, the k_z ratio and the named effects, by output error over all four
    spots — so that an unmodelled μ(T), lag or slipstream is not folded into h(V).
    """
    from brakethermo.models.disc_effects import ExtendedDisc
    from brakethermo.pipelines.diagnose.fit import _fit
    from brakethermo.pipelines.diagnose.layout import session_segments

    spot_radii = np.asarray(disc.spot_radii)
    model = disc_model(disc, est)
    T0 = np.repeat(_initial_profile(model.radii, spot_radii, y, float(inputs.t_amb[0])),
                   est.layers)
    _, _, segments = session_segments(session, inputs)
    v = inputs.speed[:-1]
    upper = np.count_nonzero(v >= law0.knee * law0.v_ref) * GRID_DT >= MIN_ABOVE_KNEE_S
    structure = tuple(e for e in STRUCTURE_EFFECTS if upper or e != "h_speed_knee")
    names = tuple(dict.fromkeys((*structure, *effects)))
    ext = ExtendedDisc(model, inputs.speed, inputs.q_brk, inputs.t_amb, T0, spot_radii,
                       disc.v_ref, names, segments)
    p0 = ext.neutral()
    p0[0], p0[1] = np.log(max(law0.a, 1.0)), law0.b
    p = _fit(ext, p0, y, np.isfinite(y), np.ones(ext.size, bool), max_nfev)
    gain = ext.values(p, "h_speed_knee").get("gain", 0.0) if upper else 0.0
    assert isinstance(gain, float)
    law = _law_with_knee(float(np.exp(p[0])), float(p[1]), gain, disc.v_ref, law0.knee)
    kz = ext.values(p, "thickness_gradient")["kz_factor"]
    assert isinstance(kz, float)
    fitted = {name: ext.values(p, name) for name in effects}
    # the reference's own (h's a and b, the mean crown weights, the power scale) as well:
    # crown weights at w1 = 0.05 or a power scale at 3 are as clamped as any effect's
    # (h's exponent b is judged by _law_check, with what a flat law means)
    at_bounds = {**{k: v for k, v in ext.reference_at_bounds(p).items()
                    if k[1] != "b" or v > B_LAW_CHECKED},
                 **ext.at_bounds(p, every=True)}
    return law, StructureFit(
        weights=ext.weights(p),
        kz_ratio=kz,
        power_scale=float(np.exp(p[2])),
        nodes=est.nodes,
        layers=est.layers,
        rmse_c=_spot_rmse(ext.predict(p)[0], y),
        rmse_uniform_c=_spot_rmse(ext.predict(p0)[0], y),
        effects=fitted,
        at_bounds=at_bounds,
        stretched=ext.at_bounds(p),
    )


def auto_effects(session: Session, options: IdentifyOptions
                 ) -> tuple[tuple[str, ...], dict[str, Any], Any]:
    """The effects the diagnosis's forward selection keeps on this session, why, and the
    diagnosis itself (``None`` when it could not run; batch writes it beside the law).

    A session the diagnosis cannot split into training and held-out laps (fewer than two
    flying laps) carries no effect, and says so.
    """
    from brakethermo.pipelines.diagnose import DiagnoseOptions, diagnose_session

    try:
        result = diagnose_session(session, DiagnoseOptions(
            disc=options.disc, tuning=options.tuning, aliases=options.aliases,
            ambient_c=options.ambient_c))
    except DataError as exc:
        return (), {"mode": "auto", "selected": [],
                    "why": f"no selection: the diagnosis could not run ({exc.detail})"}, None
    s = result.summary
    chosen = tuple(s["combined"]["effects"])
    why = (f"diagnosis verdict {s['verdict']} ({s['verdict_kind']}); forward selection on"
           f" held-out laps {s['heldout_laps']} keeps {', '.join(chosen) or 'none'}")
    return chosen, {"mode": "auto", "selected": list(chosen), "why": why,
                    "verdict": s["verdict"], "verdict_set": s["verdict_set"],
                    "next_steps": s["next_steps"]}, result


SIGMA_CROWN_GRID = (0.1, 0.2, 0.4)  # relative crown-share noise tried by validation
NODE_NOISE_FACTORS = (1.0, 3.0)  # white node noise tried, times the tuning's sigma_temp


def _held_out(
    session: Session, calibration: DiscCalibration, options: IdentifyOptions, spot: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Run the race estimator with only ``spot`` measured; errors and sigmas elsewhere.

    Returns the errors and 1-sigmas of the other spots' estimates against their
    readings (pooled) and the reading noise (degC) of each pooled point.
    """
    est = estimate_from_session(
        session,
        EstimateOptions(spot=spot, disc=options.disc, tuning=options.tuning,
                        aliases=options.aliases, ambient_c=options.ambient_c, score=False,
                        sigma_crown=calibration.sigma_crown,
                        adapt_power=calibration.adapt_power,
                        # the race switches online effects on only where it shows them; on
                        # a disc like this session's it leaves them off: calibrate for that
                        adapt_kz=False, adapt_slipstream=False),
        calibration=calibration,
    )  # fmt: skip
    # the readings as every fit takes them (frozen and clipped stretches left out)
    inputs = disc_inputs(session, est.disc, options.ambient_c)
    readings = inputs.spots.copy()
    readings[readings <= SENSOR_FLOOR_C] = np.nan
    err, std, noise = [], [], []
    for i in range(1, 5):
        if i == spot:
            continue
        ref = readings[:, i - 1]
        ok = np.isfinite(ref)
        err.append(est.frame[f"spot{i}"].to_numpy()[ok] - ref[ok])
        std.append(est.spread[ok, i - 1])
        sigma = scoring.reading_noise(ref, inputs.per_reading[i - 1], inputs.steady)
        noise.append(np.full(int(ok.sum()), sigma))
    return np.concatenate(err), np.concatenate(std), np.concatenate(noise)


def validate_filter(
    session: Session, calibration: DiscCalibration, options: IdentifyOptions,
    spot: int = 3, level: float = 0.95,
) -> tuple[float, bool, float, dict[str, float]]:
    """Crown-split noise, power adaptation and band scale chosen on unmeasured spots.

    For each crown-noise level of :data:`SIGMA_CROWN_GRID` and white node noise of
    :data:`NODE_NOISE_FACTORS`, with and without the braking-power scale as a state,
    the race estimator runs with only ``spot``
    measured; the variant under which the other spots' readings are most probable
    (held-out predictive log-likelihood, each reading with its own noise) wins: the
    process noise is identified from data the filter did not see. Then, as a check,
    by bisection, the factor ``a`` on the filter's 1-sigma for which a fraction
    ``level`` of those readings lie within ``z · sqrt(a² sigma² + sigma_n²)``, with
    ``sigma_n`` each reading's own noise (:func:`scoring.reading_noise`). It is
    reported, not applied: near 1 the filter's own bands are honest.

    Returns
    -------
    sigma_crown : float
    sigma_temp : float — degC per step
    adapt_power : bool
    band_scale : float
    scores : dict of str to float — held-out log-likelihood per reading of every variant
    """
    from scipy.stats import norm

    scores = {}
    runs = {}
    sigma_temp0 = load_tuning(options.tuning)[0].sigma_temp
    grid = [(sigma, factor * sigma_temp0, adapt) for sigma in SIGMA_CROWN_GRID
            for factor in NODE_NOISE_FACTORS for adapt in (True, False)]
    variants = [replace(calibration, sigma_crown=sigma, adapt_power=adapt,
                        sigma_temp=sigma_temp) for sigma, sigma_temp, adapt in grid]
    # the estimator's compiled kernels release the GIL: the variants share the cores
    with ThreadPoolExecutor(os.cpu_count() or 1) as pool:
        held = list(pool.map(lambda v: _held_out(session, v, options, spot), variants))
    for (sigma, sigma_temp, adapt), (e, s, noise) in zip(grid, held, strict=True):
        key = (f"sigma_crown={sigma:g}, sigma_temp={sigma_temp:g},"
               f" adapt_power={str(adapt).lower()}")
        # Held-out predictive log-likelihood per reading: the process noise that
        # makes the unmeasured spots most probable, bands and errors together.
        var = s**2 + noise**2
        scores[key] = float(np.mean(-0.5 * (np.log(2.0 * np.pi * var) + e**2 / var)))
        runs[key] = (sigma, sigma_temp, adapt, e, s, noise)
    best = max(scores, key=scores.__getitem__)
    sigma_best, temp_best, adapt_best, e, s, noise = runs[best]
    e = np.abs(e)
    z = float(norm.ppf(0.5 + level / 2.0))

    def covered(a: float) -> float:
        return float(np.mean(e <= z * np.sqrt((a * s) ** 2 + noise**2)))

    lo, hi = 1.0, 50.0
    if e.size == 0 or covered(lo) >= level:
        return sigma_best, temp_best, adapt_best, lo, scores
    if covered(hi) < level:
        return sigma_best, temp_best, adapt_best, hi, scores
    for _ in range(40):
        mid = float(np.sqrt(lo * hi))
        lo, hi = (mid, hi) if covered(mid) < level else (lo, mid)
    return sigma_best, temp_best, adapt_best, hi, scores


def _filter_facts(forward: Any) -> dict[str, Any]:
    """The joint UKF's run facts."""
    return {"filter": "joint UKF + unscented RTS smoother, h as random walk",
            "covariance_repairs": forward.n_repairs,
            "mean_nis": float(np.nanmean(forward.nis))}


def _law_dict(law: HLaw) -> dict[str, Any]:
    return {"v_ref_kmh": law.v_ref * 3.6, "knee": law.knee, "a": law.a, "b": law.b,
            "c": [law.c0, *law.c],
            **({"v_data_kmh": law.x_data * law.v_ref * 3.6} if math.isfinite(law.x_data)
               else {})}


def _effect_choice(session: Session, options: IdentifyOptions
                   ) -> tuple[tuple[str, ...], dict[str, Any], Any]:
    """The effects to carry (``--with-effect``), why, and the diagnosis when it chose them."""
    text = (options.with_effects or "").strip().lower()
    if text == "auto":
        return auto_effects(session, options)
    if text and text != "none":
        effects = parse_effects(options.with_effects)
        return effects, {"mode": "given", "selected": list(effects), "why": "--with-effect"}, None
    return (), {"mode": "none", "selected": [], "why": "--with-effect none: the plain law"}, None


RACE_TESTED = ("friction_temperature",)  # a law's effects the race checks before use


def _testable(session: Session, inputs: DiscInputs, y: np.ndarray, disc: DiscSpec,
              effects: tuple[str, ...], selection: dict[str, Any], notes: list[str]
              ) -> tuple[tuple[str, ...], dict[str, Any]]:
    """The given or selected effects less those whose signature the session does not
    hold: fitted there, such an effect's parameter comes out of the noise and the other
    parameters' trade-offs (a pyrometer emissivity ratio of 0.91 on a session read at the
    true setting; 0.6, the bound, on an independent generator's sessions where the
    diagnosis found it significant), and estimate would then apply it to every race
    unchecked."""
    from brakethermo.pipelines.diagnose.data_power import untestable_on

    blind = untestable_on(session, inputs, y, disc.v_ref)
    # μ(T) stays: the race tests a law's μ(T) on its own laps before keeping it, and a
    # strong one shows on a session whose stops start close together (diagnose names it
    # there, significant, and so does not call it untestable)
    dropped = {name: blind[name] for name in effects
               if name in blind and name not in RACE_TESTED}
    return _without(effects, selection, dropped, "not_carried", "untestable here",
                    "this session cannot test it — {}", notes)


def _without(effects: tuple[str, ...], selection: dict[str, Any], dropped: dict[str, str],
             key: str, short: str, note: str, notes: list[str]
             ) -> tuple[tuple[str, ...], dict[str, Any]]:
    """``effects`` less ``dropped`` (name -> why), each said in ``notes`` (``note`` takes
    the why) and recorded in the selection under ``key``."""
    if not dropped:
        return effects, selection
    kept = tuple(name for name in effects if name not in dropped)
    notes.extend(f"{name}: not carried, {note.format(why)}" for name, why in dropped.items())
    return kept, {**selection, "selected": list(kept), key: dropped,
                  "why": f"{selection['why']}; less {', '.join(dropped)} ({short})"}


def _refit_carried(session: Session, inputs: DiscInputs, y: np.ndarray, disc: DiscSpec,
                   start: HLaw, est_tuning: EstimateTuning, effects: tuple[str, ...],
                   selection: dict[str, Any], notes: list[str]
                   ) -> tuple[HLaw, StructureFit, EstimateTuning, tuple[str, ...],
                              dict[str, Any]]:
    """The law refitted with ``effects``; an effect the diagnosis selected (``auto``)
    whose refit ends at a bound of its range is dropped and the law refitted without it
    (it stands in for something else), until none is; one the user named is kept, and
    warned about. Each refit starts from the caller's layering (a refit that went
    thin-skin with the dropped effect may not without it)."""
    law, structure, tuning = _refit(session, inputs, y, disc, start, est_tuning, effects)
    dropped: dict[str, str] = {}
    while selection["mode"] == "auto":
        edge: dict[str, list[str]] = {}
        for (name, param), value in structure.stretched.items():
            if name in effects and name not in STRUCTURE_EFFECTS:
                edge.setdefault(name, []).append(f"{param} = {value:.4g}")
        if not edge:
            break
        dropped |= {name: ", ".join(params) for name, params in edge.items()}
        effects = tuple(e for e in effects if e not in edge)
        law, structure, tuning = _refit(session, inputs, y, disc, start, est_tuning, effects)
    effects_before = (*effects, *dropped)
    kept, selection = _without(effects_before, selection, dropped, "at_bound", "at a bound",
                               "its refit ended at a bound of its range ({}), so it stands"
                               " in for something else", notes)
    return law, structure, tuning, kept, selection


def _sample_law(inputs: DiscInputs, h_mean: np.ndarray, h_std: np.ndarray,
                fit_mask: np.ndarray, disc: DiscSpec, tuning: IdentifyTuning, refit: bool,
                notes: list[str]) -> tuple[HLaw | None, HLaw]:
    """The paper's law fitted to the UKF's h samples, and where the refit starts from."""
    try:
        law_ukf = HLaw.fit(inputs.speed[fit_mask], h_mean[fit_mask], 1.0 / h_std[fit_mask] ** 2,
                           v_ref=disc.v_ref, knee=tuning.knee)
        return law_ukf, law_ukf
    except DataError as exc:
        # The paper's joint UKF has h as its only free parameter: a braking power far from
        # nominal or a lagging sensor can drive its h track below zero everywhere. The
        # output-error refit fits the power scale too, so it can still find the law.
        shipped = shipped_h_law(disc)
        if shipped is None or not refit:
            raise
        notes.append(f"the joint UKF's h track is unusable ({exc}); the law comes from the"
                     " output-error refit alone (with the braking-power scale), started from"
                     f" the shipped law {shipped.name}")
        return None, read_h_law(shipped).law


def _refit(session: Session, inputs: DiscInputs, y: np.ndarray, disc: DiscSpec, start: HLaw,
           est_tuning: EstimateTuning, effects: tuple[str, ...]
           ) -> tuple[HLaw, StructureFit, EstimateTuning]:
    """The law refitted with the layered model (and the effects); a thin-skin disc is
    refitted once more on the finer layering it needs. (Its radial nodes stay: refitted
    on the thin-skin 15 as well, six development thin-skin laws gained, 0.37 -> 0.34 of
    the single-spot baseline, and the reporting ones lost, 0.47 -> 0.49.)"""

    def structure_fit(start: HLaw, tuning_: EstimateTuning) -> tuple[HLaw, StructureFit]:
        if effects:
            return fit_with_effects(session, inputs, y, disc, start, tuning_, effects)
        return fit_structure(inputs, y, disc, start, tuning_)

    law, structure = structure_fit(start, est_tuning)
    if structure.kz_ratio < est_tuning.thin_skin_kz_ratio:
        est_tuning = replace(est_tuning, layers=est_tuning.thin_skin_layers,
                             layer_growth=est_tuning.thin_skin_layer_growth)
        law, structure = structure_fit(law, est_tuning)
    return law, structure, est_tuning


def _calibration(session: Session, law: HLaw, structure: StructureFit | None,
                 est_tuning: EstimateTuning) -> DiscCalibration:
    """The estimate's calibration from the law and the fitted structure (neutral without
    one), before the filter's validation."""
    return DiscCalibration(
        law=law,
        weights=structure.weights if structure else (1.0, 1.0, 1.0),
        kz_ratio=structure.kz_ratio if structure else 1.0,
        power_scale=structure.power_scale if structure else 1.0,
        layers=est_tuning.layers,
        layer_growth=est_tuning.layer_growth,
        nodes=est_tuning.nodes,
        effects=structure.effects if structure else {},
        source=str(session.path),
    )


def _samples(inputs: DiscInputs, h_mean: np.ndarray, h_std: np.ndarray, braking: np.ndarray
             ) -> pd.DataFrame:
    """The ``h_samples.parquet`` table: the UKF's h (W/(m² K)), its std and the brake's
    state on the grid."""
    return pd.DataFrame({
        "time": inputs.time,
        "lap": inputs.lap.astype(np.int64),
        "speed": inputs.speed,
        "h": h_mean,
        "h_std": h_std,
        "braking": braking,
    })


def _fit_facts(fit_mask: np.ndarray, h_std: np.ndarray, residual: np.ndarray
               ) -> dict[str, Any]:
    """``fit`` of identify.json: the off-brake samples and the UKF law's residual there
    (W/(m² K))."""
    return {
        "samples_off_brake": int(fit_mask.sum()),
        "samples_total": int(fit_mask.size),
        "ukf_law_residual_rms": rmse(residual),
        "h_std_median": float(np.median(h_std[fit_mask])),
    }


def _evidence_facts(level: dict[str, Any]) -> dict[str, Any]:
    """``evidence`` of identify.json: the law's level per straight, and what it is."""
    return {
        **level,
        "what": "per off-brake straight, the factor on the written law that makes the"
                " layered model's cooling match the measured one (h_law.png); 1 = the"
                " law holds; the interval from the straight-to-straight scatter",
    }


def _bound_notes(structure: StructureFit | None) -> list[str]:
    """A note per fitted parameter that sits at a bound of its range (per-segment values
    of one parameter together)."""
    if structure is None:
        return []
    grouped: dict[tuple[str, str], list[str]] = {}
    stretched: set[str] = set()
    for (name, param), value in structure.at_bounds.items():
        grouped.setdefault((name, param.split("[", 1)[0]), []).append(
            f"{name}.{param} = {value:.4g}")
        if name == "reference" or (name, param) in structure.stretched:
            stretched.add(name)
    return [", ".join(values) + (" sit" if len(values) > 1 else " sits")
            + (" at the bound the fit allows: the data push it further than the model's"
               " range, so " + _bound_why(name) if name in stretched else
               " at the edge of its range: a single zone's or straight's value, or the"
               " effect's absent value (a lag the fit found none of) — said, not taken as"
               " the effect's form failing")
            for (name, _), values in grouped.items()]


def _bound_why(name: str) -> str:
    """What a parameter of ``name`` (an effect, or ``reference``) at a bound means."""
    if name == "reference":
        return ("the reference model (h(V), crown weights, power scale) has absorbed"
                " something it does not model (`brakethermo diagnose` tests the effects;"
                " identify-h --with-effect carries them)")
    if name in STRUCTURE_EFFECTS:
        return ("the effect's form does not fit them (part of every law's structure, kept:"
                " read the law's h(V) above the knee and its k_z with care; `brakethermo"
                " diagnose` tests the effect)")
    return ("the effect's form does not fit them (kept as named; check the carried effects"
            " against `brakethermo diagnose`)")


def _law_check(law: HLaw, speed: np.ndarray, structure: StructureFit | None,
               notes: list[str]) -> dict[str, Any] | None:
    """The written law's plausibility as forced convection (:func:`law_speed_check` on
    its off-brake speeds, m/s), warned about in ``notes``; an exponent at its bound is
    recorded in the structure's ``at_bounds`` as ``reference.b`` too. The fit is left as
    it is: the warning says what the law probably absorbed and how to find out."""
    check = law_speed_check(law, speed)
    if check is None:
        return None
    notes.append(check["text"])
    if structure is not None and check["b_at_bound"]:
        structure.at_bounds[("reference", "b")] = check["b"]
    return check


def identify_from_session(session: Session, options: IdentifyOptions) -> IdentifyResult:
    """Run identify-h on a loaded session (see :func:`identify_h`)."""
    t0 = time.perf_counter()
    options = replace(options, tuning=read_tuning(options.tuning))  # once for every run
    est_tuning, tuning = load_tuning(options.tuning)
    if options.nodes is not None:
        tuning = replace(tuning, nodes=options.nodes)
    disc, inputs, y = fit_inputs(session, options.disc, options.ambient_c)
    h_mean, h_std, forward = identify_h_samples(inputs, y, disc, tuning)
    t_ukf = time.perf_counter()

    braking = inputs.braking
    fit_mask = off_brake_mask(braking) & np.isfinite(y).all(axis=1) & (inputs.speed > 1.0)
    effects, selection, diagnosis = _effect_choice(session, options)
    notes: list[str] = []
    if selection["mode"] in ("given", "auto"):
        effects, selection = _testable(session, inputs, y, disc, effects, selection, notes)
    law_ukf, start = _sample_law(inputs, h_mean, h_std, fit_mask, disc, tuning,
                                 options.fit_structure or bool(effects), notes)
    t_law = time.perf_counter()
    law, structure = start, None
    if options.fit_structure or effects:
        law, structure, est_tuning, effects, selection = _refit_carried(
            session, inputs, y, disc, start, est_tuning, effects, selection, notes)
    t_struct = time.perf_counter()
    notes.extend(_bound_notes(structure))
    if fit_mask.any():  # what its h samples reach: beyond, the law grows as its power branch
        law = replace(law, x_data=float(np.nanmax(np.abs(inputs.speed[fit_mask]))) / law.v_ref)
    law_check = _law_check(law, inputs.speed[fit_mask], structure, notes)
    calibration = _calibration(session, law, structure, est_tuning)
    sigma_crown, sigma_temp, adapt_power, band_scale, validation = validate_filter(
        session, calibration, options
    )
    calibration = replace(calibration, band_scale=band_scale, sigma_crown=sigma_crown,
                          sigma_temp=sigma_temp, adapt_power=adapt_power)
    t_end = time.perf_counter()

    samples = _samples(inputs, h_mean, h_std, braking)
    residual = h_mean[fit_mask] - (law_ukf or law)(inputs.speed[fit_mask])
    straights = level = None
    if structure is not None:
        straights = straight_factors(inputs, y, disc, calibration, est_tuning,
                                     off_brake_mask(braking))
        level = law_level(straights)
    timings = {"ukf_s": t_ukf - t0, "law_s": t_law - t_ukf, "structure_s": t_struct - t_law,
               "calibration_s": t_end - t_struct, "total_s": t_end - t0}
    summary = {
        "session": str(session.path),
        "metadata": session.metadata,
        "law": _law_dict(law),
        "law_ukf_only": None if law_ukf is None else _law_dict(law_ukf),
        "law_check": law_check,
        "fit": _fit_facts(fit_mask, h_std, residual),
        "structure": None if structure is None else structure.facts(),
        "k_z": kz_scales(disc, calibration.kz_ratio),  # kz_ratio in W/(m K), over nominal
        "evidence": None if level is None else _evidence_facts(level),
        "with_effects": list(effects),
        "effect_selection": selection,
        "band_scale": band_scale,
        "sigma_crown": sigma_crown,
        "sigma_temp": sigma_temp,
        "adapt_power": adapt_power,
        "validation_loglik": validation,
        "run": {
            "brakethermo": __version__,
            "disc": disc.id,
            "nodes": tuning.nodes,
            "layers": tuning.layers,
            "estimate_layers": est_tuning.layers,
            "estimate_layer_growth": est_tuning.layer_growth,
            "estimate_nodes": est_tuning.nodes,
            **_filter_facts(forward),
            "timings_s": timings,
            "wall_time_s": timings["total_s"],
            "warnings": [*session.warnings, *inputs.warnings, *notes,
                         *filter(None, [assumed_disc(session, options.disc)])],
        },
    }
    return IdentifyResult(session, law, law_ukf, calibration, samples, structure, fit_mask,
                          summary, timings, straights, diagnosis)


def identify_h(path: str | Path, options: IdentifyOptions | None = None) -> IdentifyResult:
    """Identify h(V) (and the estimation model's structure) from a four-spot session.

    Parameters
    ----------
    path : str or Path
        Test session with ``disc_temp_spot1..4``.
    options : IdentifyOptions, optional

    Returns
    -------
    IdentifyResult
    """
    options = options or IdentifyOptions()
    session, read_s = load_timed(path, options.aliases)
    result = identify_from_session(session, options)
    result.timings["read_s"] = read_s
    return result


# h_law.toml's k_z values are on three scales: say which is which where they are written
KZ_NOTES = {
    "kz_ratio": "kz_ratio: through-thickness conductivity over the datasheet's in-plane k(T)"
                " (k_z = kz_ratio x k(T)),\nnot over its nominal k_z; k_z_w_mk is it in W/(m K)"
                " at k_z_ref_c (degC), kz_over_nominal\nover the datasheet's k_z (diagnose's"
                " kz_over_nominal: the same scale)",
    "effects.thickness_gradient": "kz_factor here is kz_ratio (k_z / k(T), [extra]), not"
                                  " diagnose's kz_over_nominal",
}


def write_identify(result: IdentifyResult, out_dir: str | Path,
                   shown_out: str | Path | None = None) -> Path:
    """Write ``h_law.toml``, ``h_samples.parquet``, ``identify.json`` and the h(V) plot
    (``shown_out``: the ``--out`` its suggested commands name, when ``out_dir`` is a
    staging folder)."""
    from brakethermo.pipelines.diagnose._common import with_out
    from brakethermo.report.hplot import plot_h_law

    result.summary = with_out(result.summary, shown_out or out_dir)
    folder = Path(out_dir) / result.stem
    folder.mkdir(parents=True, exist_ok=True)
    cal = result.calibration
    extra: dict[str, Any] = {
        "session": str(result.session.path),
        "disc": result.summary["run"]["disc"],  # whatif and estimate refuse another disc's law
        "brakethermo": __version__,
        "kz_ratio": cal.kz_ratio,
        **result.summary["k_z"],
        "power_scale": cal.power_scale,
        "band_scale": cal.band_scale,
        "sigma_crown": cal.sigma_crown,
        "sigma_temp": cal.sigma_temp,
        "adapt_power": cal.adapt_power,
        "layers": cal.layers,
        "layer_growth": cal.layer_growth,
        "nodes": cal.nodes,
    }
    write_text_atomic(folder / "h_law.toml",
                      result.law.toml_text(weights=cal.weights, extra=extra, effects=cal.effects,
                                           notes=KZ_NOTES))
    write_parquet(
        folder / "h_samples.parquet", result.samples,
        {"time": {"unit": "s"}, "speed": {"unit": "m/s"}, "h": {"unit": "W/(m2 K)"},
         "h_std": {"unit": "W/(m2 K)"}},
        {"brakethermo": __version__, "session": str(result.session.path)},
    )  # fmt: skip
    write_json(folder / "identify.json", result.summary)
    plot_h_law(result.samples, result.fit_mask, result.law, folder / "h_law.png",
               title=result.stem, law_ukf=result.law_ukf if result.structure else None,
               straights=result.straights, level=result.summary.get("evidence"),
               carried=tuple(cal.effects),
               warning=(result.summary.get("law_check") or {}).get("text", ""))
    return folder
