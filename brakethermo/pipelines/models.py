"""Resolving the disc datasheet and the h(V) law a session is processed with."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from brakethermo.config import config_dir
from brakethermo.errors import ConfigError
from brakethermo.io.session import Session
from brakethermo.models.effects import EFFECTS
from brakethermo.thermal.disc import DiscSpec, load_disc
from brakethermo.thermal.hlaw import HLaw, read_h_law

DEFAULT_DISC = "cc-340-8"


def disc_for(session: Session, disc: str | Path | None = None) -> DiscSpec:
    """The datasheet given by the user, else the session's ``disc`` fact, else the default."""
    return load_disc(disc or session.metadata.get("disc") or DEFAULT_DISC)


def shipped_h_law(disc: DiscSpec) -> Path | None:
    """The h law shipped for this disc (identified from the sample test session), if any."""
    path = config_dir() / "hlaw" / f"{disc.id}.toml"
    return path if path.is_file() else None


@dataclass(frozen=True)
class DiscCalibration:
    """What identify-h learns about a disc installation and estimate relies on.

    Attributes
    ----------
    law : HLaw
        Convection law h(V).
    weights : tuple of 3 float
        Mean pad-crown power weights (eq. 6–8).
    kz_ratio : float
        Through-thickness over in-plane conductivity of the layered model.
    power_scale : float
        Mean braking power relative to the datasheet formula (friction vs nominal).
    band_scale : float
        Factor on the filter's 1-sigma that makes the 95 % band cover the unmeasured
        spots of the identification session.
    sigma_crown : float or None
        Crown-split process noise chosen by held-out-spot validation on that session.
    adapt_power : bool or None
        Whether the braking-power scale is a filter state, chosen by that validation.
    layers, layer_growth : int or None, float or None
        The through-thickness layering the calibration was fitted with (``kz_ratio``
        belongs to it); ``None`` leaves the tuning's.
    effects : dict of str to dict
        Fitted effect parameters by effect name (``[effects.<name>]`` of the file),
        validated against :data:`brakethermo.models.effects.EFFECTS`.
    source : str
        Where it came from (file path).
    """

    law: HLaw
    weights: tuple[float, float, float] = (1.0, 1.0, 1.0)
    kz_ratio: float = 1.0
    power_scale: float = 1.0
    band_scale: float = 1.0
    sigma_crown: float | None = None
    adapt_power: bool | None = None
    layers: int | None = None
    layer_growth: float | None = None
    effects: dict[str, dict[str, Any]] = field(default_factory=dict)
    source: str = ""


# Ranges of the identified values an h_law.toml may carry (those identify-h can produce).
CALIBRATION_BOUNDS: dict[str, tuple[float, float]] = {
    "kz_ratio": (0.01, 10.0),
    "power_scale": (0.2, 5.0),
    "band_scale": (1.0, 100.0),
    "sigma_crown": (0.0, 5.0),
    "layers": (1, 8),
    "layer_growth": (0.2, 10.0),
}


def read_calibration(path: str | Path) -> DiscCalibration:
    """Read an ``h_law.toml`` written by identify-h, checking its ``[extra]`` values."""
    record = read_h_law(path)
    extra = record.extra
    values: dict[str, Any] = {}
    for key, (lo, hi) in CALIBRATION_BOUNDS.items():
        raw = extra.get(key)
        if raw is None:
            continue
        whole = key == "layers"
        if isinstance(raw, bool) or not isinstance(raw, int | float) or (
            whole and raw != int(raw)
        ) or not math.isfinite(raw) or not lo <= raw <= hi:
            kind = "a whole number" if whole else "a number"
            raise ConfigError(
                f"[extra] {key} = {raw!r} must be {kind} between {lo:g} and {hi:g}", path=path
            )
        values[key] = int(raw) if whole else float(raw)
    adapt = extra.get("adapt_power")
    if adapt is not None and not isinstance(adapt, bool):
        raise ConfigError(f"[extra] adapt_power = {adapt!r} must be true or false", path=path)
    return DiscCalibration(law=record.law, weights=record.weights, adapt_power=adapt,
                           effects=_checked_effects(record.effects, path), source=str(path),
                           **values)


def _checked_effects(tables: dict[str, dict[str, Any]], path: str | Path
                     ) -> dict[str, dict[str, Any]]:
    """``[effects.<name>]`` tables checked against the registry: names, keys, bounds."""
    out: dict[str, dict[str, Any]] = {}
    for name, table in tables.items():
        effect = EFFECTS.get(name)
        if effect is None:
            raise ConfigError(f"[effects.{name}]: unknown effect; valid effects are "
                              f"{', '.join(EFFECTS)}", path=path)
        known = {p.name: p for p in effect.params}
        if effect.latent_param is not None:
            known[effect.latent_param.name] = effect.latent_param
        checked: dict[str, Any] = {}
        for key, raw in table.items():
            param = known.get(key)
            if param is None:
                raise ConfigError(f"[effects.{name}] {key}: not a parameter of {name} (it has:"
                                  f" {', '.join(known) or 'none'})", path=path)
            values = raw if isinstance(raw, list) else [raw]
            for v in values:
                if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                        or not param.lower <= v <= param.upper:
                    raise ConfigError(
                        f"[effects.{name}] {key} = {raw!r} must be a number between"
                        f" {param.lower:g} and {param.upper:g} {param.unit}", path=path)
            checked[key] = [float(v) for v in values] if isinstance(raw, list) else float(raw)
        out[name] = checked
    return out


def calibration_for(disc: DiscSpec, h_law: str | Path | None) -> DiscCalibration:
    """The user's ``h_law.toml``, or the one shipped for the disc."""
    path = Path(h_law) if h_law is not None else shipped_h_law(disc)
    if path is None:
        raise ConfigError(
            f"no h(V) law for disc '{disc.id}': run `brakethermo identify-h` on a multi-spot"
            " test session and pass its h_law.toml with --h-law"
        )
    return read_calibration(path)
