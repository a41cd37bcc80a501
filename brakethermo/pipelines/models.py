"""Resolving the disc datasheet and the h(V) law a session is processed with."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from brakethermo.config import ConfigTable, config_dir
from brakethermo.errors import ConfigError
from brakethermo.io.session import Session
from brakethermo.models.effects import EFFECTS
from brakethermo.thermal.disc import DiscSpec, load_disc
from brakethermo.thermal.hlaw import HLaw, read_h_law

DEFAULT_DISC = "cc-340-8"


def disc_for(session: Session, disc: str | Path | None = None) -> DiscSpec:
    """The datasheet given by the user, else the session's ``disc`` fact, else the default."""
    return load_disc(disc or session.metadata.get("disc") or DEFAULT_DISC)


# Words that start the warnings about the disc a run assumed or a law made for another:
# batch repeats these (and only these) of a session's warnings on its console.
DISC_ASSUMED = "the session's facts name no disc"
OTHER_DISC = "this h law was identified on disc"


def assumed_disc(session: Session, disc: str | Path | None = None) -> str | None:
    """What to say when the disc is neither given nor a fact of the session (a CSV of a
    logger that writes no facts): the default disc was assumed (else None)."""
    if disc or session.metadata.get("disc"):
        return None
    return (f"{DISC_ASSUMED}: processed as the default disc {DEFAULT_DISC} — if it runs"
            " another, name it (estimate/diagnose --disc, whatif --disc-of-session) or add a"
            " 'disc' fact to the file")


def disc_warnings(warnings: list[str]) -> list[str]:
    """The warnings of a run about its disc: assumed, or the law's is another."""
    return [w for w in warnings if w.startswith(DISC_ASSUMED) or OTHER_DISC in w]


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
    sigma_temp : float or None — degC per step
        White process noise on the nodes chosen by the same validation.
    sigma_crown : float or None
        Crown-split process noise chosen by held-out-spot validation on that session.
    adapt_power : bool or None
        Whether the braking-power scale is a filter state, chosen by that validation.
    layers, layer_growth : int or None, float or None
        The through-thickness layering the calibration was fitted with (``kz_ratio``
        belongs to it); ``None`` leaves the tuning's.
    nodes : int or None
        The radial nodes it was fitted with (a thin-skin disc's law has more);
        ``None`` leaves the tuning's.
    effects : dict of str to dict
        Fitted effect parameters by effect name (``[effects.<name>]`` of the file),
        validated against :data:`brakethermo.models.effects.EFFECTS`.
    source : str
        Where it came from (file path).
    disc_id : str or None
        The datasheet the law was identified with (``[extra] disc``; older files: None).
    identified_on : str or None
        The session file it was identified on (``[extra] session``).
    h_rel_sigma : float or None
        Relative 1-sigma of the law's level (``[extra] h_rel_sigma``, set by hand; whatif
        replays over it), ``None`` when the file gives none.
    """

    law: HLaw
    weights: tuple[float, float, float] = (1.0, 1.0, 1.0)
    kz_ratio: float = 1.0
    power_scale: float = 1.0
    band_scale: float = 1.0
    sigma_crown: float | None = None
    sigma_temp: float | None = None
    adapt_power: bool | None = None
    layers: int | None = None
    layer_growth: float | None = None
    nodes: int | None = None
    effects: dict[str, dict[str, Any]] = field(default_factory=dict)
    source: str = ""
    disc_id: str | None = None
    identified_on: str | None = None
    h_rel_sigma: float | None = None


# Ranges of the values an h_law.toml's [extra] may carry: those identify-h produces, and
# h_rel_sigma, set by hand for whatif (checked wherever the law is read: a law with a
# value out of range is wrong whichever command reads it).
CALIBRATION_BOUNDS: dict[str, tuple[float, float]] = {
    "kz_ratio": (0.01, 10.0),
    "power_scale": (0.2, 5.0),
    "band_scale": (1.0, 100.0),
    "sigma_crown": (0.0, 5.0),
    "sigma_temp": (0.0, 50.0),
    "layers": (1, 8),
    "layer_growth": (0.2, 10.0),
    "nodes": (10, 400),
    "h_rel_sigma": (0.0, 1.0),
}


def read_calibration(path: str | Path) -> DiscCalibration:
    """Read an ``h_law.toml`` written by identify-h, checking its ``[extra]`` values."""
    record = read_h_law(path)
    extra = ConfigTable(record.extra, path, "extra")
    values: dict[str, Any] = {}
    for key, (lo, hi) in CALIBRATION_BOUNDS.items():
        if extra.has(key):
            if key in ("layers", "nodes"):
                values[key] = extra.integer(key, lo=lo, hi=hi)
            else:
                values[key] = extra.number(key, lo=lo, hi=hi)
    adapt = extra.boolean("adapt_power") if extra.has("adapt_power") else None
    disc_id = record.extra.get("disc")
    return DiscCalibration(law=record.law, weights=record.weights, adapt_power=adapt,
                           effects=_checked_effects(record.effects, path), source=str(path),
                           disc_id=str(disc_id) if disc_id is not None else None,
                           identified_on=(str(record.extra["session"])
                                          if "session" in record.extra else None), **values)


def _checked_effects(tables: dict[str, Any], path: str | Path) -> dict[str, dict[str, Any]]:
    """``[effects.<name>]`` tables checked against the registry: names, keys, bounds."""
    ConfigTable(tables, path, "effects").only(EFFECTS, "a registered effect")
    out: dict[str, dict[str, Any]] = {}
    for name, raw in tables.items():
        effect = EFFECTS[name]
        table = ConfigTable(raw, path, f"effects.{name}")
        latent = effect.latent_params
        known = {p.name: p for p in (*effect.params, *latent)}
        table.only(known, f"a parameter of {name}")
        checked: dict[str, Any] = {}
        for key, param in known.items():
            if not table.has(key) and param in latent:
                continue  # a missing effect parameter is an error: it would run neutral
            if param in latent:
                checked[key] = list(table.numbers(key, lo=param.lower, hi=param.upper))
            else:
                checked[key] = table.number(key, lo=param.lower, hi=param.upper)
        out[name] = checked
    return out


def calibration_for(disc: DiscSpec, h_law: str | Path | DiscCalibration | None
                    ) -> DiscCalibration:
    """The user's ``h_law.toml``, or the one shipped for the disc (a calibration a command
    already read is returned as it is)."""
    if isinstance(h_law, DiscCalibration):
        return h_law
    path = Path(h_law) if h_law is not None else shipped_h_law(disc)
    if path is None:
        raise ConfigError(
            f"no h(V) law for disc '{disc.id}': run `brakethermo identify-h` on a multi-spot"
            " test session and pass its h_law.toml with --h-law"
        )
    return read_calibration(path)


def other_disc(cal: DiscCalibration, disc: DiscSpec, option: str = "estimate --disc"
               ) -> str | None:
    """What to say when the law was identified on another disc than ``disc`` (else None);
    ``option`` is the command's option that names the session's disc (batch has none:
    the session's ``disc`` fact does it there, and is named too)."""
    if cal.disc_id is None or cal.disc_id == disc.id:
        return None
    return (f"{cal.source}: {OTHER_DISC} '{cal.disc_id}' but the session"
            f" runs disc '{disc.id}': identify-h on a test session of disc '{disc.id}', or"
            f" name the session's disc with {option} (or its 'disc' fact) if its facts are"
            " wrong")


OWN_LAW = "identified from this session by identify-h (beside it in --out)"


def own_h_law(folder: str | Path, session: Session | Path) -> DiscCalibration | None:
    """The law identify-h wrote for this very session (read, or its file) into
    ``folder``, read, if any.

    identify-h writes ``OUT/<stem>/h_law.toml`` and records the session in ``[extra]``;
    a law there of another session with the same file stem is not this session's.
    """
    path = Path(folder) / "h_law.toml"
    if not path.is_file():
        return None
    cal = read_calibration(path)
    name = session.name if isinstance(session, Path) else session.path.name
    if cal.identified_on is not None and Path(cal.identified_on).name != name:
        return None
    return cal


SHIPPED_DEFAULT = "shipped default"  # choose_h_law's reason for the disc's shipped law
SHIPPED_LAW_NOTE = ("the law shipped for the disc was identified on a simulated test session,"
                    " and a bike's own can be far from it (an independent generator's race:"
                    " 0.79x of the single-spot baseline with it, 0.14x with its own) — run"
                    " identify-h on a four-spot test session of this disc and pass --h-law")


def choose_h_law(
    given: str | Path | None, folder: str | Path, session: Session, disc: DiscSpec
) -> tuple[Path | DiscCalibration | None, str]:
    """The law a single ``estimate`` uses, and why (printed and recorded in summary.json):
    a path, or the law beside the session as already read.

    Order: the ``--h-law`` file; the law identify-h wrote for this session beside its
    outputs (``OUT/<stem>/h_law.toml``); the law shipped for the disc.
    """
    if given is not None:
        return Path(given), "given with --h-law"
    own = own_h_law(folder, session)
    if own is not None:
        return own, OWN_LAW
    shipped = shipped_h_law(disc)
    return shipped, f"{SHIPPED_DEFAULT} for disc {disc.id}"
