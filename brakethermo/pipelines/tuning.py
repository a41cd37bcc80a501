"""Filter tuning for the disc pipelines, loaded from TOML with validation.

Also the names of the roller rig's noise presets: light enough for the CLI's option help.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from brakethermo.config import ConfigTable, config_dir, config_file
from brakethermo.errors import ConfigError


@dataclass(frozen=True)
class SigmaPointTuning:
    """Merwe scaled sigma-point parameters (dimensionless)."""

    alpha: float = 0.5
    beta: float = 2.0
    kappa: float = 0.0


@dataclass(frozen=True)
class EstimateTuning(SigmaPointTuning):
    """Tuning of the race-session estimator (state: node temperatures [+ power scale]).

    Attributes
    ----------
    nodes, layers : int
        Radial nodes and through-thickness layers of the model.
    layer_growth : float
        Thickness ratio of successive layers from the face (1 = equal layers).
    thin_skin_kz_ratio : float
        Below this identified k_z ratio, identify-h switches to the thin-skin layering.
    thin_skin_layers, thin_skin_layer_growth : int, float
    thin_skin_nodes : int
        Radial nodes of a race that learns a thinner skin than its law's: the face of a
        thin skin follows the radial profile of the pads' flux, which 10 nodes smear.
    smoother, adapt_power : bool
    sigma_meas : float — degC
    sigma_temp : float — degC per step
    sigma_crown : float — relative share of braking power, per crown
    sigma_scale_step : float — per step
    init_sigma_temp : float — degC
    init_sigma_scale : float — dimensionless
    adapt_kz : bool
        Through-thickness conductivity factor as a random-walk state (race discs differ
        from the test session's disc batch to batch).
    adapt_slipstream : bool
        An h factor as a random-walk state that moves off the brakes only (following
        another bike changes the cooling air straight by straight).
    sigma_kz_step, init_sigma_kz : float — per step, dimensionless
    sigma_h_factor_step, init_sigma_h_factor : float — per step, dimensionless
    adapt_balance : bool
        The inner/outer crown balance of the pad pressure as a random-walk state (a
        race's pads need not press as the test session's did; spot 3 sees the balance
        only weakly, and cannot tell it from a k_z change: off by default).
    sigma_balance_step, init_sigma_balance : float — per step, dimensionless
    ir_calibration_pct : float — % of absolute temperature, 1 sigma
        The pyrometer's absolute calibration (emissivity) uncertainty, common to every
        reading: added to the reported band, which the filter alone cannot widen for it.
    crown_balance_sd : float — log of the inner/outer weight ratio, 1 sigma
        How far a race's pads may share the power between the crowns unlike the law's
        (test session's): what it changes at the unmeasured spots is added to the
        reported band (:mod:`brakethermo.pipelines.crown_band`); 0 turns it off.
    """

    nodes: int = 10
    layers: int = 4
    layer_growth: float = 2.25
    thin_skin_kz_ratio: float = 0.15
    thin_skin_layers: int = 6
    thin_skin_layer_growth: float = 1.9
    thin_skin_nodes: int = 15
    smoother: bool = True
    adapt_power: bool = True
    sigma_meas: float = 5.0
    sigma_temp: float = 0.2
    sigma_crown: float = 0.35
    sigma_scale_step: float = 0.003
    init_sigma_temp: float = 40.0
    init_sigma_scale: float = 0.15
    adapt_kz: bool = True
    adapt_slipstream: bool = True
    sigma_kz_step: float = 0.002
    init_sigma_kz: float = 0.3
    sigma_h_factor_step: float = 0.01
    init_sigma_h_factor: float = 0.05
    adapt_balance: bool = False
    sigma_balance_step: float = 0.0005
    init_sigma_balance: float = 0.15
    ir_calibration_pct: float = 1.0
    crown_balance_sd: float = 0.25


@dataclass(frozen=True)
class IdentifyTuning(SigmaPointTuning):
    """Tuning of the h identification (state: node temperatures and h, eq. 50).

    Attributes
    ----------
    h_init, h_init_sigma : float — W/(m² K)
    h_step : float — W/(m² K) per step, the random walk of h (eq. 48)
    knee : float — fraction of V_ref where h(V) changes branch
    """

    nodes: int = 51
    layers: int = 1
    sigma_meas: float = 5.0
    sigma_temp: float = 0.2
    sigma_crown: float = 0.35
    h_init: float = 100.0
    h_init_sigma: float = 60.0
    h_step: float = 4.0
    init_sigma_temp: float = 40.0
    knee: float = 0.8


T = TypeVar("T", bound=SigmaPointTuning)

# The roller rig's filter noise (pipelines.roller_rig): R from the session and the
# datasheet's q_measured, or the paper's P0/Q/R (eq. 15a-15c).
ROLLER_RIG_TUNINGS = ("measured", "paper")

# Ranges a value must lie in (inclusive); beyond them the model or filter is meaningless
# or numerically broken. Keys not listed only need to be finite and > 0.
BOUNDS: dict[str, tuple[float, float]] = {
    "nodes": (10, 400),
    "thin_skin_nodes": (10, 400),
    "layers": (1, 8),
    "thin_skin_layers": (1, 8),
    "layer_growth": (0.2, 10.0),
    "thin_skin_layer_growth": (0.2, 10.0),
    "thin_skin_kz_ratio": (0.0, 10.0),
    "ir_calibration_pct": (0.0, 10.0),
    "crown_balance_sd": (0.0, 1.5),
    "init_sigma_balance": (0.0, 0.6),
    "alpha": (1e-4, 1.0),
    "beta": (0.0, 10.0),
    "kappa": (-1e3, 1e3),
    "sigma_meas": (1e-3, 200.0),
    "sigma_temp": (0.0, 50.0),
    "sigma_crown": (0.0, 5.0),
    "sigma_scale_step": (0.0, 1.0),
    "init_sigma_temp": (1e-3, 1000.0),
    "init_sigma_scale": (0.0, 5.0),
    "sigma_kz_step": (0.0, 1.0),
    "init_sigma_kz": (0.0, 5.0),
    "sigma_h_factor_step": (0.0, 1.0),
    "init_sigma_h_factor": (0.0, 5.0),
    "h_init": (0.0, 5000.0),
    "h_init_sigma": (1e-3, 5000.0),
    "h_step": (0.0, 1000.0),
    "knee": (0.1, 2.0),
}


def _build(cls: type[T], table: ConfigTable) -> T:
    """Validate ``table`` against the fields of ``cls`` (types from the defaults, BOUNDS)."""
    fields = [f.name for f in dataclasses.fields(cls)]
    table.only(fields)
    defaults = cls()
    values: dict[str, Any] = {}
    for key in fields:
        default = getattr(defaults, key)
        if isinstance(default, bool):
            values[key] = table.boolean(key, default)
        elif isinstance(default, int):
            lo, hi = BOUNDS.get(key, (1, math.inf))
            values[key] = table.integer(key, default, lo=lo, hi=hi)
        elif key in BOUNDS:
            lo, hi = BOUNDS[key]
            values[key] = table.number(key, default, lo=lo, hi=hi)
        else:
            values[key] = table.number(key, default, positive=True)
    return cls(**values)


def check_overrides(overrides: dict[str, Any], where: str = "option") -> None:
    """The same bounds for values set on the command line or by a caller as for the file.

    Raises
    ------
    ConfigError
        A value outside :data:`BOUNDS` (``--nodes 100000`` would ask for terabytes).
    """
    for key, value in overrides.items():
        if value is None or isinstance(value, bool) or key not in BOUNDS:
            continue
        lo, hi = BOUNDS[key]
        if not math.isfinite(value) or not lo <= value <= hi:
            raise ConfigError(
                f"{where} {key} = {value} must be between {lo:g} and {hi:g}"
                " (the same limits as the tuning file)"
            )


@dataclass(frozen=True)
class TuningFiles:
    """The tuning files as read for one command: the shipped file overlaid with the
    user's, and the keys the user's file sets. A command reads them once and passes this
    in place of the path (``tuning=``), so identify-h's validation runs and a race's
    decision passes share one read and cannot see a file edited half-way through.

    Attributes
    ----------
    estimate : EstimateTuning
    identify : IdentifyTuning
    user_estimate, user_identify : frozenset of str — keys the user's file sets per section.
    """

    estimate: EstimateTuning
    identify: IdentifyTuning
    user_estimate: frozenset[str] = frozenset()
    user_identify: frozenset[str] = frozenset()


TuningSource = str | Path | TuningFiles | None


def read_tuning(path: TuningSource = None) -> TuningFiles:
    """Read the shipped tuning, overlaid key by key with a user's TOML file when given
    (a :class:`TuningFiles` already read is returned as it is)."""
    if isinstance(path, TuningFiles):
        return path
    shipped = config_file(config_dir() / "tuning.toml")
    user = config_file(path) if path is not None else None
    if user is not None:
        user.only(("estimate", "identify"))
    tunings, keys = [], []
    for cls, section in ((EstimateTuning, "estimate"), (IdentifyTuning, "identify")):
        base = shipped.table(section, {})
        built = _build(cls, base)  # the shipped file alone must be valid too
        mine = user.table(section, {}).raw if user is not None else {}
        if user is not None:
            built = _build(cls, ConfigTable({**base.raw, **mine}, user.path, section))
        tunings.append(built)
        keys.append(frozenset(mine))
    return TuningFiles(tunings[0], tunings[1], keys[0], keys[1])  # type: ignore[arg-type]


def load_tuning(path: TuningSource = None) -> tuple[EstimateTuning, IdentifyTuning]:
    """The estimate and identify tunings (:func:`read_tuning`)."""
    files = read_tuning(path)
    return files.estimate, files.identify


def user_tuning_keys(path: TuningSource, section: str) -> frozenset[str]:
    """The keys a user's tuning file sets in ``[section]`` (empty without a file)."""
    if path is None:
        return frozenset()
    files = read_tuning(path)
    return files.user_estimate if section == "estimate" else files.user_identify
